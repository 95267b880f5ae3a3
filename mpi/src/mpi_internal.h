/* What ntscontact-mpi's hook (cli_hook.c) shares with mpi.c (not installed). */
#ifndef NTSCONTACT_MPI_INTERNAL_H
#define NTSCONTACT_MPI_INTERNAL_H

#include <stddef.h>

#include <ntscontact/mpi.h>

/* A growing byte buffer (8-byte aligned items). */
typedef struct bytes {
    char* p;
    size_t n, cap;
    int oom;
} bytes;

/* The bodies root dealt this rank: contiguous blocks of about equal nodes
 * (a host's decomposition), their global indices and definitions (pointing
 * into `data`). */
typedef struct ntsm_dealt {
    int count;
    int* ids;
    nts_body_def* defs;
    bytes data;
} ntsm_dealt;

/* Collective: root's bodies (body_count of them, only read on root) dealt
 * to the ranks. NTS_OK or, on every rank, NTS_ENOMEM. */
int ntsm_deal_bodies(MPI_Comm comm, int root, const nts_body_def* bodies, int body_count, ntsm_dealt* out);
void ntsm_dealt_free(ntsm_dealt* d);

#endif
