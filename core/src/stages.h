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
 * the segment that starts at the entry (32 bytes; its normal is seg_normal). */
typedef struct seg_data {
    nts_vec2 t;      /* X1 - X0 (minimum image) */
    double inv_len2; /* 1/|t|^2, |t| > 0 checked */
    double len;
} seg_data;

/* The outward unit normal of a segment (t_y, -t_x)/|t|, computed where it is
 * needed (the same bits every time). */
static inline nts_vec2 seg_normal(nts_vec2 t, double len) { return nts_v2(t.y / len, -t.x / len); }

/* A master surface entry as the local search reads it once it passed the
 * cheap reject (master_key), copied in cell order next to its key (56 bytes).
 * Its previous segment and node indices are read from the scene's arrays. */
typedef struct master_hot {
    nts_vec2 p;      /* X_j */
    nts_vec2 t;      /* segment j: X_{j+1} - X_j (minimum image) */
    double inv_len2; /* 1/|t|^2 */
    double len;      /* |t| */
    int entry;       /* surface entry j */
    int body;
} master_hot;

/* What the first pass of the search reads of a master (32 bytes, cell order):
 * the cheap reject alone, so that the masters a slave visits and drops (most
 * of them: its own body's, and those out of reach) cost two loads and no
 * branch (search.c). The position is in the cell list's frame (wrapped into a
 * periodic box, nts_cells_place), where a stencil row is one shift away from
 * the slave; `reach2` is the master's reach squared, widened by the round-off
 * of that frame, or -1 when it offers nothing from here (a "slave" body, or a
 * long master, searched through its own list). */
typedef struct master_key {
    double x, y;
    double reach2;
    int body;
    int cell;        /* the cell it is binned in */
} master_key;

/* A master searched through the long lists (its key's reach2 is -1). */
typedef struct long_master {
    double reach2;   /* its real reach, squared (with the round-off allowance) */
    int hot;         /* its record in ctx->hot */
    int pad;
} long_master;

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
     * each is listed in every cell its reach box overlaps (masters.c). */
    long_master* long_m;
    int long_m_cap, long_count;
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
    const long_master* long_m; /* the long entries, listed per cell by long_start/long_items */
    const int* long_start;
    const int* long_items;
    double alpha, r, eps;    /* alpha: the options' (a body may have its own: master_hot.alpha) */
    long long max_records;   /* the candidate budget (nts_options.max_candidates) */
    int (*cancel)(void* user);
    void* cancel_user;
    int per_length;          /* NTS_PENALTY_PER_LENGTH */
    double lx, ly, qx, qy;   /* the periodic box and its quarters (0 when open) */
    int cell_shift;          /* 1 when the stencil's cells are distinct images (search.c, try_range) */
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
/* `pad`: the round-off allowance of the cell frame (0 for brute force). */
int nts_fill_hot(nts_context* ctx, const nts_scene* s, const int* order, double alpha, double r, double long_len,
                 double pad, int threads);
double nts_select_kth(double* v, int n, int k);
int nts_build_long_lists(nts_context* ctx, const nts_scene* s, double alpha, double r, double pad, long long budget);
/* search.c: the local search of slaves [begin, end) into worker w. */
void nts_search_range(const search_env* env, worker* w, int begin, int end);
/* scatter.c: the records of the workers, in slave order, into *out. */
int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, int nthreads,
                nts_result* out, nts_error* err);

#endif
