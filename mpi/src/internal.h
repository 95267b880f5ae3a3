/* The distributed evaluation's parts (mpi/src/, not installed): the scene
 * each rank keeps, the messages the ranks exchange, and the functions the
 * files share. One file per concept: bytes.c (a body on the wire), scene.c
 * (the scene and the collective errors), frame.c (the whole's frame),
 * slabs.c (the decomposition), halo.c (each rank's part), sums.c (the sums
 * in one process's order), evaluate.c, gather.c (the whole answer on a
 * root). docs/distributed.md tells the design. */
#ifndef NTSCONTACT_MPI_INTERNAL_H
#define NTSCONTACT_MPI_INTERNAL_H

#include <math.h>
#include <stddef.h>

#include <ntscontact/mpi.h>

/* A growing byte buffer (8-byte aligned items). */
typedef struct bytes {
    char* p;
    size_t n, cap;
    int oom;
} bytes;


/* One contribution to a node's force, with the key one process adds it in
 * (deep, slave entry, master body, place), to the rank that owns the node. */
typedef struct share_msg {
    int at;    /* the node among its owner's nodes */
    int entry; /* global slave entry; -1: the node's whole force, summed by the one rank that touches it */
    int body;  /* global master body */
    int dq;    /* deep << 2 | place in the contact (0: the slave) */
    double fx, fy;
} share_msg;

/* One contact's sums, with its key. */
/* What active contacts add up to: energy, virial, dissipation. */
typedef struct sums6 {
    double e, xx, yy, xy, yx, dis;
} sums6;

/* Add b to a, field by field (each field's sum in the order of the calls). */
static inline void sums6_add(sums6* a, const sums6* b) {
    a->e += b->e;
    a->xx += b->xx;
    a->yy += b->yy;
    a->xy += b->xy;
    a->yx += b->yx;
    a->dis += b->dis;
}

typedef struct sum_msg {
    int entry, body, pad[2];
    sums6 s;
} sum_msg;

/* A chunk's sums. */
typedef struct chunk_msg {
    int chunk, pad;
    sums6 s;
} chunk_msg;

/* A buffer kept between evaluations (it only grows): a step in a solver's
 * loop allocates nothing and touches no fresh page. */
typedef struct scratch {
    void* p;
    size_t cap;
} scratch;
enum {
    SC_SHARES_OUT, SC_SHARES_IN, SC_SUMS_OUT, SC_SUMS_SORTED, SC_SUMS_IN, SC_SUMS_TMP,
    SC_SUMS_START, SC_DEEP, SC_POS_SEND, SC_POS_RECV, SC_POS_PART, SC_MIXED, SC_MIXED_ALL, SC_DEEP_AT, SC_CHUNKS, SC_CHUNK_SUMS, SC_EXCHANGE, SC_SHARES_TMP, SC_SHARES_DEST, SC_OLD_POS, SC_PRESUM_NODE, SC_PRESUM_F, SC_COUNT
};

/* The slabs: cuts along one axis (docs/distributed.md). */
typedef struct slabs {
    int axis;        /* the direction: 0 x, 1 y, 2 -x, 3 -y (slab r for rank r in its order) */
    double period;   /* the box along the axis, or 0 */
    double lo, hi;
    double* cut;     /* size + 1: slab r is [cut[r], cut[r + 1]) */
} slabs;

