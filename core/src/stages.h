/* The stages of an evaluation and the state they share (private to the core):
 *   segments.c  segment data of every surface entry; order statistics
 *   cell_list.c the grid, its counting sort and the stencil of a cell
 *   masters.c   the masters' keys in cell order, the long masters' lists
 *   search.c    the local search per slave, and its records   (docs/model.md §4, §5)
 *   scatter.c   forces, energy, virial, contacts, tangent    (docs/model.md §6, §7)
 *   context.c   the context, its workers and chunks          (buffers that only grow)
 *   evaluate.c  nts_evaluate: segments -> cells -> search -> scatter -> summary */
#ifndef NTSCONTACT_STAGES_H
#define NTSCONTACT_STAGES_H

#include <stdio.h>
#include <string.h>

#include "corner.h"
#include "internal.h"
#include "parallel.h"

#if defined(__GNUC__)
#define NTS_ALWAYS_INLINE __attribute__((always_inline))
#else
#define NTS_ALWAYS_INLINE
#endif

/* ------------------------------------------------------------ segments */

/* Segment data of surface entry j, recomputed each evaluation from the
 * positions (entry order): its node X_j and the segment j that starts there
 * (its normal is seg_normal), with the scene's topology of the entry. One
 * record is one 64-byte cache line (the buffer is aligned): everything the
 * local search and the forces read of a master is in its line or in the line
 * of the entry before it, so a master costs one prefetch, not one per array. */
typedef struct seg_data {
    nts_vec2 p;      /* X_j */
    nts_vec2 t;      /* X_{j+1} - X_j (minimum image) */
    double inv_len2; /* 1/|t|^2, |t| > 0 checked */
    double len;      /* |t| */
    int prev, next;  /* the entries before and after j in its loop */
    int node, body;  /* the node of X_j and its body */
} seg_data;

/* The buffer's alignment: a record never straddles two cache lines. */
enum { NTS_SEG_ALIGN = 64 };
typedef char nts_seg_data_is_one_line[sizeof(seg_data) == NTS_SEG_ALIGN ? 1 : -1];

/* What the segment pass finds besides the data: the first bad segment in
 * entry order (or surface_count), the longest segment, the largest
 * coordinate (for round-off allowances), the bounding box of the nodes, and
 * the k-th smallest length when asked for (and no segment is bad). */
typedef struct seg_summary {
    int bad;
    double lmax;
    double coord_max;
    double xmin, xmax, ymin, ymax;
    double kth;
} seg_summary;

/* The outward unit normal of a segment (t_y, -t_x)/|t|, computed where it is
 * needed (the same bits every time). */
static inline nts_vec2 seg_normal(nts_vec2 t, double len) { return nts_v2(t.y / len, -t.x / len); }

/* ------------------------------------------------------------ the grid */

/* Square-ish cells over the plane (docs/model.md §9). The frame is the grid's
 * own: coordinates relative to (x0, y0), wrapped into the box when periodic.
 * `scale` is a power of two with scale * (frame coordinate) in [0, 1], the
 * frame of the masters' float keys. */
typedef struct nts_cells {
    double x0, y0, hx, hy, inv_hx, inv_hy;
    double lx, ly;   /* the periodic box, 0 when open */
    double scale;
    int nx, ny;
    int periodic;
    int* cell_start; /* nx*ny + 1: the keys of cell c are [cell_start[c], cell_start[c+1]) */
    int cap_cells;
} nts_cells;

/* Where the grid puts a point: its frame coordinates and its cell. One
 * function for the masters' keys and for the slaves, so that both agree to
 * the bit. Points inside the box (the usual case) skip the wrap. */
