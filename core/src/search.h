/* The local search (search.c, docs/model.md §4, §5), and the contract any
 * search meets: what a GPU or distributed search would plug in as.
 *
 * In:  the segment records (segments.h: seg_data, one per surface entry, in
 *      entry order) and the masters' keys (masters.h) or none (brute force),
 *      in a search_env; a range [begin, end) of slave entries.
 * Out: per slave, in slave (entry) order, and per slave in increasing master
 *      body, one candidate record per (slave, master body) pair with a
 *      closest point within r (docs/model.md §4: gap, parameter, normal,
 *      point, feature); which of them it keeps is the path's (search_env:
 *      every record, the active ones' sums and force shares, or sums and
 *      forces directly: the three paths below), and the items the reach's growth needs
 *      (reach_item). The result depends on nothing but the positions and the
 *      options: not on the order of the masters visited, nor on which worker
 *      ran which range. */
#ifndef NTSCONTACT_SEARCH_H
#define NTSCONTACT_SEARCH_H

#include "candidates.h"
#include "contact_law.h"
#include "corner.h"
#include "masters.h"

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
    int slave, slave_body; /* the slave being searched (self-contact's tests read them) */
    nts_vec2 slave_pn;     /* its pseudo-normal n_{i-1} + n_i, when its body meets itself */
    /* The closest penetration of the slave's own body, in its own periodic
     * image, that passes (T) and (N) (docs/model.md §16), and the slave
     * minus its closest point: (C) decides at the slave's end whether it
     * counts (search.c, self_settle). */
    candidate self_best;
    nts_vec2 self_delta;
    int self_has;
    /* Finished chunks' records and items that the pools had no room for. */
    char* spill[STREAMS];
    size_t spill_used[STREAMS], spill_cap[STREAMS];
    /* The direct path's forces not yet added, first in first out (search.c:
     * forces_delayed). */
    force_shares fifo[FORCE_DELAY];
    int fifo_head, fifo_count;
    int forces_bad;    /* the direct path wrote a force that is not finite (law_add_shares) */
    long long gaps;    /* closest points within r found (kept or not) */
    long long owned_gaps; /* those of the slaves search_env.owned marks (a distributed host's) */
    long long pruned;  /* masters kept_prune moved out of the inner lists (search_env.kept_prune) */
    contact_sums* sums;/* the current chunk's, when the search sums as it goes (direct or shares) */
    int status;
    /* Workers sit side by side in one array and update their counts all the
     * time: keep each on its own cache lines (no false sharing between threads). */
    char pad[64];
} worker;

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
    const unsigned char* surf_flag; /* the contact surfaces' flags (nts_scene.surf_flag), or NULL */
    double ext;              /* their ends' extension (nts_options.surface_extension; 0 without ends) */
    /* Friction (friction.h, docs/model.md §14): on when some pair's
     * coefficient is positive; then every record is kept (the records path)
     * and each active one gets its friction_out before it is summed. */
    int friction;
    double mu, eps_t;        /* the options' coefficient and tangential penalty (the normal one when 0) */
    const nts_history* history;
    double brute_pad;        /* brute force: the round-off allowance of its reach test */
    double wide_pad;         /* the widened searches' round-off allowance (reach.c) */
    double wide_lmax;        /* the longest reach around a node: (1 + ext) L_max (alpha <= 1/2, reach_at_node) */
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
    /* A distributed host's part (distributed.h): which slaves it owns (by
     * entry), whose closest points the workers count apart; NULL: none. */
    const unsigned char* owned;
    nts_vec2* forces;
    /* Several threads and no records asked for: each chunk sums its active
     * contacts as it goes and keeps only their force shares (when forces are
     * asked, `want_forces`), in the order the scatter would compute them. */
    int shares;
    int want_forces;
    /* Kept candidates (candidates.h, docs/model.md §15): the lists the
     * search tries instead of screening the cells (NULL: the cells), and
     * the largest radius a widened search may take from them now
     * (kept_covers); without them, a widened search needs the cells, which
     * nts_cells_now builds from the segment summary `ss` on `run`. */
    const nts_candidates* kept;
    double kept_shift;
    int kept_ahead;          /* the kept masters' lines asked for ahead (nts_kept_ahead) */
    nts_candidates* kept_prune; /* the lists just built, which this replay prunes (eq. (32)), or NULL */
    double cell_side;        /* nts_summary.cell_size (evaluate.c: summary_cell_side) */
    const seg_summary* ss;
    const nts_run* run;
    /* Self-contact (docs/model.md §16): per body, 1 when its nodes meet its
     * own surface (NULL when no body's do: nothing of it runs), and its
     * entries unwrapped along their loops (self_u, by surface entry). */
    const unsigned char* self;
    const nts_vec2* self_u;
    /* The coverage's slabs: a self-contact body's loop edges listed by the
     * horizontal slabs their heights span (about the square root of its
     * entries of them), so that the crossings of a horizontal ray are counted
     * over one slab's edges, not the whole body's (bodies of at least
     * NTS_SELF_SLAB_MIN entries; a smaller one has none and is read whole).
     * self_y[2 b], [2 b + 1]:
     * the body's lowest height and 1 / slab height; self_first[b]: its first
     * slab; self_start: each slab's first edge in self_items. */
    const double* self_y;
    const int* self_first;
    const int* self_start;
    const int* self_items;
} search_env;