struct ntsm_scene {
    MPI_Comm comm;
    int rank, size;
    /* what this rank owns */
    int count;
    int* ids;             /* global index of each owned body */
    bytes own_bytes;      /* the owned bodies, as sent */
    size_t* own_at;       /* each one's offset in own_bytes */
    nts_body_def* own_defs;
    nts_scene* own;       /* the owned bodies alone (positions, the frame's lengths) */
    nts_context* own_ctx;
    int own_nodes;
    int* own_node_at;     /* count + 1: each owned body's first node among this rank's */
    nts_limits own_limits; /* the limits its own scene was made with (the error path's one-body scenes) */
    /* the whole, by global body */
    int bodies;
    int* owner;           /* rank */
    int* local_of;        /* index among this rank's bodies, or -1 */
    long long* node_off;  /* bodies + 1 */
    long long* entry_off; /* bodies + 1 */
    int* owner_node_at;   /* each body's first node among its owner's nodes */
    int loops_reversed;
    double lx, ly;        /* the periodic box (0: open) */
    nts_frame frame;
    int frame_given;
    /* The decomposition kept between evaluations (a solver's loop): the
     * slabs, the halo it was built with, where each owned body went (to,
     * count x size) and the positions then, and each received body's nodes
     * and place in the part (arrival order). Rebuilt when some node has
     * moved more than the skin allows, or the load is uneven. */
    int built, rebuild_next;
    int maps_whole;       /* the part's maps hold its nodes' and entries' (ntsm_part_maps), not only who owns each slave */
    double skin;          /* negative: 0.3 times the search radius */
    /* The part's kept candidate list (docs/model.md §15), while the part is
     * kept (skin not 0): a new part makes it build anew (a scene of its own). */
    nts_candidates* part_kc;
    /* The slabs' shares of the surface nodes (slabs.c): the host's fixed
     * weights (NULL: balanced by measured time), the shares the slabs are
     * cut at (NULL: equal), each rank's measured speed (owned slaves a
     * second, smoothed), the seconds cuts at those speeds would have saved
     * since the last cut, and what a cut costs (the last warm evaluation
     * that made the parts, measured; 0: none yet; evaluate.c, balance.h). */
    double* weights;
    double* share; /* (size doubles, kept; used when share_on) */
    int share_on;
    double* speed;
    double lost, recut_cost;
    double halo_b, ext_b;
    double* cut_b;
    int axis_b;
    double period_b, lo_b, hi_b;
    unsigned char* to;
    nts_vec2* build_pos;
    int* arrival_nodes;
    int* arrival_off;
    int arrivals;
    long long rebuilds;
    /* friction's committed anchors (global bodies; ntsm_scene_set_history),
     * and the part's share of them */
    nts_anchor* hist;
    int hist_count;
    nts_history* part_history;
    nts_anchor* part_anchors;
    int part_anchors_cap;
    int* part_of;         /* global body -> part body, or -1 (bodies) */
    scratch sc[SC_COUNT];
    /* the last evaluation's part */
    bytes recv;
    nts_scene* part;
    nts_context* ctx;
    int* part_ids;        /* part body -> global */
    int part_cap_ids;
    long long* part_node; /* part node -> global node */
    int part_node_cap;
    int* node_owner;      /* part node -> its owner rank, and its place among the owner's nodes */
    int* node_at;
    int node_owner_cap, node_at_cap;
    /* Part bodies in no other rank's part (part_single, by part body;
     * node_single, by part node): every contact that touches their nodes
     * is this rank's, so its forces on another rank's node of theirs go as
     * one sum a node (sums.c); ps_slot: each part node's place among those
     * sums during ntsm_sums, -1 otherwise (kept -1 between calls). */
    unsigned char* part_single;
    int part_single_cap;
    unsigned char* node_single;
    int node_single_cap;
    int* ps_slot;
    int ps_slot_cap;
    int* entry_owned;     /* part entry -> 1 when this rank owns its slave */
    unsigned char* owned_mask; /* the same, for the core (nts_context_set_owned) */
    int owned_mask_cap;
    long long* entry_global;
    int entry_cap;
    int* entry_node;      /* part entry -> its slave's part node (kept while the part is) */
    int entry_node_cap;
    nts_result part_result;
    unsigned outputs;
    /* the answer on this rank */
    nts_vec2* forces;
    double* pressure;
    int forces_cap, pressure_cap;
    /* ntsm_gather's arrays on the root */
    nts_vec2* g_forces;
    double* g_pressure;
    nts_contact* g_contacts;
    nts_contact* g_gaps;
    nts_anchor* g_anchors;
    int* g_rows;
    int* g_cols;
    double* g_vals;
    nts_summary summary;
    nts_warning warnings[NTS_WARN_COUNT_];
    int warning_count;
    ntsm_stats stats;
};

