/* ntscontact-mpi: the CLI (cli/src/main.c) on rank 0, evaluating across
 * every rank of MPI_COMM_WORLD (docs/distributed.md). Rank 0 reads and
 * checks the request as ntscontact does; at the evaluation the codec calls
 * `evaluate` below, which deals the bodies to the ranks (blocks of about
 * equal nodes), gives them the whole scene's frame, evaluates with the
 * library and gathers the answer on rank 0, which the codec encodes: the
 * bytes ntscontact writes. The other ranks wait for jobs until rank 0 is
 * done. */
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/codec.h>
#include <ntscontact/mpi.h>

#include "internal.h"

int nts_cli_main(int argc, char** argv);
void ntsm_cli_configure(ntsj_config* cfg);

enum { JOB_STOP = 0, JOB_EVALUATE = 1 };

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

static int deal_bodies(MPI_Comm comm, int root, const nts_body_def* bodies, int body_count, ntsm_dealt* out) {
    int rank, size, r, k, ok = 1;
    memset(out, 0, sizeof *out);
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    if (rank == root) {
        /* contiguous blocks of about equal nodes, as a host's decomposition:
         * body b goes to the rank its first node's place falls in */
        long long nodes = 0, acc = 0;
        int b = 0;
        for (k = 0; k < body_count; ++k) nodes += bodies[k].node_count;
        for (r = 0; r < size; ++r) {
            bytes blk;
            const int first = b;
            long long head[2];
            memset(&blk, 0, sizeof blk);
            while (b < body_count && (nodes == 0 ? r == size - 1 : (int)(acc * size / nodes) == r)) {
                ntsm_body_write(&blk, &bodies[b], b, bodies[b].reference ? bodies[b].reference : bodies[b].nodes);
                acc += bodies[b++].node_count;
            }
            head[0] = b - first;
            if (blk.oom || blk.n > INT_MAX) {
                ok = 0;
                head[0] = 0; /* nothing sent: every rank learns it below */
                blk.n = 0;
            }
            head[1] = (long long)blk.n;
            if (r == root) {
                out->count = (int)head[0];
                out->data = blk;
            } else {
                MPI_Send(head, 2, MPI_LONG_LONG, r, 71, comm);
                if (head[1] > 0) MPI_Send(blk.p, (int)blk.n, MPI_BYTE, r, 72, comm);
                free(blk.p);
            }
        }
    } else {
        long long head[2];
        MPI_Recv(head, 2, MPI_LONG_LONG, root, 71, comm, MPI_STATUS_IGNORE);
        out->count = (int)head[0];
        if (ntsm_bytes_room(&out->data, (size_t)head[1] + 8) == NULL) {
            /* nowhere to receive the bodies into: end the job, not in a crash */
            fprintf(stderr, "ntscontact-mpi: rank %d: out of memory receiving its bodies\n", rank);
            MPI_Abort(comm, 4);
        }
        out->data.n = (size_t)head[1];
        if (head[1] > 0) MPI_Recv(out->data.p, (int)head[1], MPI_BYTE, root, 72, comm, MPI_STATUS_IGNORE);
    }
    out->defs = (nts_body_def*)calloc((size_t)out->count + 1, sizeof(nts_body_def));
    out->ids = (int*)calloc((size_t)out->count + 1, sizeof(int));
    if (out->defs == NULL || out->ids == NULL) ok = 0;
    if (ok) {
        size_t p = 0;
        for (k = 0; k < out->count; ++k) p += ntsm_body_read(out->data.p + p, &out->defs[k], &out->ids[k]);
    }
    {
        int all_ok;
        MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, comm);
        return all_ok ? NTS_OK : NTS_ENOMEM;
    }
}

static void dealt_free(ntsm_dealt* d) {
    free(d->data.p);
    free(d->defs);
    free(d->ids);
    memset(d, 0, sizeof *d);
}


/* A job's state, kept until the next (its result's arrays live in it). */
typedef struct job {
    ntsm_dealt dealt;
    ntsm_scene* scene;
} job;

static job current;

static void job_end(void) {
    ntsm_scene_destroy(current.scene);
    dealt_free(&current.dealt);
    memset(&current, 0, sizeof current);
}

/* Every rank: one evaluation of the bodies root deals (def only read on
 * root), with root's options and frame. */