typedef struct nts_cell_place {
    double x, y;
    int cx, cy, cell; /* column, row, and cy nx + cx */
} nts_cell_place;
static inline int nts_cells_clamp(double v, int n) {
    /* Compare in double before converting: (int) of a huge double is undefined. */
    if (!(v >= 0.0)) return 0;
    if (v >= (double)(n - 1)) return n - 1;
    return (int)v;
}
static inline nts_cell_place nts_cells_place(const nts_cells* c, nts_vec2 p) {
    nts_cell_place q;
    q.x = p.x - c->x0;
    q.y = p.y - c->y0;
    if (c->periodic) {
        if (!(q.x >= 0.0 && q.x < c->lx)) q.x -= c->lx * floor(q.x / c->lx);
        if (!(q.y >= 0.0 && q.y < c->ly)) q.y -= c->ly * floor(q.y / c->ly);
    }
    q.cx = nts_cells_clamp(q.x * c->inv_hx, c->nx);
    q.cy = nts_cells_clamp(q.y * c->inv_hy, c->ny);
    q.cell = q.cy * c->nx + q.cx;
    return q;
}
/* Shape the grid: cells of side >= h over the box (periodic) or over the
 * bounding box of the summary (open); at most about 4 cells per surface entry
 * (h grows if needed, which the search allows). Room for at least
 * `min_cells` cells. NTS_OK or NTS_ENOMEM. */
int nts_cells_shape(nts_cells* c, const nts_scene* s, const seg_summary* sum, double h, int min_cells);
/* How many cells nts_cells_shape would make for side h. */
int nts_cells_count(const nts_scene* s, const seg_summary* sum, double h);
/* The first slice entry of slice u of `slices` equal slices of [0, n). */
static inline int nts_slice_begin(int n, int slices, int u) { return (int)((long long)n * u / slices); }
/* Sort entries by cell, first half: cell_start gets the cells' bounds and
 * hist (slices * cells ints) the first place of each slice's entries in each
 * cell, for the caller to place the entries e with cell_of[e] >= 0, each
 * slice in increasing e (in parallel): then every cell lists its entries in
 * increasing e, whatever the slices. With one slice hist is not used: the
 * first places are the cells' starts. */
/* At most this many slices: each costs a count per cell (the sort is a
 * small part of the work). */
enum { SORT_SLICES = 4 };
void nts_cells_offsets(nts_cells* c, const int* cell_of, int n, int* hist, int slices, const nts_run* run);
void nts_cells_free(nts_cells* c);

/* The masters a slave in one cell visits: the key ranges of the 3 x 3 cells
 * around it, each with the image shift (in the keys' scaled frame) that brings
 * its masters next to the slave. The three cells of a row are consecutive in
 * cell order, so a row is one range unless it wraps around the box. In a
 * periodic grid of fewer than 3 cells a side the same cell comes back with
 * another shift: a master may then be tried twice, which changes nothing
 * (the better of two equal candidates is the first). */
typedef struct nts_stencil {
    int n;
    int keys; /* in all the ranges */
    int begin[9], end[9];
    double shift_x[9], shift_y[9];
} nts_stencil;
void nts_cells_stencil(const nts_cells* c, int cell, nts_stencil* st);

/* ------------------------------------------------------------- masters */

/* The masters that the stencil offers, in cell order, as the first pass of
 * the search reads them: float positions in the scaled frame and the reach
 * squared, widened to cover every round-off on the way (masters.c), so that
 * the float test never drops a master that the exact test could keep. Struct
 * of arrays, KEY_PAD elements past the end that no range reaches, so that
 * the last range of the arrays can be read 8 at a time. 16 bytes a master. */
enum { KEY_PAD = 8 };
typedef struct master_keys {
    float* x;
    float* y;
    float* reach2;
    int* entry; /* a body's entries are consecutive: its range tells own from other */
    int count, cap;
    void* block;
} master_keys;

/* A master that reaches farther than the cell side allows (a long wall),
 * searched through the long lists of the cells its reach box overlaps: the
 * exact test is in double, around X_j. */
typedef struct long_master {
    double reach2;
    int entry;
    int pad;
} long_master;

/* ---------------------------------------------------- search, records */

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

/* What active contacts add up to: their count, energy (9), virial (11) and
 * largest penetration, and whether one overflowed a double. */
typedef struct contact_sums {
    double energy, vxx, vyy, vxy, maxpen;
    int active, overflow;
} contact_sums;

/* An active record's forces (10), node by node: f_s = -eps g n on the slave
 * (node[0]), f_k = eps g N_k n on master node k (node[1..3], -1 past the
 * last). Kept as eps g, n and the N_k, one 64-byte line: share_force makes
 * each node's force by the same products wherever it runs (the same bits). */
typedef struct force_shares {
    int node[4];
    double eg;
    nts_vec2 n;
    double w[3];
} force_shares;