/* bytes.c */
void* ntsm_bytes_room(bytes* b, size_t n);
void ntsm_bytes_put(bytes* b, const void* v, size_t n);
int ntsm_grow(void* pp, int* cap, long long count, size_t size);
size_t ntsm_al8(size_t n);
void ntsm_body_write(bytes* b, const nts_body_def* d, int id, const nts_vec2* reference);
size_t ntsm_body_read(const char* p, nts_body_def* d, int* id);
/* The number of ranks a body's bytes at p went to (ntsm_part_build sets it
 * in the copies it sends; 0 elsewhere). */
void ntsm_body_set_parts(char* p, int parts);
int ntsm_body_parts(const char* p);

/* `need` bytes of s (NULL when they cannot be had). */
void* ntsm_scratch(scratch* s, size_t need);

/* scene.c: collective errors */
int ntsm_agree(ntsm_scene* m, MPI_Comm comm, int rank, int size, int rc, nts_error* err);
/* Whether ids[0..count) ascend; the places 0..count-1 in ascending order of
 * ids (malloc, count + 1; NULL when out of memory). */
int ntsm_ascending(const int* ids, int count);
int* ntsm_global_order(const int* ids, int count);
/* After a failure of a rank's own scene at e (a local body), the body one
 * process would name among the rank's bodies (ids: their global indices),
 * made again in global order; with moved (rows at node_at per body), at
 * those positions. Local in e; nothing changes when the order is global. */
void ntsm_lowest_failing(const nts_scene_def* def, const int* ids, const nts_vec2* moved, const int* node_at,
                         nts_error* e);
int ntsm_fail(nts_error* err, int code, const char* msg);
void ntsm_global_body(nts_error* err, const int* ids, int count);

/* frame.c, slabs.c */
int ntsm_frame_find(ntsm_scene* m, const nts_options* opt, nts_frame* f, nts_error* err);
int ntsm_slabs_make(ntsm_scene* m, const nts_frame* f, double lx, double ly, slabs* sl);
/* p's coordinate along the direction (ntsm_axis_coord); the same within
 * the period, if any (ntsm_axis_of); the slab holding coordinate c, the
 * last r with cut[r] <= c (ntsm_slab_of). Inline: the part's maps ask
 * them for every entry at every evaluation. */
static inline double ntsm_axis_coord(const slabs* sl, nts_vec2 p) {
    const double c = (sl->axis & 1) ? p.y : p.x;
    return (sl->axis & 2) ? -c : c;
}
static inline double ntsm_axis_of(const slabs* sl, nts_vec2 p) {
    double c = ntsm_axis_coord(sl, p);
    if (sl->period > 0.0) {
        c -= sl->period * floor(c / sl->period);
        if (!(c < sl->period)) c = 0.0; /* a round-off at the top */
    }
    return c;
}
static inline int ntsm_slab_of(const slabs* sl, int size, double c) {
    int lo = 0, hi = size - 1;
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (sl->cut[mid] <= c) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}
int ntsm_meets(const slabs* sl, int r, double a, double b);

/* halo.c */
int ntsm_part_build(ntsm_scene* m, const slabs* sl, double halo, double lx, double ly, nts_error* err);
int ntsm_part_move(ntsm_scene* m, const nts_vec2** moved, nts_error* err);
int ntsm_part_maps(ntsm_scene* m, const slabs* sl, int all, const nts_vec2* moved);

/* gather.c: the last ntsm_gather's arrays, freed */
void ntsm_gathered_free(ntsm_scene* m);

/* sums.c */
int ntsm_sums(ntsm_scene* m, const nts_options* opt, nts_error* err);
/* The whole's candidate budget, nts_evaluate's (nts_candidate_budget of
 * the whole's surface nodes). */
long long ntsm_candidate_budget(const ntsm_scene* m, const nts_options* opt);

#endif
