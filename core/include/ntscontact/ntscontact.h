/** @file
 * ntscontact: node-to-segment contact between deformable 2D bodies with
 * Hermite-smoothed corners. The public API: scenes (topology + positions),
 * options, a reusable evaluation context and its result.
 *
 * Ownership: a scene owns copies of everything given to it. A context owns the
 * memory its result points into; the result stays valid until the next
 * evaluation with that context or its destruction. */
#ifndef NTSCONTACT_H
#define NTSCONTACT_H

#include "base.h"
#include "geometry.h"
#include "math_functions.h"
#include "tables.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- scene */

/** What a body takes part in (docs/model.md §5; docs/model.md,
 * "Per-body options"). */
typedef enum nts_role {
    NTS_ROLE_BOTH = 0,   /**< its nodes touch other bodies and it offers its surface (default) */
    NTS_ROLE_MASTER = 1, /**< an obstacle: offers its surface, its nodes are never slaves; two
                            master bodies never interact; the reaction on its nodes is returned */
    NTS_ROLE_SLAVE = 2   /**< its nodes touch other bodies, it offers no surface */
} nts_role;

/** One body as the caller has it. Give either loops or triangles:
 * - loops: `loop_count` loops, loop l is loop_nodes[loop_start[l] .. loop_start[l+1]),
 *   `loop_start` has loop_count + 1 entries;
 * - triangles: `triangle_count` triples of node indices (a linear triangle mesh);
 *   the boundary is extracted from the connectivity (each connected piece
 *   oriented through its shared edges, directed edges whose reverse is absent,
 *   chained into loops, the piece turned so that its outer loop runs
 *   counter-clockwise); interior triangles are not checked (zero area or
 *   turned over is fine: contact reads the boundary);
 * - neither: one loop through all nodes in order. */
typedef struct nts_body_def {
    const nts_vec2* nodes;     /**< node_count positions (copied by nts_scene_create) */
    int node_count;            /**< how many nodes */
    const int* loop_nodes;     /**< the loops' node indices, one loop after the other */
    const int* loop_start;     /**< loop_count + 1 offsets into loop_nodes */
    int loop_count;            /**< how many loops (0: none given) */
    const int* triangles;      /**< triangle_count triples of node indices, or NULL */
    int triangle_count;        /**< how many triangles (0: none given) */
    /** Per-body model options; zero-initialised they change nothing. */
    nts_role role;
    int has_alpha;    /**< 1: `alpha` shapes this body's surface instead of nts_options.alpha */
    double alpha;     /**< in [0, 0.5]; walls and containers want 0 (sharp inner corners) */
    /** The reference configuration: node_count positions (same order as
     * `nodes`) at which the tributary lengths of NTS_PENALTY_PER_LENGTH are
     * measured; NULL: `nodes` themselves. A solver that creates the scene anew
     * after NTS_ERESHAPED passes its first positions here, so that the same
     * positions give the same answer whatever the session's history. Checked
     * as nodes are (finite, within +-1e100; err->option "reference"), and
     * every surface node's tributary length in it must be positive. */
    const nts_vec2* reference;
    /** The contact surface (docs/model.md §13, a side set): `surface_count`
     * pairs of node indices, surface[2k], surface[2k + 1], each a segment of
     * one of the body's loops (either direction, each segment once). Only
     * the surface's segments are masters and only their nodes are slaves; an
     * end of the surface is a sharp end (no corner across it, the end
     * segment's flat part reaches its end node). NULL: the whole boundary
     * (surface_count is not read); a non-NULL pointer with surface_count 0:
     * no surface (the body takes part in nothing). A pair out of range is
     * NTS_EINDEX_RANGE, one that is not a boundary segment or repeats one
     * NTS_EINVALID_SURFACE (err->option "surface", err->item the pair). */
    const int* surface;
    int surface_count; /**< how many pairs `surface` holds */
    /** This body's own Coulomb friction coefficient instead of
     * nts_options.friction (docs/model.md §14): a pair of bodies rubs with
     * the smaller of their two coefficients. In [0, 10]. */
    int has_friction;
    double friction; /**< the coefficient, read when has_friction is 1 */
    /** 1: this body's slave nodes are also tested against its own surface
     * (docs/model.md §16): a feature counts when it does not contain the
     * node, faces it (opposed normals), and, for a penetration, lies where
     * the body covers itself (the winding numbers of its loops sum to at
     * least 2 at the node and all along its way to the feature). 0 (the
     * default): never. */
    int self_contact;
} nts_body_def;
/** Defined when nts_body_def has `self_contact` (after 0.3.0): code built
 * against several releases (the benchmarks' cross-version runs) asks it. */
#define NTS_HAS_SELF_CONTACT 1

/** Bounds on the size of a scene, checked by nts_scene_create (NTS_ELIMIT). */
typedef struct nts_limits {
    int max_bodies;          /**< default 1,000,000 */
    int max_nodes_per_body;  /**< default 10,000,000 */
    long long max_nodes;     /**< all nodes of a scene; default 50,000,000 */
} nts_limits;
/** The default limits (the values above). */
NTS_API nts_limits nts_default_limits(void);