typedef char nts_force_shares_are_one_line[sizeof(force_shares) == 64 ? 1 : -1];

static inline nts_vec2 share_force(const force_shares* sh, int q) {
    return q == 0 ? nts_scale(-sh->eg, sh->n) : nts_scale(sh->eg * sh->w[q - 1], sh->n);
}

/* A hint to load a line that will be read (written) soon. */
#if defined(__GNUC__)
#define NTS_PREFETCH(p) __builtin_prefetch(p)
#define NTS_PREFETCH_W(p) __builtin_prefetch(p, 1)
#else
#define NTS_PREFETCH(p) ((void)0)
#define NTS_PREFETCH_W(p) ((void)0)
#endif

/* How many contacts later the direct path adds a contact's forces. */
enum { FORCE_DELAY = 8 };

/* What the search leaves for the reach's growth (reach.c), 32 bytes. As it
 * goes it compares each slave's closest points with those of the slave
 * before it along the loop (search.c: reach_neighbours):
 * - REACH_ASK: `slave` has no closest point within r on `body`, but its
 *   neighbour on side `from` has one (normal nx, ny, in single precision:
 *   it only rules slaves out, with an allowance), and `slave` could lie
 *   deeper than r in the body: search it widened to radius `value`.
 * - REACH_EDGE: a closest point of `slave` on `body` (gap `value`, normal
 *   nx, ny) whose neighbour on side `from` is across the end of the chunk or
 *   of the loop: reach.c compares the two.
 * - REACH_COARSE: `slave` is next to a segment longer than 2 r: its
 *   chain may have no closest point within r at all. */
enum { REACH_ASK = 0, REACH_EDGE = 1, REACH_COARSE = 2 };
enum { SIDE_PREV = 1, SIDE_NEXT = 2 }; /* bits: the neighbour before or after along the loop */
typedef struct reach_item {
    int slave, body;
    unsigned char kind, from;
    int pad;
    double value;
    float nx, ny;
} reach_item;

/* What a chunk leaves behind, stream by stream: its records (candidates, or
 * force shares with search_env.shares) and its items for the reach. */
enum { STREAM_RECORDS = 0, STREAM_REACH = 1, STREAMS = 2 };

/* One worker's scratch: the per-slave best candidate of each master body, and
 * the records of the chunk it runs, in slave order: every closest point
 * within r when contacts, gaps or the tangent are asked for, else only the
 * active contacts (g < 0), all that forces, energy and virial need; or, with
 * several threads and no records asked for, only the active contacts' force
 * shares. A finished chunk's records move to the context's pool
 * (nts_chunk_keep), or to the worker's spill when the pool is full. */
typedef struct worker {
    int* slot;         /* body -> index into best, -1 if none (all -1 between slaves) */
    candidate* best;   /* candidates of the current slave */
    int best_count, best_cap;
    int best_most;     /* the most candidates of one slave this evaluation (a need of the
                          scene, whichever worker met it: nts_chunks_settle) */
    candidate* recs;   /* the current chunk's records */
    int rec_count, rec_cap;
    force_shares* shares; /* the current chunk's force shares (search_env.shares) */
    int share_count, share_cap;
    reach_item* items; /* the current chunk's items for the reach */
    int item_count, item_cap;
    candidate* last;   /* the closest points of the slave flushed last in this chunk */
    int last_count, last_cap, last_slave;
    int first_slave;   /* the first slave of the current loop, when it is in this chunk (else -1) */
    /* Finished chunks' records and items that the pools had no room for. */
    char* spill[STREAMS];
    size_t spill_used[STREAMS], spill_cap[STREAMS];
    /* The direct path's forces not yet added, first in first out (search.c:
     * forces_delayed). */
    force_shares fifo[FORCE_DELAY];
    int fifo_head, fifo_count;
    long long gaps;    /* closest points within r found (kept or not) */
    contact_sums* sums;/* the current chunk's, when the search sums as it goes (direct or shares) */
    int status;
    /* Workers sit side by side in one array and update their counts all the
     * time: keep each on its own cache lines (no false sharing between threads). */
    char pad[64];
} worker;

