/* The stages of an evaluation and the state they share (private to the core):
 *   context.c  the context and its workers          (buffers that only grow)
 *   masters.c  the masters' hot records, long lists  (what the search reads)
 *   search.c   the local search per slave, records   (docs/model.md §4, §5)
 *   scatter.c  forces, energy, virial, tangent       (docs/model.md §6, §7)
 *   evaluate.c nts_evaluate: segments -> cells -> search -> scatter -> summary
 * The cell list itself (and its stencil) is cell_list.c. */
#ifndef NTSCONTACT_STAGES_H
#define NTSCONTACT_STAGES_H

#include <stdio.h>
#include <string.h>

#include "internal.h"

#if defined(__GNUC__)
#define NTS_ALWAYS_INLINE __attribute__((always_inline))
#else
#define NTS_ALWAYS_INLINE
#endif

/* Per-surface-entry segment data, recomputed each evaluation from the positions:
 * the segment that starts at the entry. */
typedef struct seg_data {
    nts_vec2 t;      /* X1 - X0 (minimum image) */
    nts_vec2 n;      /* outward unit normal (t_y, -t_x)/|t| */
    double inv_len2; /* 1/|t|^2, |t| > 0 checked */
    double len;
} seg_data;

/* A master surface entry as the local search reads it, copied in cell order
 * (nodes sorted by cell) so the 3x3 stencil walks contiguous memory (72
 * bytes). Everything else of the entry (its previous segment, its node
 * indices) is read only for the few entries that pass the cheap rejects. */
typedef struct master_hot {
    nts_vec2 p;      /* X_j */
    nts_vec2 t;      /* segment j: X_{j+1} - X_j (minimum image) */
    nts_vec2 n;      /* its outward unit normal */
    double inv_len2; /* 1/|t|^2 */
    double reach2;   /* no feature of this master counts for a slave farther than sqrt(reach2);
                        -1 when it offers nothing from here (a "slave" body, or a long entry
                        of the cell list, searched through its own list) */
    double alpha;    /* the smoothing of this master's body (per-body options) */
    int body;
    int entry;       /* surface entry j */
} master_hot;

/* What the first pass of the search reads of a master (32 bytes, in the
 * order of master_hot): the cheap reject alone, so that the masters a slave
 * visits and drops (most of them: its own body's, and those out of reach)
 * cost two loads and no branch (search.c). */
typedef struct master_key {
    nts_vec2 p;      /* X_j, as in master_hot */
    double reach2;   /* as in master_hot */
    int body;
    int is_long;     /* searched through the long lists (nts_fill_hot) */
} master_key;

/* The best candidate so far of one (slave, master body) pair, and the record
 * it becomes (64 bytes): only what the selection needs. The full nts_contact
 * (152 bytes) is made by the scatter, and only for what is asked. */
typedef struct candidate {
    double gap;
    double param;    /* s (segment), xi (corner), 0 (vertex) */
    nts_vec2 normal;
    nts_vec2 point;
    int body;        /* master body */
    int entry;       /* surface entry j of the feature's master node */
    int slave;       /* surface entry of the slave (set when the slave is done) */
    int kind;
} candidate;

/* One worker's scratch: the per-slave best candidate of each master body, and
 * the records of the slaves it handled, in slave order: every closest point
 * within r when contacts, gaps or the tangent are asked for, else only the
 * active contacts (g < 0), the only ones that forces, energy and virial need. */
typedef struct worker {
    int* slot;         /* body -> index into best, -1 if none (all -1 between slaves) */
    candidate* best;   /* candidates of the current slave */
    int best_count, best_cap;
    candidate* recs;
    int rec_count, rec_cap;
    long long gaps;    /* closest points within r found (kept or not) */
    int status;
    /* Workers sit side by side in one array and update their counts all the
     * time: keep each on its own cache lines (no false sharing between threads). */
    char pad[64];
} worker;