/** A scene as the caller has it: the bodies, the periodic box and the limits
 * (start from nts_default_scene_def). */
typedef struct nts_scene_def {
    const nts_body_def* bodies; /**< body_count bodies */
    int body_count;             /**< how many bodies */
    /** periodic box [0,lx) x [0,ly); both 0 for an open scene @{ */
    double lx, ly;
    /** @} */
    nts_limits limits;          /**< the bounds nts_scene_create checks */
} nts_scene_def;
/** No bodies, an open scene and nts_default_limits(). */
NTS_API nts_scene_def nts_default_scene_def(void);

/** A validated, normalised scene (opaque): nts_scene_create, nts_scene_destroy. */
typedef struct nts_scene nts_scene;

/** Copy, validate and normalise (outer loop counter-clockwise, holes clockwise).
 * Returns NULL and fills *err (when not NULL) on failure. */
NTS_API nts_scene* nts_scene_create(const nts_scene_def* def, nts_error* err);
/** Frees the scene and everything it owns; NULL is a no-op. */
NTS_API void nts_scene_destroy(nts_scene* scene);

/** New positions for body `body` (node_count entries, same order as created).
 * Checks every coordinate as nts_scene_create does (finite, within +-1e100:
 * NTS_ENONFINITE or NTS_EOUT_OF_RANGE naming the node), not the geometry;
 * allocates nothing. */
NTS_API int nts_scene_set_positions(nts_scene* scene, int body, const nts_vec2* nodes, nts_error* err);

/** New positions for every node (node_count entries, global order: bodies in
 * order, nodes in body order), for a solver that evaluates the same topology at
 * many configurations (sessions). Makes every check of nts_scene_create on the
 * new positions and takes them only when creating the scene anew from them
 * would give this very scene: every loop keeps its orientation verdict, the
 * outer loop of each body stays the outer one, and each piece of a mesh keeps
 * its outer loop counter-clockwise (its interior triangles are not read).
 * Otherwise returns the error of the failed check, or NTS_ERESHAPED when
 * the positions are valid but the scene must be created anew from them; the
 * scene is then unchanged. Allocates nothing; O(nodes). */
NTS_API int nts_scene_update_positions(nts_scene* scene, const nts_vec2* positions, nts_error* err);
/** Bytes held by the scene (its arrays), for budgets. */
NTS_API size_t nts_scene_memory_bytes(const nts_scene* scene);

/* The accessors below read a valid scene: `scene` must not be NULL and
 * `body`, `loop` must be in range (they are not checked). */
/** How many bodies. */
NTS_API int nts_scene_body_count(const nts_scene* scene);
/** all nodes of all bodies */
NTS_API int nts_scene_node_count(const nts_scene* scene);
/** nodes on loops */
NTS_API int nts_scene_surface_node_count(const nts_scene* scene);
/** first global node of a body */
NTS_API int nts_scene_body_node_offset(const nts_scene* scene, int body);
/** How many nodes body `body` has. */
NTS_API int nts_scene_body_node_count(const nts_scene* scene, int body);
/** How many loops body `body` has after normalisation (a mesh's extracted ones included). */
NTS_API int nts_scene_body_loop_count(const nts_scene* scene, int body);
/** The normalised loop (node indices of the body), its length returned; `out` may be NULL. */
NTS_API int nts_scene_body_loop(const nts_scene* scene, int body, int loop, const int** out);
/** 1 when segment k of the normalised loop (from its place k to k + 1, as
 * nts_scene_body_loop gives it) is on the body's contact surface
 * (nts_body_def.surface; every segment of a body without one). */
NTS_API int nts_scene_on_surface(const nts_scene* scene, int body, int loop, int k);
/** 1 when some body of the scene names a contact surface. */
NTS_API int nts_scene_has_surfaces(const nts_scene* scene);
/** How many loops nts_scene_create reversed to normalise them (the summary's
 * loops_reversed; the loops a mesh's boundary gives are not counted). */
NTS_API int nts_scene_loops_reversed(const nts_scene* scene);
/** all nodes, global order (the scene's own array, valid until its destruction;
 * new positions are written into it) */
NTS_API const nts_vec2* nts_scene_positions(const nts_scene* scene);

/* -------------------------------------------------------------- options */

/** NTS_OUT_FORCES ... from NTS_OUTPUT_MAP (tables.h); NTS_OUT_STIFFNESS is the
 * tangent K = d2E/dx2 = -df/dx (nts_result.stiffness); NTS_OUT_PRESSURE the
 * normal contact traction on each slave node (nts_result.pressure). */
