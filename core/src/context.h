/* The evaluation context (context.c): its buffers (they only grow), its
 * workers and the chunks of slaves they run, and the failures of an
 * evaluation. */
#ifndef NTSCONTACT_CONTEXT_H
#define NTSCONTACT_CONTEXT_H

#include <limits.h>

#include "friction.h"
#include "reach.h"
#include <ntscontact/distributed.h>

/* The slaves are searched in chunks of CHUNK_SLAVES entries, handed out by
 * the backend (the stock one: each thread its contiguous block of them, then
 * the others' that are left, so a thread that the machine slows down takes
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
    int node_lo, node_hi;     /* the nodes its force shares touch lie in [node_lo, node_hi] (none: lo > hi) */
    contact_sums sums;        /* of its active contacts */
} chunk_info;

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
    /* Self-contact (docs/model.md §16): the entries of self-contact bodies
     * unwrapped along their loops (open: the positions), for the coverage. */
    nts_vec2* self_u;
    int self_u_cap;
    /* and its slabs (search.h, self_slabs) */
    double* self_y;    /* per body: the lowest height and 1 / slab height */
    int self_y_cap;
    int* self_first;   /* per body + 1: its first slab */
    int self_first_cap;
    int* self_start;   /* per slab + 1: its first edge */
    int self_start_cap;
    int* self_items;   /* the slabs' edges (surface entries) */
    int self_items_cap;
    /* Checking new positions (nts_evaluate_positions): each loop's twice
     * signed area and perimeter (segments.c). */
    double* area_perim;
    int area_perim_cap;
    /* A friction history checked against the scene it is used on (each
     * node's surface entry, or -1: nts_history_check). */
    int* entry_of;
    int entry_of_cap;
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
    /* The scene (nts_scene.serial; 0: none) whose forces were the last
     * written in forces[]: every node of it off its surface still holds
     * zero there (the adds reach surface nodes only), so that its next
     * direct path zeroes the surface nodes alone (evaluate.c). */
    unsigned long long forces_serial;
    double* pressure;  /* NTS_OUT_PRESSURE (pressure.c) */
    int pressure_cap;
    force_shares* shares; /* each active record's forces, computed once (records kept) */
    int shares_cap;
    nts_contact* contacts;
    int contacts_cap;
    nts_contact* gaps;
    int gaps_cap;
    nts_kbuf stiffness; /* the tangent's triplets (NTS_OUT_STIFFNESS) */
    /* Friction (friction.h): each active record's friction (chunks' records
     * at their share_at, the deep contacts' apart), and the result's anchors
     * in contact order. */
    friction_out* fric;
    int fric_cap;
    friction_out* fric_deep;
    int fric_deep_cap;
    nts_anchor* anchors;
    int anchors_cap;
    nts_reach reach;
    nts_warning warnings[NTS_WARN_COUNT_]; /* the last result's (nts_result.warnings) */
    double phase[4];    /* seconds of the last evaluation: segments, cells, local search, scatter */
    int median_from;    /* nts_profile.median_from */
    nts_parallel host;  /* the host's backend (nts_context_set_parallel), when host_set */
    int host_set;
    /* A distributed host's seam (ntscontact/distributed.h, distributed.c):
     * the whole scene's frame, taken for the scene's own when frame_set, and
     * the parts each evaluation leaves when parts_on (scatter.c). */
    nts_frame frame;
    int frame_set, parts_on;
    const unsigned char* owned; /* the host's slaves, by entry (nts_context_set_owned) */
    long long owned_gaps;       /* the last evaluation's closest points of those */
    nts_part* parts;
    int parts_cap, part_count;
    int* gap_entries;   /* the slave entry of every closest point, in the gaps' order */
    int gap_entries_cap, gap_entry_count;
};

/* A failed evaluation: the error record filled, the status returned. */
static inline int eval_fail(nts_error* err, int code, int body, int node, const char* msg) {
    return nts_error_set(err, code, nts_at(body, -1, -1, node), "%s", msg);
}

/* eval_fail for a fault of an option or limit, which err->option names. */
static inline int eval_fail_option(nts_error* err, int code, const char* option, const char* msg) {
    return nts_error_set(err, code, nts_naming(nts_at(-1, -1, -1, -1), option), "%s", msg);
}

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

/* evaluate.c: the cells for radius env->r (and env's pointers to them), when
 * env has none yet: a widened search past the kept lists (reach.c). */
int nts_cells_now(nts_context* ctx, search_env* env);

/* ---- the records after the search (scatter.c, pressure.c) ---- */

/* A chunk's records (none, and maybe no buffer, when it found nothing). */
static inline const candidate* chunk_recs(const chunk_info* ch) {
    return (const candidate*)ch->part[STREAM_RECORDS].data;
}
static inline int chunk_count(const chunk_info* ch) { return ch->part[STREAM_RECORDS].count; }

/* The nodes shares sh[0..n) touch, as the chunk's span: a thread adding
 * the forces of a range of nodes skips the chunks that miss it (scatter.c). */
static inline void chunk_node_span(chunk_info* ch, const force_shares* sh, int n) {
    int lo = INT_MAX, hi = -1, k, q;
    for (k = 0; k < n; ++k)
        for (q = 0; q < 4 && sh[k].node[q] >= 0; ++q) {
            if (sh[k].node[q] < lo) lo = sh[k].node[q];
            if (sh[k].node[q] > hi) hi = sh[k].node[q];
        }
    ch->node_lo = lo;
    ch->node_hi = hi;
}

/* The records of chunk ch and its deep contacts (reach.c), merged by slave
 * then master body (each pair is in one of them only): the order of the
 * contacts and gaps, and of the tangent's blocks and the pressure, the order a radius large
 * enough for every contact would give. */
typedef struct merged {
    const candidate *rec, *deep;
    int i, n, j, m;
} merged;

static inline merged merged_begin(const nts_context* ctx, const chunk_info* ch) {
    merged it;
    it.rec = chunk_recs(ch);
    it.n = chunk_count(ch);
    it.deep = ch->deep_count > 0 ? ctx->reach.deep + ch->deep_at : NULL; /* (no deep contact: maybe no buffer) */
    it.m = ch->deep_count;
    it.i = it.j = 0;
    return it;
}

/* The next record in the merged order, NULL after the last. */
static inline const candidate* merged_next(merged* it) {
    if (it->i < it->n && (it->j == it->m || it->rec[it->i].slave < it->deep[it->j].slave ||
                          (it->rec[it->i].slave == it->deep[it->j].slave && it->rec[it->i].body < it->deep[it->j].body)))
        return &it->rec[it->i++];
    return it->j < it->m ? &it->deep[it->j++] : NULL;
}

#endif