struct nts_context {
    seg_data* seg;
    int seg_cap;
    nts_cells cells;
    master_hot* hot;   /* masters in cell order (or entry order for brute force) */
    int hot_cap;
    master_key* keys;  /* their cheap rejects, same order */
    int keys_cap;
    worker* workers;
    int worker_count, slot_cap;
    nts_vec2* forces;
    int forces_cap;
    nts_contact* contacts;
    int contacts_cap;
    nts_contact* gaps;
    int gaps_cap;
    double phase[4]; /* seconds of the last evaluation: segments, cells, local search, scatter */
    double* scratch;   /* surface_count: segment lengths for the median and the percentile */
    int scratch_cap;
    /* Long entries of the cell list (reach longer than the cell side allows):
     * each is listed in every cell its reach box overlaps (cell_list.c). */
    master_hot* long_hot;
    int long_hot_cap, long_count;
    int* long_start;   /* cells + 1 */
    int long_start_cap;
    int* long_items;   /* into long_hot, by cell */
    int long_items_cap;
    nts_kbuf stiffness; /* the tangent's triplets (NTS_OUT_STIFFNESS) */
};

/* Everything the local search reads, copied once (hot loop locals). */
typedef struct search_env {
    const nts_scene* s;
    const seg_data* seg;
    const nts_cells* cells;  /* NULL: brute force */
    const master_hot* hot;   /* cells: in cell order (cells->items); brute force: entry order */
    const master_key* keys;  /* hot's rejects, same order */
    const master_hot* long_hot; /* the long entries, listed per cell by long_start/long_items */
    const int* long_start;
    const int* long_items;
    double alpha, r, eps;    /* alpha: the options' (a body may have its own: master_hot.alpha) */
    long long max_records;   /* the candidate budget (nts_options.max_candidates) */
    int (*cancel)(void* user);
    void* cancel_user;
    int per_length;          /* NTS_PENALTY_PER_LENGTH */
    double lx, ly, qx, qy;   /* the periodic box and its quarters (0 when open) */
    double cell_reach2;      /* the same for a whole cell, with a round-off allowance */
    int cell_cull;           /* 1 when the stencil offsets are exact images (cull whole cells) */
    nts_solver solver;
    int want_virial;
    int keep_all;            /* records for every closest point (contacts, gaps or tangent asked) */
} search_env;


/* A failed evaluation: the error record filled, the status returned. */
static inline int eval_fail(nts_error* err, int code, int body, int node, const char* msg) {
    return nts_error_set(err, code, nts_at(body, -1, -1, node), "%s", msg);
}

/* The reach length of master j: its features lie within r + max(|t_j|,
 * alpha |t_{j-1}|) of X_j (the flat part of segment j within |t_j| + r, the
 * corner within r + alpha max(|t_{j-1}|, |t_j|), the vertex within r), with
 * alpha the master body's. */
static inline double reach_length(const seg_data* seg, const nts_scene* s, int j, double alpha) {
    double lp = alpha * seg[s->surf_prev[j]].len, lj = seg[j].len;
    return lj > lp ? lj : lp;
}

/* The alpha that shapes body b's surface: its own, or the options' (docs/model.md §10). */
static inline double alpha_of_body(const nts_scene* s, int b, double alpha) {
    return s->body_alpha[b] >= 0.0 ? s->body_alpha[b] : alpha;
}

/* context.c: `count` workers with a body slot map of at least body_count entries. */
int nts_workers_prepare(nts_context* ctx, int count, int body_count);
/* masters.c */
/* NTS_OK, or NTS_ENOMEM (the long masters' copies). */
int nts_fill_hot(nts_context* ctx, const nts_scene* s, const int* order, double alpha, double r, double long_len,
                 int threads);
double nts_select_kth(double* v, int n, int k);
int nts_build_long_lists(nts_context* ctx, const nts_scene* s, double r, double pad, long long budget);
/* search.c: the local search of slaves [begin, end) into worker w. */
void nts_search_range(const search_env* env, worker* w, int begin, int end);
/* scatter.c: the records of the workers, in slave order, into *out. */
int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, int nthreads,
                nts_result* out, nts_error* err);

#endif