enum nts_output_flags {
#define NTS_XX_(ID, bit, name, result, records) NTS_OUT_##ID = 1u << (bit),
    NTS_OUTPUT_MAP(NTS_XX_)
#undef NTS_XX_
#define NTS_XX_(ID, bit, name, result, records) | (1u << (bit))
    NTS_OUT_ALL = 0u NTS_OUTPUT_MAP(NTS_XX_),
#undef NTS_XX_
    /* the outputs that keep every contact's record (tables.h's records column) */
#define NTS_XX_(ID, bit, name, result, records) | ((records) ? 1u << (bit) : 0u)
    NTS_OUT_RECORDS_ = 0u NTS_OUTPUT_MAP(NTS_XX_)
#undef NTS_XX_
};

/** The penalty of a slave node (docs/model.md §6): eps itself, or
 * eps times the node's tributary length (half of its two segments, measured at
 * nts_scene_create in the body's reference configuration, nts_body_def.reference),
 * so that eps is a pressure stiffness and the contact pressure and the
 * penetration converge under mesh refinement. */
typedef enum nts_penalty_scaling {
    NTS_PENALTY_PER_NODE = 0,
    NTS_PENALTY_PER_LENGTH = 1
} nts_penalty_scaling;

/* ------------------------------------------------------------ friction */

/** A friction anchor (docs/model.md §14): the material point of the master
 * surface that a sticking contact is tied to, by its feature and its
 * convective coordinate, so that it moves with the master's nodes. Keyed by
 * (slave body, slave node, master body): a scene has at most one contact per
 * key. `nodes` are node indices inside the master body: a segment's two ends
 * (X = (1 - s) X0 + s X1, `param` s), a corner's three (X2, X3, X4, eq. (2),
 * `param` xi, with the master body's alpha), a vertex's one. */
typedef struct nts_anchor {
    /** The key: slave body, slave node (inside its body), master body. @{ */
    int slave_body, slave_node, master_body;
    /** @} */
    nts_kind kind;  /**< the feature: segment, corner or vertex */
    int nodes[3];   /**< -1 past the feature's own */
    double param;   /**< s (segment) or xi (corner) */
} nts_anchor;

/** The committed anchors of a sequence of steps (a session, a solver's loop),
 * kept by the caller and read by nts_evaluate through nts_options.history:
 * each step is a trial from them; nts_history_commit makes a result's
 * anchors the new ones (an implicit solver commits at convergence, an
 * explicit one every step). Not thread-safe; may be read by any number of
 * evaluations at once while nobody commits. */
typedef struct nts_history nts_history;
typedef struct nts_candidates nts_candidates; /**< a kept candidate list (below) */
/* (nts_history_create ... below nts_result.) */

/** A contact's friction state. */
typedef enum nts_friction_state {
    NTS_FRICTIONLESS = 0, /**< friction is off for this pair (coefficient 0) */
    NTS_STICK = 1,
    NTS_SLIP = 2
} nts_friction_state;

/** How an evaluation finds each slave node's candidate masters (nts_options.search). */
typedef enum nts_search {
    NTS_SEARCH_CELLS = 0,      /**< cell list (Verlet buckets), O(N) */
    NTS_SEARCH_BRUTE_FORCE = 1 /**< every surface node against every other body: for tests */
} nts_search;

/** The options of an evaluation (start from nts_default_options; the defaults
 * and ranges are NTS_OPTION_MAP's, tables.h). */
typedef struct nts_options {
    double alpha;          /**< smoothing fraction in [0, 0.5]; default 0.2 */
    double penalty;        /**< epsilon > 0; default 1 */
    double search_radius;  /**< r >= 0: closest points count within r, and an active contact
                              deeper than r is left out (the result says so: a warning);
                              negative (default): r is the median segment (a typical segment,
                              so that one long wall does not widen the search), and the active
                              contacts deeper than r are found too, at any depth (docs/model.md
                              §4.5) */
    nts_solver solver;     /**< default NTS_SOLVER_CLOSED_FORM */
    unsigned outputs;      /**< NTS_OUT_* flags; default forces | energy | virial */
    nts_search search;     /**< default NTS_SEARCH_CELLS */
    int threads;           /**< 0 = serial; results are bitwise identical for any value; in a process forked
                                from one that loaded the library, 1 (OpenMP's threads do not survive fork) */
    nts_penalty_scaling penalty_scaling; /**< default NTS_PENALTY_PER_NODE */
    /** Bounds on one evaluation (docs/model.md §11), so that no input that fits
     * in memory costs unbounded memory or time:
     * - max_candidates: closest points within the search radius found (a
     *   64-byte record each while contacts, gaps or the tangent are asked
     *   for); more is an NTS_ELIMIT error naming "max_candidates".
     *   0 means the default, 64 per surface node plus 1,000,000.
     * - cancel: asked every 1024 slave nodes and between the phases; a
     *   non-zero answer stops the evaluation with NTS_ECANCELLED (a deadline,
     *   a client that left). NULL: never. It may be called from the worker
     *   threads at once: it must be thread-safe. */
    /** @{ */
    long long max_candidates;
    int (*cancel)(void* user);
    void* cancel_user; /**< the argument `cancel` is called with */
    /** @} */
    /** How far the flat part of a contact surface's end segment reaches past
     * its end node, as a fraction of that segment (docs/model.md §13): a
     * slave node flush with the end (a block stacked on a block of the same
     * width) is in contact whatever the round-off of its position. In
     * [0, 0.5]; default 0.01; read only for bodies with a surface. */
    double surface_extension;
    /** Coulomb friction (docs/model.md §14): the coefficient mu of every pair
     * whose bodies give none of their own (0, the default: frictionless,
     * today's answer bit for bit; at most 10), the tangential penalty eps_T
     * (0, the default: the normal penalty; scaled per length as the normal
     * one), and the committed anchors each contact starts from (NULL: every
     * contact is new and starts sticking where it is). */
    /** @{ */
    double friction;
    double tangential_penalty;
    const nts_history* history;
    /** @} */
    /** The kept candidate list of a solver's loop (nts_candidates below), or
     * NULL (the default): every evaluation searches from scratch. The answer
     * is the same bits either way. */
    nts_candidates* candidates;
} nts_options;
/** The defaults of every option (NTS_OPTION_MAP's), serial, no bounds beyond
 * the default ones, no cancel, no history, no kept candidate list. */
