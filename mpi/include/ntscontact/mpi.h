/** @file
 * One scene across the ranks of an MPI communicator (docs/distributed.md):
 * each rank holds the bodies the host gives it, the library cuts the plane
 * into slabs of about equal surface nodes, sends each slab the bodies that
 * reach into it (the halo), evaluates the slave nodes each slab owns, and
 * sums every contribution in the order one process would: the answer is the
 * same bits as nts_evaluate on the whole scene, for any number of ranks.
 * Every call is collective, and an error is every rank's: the same code,
 * message and body (the global index) everywhere. */
#ifndef NTSCONTACT_MPI_H
#define NTSCONTACT_MPI_H

#include <mpi.h>

#include <ntscontact/distributed.h>
#include <ntscontact/ntscontact.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A scene distributed over a communicator. */
typedef struct ntsm_scene ntsm_scene;

/** What an evaluation moved and held, on this rank. */
typedef struct ntsm_stats {
    long long bytes_sent;     /**< bytes this rank sent (bodies, contributions, sums) */
    long long bytes_received; /**< bytes it received */
    int owned_slaves;         /**< the slave entries its slab owns */
    int part_entries;         /**< the surface entries it evaluated (owned, and the halo's) */
    int part_bodies;          /**< the bodies it held for the evaluation */
    int rebuilt;              /**< 1: the decomposition was made anew (else the kept one's positions moved) */
    double seconds[4];        /**< frame and decomposition, bodies' exchange, evaluation, sums */
    int candidates_replayed;  /**< 1: the part's evaluation replayed its kept candidate list (it held: not built) */
} ntsm_stats;

/** The answer on one rank: the whole scene's summary and warnings, and the
 * forces (and pressure) on the nodes of the bodies this rank owns, body by
 * body in the order it gave them. Valid until the next evaluation. */
typedef struct ntsm_result {
    nts_summary summary;      /**< the whole scene's, as nts_evaluate gives it */
    nts_warning warnings[NTS_WARN_COUNT_]; /**< what may be missing, in code order */
    int warning_count;        /**< how many `warnings` */
    const nts_vec2* forces;   /**< NULL unless NTS_OUT_FORCES */
    const double* pressure;   /**< NULL: the pressure comes from ntsm_gather */
    int node_count;           /**< this rank's nodes */
    ntsm_stats stats;         /**< what this rank moved and held */
} ntsm_result;

/** Collective: the bodies this rank owns, `ids[k]` the global index of
 * bodies[k] (every index 0..B-1 on exactly one rank), the periodic box and
 * the limits the same on every rank (boxes that differ are
 * NTS_EINVALID_ARGUMENT, err->option "periodic"). The bodies are copied.
 * NULL on error, with *err the same on every rank (err->body a global
 * index). */
NTS_API ntsm_scene* ntsm_scene_create(MPI_Comm comm, const nts_body_def* bodies, const int* ids, int count, double lx,
                              double ly, nts_limits limits, nts_error* err);
/** Frees this rank's part of the scene (not collective); NULL is a no-op. */
NTS_API void ntsm_scene_destroy(ntsm_scene* scene);

/** New positions of this rank's nodes (its bodies' in order). Collective:
 * NTS_OK everywhere, or every rank's error (a rank whose bodies are
 * reshaped: NTS_ERESHAPED, naming the body). */
NTS_API int ntsm_scene_update_positions(ntsm_scene* scene, const nts_vec2* positions, nts_error* err);

/** Collective: the whole scene's frame (distributed.h) for the next
 * evaluations, when a rank holds the whole scene and computed it
 * (nts_scene_frame; ntscontact-mpi's rank 0 does), so that the summary's
 * cell size is the whole scene's too; NULL: found across the ranks. */
NTS_API void ntsm_scene_set_frame(ntsm_scene* scene, const nts_frame* frame);

/** The skin of the kept decomposition (docs/distributed.md): the slabs and
 * halos are kept between evaluations while no node has moved more than
 * skin / 2... precisely: while twice the largest move since they were made,
 * added to the halo now needed, stays within the halo they were made with
 * (the needed one plus 2 skin). Negative (the default): 0.3 times the search
 * radius. 0: made anew every evaluation. The answer is the same bits
 * whatever the skin. Call it on every rank with the same value. */
NTS_API void ntsm_scene_set_skin(ntsm_scene* scene, double skin);

/** How many of the surface nodes each rank's slab takes (docs/distributed.md).
 * NULL (the default): equal shares at first, then balanced by measured time:
 * when cuts in proportion to each rank's measured speed (smoothed) would
 * make the slowest part at least 5% shorter and the time such cuts would
 * have saved since the last cut reaches what a cut costs (about an
 * evaluation that makes the parts; nothing with a skin of 0), the slabs
 * are cut anew at those speeds (a core shared with other work, unequal
 * machines; noise that moves between the ranks does not cut). Else
 * `weights` (one for each rank of the communicator, positive and finite):
 * each rank's relative speed, fixed (all equal: equal shares, never moved).
 * Call it on every rank with the same values (an evaluation checks:
 * NTS_EINVALID_OPTION); the next evaluation cuts the slabs anew. The answer
 * is the same bits whatever the weights. NTS_OK or NTS_ENOMEM. */
NTS_API int ntsm_scene_set_weights(ntsm_scene* scene, const double* weights);

/** Friction's committed anchors (docs/model.md §14) the next evaluations
 * start from, with global body indices (a previous evaluation's, from
 * ntsm_gather: nts_result.anchors), the same on every rank; copied. NULL or
 * 0: none (every contact new). Not collective; NTS_OK or NTS_ENOMEM. */
NTS_API int ntsm_scene_set_history(ntsm_scene* scene, const nts_anchor* anchors, int count);

/** Collective: evaluate. opt->history, opt->candidates and opt->cancel must
 * be NULL (NTS_EINVALID_ARGUMENT; friction's history is given by
 * ntsm_scene_set_history). While the decomposition is kept (a skin not 0,
 * ntsm_scene_set_skin), each rank's part keeps its own candidate list
 * between evaluations (docs/model.md §15; about 90 bytes a surface node of
 * the part): the same bits as searching anew. NTS_OK or every rank's error. */
NTS_API int ntsm_evaluate(ntsm_scene* scene, const nts_options* opt, ntsm_result* out, nts_error* err);

/** Collective, after a successful ntsm_evaluate: the whole answer on `root`,
 * as nts_evaluate gives it (forces, pressure, contacts, gaps, tangent and
 * anchors as the options asked, global node and body indices), in *out,
 * valid until the next evaluation; other ranks get nothing. NTS_OK or
 * every rank's NTS_ENOMEM. */
NTS_API int ntsm_gather(ntsm_scene* scene, int root, nts_result* out, nts_error* err);

#ifdef __cplusplus
}
#endif
#endif