/* Bodies of fewer entries have no slabs: their coverage reads every edge. */
enum { NTS_SELF_SLAB_MIN = 256 };

/* The slab of height y among a body's `count` (y_lo_inv[0]: its lowest
 * height, [1]: 1 / slab height), clamped to the body's slabs. */
static inline int nts_self_slab(const double* y_lo_inv, int count, double y) {
    const double q = (y - y_lo_inv[0]) * y_lo_inv[1];
    return q <= 0.0 ? 0 : (q >= (double)(count - 1) ? count - 1 : (int)q);
}

/* Whether a slave of body b may take its own body's masters. */
static inline int self_body(const search_env* env, int b) { return env->self != NULL && env->self[b]; }

/* Whether slave k's kept list holds every master that could offer it a
 * feature within rho (eq. (30)). */
static inline int kept_covers(const search_env* env, int k, double rho) {
    return env->kept != NULL && kept_hi(env->kept)[k] >= 0 && rho * (1.0 + 1e-9) + env->kept_shift <= env->kept->ring[k];
}

/* Whether a slave's neighbour |d| = l away along its loop, with no closest
 * point within r on a body where the slave has one at gap g, could lie
 * deeper than r in it (reach.c): it lies within |g| + l of the body's
 * surface, so deeper than r only when l - g > r. The factor allows for the
 * round-off of g and l: a neighbour asked for in vain costs a search, never
 * an answer. */
static inline int reach_may_be_deeper(double l, double g, double r) { return (l - g) * (1.0 + 1e-9) > r; }

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

/* The local search of slaves [begin, end) into worker w. */
void nts_search_range(const search_env* env, worker* w, int begin, int end);
/* A widened search around slave entry k, in worker w: the best
 * candidate on body `body` among its features within `rho` of the slave;
 * or, when body < 0, on every other body b that offers a surface, within
 * min(rho, the body's depth) for the bodies whose circle holds the slave
 * (nts_body_shape: no other can hold it, or give it an active contact).
 * The candidates are left in w->best (w->best_count
 * of them); nts_search_wide_done clears them. */
void nts_search_wide(const search_env* env, worker* w, int k, int body, double rho, double* shape);
void nts_search_wide_done(worker* w);
/* Build the kept lists of chunk c's slaves into kc (candidates.h): the
 * masters the cells (built for radius kc->outer) offer, whose middle lies
 * within their reach plus the slave's ring of the slave, those within kc->inner
 * first. NTS_OK, NTS_ENOMEM, or NTS_ELIMIT past KEPT_CHUNK_BUDGET. */