NTS_API nts_options nts_default_options(void);
/** 0 or NTS_EINVALID_OPTION with err->option naming the field. */
NTS_API int nts_options_validate(const nts_options* opt, nts_error* err);

/* --------------------------------------------------------------- result */

/** One closest point of a slave node on one other body. */
typedef struct nts_contact {
    /** body index, node index inside the body @{ */
    int slave_body, slave_node;
    /** @} */
    int master_body;              /**< the body whose surface the closest point is on */
    nts_kind kind;                /**< the master feature: segment, corner or vertex */
    int master_count;             /**< 2 (segment), 3 (corner) or 1 (vertex) */
    int master_nodes[3];          /**< node indices inside the master body */
    double weights[3];            /**< shape function values, summing to one */
    double param;                 /**< s (segment, vertex) or xi (corner) */
    double gap;                   /**< signed; < 0 when penetrating */
    nts_vec2 normal;              /**< outward unit normal of the master at the PCA */
    nts_vec2 point;               /**< the PCA (in the master node's image) */
    nts_vec2 force;               /**< force on the slave: -eps g n (zero when g >= 0) */
    nts_virial virial;            /**< -sum f_i (X_i - Xs), = eps g^2 n n */
    double penalty;               /**< the eps of this contact: nts_options.penalty, times the slave's
                                     tributary length with NTS_PENALTY_PER_LENGTH */
    /** Friction (docs/model.md §14; zero and NTS_FRICTIONLESS without): the
     * tangential force on the slave (`force` is the whole: normal plus
     * tangential), the slip of this step (0 in stick), the state. */
    /** @{ */
    nts_vec2 tangential_force;
    double slip;
    /** @} */
    int state;                    /**< nts_friction_state */
    int reserved;                 /**< 0; keeps the layout for what comes next */
} nts_contact;

/** The totals of an evaluation, always filled whatever the outputs. */
typedef struct nts_summary {
    int bodies;            /**< bodies of the scene */
    int surface_nodes;     /**< nodes on loops (the candidate slaves) */
    int contacts;          /**< active contacts (g < 0) */
    int gaps;              /**< closest points within the search radius, and the deep contacts */
    int deep_contacts;     /**< of the active contacts, those deeper than the (default) search radius */
    double energy;         /**< 1/2 eps sum g^2 */
    nts_virial virial;     /**< the sum of the contacts' virials */
    double max_penetration;/**< max(-g) over active contacts, 0 if none */
    int loops_reversed;    /**< loops the scene reversed to normalise them (nts_scene_loops_reversed) */
    double search_radius;  /**< the radius used */
    double cell_size;      /**< the bucket side the cell search starts from (docs/model.md §9: long
                              lists may coarsen it), with or without a kept candidate list;
                              0 for brute force */
    /** Friction (docs/model.md §14): the work the slipping contacts turned
     * into heat this step (>= 0), and the active contacts sticking and
     * slipping. The energy above includes the tangential springs'. */
    /** @{ */
    double dissipation;
    int sticking, slipping;
    /** @} */
} nts_summary;

/** A sparse matrix as triplets (COO): entry k is (rows[k], cols[k], values[k]);
 * an entry may appear several times, and the matrix is the SUM of its
 * duplicates. size x size, size = 2 * node_count, degree of freedom
 * 2 * node + component (component 0 = x, 1 = y; node in global order). */
typedef struct nts_triplets {
    const int* rows;      /**< count row indices */
    const int* cols;      /**< count column indices */
    const double* values; /**< count values */
    int count;            /**< how many entries */
    int size;             /**< the matrix's rows and columns, 2 * node_count */
} nts_triplets;