/* The slaves are searched in chunks of CHUNK_SLAVES entries, each taken by
 * whichever thread is free (so a thread that the machine slows down takes
 * fewer); a chunk's records go to one pool for all the chunks, wherever they
 * ran, and the scatter reads the chunks in order: slave order, whoever ran
 * them. The scatter also leaves each chunk's partial sums here, added in
 * chunk order: the same bits for any number of threads. */
enum { CHUNK_SLAVES = 1024 };

/* One stream of one chunk: how many items, and where they are. */
typedef struct chunk_part {
    int count;
    int spilled;              /* 1: in workers[worker].spill[stream] at `at` */
    size_t at;                /* the byte where they are, in the pool or the spill */
    const void* data;         /* once the search is over (nts_chunks_settle) */
} chunk_part;

typedef struct chunk_info {
    int worker;               /* who ran it */
    chunk_part part[STREAMS]; /* its records (force shares with search_env.shares), its reach items */
    int gap_at, contact_at;   /* the first places of its records in the gaps and contacts */
    int deep_at, deep_count;  /* the deep contacts of its slaves (ctx->reach.deep) */
    int share_at;             /* the first place of its active records' force shares in ctx->shares */
    const force_shares* sh;   /* its force shares (sums.active of them), wherever they are */
    contact_sums sums;        /* of its active contacts */
} chunk_info;

/* The growth of the reach (reach.c, docs/model.md §4.5): the closest points
 * deeper than r that the search could not see, found by widening the search
 * around the slaves next to those it found. */
typedef struct reach_request {
    int slave, body; /* a slave entry and a master body it may be inside of */
    double rho;      /* a radius within which its closest point on the body lies */
    int from;        /* SIDE_* bits: the neighbours that asked (they have a closest point there) */
    int pad;
} reach_request;

/* A pair queued or settled: slave * bodies + body, and its place in the queue
 * (-1: settled outside it). */
typedef struct reach_seen {
    long long key;
    int at, pad;
} reach_seen;

enum { SHAPE = 8 }; /* doubles per body in nts_reach.shape */

typedef struct nts_reach {
    reach_request* queue;   /* the pairs to search, each once */
    int queue_count, queue_cap;
    candidate* hits;        /* each queued pair's closest point (kind -1: none) */
    int hits_cap;
    reach_seen* seen;       /* open addressing, key -1: empty */
    int seen_cap, seen_count;
    reach_item* edges;      /* the chunks' REACH_EDGE items, by slave */
    int edge_count, edge_cap;
    candidate* deep;        /* the active contacts deeper than r, by slave then body */
    int deep_count, deep_cap;
    force_shares* shares;   /* their forces */
    int shares_cap;
    double* shape;          /* per body, SHAPE: a circle around its nodes, the deepest a point inside can
                               be, its bounding box (nts_body_shape) */
    int shape_cap;
    int* grid_start;        /* the bodies' grid (reach.c: body_grid), cells + 1 */
    int* grid_items;
    int grid_start_cap, grid_items_cap, grid_built; /* built: 1, not yet: 0, too many: -1 */
    long long beyond;       /* with an explicit radius: the active contacts deeper than r, left out */
    long long unresolved;   /* slaves inside a body deeper than the periodic box's limit */
} nts_reach;

struct nts_context {
    seg_data* seg;    /* aligned to NTS_SEG_ALIGN inside seg_block */
    void* seg_block;
    int seg_cap;
    nts_cells cells;
    master_keys keys;
    long_master* long_m;
    int long_m_cap, long_count;
    int* long_start;   /* cells + 1 */
    int long_start_cap;
    int* long_items;   /* into long_m, by cell */
    int long_items_cap;
    /* Two ints per surface entry, lent to one phase at a time: the order
     * statistics' values, then the cells of the masters. */
    int* scratch;
    int scratch_cap;
    int* hist;         /* per-slice cell counts of the counting sort */
    int hist_cap;
    worker* workers;
    int worker_count, slot_cap;
    /* Per stream, the chunks' items (records or force shares; reach items),
     * each chunk's in one piece. */
    char* pool[STREAMS];
    size_t pool_cap[STREAMS], pool_at[STREAMS];
    chunk_info* chunks;
    int chunk_cap, chunk_count;
    nts_vec2* forces;
    int forces_cap;
    force_shares* shares; /* each active record's forces, computed once (records kept) */
    int shares_cap;
    nts_contact* contacts;
    int contacts_cap;
    nts_contact* gaps;
    int gaps_cap;
    nts_kbuf stiffness; /* the tangent's triplets (NTS_OUT_STIFFNESS) */
    nts_reach reach;
    nts_warning warnings[NTS_WARN_COUNT_]; /* the last result's (nts_result.warnings) */
    double phase[4];    /* seconds of the last evaluation: segments, cells, local search, scatter */
    nts_parallel host;  /* the host's backend (nts_context_set_parallel), when host_set */
    int host_set;
};