static int job_run(const nts_scene_def* def, nts_options* opt, nts_frame* frame, const nts_anchor* anchors, int count,
                   nts_result* out, nts_error* err) {
    double box[2] = {0.0, 0.0};
    nts_limits limits = nts_default_limits();
    int rank, rc;
    ntsm_result mine;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    job_end();
    if (rank == 0) {
        box[0] = def->lx;
        box[1] = def->ly;
        limits = def->limits;
    }
    MPI_Bcast(opt, (int)sizeof *opt, MPI_BYTE, 0, MPI_COMM_WORLD);
    MPI_Bcast(frame, (int)sizeof *frame, MPI_BYTE, 0, MPI_COMM_WORLD);
    MPI_Bcast(box, 2, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Bcast(&limits, (int)sizeof limits, MPI_BYTE, 0, MPI_COMM_WORLD);
    if ((rc = deal_bodies(MPI_COMM_WORLD, 0, rank == 0 ? def->bodies : NULL, rank == 0 ? def->body_count : 0,
                               &current.dealt)) != NTS_OK) {
        *err = nts_error_none();
        err->code = rc;
        strcpy(err->message, "out of memory");
        return rc;
    }
    current.scene = ntsm_scene_create(MPI_COMM_WORLD, current.dealt.defs, current.dealt.ids, current.dealt.count,
                                      box[0], box[1], limits, err);
    if (current.scene == NULL) return err->code;
    ntsm_scene_set_frame(current.scene, frame);
    /* friction's committed anchors: rank 0's, to every rank */
    {
        nts_anchor* given = NULL;
        int ok = 1, all;
        MPI_Bcast(&count, 1, MPI_INT, 0, MPI_COMM_WORLD);
        if (count > 0) {
            given = rank == 0 ? (nts_anchor*)(uintptr_t)anchors : (nts_anchor*)malloc(sizeof(nts_anchor) * (size_t)count);
            ok = given != NULL;
        }
        MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (!all) {
            if (rank != 0) free(given);
            *err = nts_error_none();
            err->code = NTS_ENOMEM;
            strcpy(err->message, "out of memory");
            return NTS_ENOMEM;
        }
        if (count > 0) MPI_Bcast(given, (int)(sizeof(nts_anchor) * (size_t)count), MPI_BYTE, 0, MPI_COMM_WORLD);
        ok = ntsm_scene_set_history(current.scene, given, count) == NTS_OK;
        if (rank != 0) free(given);
        MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (!all) {
            *err = nts_error_none();
            err->code = NTS_ENOMEM;
            strcpy(err->message, "out of memory");
            return NTS_ENOMEM;
        }
    }
    if ((rc = ntsm_evaluate(current.scene, opt, &mine, err)) != NTS_OK) return rc;
    return ntsm_gather(current.scene, 0, out, err);
}

/* The codec's evaluation on rank 0. */
static int evaluate(void* user, const nts_scene_def* def, const nts_scene* scene, const nts_options* opt,
                    nts_result* out, nts_error* err) {
    int cmd = JOB_EVALUATE, rc;
    nts_options o = *opt;
    nts_frame frame;
    nts_context* ctx;
    (void)user;
    memset(out, 0, sizeof *out);
    /* the whole scene's frame, computed here where the whole scene is */
    if ((ctx = nts_context_create()) == NULL) return NTS_ENOMEM;
    rc = nts_scene_frame(ctx, scene, opt, &frame, NULL, err);
    nts_context_destroy(ctx);
    if (rc != NTS_OK) return rc;
    o.cancel = NULL; /* a deadline is rank 0's: the others cannot ask it */
    o.cancel_user = NULL;
    o.history = NULL; /* its anchors go to every rank (job_run) */
    o.candidates = NULL;
    MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
    {
        int n = 0;
        const nts_anchor* anchors = opt->history != NULL ? nts_history_anchors(opt->history, &n) : NULL;
        return job_run(def, &o, &frame, anchors, n, out, err);
    }
}

void ntsm_cli_configure(ntsj_config* cfg) {
    cfg->evaluate = evaluate;
    cfg->evaluate_user = NULL;
}

int main(int argc, char** argv) {
    int rank, status = 0, provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (rank == 0) {
        int cmd = JOB_STOP;
        status = nts_cli_main(argc, argv);
        MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
    } else {
        for (;;) {
            int cmd;
            nts_options opt;
            nts_frame frame;
            nts_result out;
            nts_error err;
            MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
            if (cmd != JOB_EVALUATE) break;
            (void)job_run(NULL, &opt, &frame, NULL, 0, &out, &err);
        }
    }
    job_end();
    MPI_Finalize();
    return status;
}