/** Compressed sparse rows: row r holds cols[row_start[r] .. row_start[r+1]) in
 * increasing column order, each once. Arrays from nts_alloc: nts_csr_free. */
typedef struct nts_csr {
    int* row_start;  /**< size + 1 */
    int* cols;       /**< nnz column indices, row after row */
    double* values;  /**< nnz values, as cols */
    int nnz;         /**< stored entries */
    int size;        /**< rows and columns */
} nts_csr;

/** Sum duplicates of `t` into `out` (duplicates are added in triplet order, so
 * the sums are deterministic). 0, NTS_ENOMEM or NTS_EINVALID_ARGUMENT. */
NTS_API int nts_triplets_to_csr(const nts_triplets* t, nts_csr* out, nts_error* err);
/** Frees the arrays of `csr` and zeroes it (the struct itself is the caller's); NULL is a no-op. */
NTS_API void nts_csr_free(nts_csr* csr);

/** A result that may be incomplete says so: what, and how many times (one
 * table, as the errors). XX(enum suffix, value, stable name, message); the
 * names are part of the JSON contract: never renumber or rename, only append. */
#define NTS_WARNING_MAP(XX)                                                                             \
    XX(PENETRATION_BEYOND_RADIUS, 1, "penetration_beyond_radius",                                      \
       "active contacts deeper than the explicit search radius were left out (leave search_radius "   \
       "unset to find every contact, or raise it)")                                                    \
    XX(PENETRATION_BEYOND_REACH, 2, "penetration_beyond_reach",                                        \
       "a slave node's closest point lies beyond half the periodic box: its contact may be missing")

/** A warning's code: NTS_WARN_NONE (0) or one of the NTS_WARN_<suffix> of NTS_WARNING_MAP. */
typedef enum nts_warning_code {
    NTS_WARN_NONE = 0,
#define NTS_XX_(e, v, name, msg) NTS_WARN_##e = (v),
    NTS_WARNING_MAP(NTS_XX_)
#undef NTS_XX_
#define NTS_XX_(e, v, name, msg) +1
    NTS_WARN_COUNT_ = 0 NTS_WARNING_MAP(NTS_XX_) /**< the table's rows */
#undef NTS_XX_
} nts_warning_code;

/** One thing a result may lack (nts_result.warnings). */
typedef struct nts_warning {
    int code;         /**< nts_warning_code */
    long long count;  /**< how many contacts (or slave nodes) it concerns */
} nts_warning;

/** Stable snake_case name and human message of a warning code.
 * Both are static strings ("unknown_warning", "unknown warning" for a code
 * that is none of the table's).
 * @{ */
NTS_API const char* nts_warning_name(int code);
NTS_API const char* nts_warning_message(int code);
/** @} */

/** The result of nts_evaluate. Its arrays are owned by the context that
 * evaluated it and stay valid until that context's next evaluation, its
 * nts_context_trim or its destruction. */
typedef struct nts_result {
    nts_summary summary;        /**< the totals (always) */
    /** What may be missing from this result, in code order; none when
     * warning_count is 0 (every contact there is was found). */
    const nts_warning* warnings;
    int warning_count;          /**< how many `warnings` */
    const nts_vec2* forces;     /**< global node order (see nts_scene_body_node_offset), or NULL if not asked */
    /** The normal contact traction on each node as a slave (docs/model.md
     * (21)): the sum of -eps g over its active contacts divided by its
     * tributary length; 0 for a node in no contact or on no surface. Global
     * node order, or NULL unless NTS_OUT_PRESSURE. */
    const double* pressure;
    const nts_contact* contacts;/**< active contacts, slave order; NULL unless NTS_OUT_CONTACTS and some
                                   (every array here is NULL when its count is 0, whatever the
                                   context evaluated before) */
    int contact_count;          /**< how many `contacts` */
    const nts_contact* gaps;    /**< all closest points within r and the deep contacts, slave order;
                                   NULL unless NTS_OUT_GAPS and some */
    int gap_count;              /**< how many `gaps` */
    /** The consistent tangent of the active contacts (docs/model.md, "Tangent
     * stiffness"): duplicates summed; symmetric without friction (with
     * friction it is not: §14). Empty unless NTS_OUT_STIFFNESS. */
    nts_triplets stiffness;
    /** With friction on (some pair's coefficient > 0): each active contact's
     * anchor after this step (its returned anchor when slipping), in contact
     * order, whatever the outputs: what nts_history_commit keeps. */
    const nts_anchor* anchors;
    int anchor_count;           /**< how many `anchors` (0 without friction) */
} nts_result;

/* ------------------------------------------------------------ history */

/** @name History
 * The friction anchors of a sequence of steps (nts_history above).
 * @{ */
