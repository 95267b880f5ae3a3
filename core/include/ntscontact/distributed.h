/** @file
 * The seam a distributed host evaluates through (docs/distributed.md):
 * evaluate a part of a scene (the bodies one rank holds) as if it were the
 * whole, and get each active contact's contributions, in contact order, so
 * that the host can sum them in the order one process would and give the
 * same bits for any number of ranks.
 *
 * Two things tie a part to its whole:
 * - the frame (nts_frame): what the whole scene's segments set, its median
 *   segment (the default search radius, docs/model.md §9), its longest
 *   segment and its extent (the reach's allowances) and the summary's cell
 *   size. A context given a frame evaluates with it instead of its scene's.
 * - the parts (nts_part): with nts_context_set_parts on, an evaluation keeps
 *   its active contacts' records and leaves, per active contact, the terms
 *   the energy and virial add and the forces on each of its nodes, computed
 *   by the contact law as the scatter computes them.
 * The host keeps the parts of the slaves it owns, sums the energy of each
 * chunk of NTS_PART_CHUNK slave entries (global entry order) in contact
 * order and the chunks in order, then the deep contacts; and each node's
 * forces in contact order, the deep contacts last (ntscontact-mpi does). */
#ifndef NTSCONTACT_DISTRIBUTED_H
#define NTSCONTACT_DISTRIBUTED_H

#include <ntscontact/ntscontact.h>

#ifdef __cplusplus
extern "C" {
#endif

/** The slave entries whose sums one process adds up before the next chunk's
 * (context.h's CHUNK_SLAVES). */
#define NTS_PART_CHUNK 1024

/** What the whole scene's segments set (docs/distributed.md). */
typedef struct nts_frame {
    double median;    /**< the median segment ((n - 1) / 2-th smallest length): the default radius */
    double lmax;      /**< the longest segment */
    double coord_max; /**< the largest |coordinate| of a surface node */
    /** the surface nodes' bounding box @{ */
    double xmin, xmax, ymin, ymax;
    /** @} */
    double cell_size; /**< nts_summary.cell_size of the whole scene; negative: the part's own */
    int surface_nodes;/**< the whole scene's surface entries (the cell grid's cap) */
    int surface_ends; /**< 1: some contact surface of the whole has an end (nts_options.surface_extension applies) */
    /** the bodies of the whole whose friction coefficient is above 0: those
     * that can be slaves, masters, both, and those that meet themselves
     * (summed over the parts: friction runs when some pair that can meet
     * rubs, decided on the whole, docs/model.md §14) @{ */
    long long rubbing[4];
    /** @} */
} nts_frame;

/** One active contact's contributions (contact order: by slave entry, then
 * master body; deep contacts at their places). */
typedef struct nts_part {
    int entry;          /**< the slave's surface entry in this scene */
    int master_body;    /**< in this scene */
    int deep;           /**< 1: found deeper than r (summed after every chunk's contacts) */
    int state;          /**< nts_friction_state */
    int nodes[4];       /**< scene nodes: the slave, then the master nodes; -1 past the last */
    nts_vec2 force[4];  /**< the force on each of them */
    double energy;      /**< what it adds to the energy (9) (with its tangential spring's (26)) */
    double dissipation; /**< what it adds to the dissipation (27) */
    nts_virial virial;  /**< what it adds to the virial (11) (or (28) with friction) */
    double penetration; /**< -g */
    /** its tangent's triplets in nts_result.stiffness: from stiff_at, stiff_count of them @{ */
    int stiff_at, stiff_count;
    /** @} */
} nts_part;

/** The frame of `scene` for `opt` as one process computes it (the median only
 * with a default radius, the cell size only for the cell search). NTS_OK,
 * NTS_ENOMEM, or NTS_EDEGENERATE_SEGMENT. `lengths`, when not NULL, gets
 * every surface entry's segment length (surface_count of them). */
NTS_API int nts_scene_frame(nts_context* ctx, const nts_scene* scene, const nts_options* opt, nts_frame* out,
                            double* lengths, nts_error* err);

/** The context's evaluations take `frame` for their scene's (NULL: their own). */
NTS_API void nts_context_set_frame(nts_context* ctx, const nts_frame* frame);

/** 1: the context's evaluations keep their parts (nts_context_parts); 0: not. */
NTS_API void nts_context_set_parts(nts_context* ctx, int on);

/** The last evaluation's parts, in contact order. */
NTS_API const nts_part* nts_context_parts(const nts_context* ctx, int* count);

/** The slaves the host owns, by surface entry of the scene it evaluates
 * next (1: owned; NULL: none, the default): with parts on, an evaluation
 * counts their closest points within r apart (nts_context_owned_gaps). The
 * array is the host's and must outlive the evaluations. */
NTS_API void nts_context_set_owned(nts_context* ctx, const unsigned char* owned);

/** The last evaluation's closest points within r of the owned slaves (their
 * deep contacts not counted). */
NTS_API long long nts_context_owned_gaps(const nts_context* ctx);

/** The candidate budget of an evaluation under opt of a scene of
 * `surface_nodes` surface nodes (a part's: its whole's): max_candidates, or
 * 64 a surface node plus a million; at most INT_MAX (the count is
 * nts_summary.gaps, an int). */
NTS_API long long nts_candidate_budget(const nts_options* opt, long long surface_nodes);

/** The words of an evaluation over that budget, NUL-terminated in out:
 * "... within the search radius" when the closest points within r alone
 * exceed it, "... within the search radius and deeper" (deeper != 0) when
 * only those deeper take it over. */
NTS_API void nts_candidate_budget_message(char* out, size_t size, long long budget, int deeper);

/** With NTS_OUT_GAPS or NTS_OUT_CONTACTS asked (every record kept): the
 * slave entry of every closest point of the last evaluation (its gaps, the
 * deep contacts among them), in the order of nts_result.gaps. */
NTS_API const int* nts_context_gap_entries(const nts_context* ctx, int* count);

/** The slave entries a warning of the last evaluation counted (code:
 * NTS_WARN_PENETRATION_BEYOND_RADIUS or _BEYOND_REACH), once per count. */
NTS_API const int* nts_context_warning_entries(const nts_context* ctx, int code, int* count);

/** Surface entry e of `scene`: its body and its node inside the body. */
NTS_API void nts_scene_entry(const nts_scene* scene, int e, int* body, int* node);

/** Body b's first surface entry (b = body count: the scene's surface count). */
NTS_API int nts_scene_body_entry_start(const nts_scene* scene, int b);

#ifdef __cplusplus
}
#endif
#endif