/* Everything the local search reads, copied once (hot loop locals). */
typedef struct search_env {
    const nts_scene* s;
    const seg_data* seg;
    const nts_cells* cells;  /* NULL: brute force */
    const master_keys* keys;
    const long_master* long_m; /* the long masters, listed per cell by long_start/long_items */
    const int* long_start;
    const int* long_items;
    double alpha, r, eps;    /* alpha: the options' (a body may have its own) */
    int body_alphas;         /* some body has its own alpha */
    double brute_pad;        /* brute force: the round-off allowance of its reach test */
    double wide_pad;         /* the widened searches' round-off allowance (reach.c) */
    double wide_lmax;        /* the longest reach around a node: L_max (alpha <= 1/2, reach_at_node) */
    double reach_max;        /* the largest radius a widened search may take */
    double coarse;           /* 2 r: a slave next to a longer segment is searched widened (reach.c) */
    int grow;                /* default radius: the active contacts deeper than r are kept (reach.c) */
    long long max_records;   /* the candidate budget (nts_options.max_candidates) */
    int (*cancel)(void* user);
    void* cancel_user;
    int per_length;          /* NTS_PENALTY_PER_LENGTH */
    double lx, ly, qx, qy;   /* the periodic box and its quarters (0 when open) */
    nts_solver solver;
    int want_virial;
    int keep_all;            /* records for every closest point (contacts, gaps or tangent asked) */
    /* One thread and no records asked for: the search adds each slave's
     * active contacts to its chunk's sums and to the forces (when asked, into
     * `forces`) itself, in the order the scatter would, and keeps no records. */
    int direct;
    nts_vec2* forces;
    /* Several threads and no records asked for: each chunk sums its active
     * contacts as it goes and keeps only their force shares (when forces are
     * asked, `want_forces`), in the order the scatter would compute them. */
    int shares;
    int want_forces;
} search_env;

/* A failed evaluation: the error record filled, the status returned. */
static inline int eval_fail(nts_error* err, int code, int body, int node, const char* msg) {
    return nts_error_set(err, code, nts_at(body, -1, -1, node), "%s", msg);
}

/* eval_fail for a fault of an option or limit, which err->option names. */
static inline int eval_fail_option(nts_error* err, int code, const char* option, const char* msg) {
    return nts_error_set(err, code, nts_naming(nts_at(-1, -1, -1, -1), option), "%s", msg);
}

/* The alpha that shapes body b's surface: its own, or the options' (docs/model.md §10). */
static inline double alpha_of_body(const nts_scene* s, int b, double alpha) {
    return s->body_alpha[b] >= 0.0 ? s->body_alpha[b] : alpha;
}

/* A reach length plus the search radius, with the allowances of every test
 * that stands for the exact ones: the factor 1 + 1e-9 covers the round-off of
 * the feature tests, `pad` that of the frame the distance is taken in. */
static inline double reach_allowed(double reach, double r, double pad) { return (reach + r) * (1.0 + 1e-9) + pad; }

/* The reach of master j around X_j: its features lie within r + max(|t_j|,
 * alpha |t_{j-1}|) of X_j (the flat part of segment j within |t_j| + r, the
 * corner within r + alpha max(|t_{j-1}|, |t_j|), the vertex within r), with
 * alpha the master body's. */
static inline double reach_at_node(const seg_data* seg, int j, double alpha) {
    double lp = alpha * seg[seg[j].prev].len, lj = seg[j].len;
    return lj > lp ? lj : lp;
}

/* The reach of master j around the middle M_j = X_j + t_j / 2 of its segment,
 * which the cells bin: the flat part lies within |t_j| / 2 of M_j, and the
 * corner in the triangle X_j, X_j + alpha t_j, X_j - alpha t_{j-1}, within
 * |t_j| / 2 + alpha |t_{j-1}|; so every feature within r of a slave puts the
 * slave within r + this of M_j. Smaller than the reach around X_j, so the
 * cells are smaller and fewer masters pass the first test. */