/** An empty history, or NULL when out of memory. Free with nts_history_destroy. */
NTS_API nts_history* nts_history_create(void);
/** Frees the history and its anchors; NULL is a no-op. */
NTS_API void nts_history_destroy(nts_history* history);
/** Set the anchors from a list (a stateless request's "history"), checked
 * against the scene: bodies and nodes in range (a body with itself only
 * where it has self-contact, and then no feature holding the slave node), the
 * feature's nodes those of one segment, corner or vertex of the master
 * body's loops, a finite param, each key once. 0, NTS_ENOMEM,
 * NTS_EINVALID_ARGUMENT (a NULL argument), or NTS_EINVALID_HISTORY naming
 * the entry (err->option "history", err->item). */
NTS_API int nts_history_set(nts_history* history, const nts_scene* scene, const nts_anchor* anchors, int count,
                            nts_error* err);
/** The result's anchors (one per active contact, nts_result.anchors) become
 * the committed ones; contacts that opened are forgotten. Allocates only
 * when the history grows. 0 or NTS_ENOMEM (the history is then unchanged);
 * NTS_EINVALID_ARGUMENT for a NULL history or result. */
NTS_API int nts_history_commit(nts_history* history, const nts_result* result);
/** The committed anchors, sorted by key (slave body, slave node, master body).
 * The history's own array, valid until it next changes; *count (when `count`
 * is not NULL) gets how many. */
NTS_API const nts_anchor* nts_history_anchors(const nts_history* history, int* count);
/** Forget every committed anchor (keeps the memory); NULL is a no-op. */
NTS_API void nts_history_clear(nts_history* history);
/** Bytes held, for budgets (0 for NULL). */
NTS_API size_t nts_history_bytes(const nts_history* history);
/** Whether an evaluation of `scene` with `options` has friction on: some
 * pair of bodies that can meet (a slave of one and a master of another, or
 * a body that meets itself) has a coefficient above 0, the smaller of its
 * two bodies' (their own, else the options', §14). Then the result carries
 * anchors, the summary dissipation, the virial yx; otherwise it is the
 * frictionless answer bit for bit. */
NTS_API int nts_friction_on(const nts_scene* scene, const nts_options* options);
/** @} */

/* ------------------------------------------------------ kept candidates */

/** @name Kept candidates
 * A kept candidate list (a Verlet list) for a loop of evaluations of one
 * scene whose nodes move a little between them (a solver's steps, a
 * session): each slave node keeps the masters within its reach plus a
 * skin, and the evaluations that follow try only those, until some node has
 * moved far enough that the list could miss one; then the list is built
 * again (docs/model.md §15). The answer is that of an evaluation from
 * scratch, bit for bit, always; only the time differs. It keeps the
 * surface nodes' positions at the last build and the lists (4 bytes a kept
 * master). One per scene and loop; not thread-safe.
 * @{ */
/** An empty list (built by the first evaluation that uses it through
 * nts_options.candidates), or NULL when out of memory.
 * skin: the margin beyond the search radius, a length >= 0; negative: 0.3
 * times the search radius at each build (the default; plus the round-off
 * allowances of docs/model.md eq. (29), nothing at moderate coordinates). */
NTS_API nts_candidates* nts_candidates_create(double skin);
/** Frees the list; NULL is a no-op. */
NTS_API void nts_candidates_destroy(nts_candidates* candidates);
/** Forget the list (the next evaluation builds it). */
NTS_API void nts_candidates_clear(nts_candidates* candidates);
/** Bytes held, for budgets (0 for NULL). */
NTS_API size_t nts_candidates_bytes(const nts_candidates* candidates);
/** What the evaluations did with it: how many used it, how many of those
 * built it, how many needed the cells of the deep contacts' search all the
 * same, the largest displacement of a node since the last build, the skin
 * of the last build and the masters it kept. */
typedef struct nts_candidates_info {
    /** evaluations that used it, builds, builds that needed the cells @{ */
    long long evaluations, builds, cell_builds;
    /** @} */
    /** the largest displacement since the last build, the skin of that build @{ */
    double moved, skin;
    /** @} */
    long long kept; /**< masters kept at the last build */
    /** of the evaluations that used the lists (built or replayed), those
     * whose search asked for the masters' lines ahead and those that did
     * not: a choice of speed alone, each giving the same answer (never
     * below 2 MB of segment records; above, each way's search is timed and
     * the faster taken, the other tried one timed replay in 8) @{ */
    long long ahead_replays, plain_replays;
    /** @} */
    /** of `kept`, the masters the last build's own evaluation moved out of
     * the inner lists that replays try: those that can offer their slave
     * nothing while the lists hold (docs/model.md eq. (32)) */
    long long pruned;
} nts_candidates_info;
/** The counts of `candidates` (all zero for NULL). */
NTS_API nts_candidates_info nts_candidates_get_info(const nts_candidates* candidates);
/** @} */

/* ------------------------------------------------------- contact state */

/** A contact's key (as Box2D's b2ManifoldPoint.id): the slave node, the
 * master body and the master feature, its kind and the master node it sits
 * at (a segment's first node, a corner's middle node X3, a vertex's node).
 * A scene has at most one contact per (slave node, master body) pair. */
