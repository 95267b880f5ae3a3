/** @file
 * The distributed evaluation for hosts that load C at run time (the Python
 * package's ntscontact.mpi over mpi4py, through ctypes): flat calls, text in
 * and out, in libntscontact_mpi_engine.so (the codec, the core and
 * libntscontact_mpi in one shared object). Each rank holds a session of the
 * bodies it owns, given as a scene document (schemas/scene.schema.json) and
 * their global indices; a step takes this rank's positions and gives the
 * forces on its nodes and the whole scene's summary as the daemon's binary
 * answer headers (NTS-Energy, ...). Every call is collective; an error is
 * every rank's, as an error document (schemas/error.schema.json) whose
 * pointer names the body by its global index (/bodies/B/...). */
#ifndef NTSCONTACT_MPI_ENGINE_H
#define NTSCONTACT_MPI_ENGINE_H

#include <stddef.h>

#include <ntscontact/base.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A session of this rank's bodies. */
typedef struct ntsm_engine ntsm_engine;

/** Collective: a session of the bodies in `json` (this rank's part of the
 * scene; "options" the same on every rank), ids[k] the global index of its
 * k-th body, over the communicator whose Fortran handle is `comm_f`
 * (MPI_Comm_c2f; mpi4py: comm.py2f()), evaluating on `threads` threads.
 * NULL on error with *error an error document (ntsm_engine_free_text). */
NTS_API ntsm_engine* ntsm_engine_create(int comm_f, const char* json, size_t length, const int* ids, int count,
                                        int threads, char** error);

/** This rank's nodes, the whole scene's bodies and surface nodes. */
NTS_API void ntsm_engine_counts(const ntsm_engine* engine, long long out[3]);

/** Collective: a step at `positions` (this rank's nodes, x then y, `length`
 * bytes = 16 x its nodes; NULL: the stored ones), with the scene's options
 * but for the overrides given (has_* 1; solver -1: the scene's; outputs 0:
 * the scene's, else NTS_OUT_* flags among forces, energy and virial).
 * Writes this rank's forces into `forces` (2 x its nodes doubles) and the
 * summary's header lines into *headers. 0, or -1 with *error. */
NTS_API int ntsm_engine_step(ntsm_engine* engine, const double* positions, size_t length, int has_penalty,
                             double penalty, int has_alpha, double alpha, int has_radius, double radius,
                             int solver, unsigned outputs, double* forces, char** headers, char** error);

/** Text from ntsm_engine_create or ntsm_engine_step; NULL is a no-op. */
NTS_API void ntsm_engine_free_text(char* text);

/** Not collective: frees this rank's session. */
NTS_API void ntsm_engine_destroy(ntsm_engine* engine);

#ifdef __cplusplus
}
#endif
#endif