static inline double reach_at_middle(const seg_data* seg, int j, double alpha) {
    return 0.5 * seg[j].len + alpha * seg[seg[j].prev].len;
}

/* Whether a slave's neighbour |d| = l away along its loop, with no closest
 * point within r on a body where the slave has one at gap g, could lie
 * deeper than r in it (reach.c): it lies within |g| + l of the body's
 * surface, so deeper than r only when l - g > r. The factor allows for the
 * round-off of g and l: a neighbour asked for in vain costs a search, never
 * an answer. */
static inline int reach_may_be_deeper(double l, double g, double r) { return (l - g) * (1.0 + 1e-9) > r; }

/* ------------------------------------------------------------ contacts */

/* The master nodes of record b, as surface entries, and their weights
 * (docs/model.md §4): the segment's two ends, the corner's three nodes
 * (X2, X3, X4) with the shape functions (3), or the vertex. */
static inline int record_masters(const search_env* env, const candidate* b, int entry[3], double w[3]) {
    const nts_scene* s = env->s;
    const int j = b->entry;
    if (b->kind == NTS_KIND_SEGMENT) {
        entry[0] = j;
        entry[1] = env->seg[j].next;
        w[0] = 1.0 - b->param;
        w[1] = b->param;
        return 2;
    }
    if (b->kind == NTS_KIND_CORNER) {
        const nts_shape3 N = corner_shape(alpha_of_body(s, b->body, env->alpha), b->param);
        entry[0] = env->seg[j].prev;
        entry[1] = j;
        entry[2] = env->seg[j].next;
        w[0] = N.n2;
        w[1] = N.n3;
        w[2] = N.n4;
        return 3;
    }
    entry[0] = j;
    w[0] = 1.0;
    return 1;
}

/* The slave's penalty (docs/model.md §6): per node, or per unit of the node's
 * tributary length at creation (a pressure stiffness). */
static inline double record_penalty(const search_env* env, const candidate* b) {
    return env->per_length ? env->eps * env->s->surf_trib[b->slave] : env->eps;
}

/* The virial of an active contact (11): -sum_k f_k (X_k - Xs) over its nodes
 * is -eps g n (X - Xs) with X the closest point, and Xs - X = g n there, so
 * it is eps g^2 n n: no node positions needed. `eg` = eps g. */
static inline nts_virial record_virial(double eg, double g, nts_vec2 n) {
    const double e2 = eg * g;
    nts_virial v;
    v.xx = e2 * n.x * n.x;
    v.yy = e2 * n.y * n.y;
    v.xy = e2 * n.x * n.y;
    return v;
}

/* Add an active record to the sums. */
static inline void contact_sum(const search_env* env, const candidate* b, contact_sums* cs) {
    const double pen = record_penalty(env, b);
    ++cs->active;
    cs->energy += 0.5 * pen * b->gap * b->gap; /* (9) */
    if (-b->gap > cs->maxpen) cs->maxpen = -b->gap;
    cs->overflow |= !isfinite(pen * b->gap);
    if (env->want_virial) {
        const nts_virial v = record_virial(pen * b->gap, b->gap, b->normal);
        cs->overflow |= !isfinite(v.xx + v.yy + v.xy);
        cs->vxx += v.xx;
        cs->vyy += v.yy;
        cs->vxy += v.xy;
    }
}


static inline force_shares contact_shares(const search_env* env, const candidate* b) {
    force_shares sh;
    int entry[3], q, m;
    sh.eg = record_penalty(env, b) * b->gap;
    sh.n = b->normal;
    sh.node[0] = env->seg[b->slave].node;
    m = record_masters(env, b, entry, sh.w);
    for (q = 0; q < 3; ++q) {
        sh.node[q + 1] = q < m ? env->seg[entry[q]].node : -1;
        if (q >= m) sh.w[q] = 0.0;
    }
    return sh;
}

/* Add a record's force shares into F, node by node in order (the scatter
 * adds them the same way: the same bits). */