typedef struct nts_contact_key {
    /** slave body, slave node (inside its body), master body @{ */
    int slave_body, slave_node, master_body;
    /** @} */
    nts_kind kind;    /**< the master feature's kind */
    int feature_node; /**< the master node it sits at (inside the master body) */
} nts_contact_key;
/** The key of contact `c` (not NULL). */
NTS_API nts_contact_key nts_contact_key_of(const nts_contact* c);

/** The previous step's contacts, kept by the caller across evaluations (a
 * session, a solver's loop), and each new contact matched to them by key:
 * what friction's anchors and kept candidate lists start from. The
 * evaluation knows nothing of it: a caller that keeps no contacts pays
 * nothing. One per sequence of steps of one scene; not thread-safe. */
typedef struct nts_contact_memory nts_contact_memory;
/** A contact's match among the previous step's: `previous` is the index of
 * the previous contact of the same slave node and master body (-1: the
 * contact is new), `persisted` 1 when its whole key is equal too (the same
 * feature; 0: the contact moved to another feature of the body). */
typedef struct nts_contact_match {
    int previous;  /**< the previous contact's index, or -1 */
    int persisted; /**< 1: the same feature too */
} nts_contact_match;
/** What a step did to the contacts: kept (same key), moved (same pair, other
 * feature), new, and ended (previous contacts with no match). */
typedef struct nts_contact_changes {
    /** the counts @{ */
    int persisted, moved, added, ended;
    /** @} */
} nts_contact_changes;
/** An empty contact memory (the first step's contacts are all new), or NULL
 * when out of memory. Free with nts_contact_memory_destroy. */
NTS_API nts_contact_memory* nts_contact_memory_create(void);
/** Frees the memory and everything it keeps; NULL is a no-op. */
NTS_API void nts_contact_memory_destroy(nts_contact_memory* memory);
/** Match the active contacts of `result` (evaluated with NTS_OUT_CONTACTS) to
 * the committed ones, and hold them pending: a trial step (an implicit
 * solver's Newton iteration) matches again from the same committed step;
 * nts_contact_memory_commit makes the pending contacts the committed ones.
 * *match (may be NULL) gets result->contact_count matches, owned by the
 * memory and valid until its next match; *changes (may be NULL) the counts.
 * O(n log n) in the contacts. NTS_OK, NTS_ENOMEM (nothing pending then), or
 * NTS_EINVALID_ARGUMENT (no memory or result, or contacts not asked for
 * while some are active). */
NTS_API int nts_contact_memory_match(nts_contact_memory* memory, const nts_result* result,
                                     const nts_contact_match** match, nts_contact_changes* changes);
/** The last match's contacts become the committed step (the next matches are
 * against them). NTS_OK, or NTS_EINVALID_ARGUMENT when nothing is pending. */
NTS_API int nts_contact_memory_commit(nts_contact_memory* memory);
/** Match and commit: an explicit solver's step. */
NTS_API int nts_contact_memory_step(nts_contact_memory* memory, const nts_result* result,
                                    const nts_contact_match** match, nts_contact_changes* changes);
/** The contacts that the last match's `previous` indices point into (the
 * committed step it was matched against), and how many. */
NTS_API const nts_contact* nts_contact_memory_previous(const nts_contact_memory* memory, int* count);
/** Bytes the memory holds, for budgets (0 for NULL). */
NTS_API size_t nts_contact_memory_bytes(const nts_contact_memory* memory);
/** Forget every kept contact (the next step's are all new). */
NTS_API void nts_contact_memory_clear(nts_contact_memory* memory);

/* ------------------------------------------------------------- context */

/** A reusable evaluation context (opaque): the buffers of its evaluations and
 * the arrays of its last result. One evaluation at a time on a context: give
 * each concurrent evaluation its own. */
typedef struct nts_context nts_context;
/** An empty context (it allocates on its first evaluation), or NULL when out
 * of memory. Free with nts_context_destroy. */
NTS_API nts_context* nts_context_create(void);
/** Frees the context, its buffers and so its last result; NULL is a no-op. */
NTS_API void nts_context_destroy(nts_context* ctx);
/** Where the last evaluation on a context spent its time, in seconds, phase by
 * phase (as Box2D's b2World_GetProfile): segment data, cell list and masters,
 * local search, scatter. Wall clock; zero before the first evaluation. */
typedef struct nts_profile {
    /** seconds per phase @{ */
    double segments, cells, search, scatter;
    /** @} */
    /** How many segment lengths the default radius (the median segment) was
     * selected among at last: every surface segment when the scene has too
     * few to sample (at most 4 x 4,096) or the sampled bracket missed the
     * median (the answer is the same, only slower), a few when the bracket
     * held it; 0 when no median was needed (an explicit search radius, or a
     * distributed part, which takes the whole scene's). A diagnostic. */
    int median_from;
} nts_profile;
/** The profile of the context's last evaluation (zero for NULL). */
NTS_API nts_profile nts_context_profile(const nts_context* ctx);
/** Bytes held by the context's buffers (they only grow), for budgets. */
NTS_API size_t nts_context_memory_bytes(const nts_context* ctx);
/** Give back every buffer the context holds, keeping the context usable: it is
 * then as nts_context_create made it, and the next evaluation allocates what
 * it needs again (results are unchanged, bit for bit). For a long-lived
 * context that met one large evaluation (a session's step with gaps on a wide
 * radius) and should not hold its buffers for the smaller ones after it. The
 * last result's arrays (forces, contacts, gaps, the tangent) are freed with
 * them. */