int nts_kept_collect(const search_env* env, nts_candidates* kc, int c);


/* ---------------------------------------------- the scatter's three paths
 *
 * What becomes of each active candidate the search finds (docs/model.md §6,
 * §7), by one of three paths, side by side here, chosen by nts_evaluate for
 * what is asked. Each calls the contact law (contact_law.h) for each active
 * contact in the same order, slave order then master body, and adds the
 * same terms in the same order, so the three give the same bits
 * (test_backend.c: the paths). They live with the search, which runs them:
 * the scatter (scatter.h) reads what they leave, never the reverse.
 *
 *   direct   one worker, no records asked: the search sums each slave's
 *            active contacts into its chunk's sums and adds their forces as
 *            it goes (scatter_direct, scatter_direct_drain);
 *   shares   several workers, no records asked: each chunk sums its active
 *            contacts and keeps their force shares (scatter_share), added
 *            node range by node range after the search (scatter.c);
 *   records  an output that keeps records asked (contacts, gaps, the
 *            tangent, the pressure: NTS_OUT_RECORDS_): every closest point
 *            is kept (scatter_record), and scatter.c sums, shares and makes
 *            the contacts of the chunks' records after the search
 *            (pressure.c the pressure), with the same functions. */

/* The slave's penalty (docs/model.md §10) for record b. */
static inline double record_penalty(const search_env* env, const candidate* b) {
    return law_penalty(env->eps, env->per_length, env->s->surf_trib, b->slave);
}

/* Add active record b to the sums. */
static inline void contact_sum(const search_env* env, const candidate* b, contact_sums* cs) {
    law_sum(cs, record_penalty(env, b), b->gap, b->normal, env->want_virial);
}

/* Active record b's forces, node by node (10). */
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

/* ---- path 1: direct ---- */

/* The direct path adds a contact's forces FORCE_DELAY contacts after it was
 * found, in the order found (first in, first out: the same sums, the same
 * bits), and asks for the nodes' forces when it is found: they are scattered
 * over the whole node array, and the additions would otherwise wait on
 * memory one after another. */
static inline void scatter_direct(const search_env* env, worker* w, const candidate* b) {
    force_shares sh;
    int q;
    contact_sum(env, b, w->sums);
    if (env->forces == NULL) return;
    sh = contact_shares(env, b);
    for (q = 0; q < 4 && sh.node[q] >= 0; ++q) NTS_PREFETCH_W(&env->forces[sh.node[q]]);
    if (w->fifo_count == FORCE_DELAY) {
        w->forces_bad |= law_add_shares(env->forces, &w->fifo[w->fifo_head]);
        w->fifo[w->fifo_head] = sh;
        w->fifo_head = (w->fifo_head + 1) % FORCE_DELAY;
    } else {
        w->fifo[(w->fifo_head + w->fifo_count++) % FORCE_DELAY] = sh;
    }
}

/* The forces still delayed, at the end of the worker's range. */
static inline void scatter_direct_drain(const search_env* env, worker* w) {
    for (; w->fifo_count > 0; --w->fifo_count) {
        w->forces_bad |= law_add_shares(env->forces, &w->fifo[w->fifo_head]);
        w->fifo_head = (w->fifo_head + 1) % FORCE_DELAY;
    }
    w->fifo_head = 0;
}

/* ---- path 2: shares (the room is the caller's: flush_slave) ---- */
static inline void scatter_share(const search_env* env, worker* w, const candidate* b) {
    contact_sum(env, b, w->sums);
    if (env->want_forces) w->shares[w->share_count++] = contact_shares(env, b);
}

/* ---- path 3: records (every closest point: summed, shared and made into
 * contacts by scatter.c, after the search, in the same order) ---- */
static inline void scatter_record(worker* w, const candidate* b) { w->recs[w->rec_count++] = *b; }

#endif