static inline void add_shares(nts_vec2* F, const force_shares* sh) {
    int q;
    for (q = 0; q < 4 && sh->node[q] >= 0; ++q) F[sh->node[q]] = nts_add(F[sh->node[q]], share_force(sh, q));
}

/* segments.c */
/* The order statistic's sample: this many entries at a fixed stride. */
enum { NTS_SAMPLE = 4096 };
/* The segment data, the summary, and the k-th smallest segment length
 * (0-based, exactly; k < 0: none) found in the same pass. `scratch` holds
 * surface_count + NTS_SAMPLE doubles. */
int nts_segments_compute(nts_context* ctx, const nts_scene* s, int k, double* scratch, const nts_run* run,
                         seg_summary* out);
/* The k-th smallest of v[0..n) (v is reordered): quickselect, O(n log n) at worst. */
double nts_select_kth(double* v, int n, int k);

/* masters.c: bin the masters that reach at most `hcell` (with their round-off
 * allowance `pad`; every master when hcell = 0) and fill their keys in cell order; list the others in the
 * long lists of the cells they reach. `min_cells`: the room to keep for the
 * cells' buffers. NTS_OK, NTS_ENOMEM, or NTS_ELIMIT when
 * the long lists would exceed `budget` entries (the caller coarsens). */
int nts_masters_build(nts_context* ctx, const nts_scene* s, double alpha, double r, double hcell, double pad,
                      long long budget, int min_cells, const nts_run* run);

/* context.c: `count` workers with a body slot map of at least body_count
 * entries, and room for `chunks` chunks. */
int nts_workers_prepare(nts_context* ctx, int count, int body_count, int chunks);
/* context.c: chunk ch, just run by worker w, keeps its `bytes` of records
 * or reach items (`stream`) from `staged`: in that stream's pool when it has room
 * (any thread may call it at once), else in w's spill (w->status is
 * NTS_ENOMEM if that fails). */
void nts_chunk_keep(nts_context* ctx, worker* w, chunk_info* ch, int stream, const void* staged, size_t bytes);
/* context.c: once the search is over, every chunk's records and items in
 * their pools, in chunk order when a pool had to grow, and room kept for the
 * next evaluation to allocate nothing whoever runs which chunk: the pools
 * for all the items, each worker for the largest chunk and the most
 * candidates of a slave. Sets each chunk's parts' `data`. */
int nts_chunks_settle(nts_context* ctx, int nthreads, int shares);

/* search.c: the local search of slaves [begin, end) into worker w. */
void nts_search_range(const search_env* env, worker* w, int begin, int end);
/* search.c: a widened search around slave entry k, in worker w: the best
 * candidate on body `body` among its features within `rho` of the slave;
 * or, when body < 0, on every other body b that offers a surface, within
 * min(rho, the body's depth) for the bodies whose circle holds the slave
 * (nts_body_shape: no other can hold it, or give it an active contact).
 * The candidates are left in w->best (w->best_count
 * of them); nts_search_wide_done clears them. */
void nts_search_wide(const search_env* env, worker* w, int k, int body, double rho, double* shape);
void nts_search_wide_done(worker* w);

/* reach.c: after the search, the pairs (slave, master body) next to those
 * it found whose closest point lies deeper than r; kept in ctx->reach.deep
 * when env->grow, else counted in ctx->reach.beyond. The widened searches
 * run on `threads` workers. NTS_OK, NTS_ENOMEM, NTS_ELIMIT (more than
 * env->max_records closest points with `found`) or NTS_ECANCELLED. */
int nts_reach_grow(nts_context* ctx, const search_env* env, long long found, const nts_run* run);
size_t nts_reach_memory_bytes(const nts_reach* r);
/* shape.c: body b's shape, once per evaluation (shape[SHAPE b + 3] < 0
 * until then): a circle around its nodes, centre relative to its first node
 * and radius squared, the deepest a point inside can lie below its surface,
 * and its bounding box. A point outside the circle is outside the body
 * (nts_outside_circle). */
const double* nts_body_shape(const search_env* env, double* shape, int b);
int nts_outside_circle(const search_env* env, double* shape, int b, nts_vec2 x);
void nts_reach_free(nts_reach* r);

/* scatter.c: the chunks' records, in slave order, into *out. */
int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, const nts_run* run,
                nts_result* out, nts_error* err);

#endif