NTS_API void nts_context_trim(nts_context* ctx);

/** The host's threads (as Box2D's b2WorldDef enqueueTask / finishTask /
 * workerCount). Every parallel loop of an evaluation is one task over the
 * items [0, count): the host calls `task` on ranges [begin, end) that cover
 * [0, count) exactly once, each of at least `min_range` items (the last may
 * be shorter), in any order, on any of its threads at once, each call with a
 * worker index in [0, worker_count) that no other call running at the same
 * time has. `enqueue` may run the task itself and return NULL; otherwise it
 * returns a handle, and `finish(handle, user)` returns once every range is
 * done. Results are bitwise identical for any backend, order and worker
 * count. Without a host backend the build's own runs the loops (OpenMP on
 * nts_options.threads threads, or serial; docs/architecture.md). */
typedef void nts_task_fn(int begin, int end, int worker, void* task_context);
/** Starts `task` over [0, count) in ranges of at least `min_range` items;
 * returns a handle for nts_finish_fn, or NULL when it ran the task itself. */
typedef void* nts_enqueue_fn(nts_task_fn* task, int count, int min_range, void* task_context, void* user);
/** Returns once every range of the task behind `handle` is done. */
typedef void nts_finish_fn(void* handle, void* user);
/** A host backend (nts_context_set_parallel); see nts_task_fn. */
typedef struct nts_parallel {
    nts_enqueue_fn* enqueue; /**< starts a task (not NULL) */
    nts_finish_fn* finish;   /**< waits for a task (not NULL) */
    int worker_count; /**< >= 1; the context's evaluations use this many workers (nts_options.threads is not read) */
    void* user;              /**< passed to enqueue and finish */
} nts_parallel;
/** Run the context's evaluations on the host's threads; NULL gives the loops
 * back to the build's own backend. NTS_OK, or NTS_EINVALID_ARGUMENT when
 * enqueue or finish is NULL or worker_count < 1. */
NTS_API int nts_context_set_parallel(nts_context* ctx, const nts_parallel* backend);

/** Evaluate contact. Returns 0 or a negative status (with *err filled when not
 * NULL); on success fills *out. A context's buffers are sized by what the
 * scene needs (its records, the largest chunk of slaves, the most candidates
 * of one slave), never by which thread ran which part: evaluating the same
 * scene at the same positions with the same options and thread count again
 * allocates nothing, whatever the schedule, and a context never holds more
 * than a fixed multiple of the largest needs it has met. On success every
 * force, the energy, the virial and the tangent are finite: finite input
 * whose result overflows a double is NTS_ENONFINITE with err->option
 * "penalty". */
NTS_API int nts_evaluate(nts_context* ctx, const nts_scene* scene, const nts_options* opt,
                 nts_result* out, nts_error* err);

/** A solver's step in one call: nts_scene_update_positions(scene, positions)
 * then nts_evaluate, with the same answer, the same errors and the same scene
 * afterwards, but the positions checked in the evaluation's own pass over the
 * segments (each length computed once) rather than in a pass of their own.
 * When a check fails the scene is unchanged, nothing is evaluated, and the
 * error is the update's (the first fault in its order, named as it names it).
 * A caller that must tell a rejection (to create the scene anew, after
 * NTS_ERESHAPED) from a failed evaluation asks nts_scene_update_positions
 * with the same positions: it fails only on a rejection. */
NTS_API int nts_evaluate_positions(nts_context* ctx, nts_scene* scene, const nts_vec2* positions,
                                   const nts_options* opt, nts_result* out, nts_error* err);

/** nts_evaluate_positions for a step that moves only the nodes on the
 * scene's loops (a mesh's boundary, every node of a polygon:
 * nts_scene_body_loop), the only nodes contact reads: `positions` is indexed
 * by global node as there, but only the loops' entries are read and taken;
 * the other nodes keep their stored positions, and their entries may hold
 * anything. The same answer, errors and scene afterwards as
 * nts_evaluate_positions given the stored positions with the loops' nodes
 * replaced, without a pass over the other nodes (a mesh's interior) on the
 * way: a step costs what the surface costs. */
NTS_API int nts_evaluate_surface_positions(nts_context* ctx, nts_scene* scene, const nts_vec2* positions,
                                           const nts_options* opt, nts_result* out, nts_error* err);

#ifdef __cplusplus
}
#endif
#endif
