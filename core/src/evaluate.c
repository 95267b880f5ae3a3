/* Evaluation: global search (cells or brute force), local search per slave node
 * (docs/model.md §4), then forces, energy and virial ("Forces,
 * energy, virial"). The local search writes per-slave records into per-worker
 * buffers; a serial pass scatters them in slave order, so the result is bitwise
 * the same for any number of threads. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#if NTS_CONFIG_OPENMP
#include <omp.h>
#endif
#include <time.h>

/* Wall clock for the phase timings (nts_context_phase_times). */
static double wall_time(void) {
#if NTS_CONFIG_OPENMP
    return omp_get_wtime();
#else
    return (double)clock() / (double)CLOCKS_PER_SEC;
#endif
}

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

/* The best candidate so far of one (slave, master body) pair. Only what the
 * selection needs; the full nts_contact is made once, when the slave is done. */
typedef struct candidate {
    double gap;
    double param;    /* s (segment), xi (corner), 0 (vertex) */
    nts_vec2 normal;
    nts_vec2 point;
    int body;        /* master body */
    int entry;       /* surface entry j of the feature's master node */
    int key;         /* the master node index inside its body (tie-break) */
    int kind;
} candidate;

/* One worker's scratch: the per-slave best candidate of each master body, and
 * the records (nts_contact) of the slaves it handled, in slave order. */
typedef struct worker {
    int* slot;         /* body -> index into best, -1 if none (all -1 between slaves) */
    candidate* best;   /* candidates of the current slave */
    int best_count, best_cap;
    nts_contact* recs;
    int rec_count, rec_cap;
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

/* Phase timings of the last evaluation (internal.h; used by bench/). */
void nts_context_phase_times(const nts_context* ctx, double out[4]) {
    int i;
    for (i = 0; i < 4; ++i) out[i] = ctx->phase[i];
}

size_t nts_context_memory_bytes(const nts_context* ctx) {
    size_t n;
    int i;
    if (ctx == NULL) return 0;
    n = sizeof *ctx + (size_t)ctx->seg_cap * sizeof(seg_data) + (size_t)ctx->hot_cap * sizeof(master_hot) +
        (size_t)ctx->forces_cap * sizeof(nts_vec2) + (size_t)ctx->contacts_cap * sizeof(nts_contact) +
        (size_t)ctx->gaps_cap * sizeof(nts_contact) + (size_t)ctx->cells.cap_cells * sizeof(int) +
        2 * (size_t)ctx->cells.cap_items * sizeof(int) + (size_t)ctx->scratch_cap * sizeof(double) +
        (size_t)ctx->long_hot_cap * sizeof(master_hot) + (size_t)ctx->long_start_cap * sizeof(int) +
        (size_t)ctx->long_items_cap * sizeof(int) +
        (size_t)ctx->stiffness.cap * (2 * sizeof(int) + sizeof(double));
    for (i = 0; i < ctx->worker_count; ++i) {
        const worker* w = &ctx->workers[i];
        n += sizeof *w + (size_t)ctx->slot_cap * sizeof(int) + (size_t)w->best_cap * sizeof(candidate) +
             (size_t)w->rec_cap * sizeof(nts_contact);
    }
    return n;
}

nts_context* nts_context_create(void) {
    nts_context* ctx = (nts_context*)nts_alloc(sizeof *ctx);
    if (ctx != NULL) memset(ctx, 0, sizeof *ctx);
    return ctx;
}

static void workers_free(nts_context* ctx) {
    int i;
    for (i = 0; i < ctx->worker_count; ++i) {
        nts_free(ctx->workers[i].slot);
        nts_free(ctx->workers[i].best);
        nts_free(ctx->workers[i].recs);
    }
    nts_free(ctx->workers);
    ctx->workers = NULL;
    ctx->worker_count = 0;
    ctx->slot_cap = 0;
}

void nts_context_destroy(nts_context* ctx) {
    if (ctx == NULL) return;
    nts_free(ctx->seg);
    nts_cells_free(&ctx->cells);
    nts_free(ctx->hot);
    workers_free(ctx);
    nts_free(ctx->forces);
    nts_free(ctx->contacts);
    nts_free(ctx->gaps);
    nts_free(ctx->scratch);
    nts_free(ctx->long_hot);
    nts_free(ctx->long_start);
    nts_free(ctx->long_items);
    nts_kbuf_free(&ctx->stiffness);
    nts_free(ctx);
}

/* Workers with a body slot map of at least body_count entries. */
static int workers_prepare(nts_context* ctx, int count, int body_count) {
    int i, j;
    if (ctx->worker_count != count || ctx->slot_cap < body_count) {
        workers_free(ctx);
        ctx->workers = (worker*)nts_alloc(sizeof(worker) * (size_t)count);
        if (ctx->workers == NULL) return NTS_ENOMEM;
        memset(ctx->workers, 0, sizeof(worker) * (size_t)count);
        ctx->worker_count = count;
        for (i = 0; i < count; ++i) {
            ctx->workers[i].slot = (int*)nts_alloc(sizeof(int) * (size_t)body_count);
            if (ctx->workers[i].slot == NULL) return NTS_ENOMEM;
            for (j = 0; j < body_count; ++j) ctx->workers[i].slot[j] = -1;
        }
        ctx->slot_cap = body_count;
    }
    for (i = 0; i < count; ++i) {
        ctx->workers[i].rec_count = 0;
        ctx->workers[i].best_count = 0;
        ctx->workers[i].status = NTS_OK;
    }
    return NTS_OK;
}

/* Everything the local search reads, copied once (hot loop locals). */
typedef struct search_env {
    const nts_scene* s;
    const seg_data* seg;
    const nts_cells* cells;  /* NULL: brute force */
    const master_hot* hot;   /* cells: in cell order (cells->items); brute force: entry order */
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
} search_env;

#if defined(__GNUC__)
#define NTS_ALWAYS_INLINE __attribute__((always_inline))
#else
#define NTS_ALWAYS_INLINE
#endif

/* Xs - X exactly as nts_scene_diff computes it (docs/model.md
 * §8: the minimum image), without its division and library call in the
 * common case: when |d.x| < lx/4 the image is 0 (nearbyint gives a signed zero,
 * and d.x - lx * (+-0) is d.x + 0.0, which also turns -0 into +0 as it does), so
 * only pairs across the box edge pay for the general formula. Bitwise equal. */
static inline double min_image_1(double d, double l, double quarter) {
    if (!(l > 0.0)) return d;
    if (fabs(d) < quarter) return d + 0.0;
    return d - l * nearbyint(d / l);
}
/* `periodic` is a compile-time constant at every call (the search loop is
 * instantiated twice), so an open scene pays nothing for the box. */
static inline nts_vec2 search_diff(const search_env* env, nts_vec2 p, nts_vec2 q, const int periodic) {
    nts_vec2 d = nts_sub(p, q);
    if (!periodic) return d;
    if (fabs(d.x) < env->qx && fabs(d.y) < env->qy) {
        d.x += 0.0;
        d.y += 0.0;
        return d;
    }
    d.x = min_image_1(d.x, env->lx, env->qx);
    d.y = min_image_1(d.y, env->ly, env->qy);
    return d;
}

/* Tie-break (docs/model.md §5): smaller |g|, then the smaller master
 * node index, then segment before corner/vertex at the same node. */
static inline int better(const candidate* c, const candidate* b) {
    double gc = fabs(c->gap), gb = fabs(b->gap);
    if (gc != gb) return gc < gb;
    if (c->key != b->key) return c->key < b->key;
    return c->kind < b->kind;
}

static inline void offer(worker* w, const candidate* c) {
    int k = w->slot[c->body];
    if (k < 0) {
        if (w->best_count == w->best_cap &&
            nts_grow((void**)&w->best, &w->best_cap, w->best_count + 1, sizeof(candidate)) != NTS_OK) {
            w->status = NTS_ENOMEM;
            return;
        }
        k = w->best_count++;
        w->slot[c->body] = k;
        w->best[k] = *c;
    } else if (better(c, &w->best[k])) {
        w->best[k] = *c;
    }
}

/* Try the features that master m (surface entry j) offers to a slave at xs: the
 * flat part of segment (j, j+1), and the corner (alpha > 0) or vertex (alpha = 0)
 * at j. The arithmetic of every accepted candidate is the first core's, operation
 * for operation, so results are bitwise unchanged. */
static inline NTS_ALWAYS_INLINE void try_master(const search_env* env, worker* w, nts_vec2 xs, int slave_body,
                                                const master_hot* m, const int periodic) {
    const double alpha = m->alpha, r = env->r; /* the master's alpha shapes the master's surface */
    const nts_vec2 pj = m->p;
    nts_vec2 d = search_diff(env, xs, pj, periodic); /* Xs - X0 (or Xs - X3): subtract first */
    double d2 = d.x * d.x + d.y * d.y, sj_param;
    candidate c;

    /* Cheap reject: every feature of this master lies within its reach of X_j
     * (segment: |d| <= |t| + |g|; corner: |d| <= r + alpha max(|a|, |c|); vertex:
     * |d| = |g|), so a farther master offers nothing (fill_hot). One branch
     * for both tests (no self-contact): they are hard to predict. */
    if (!((d2 <= m->reach2) & (m->body != slave_body))) return;
    sj_param = nts_dot(d, m->t) * m->inv_len2; /* docs/model.md §12, correction 2 */

    /* Flat candidate of segment j (alpha <= s <= 1 - alpha). */
    if (sj_param >= alpha && sj_param <= 1.0 - alpha) {
        double g = nts_dot(d, m->n);
        if (fabs(g) <= r) {
            c.gap = g;
            c.param = sj_param;
            c.normal = m->n;
            c.point = nts_mul_add(pj, sj_param, m->t);
            c.body = m->body;
            c.entry = m->entry;
            c.key = env->s->surf_local[m->entry];
            c.kind = NTS_KIND_SEGMENT;
            offer(w, &c);
        }
    }
    if (sj_param > (alpha > 0.0 ? alpha : 0.0)) return; /* needs s_j <= alpha */
    {
        const nts_scene* s = env->s;
        const int j = m->entry, jp = s->surf_prev[j];
        const seg_data* sp = &env->seg[jp];
        nts_vec2 pp = s->pos[s->surf_node[jp]];
        nts_vec2 dp = search_diff(env, xs, pp, periodic);
        double sp_param = nts_dot(dp, sp->t) * sp->inv_len2;
        if (alpha > 0.0) {
            /* Corner candidate: s_{j-1} >= 1 - alpha and s_j <= alpha (docs/model.md §12, correction 3). */
            const seg_data* sj = &env->seg[j];
            nts_vec2 a, cc;
            double reach;
            nts_corner k;
            nts_corner_solution sol;
            if (sp_param < 1.0 - alpha) return;
            a = nts_neg(sp->t); /* X2 - X3 */
            cc = m->t;          /* X4 - X3 */
            /* Cheap reject: the curve lies in the triangle Xa X3 Xb, within
             * alpha max(|a|, |c|) of X3, so |g| >= |d| - that reach. */
            reach = alpha * (sp->len > sj->len ? sp->len : sj->len);
            if (sqrt(d2) > (r + reach) * (1.0 + 1e-12)) return;
            k = nts_corner_make(a, cc, alpha);
            sol = nts_corner_solve(k, d, env->solver);
            if (!sol.ok || !(fabs(sol.gap) <= r)) return;
            c.gap = sol.gap;
            c.param = sol.xi;
            c.normal = sol.normal;
            c.point = nts_add(pj, sol.point);
            c.body = m->body;
            c.entry = j;
            c.key = s->surf_local[j];
            c.kind = NTS_KIND_CORNER;
            offer(w, &c);
        } else {
            /* Vertex candidate (alpha = 0): s_{j-1} >= 1 and s_j <= 0; the sign
             * comes from the pseudo-normal n_{j-1} + n_j. */
            double dist, side;
            nts_vec2 pseudo;
            if (sp_param < 1.0) return;
            dist = sqrt(d2);
            if (!(dist <= r)) return;
            pseudo = nts_add(sp->n, m->n);
            side = nts_dot(d, pseudo) >= 0.0 ? 1.0 : -1.0;
            if (dist > 0.0) {
                c.normal = nts_scale(side / dist, d);
                c.gap = side * dist;
            } else {
                /* On the node itself: the pseudo-normal direction, zero gap. */
                c.normal = nts_normalize_or_zero(pseudo);
                c.gap = 0.0;
            }
            c.param = 0.0;
            c.point = pj;
            c.body = m->body;
            c.entry = j;
            c.key = s->surf_local[j];
            c.kind = NTS_KIND_VERTEX;
            offer(w, &c);
        }
    }
}

/* flush_slave writes every field of a record instead of clearing it first: that
 * gives the same bytes only while nts_contact has no padding (compile-time check). */
typedef char nts_contact_has_no_padding[sizeof(nts_contact) == 8 * sizeof(int) + 15 * sizeof(double) ? 1 : -1];

/* The alpha that shapes body b's surface (its own, or the options'). */
static inline double body_alpha(const search_env* env, int b) {
    double a = env->s->body_alpha[b];
    return a >= 0.0 ? a : env->alpha;
}

/* Move the current slave's best candidates to the worker's records, filling the
 * slave fields, forces and virial; reset the slot map. Candidates are emitted in
 * increasing master body order (determinism independent of visiting order). */
static void flush_slave(const search_env* env, worker* w, int i) {
    const nts_scene* s = env->s;
    int k, m, need = w->rec_count + w->best_count;
    nts_vec2 xs = s->pos[s->surf_node[i]];
    /* The slave's penalty (docs/model.md §6): per node, or per unit of
     * the node's tributary length at creation (a pressure stiffness). */
    const double eps = env->per_length ? env->eps * s->surf_trib[i] : env->eps;
    if (w->best_count == 0) return;
    if ((long long)need > env->max_records) {
        /* Over the budget in this worker alone, so the total is too (the caller
         * checks the sum as well: the verdict does not depend on threads). */
        w->status = NTS_ELIMIT;
    } else if (need > w->rec_cap && nts_grow((void**)&w->recs, &w->rec_cap, need, sizeof(nts_contact)) != NTS_OK) {
        w->status = NTS_ENOMEM;
    }
    /* Insertion sort by master body (a handful of entries). */
    for (k = 1; k < w->best_count; ++k) {
        candidate t = w->best[k];
        m = k - 1;
        while (m >= 0 && w->best[m].body > t.body) { w->best[m + 1] = w->best[m]; --m; }
        w->best[m + 1] = t;
    }
    for (k = 0; k < w->best_count; ++k) {
        const candidate* b = &w->best[k];
        nts_contact* c;
        const int j = b->entry;
        w->slot[b->body] = -1;
        if (w->status != NTS_OK) continue;
        c = &w->recs[w->rec_count++];
        /* Every field is written below (nts_contact has no padding: 8 ints, then
         * doubles), zeros where the first core's memset left them. */
        c->weights[1] = c->weights[2] = 0.0;
        c->force = nts_v2(0.0, 0.0);
        c->virial.xx = c->virial.yy = c->virial.xy = 0.0;
        c->master_body = b->body;
        c->kind = (nts_kind)b->kind;
        if (b->kind == NTS_KIND_SEGMENT) {
            c->master_count = 2;
            c->master_nodes[0] = s->surf_local[j];
            c->master_nodes[1] = s->surf_local[s->surf_next[j]];
            c->master_nodes[2] = -1;
            c->weights[0] = 1.0 - b->param;
            c->weights[1] = b->param;
        } else if (b->kind == NTS_KIND_CORNER) {
            nts_shape3 N = nts_corner_shape(body_alpha(env, b->body), b->param);
            c->master_count = 3;
            c->master_nodes[0] = s->surf_local[s->surf_prev[j]];
            c->master_nodes[1] = s->surf_local[j];
            c->master_nodes[2] = s->surf_local[s->surf_next[j]];
            c->weights[0] = N.n2;
            c->weights[1] = N.n3;
            c->weights[2] = N.n4;
        } else {
            c->master_count = 1;
            c->master_nodes[0] = s->surf_local[j];
            c->master_nodes[1] = c->master_nodes[2] = -1;
            c->weights[0] = 1.0;
        }
        c->param = b->param;
        c->gap = b->gap;
        c->normal = b->normal;
        c->point = b->point;
        c->slave_body = s->surf_body[i];
        c->slave_node = s->surf_local[i];
        c->penalty = eps;
        if (c->gap < 0.0) {
            /* f_s = -eps g n (docs/model.md §6). */
            double eg = eps * c->gap;
            c->force = nts_scale(-eg, c->normal);
            if (env->want_virial) {
                /* W_ab = -sum_k f_ka (X_k - Xs)_b over the master nodes, f_k = eps g N_k n
                 * (the slave's own term vanishes); equals eps g^2 n_a n_b at the PCA. */
                int base = s->body_node_start[c->master_body], q;
                double wxx = 0.0, wyy = 0.0, wxy = 0.0, wyx = 0.0;
                for (q = 0; q < c->master_count; ++q) {
                    nts_vec2 rel = nts_scene_diff(s, s->pos[base + c->master_nodes[q]], xs);
                    nts_vec2 f = nts_scale(eg * c->weights[q], c->normal);
                    wxx -= f.x * rel.x;
                    wyy -= f.y * rel.y;
                    wxy -= f.x * rel.y;
                    wyx -= f.y * rel.x;
                }
                c->virial.xx = wxx;
                c->virial.yy = wyy;
                c->virial.xy = 0.5 * (wxy + wyx);
            }
        }
    }
    w->best_count = 0;
}

/* The cells of the 3x3 stencil around (cx, cy), each with its offset (ox, oy)
 * in cells. In a periodic grid narrower than 3 cells the wrapped neighbours
 * repeat: visit each once (nts_cells_stencil's rule). */
typedef struct stencil {
    int n;
    int cell[9];
    int ox[9], oy[9];
} stencil;

static void make_stencil(const nts_cells* c, int cell, stencil* st) {
    int cx = cell % c->nx, cy = cell / c->nx, dx, dy;
    st->n = 0;
    if (!c->periodic || (c->nx >= 3 && c->ny >= 3)) {
        /* No repeats: wrap (periodic) or clip (open) each neighbour once. */
        for (dy = -1; dy <= 1; ++dy) {
            int y = cy + dy;
            if (y < 0 || y >= c->ny) {
                if (!c->periodic) continue;
                y += y < 0 ? c->ny : -c->ny;
            }
            for (dx = -1; dx <= 1; ++dx) {
                int x = cx + dx;
                if (x < 0 || x >= c->nx) {
                    if (!c->periodic) continue;
                    x += x < 0 ? c->nx : -c->nx;
                }
                st->cell[st->n] = y * c->nx + x;
                st->ox[st->n] = dx;
                st->oy[st->n] = dy;
                ++st->n;
            }
        }
        return;
    }
    for (dy = -1; dy <= 1; ++dy) {
        int y = cy + dy, dup, k;
        if (c->periodic) y = ((y % c->ny) + c->ny) % c->ny;
        if (y < 0 || y >= c->ny) continue;
        for (dup = 0, k = -1; k < dy; ++k) {
            int yk = cy + k;
            if (c->periodic) yk = ((yk % c->ny) + c->ny) % c->ny;
            dup |= (yk == y);
        }
        if (dup) continue;
        for (dx = -1; dx <= 1; ++dx) {
            int x = cx + dx, dupx = 0, q;
            if (c->periodic) x = ((x % c->nx) + c->nx) % c->nx;
            if (x < 0 || x >= c->nx) continue;
            for (q = -1; q < dx; ++q) {
                int xq = cx + q;
                if (c->periodic) xq = ((xq % c->nx) + c->nx) % c->nx;
                dupx |= (xq == x);
            }
            if (dupx) continue;
            st->cell[st->n] = y * c->nx + x;
            st->ox[st->n] = dx;
            st->oy[st->n] = dy;
            ++st->n;
        }
    }
}

static inline double max2(double a, double b) { return a > b ? a : b; }

/* Distance from fx (the slave's place in its cell, from the cell's low edge) to
 * the neighbour cell at offset o of side h, branch-free. */
static inline double cell_gap(double f, int o, double h) {
    double lo = o * h;
    return max2(0.0, max2(lo - f, f - (lo + h)));
}

/* The local search of slaves [begin, end) with the cell list. With the
 * whole-cell cull, the stencil cells that survive it form, in each row, one run
 * of consecutive cells (the distance is convex along the row), whose masters
 * are contiguous in cell order: one range per row (two where the row wraps
 * around the periodic box), so the inner loop runs long and branches little. */
static inline NTS_ALWAYS_INLINE void search_cells(const search_env* env, worker* w, int begin, int end,
                                                  const int periodic) {
    const nts_scene* s = env->s;
    const master_hot* hot = env->hot;
    const nts_cells* cl = env->cells;
    const int nx = cl->nx, ny = cl->ny;
    const double reach2 = env->cell_reach2;
    stencil st;
    int last_cell = -1, i, cx = 0, cy = 0;
    double cell_x0 = 0.0, cell_y0 = 0.0;
    st.n = 0;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = s->surf_body[i], cell = cl->entry_cell[i];
        if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
            w->status = NTS_ECANCELLED;
            break;
        }
        const nts_vec2 xs = s->pos[s->surf_node[i]];
        int q;
        if (s->body_role[bi] == NTS_ROLE_MASTER) continue; /* an obstacle's nodes are never slaves */
        if (cell != last_cell) {
            last_cell = cell;
            cx = cell % nx;
            cy = cell / nx;
            cell_x0 = cx * cl->hx;
            cell_y0 = cy * cl->hy;
            if (!env->cell_cull) make_stencil(cl, cell, &st);
        }
        if (env->cell_cull) {
            /* The slave's place inside its cell, as nts_cells_build binned it. */
            double x = xs.x - cl->x0, y = xs.y - cl->y0, fx, fy, ex[3];
            int rb[6], re[6], nr = 0, dy, k;
            if (periodic) {
                x -= s->lx * floor(x / s->lx);
                y -= s->ly * floor(y / s->ly);
            }
            fx = x - cell_x0;
            fy = y - cell_y0;
            for (k = 0; k < 3; ++k) ex[k] = cell_gap(fx, k - 1, cl->hx);
            for (dy = -1; dy <= 1; ++dy) {
                double ey = cell_gap(fy, dy, cl->hy), ey2 = ey * ey;
                int yy = cy + dy, lo = 2, hi = -1, row;
                if (yy < 0 || yy >= ny) {
                    if (!periodic) continue;
                    yy += yy < 0 ? ny : -ny;
                }
                for (k = 0; k < 3; ++k)
                    if (ex[k] * ex[k] + ey2 <= reach2) {
                        if (k < lo) lo = k;
                        hi = k;
                    }
                if (hi < 0) continue;
                row = yy * nx;
                lo += cx - 1;
                hi += cx - 1;
                if (!periodic) {
                    if (lo < 0) lo = 0;
                    if (hi > nx - 1) hi = nx - 1;
                    if (lo > hi) continue;
                    rb[nr] = cl->cell_start[row + lo];
                    re[nr++] = cl->cell_start[row + hi + 1];
                } else if (lo < 0) {
                    rb[nr] = cl->cell_start[row + lo + nx];
                    re[nr++] = cl->cell_start[row + nx];
                    rb[nr] = cl->cell_start[row];
                    re[nr++] = cl->cell_start[row + hi + 1];
                } else if (hi > nx - 1) {
                    rb[nr] = cl->cell_start[row + lo];
                    re[nr++] = cl->cell_start[row + nx];
                    rb[nr] = cl->cell_start[row];
                    re[nr++] = cl->cell_start[row + hi - nx + 1];
                } else {
                    rb[nr] = cl->cell_start[row + lo];
                    re[nr++] = cl->cell_start[row + hi + 1];
                }
            }
            for (q = 0; q < nr; ++q) {
                int e;
                for (e = rb[q]; e < re[q]; ++e) try_master(env, w, xs, bi, &hot[e], periodic);
            }
        } else {
            for (q = 0; q < st.n; ++q) {
                int e, e0 = cl->cell_start[st.cell[q]], e1 = cl->cell_start[st.cell[q] + 1];
                for (e = e0; e < e1; ++e) try_master(env, w, xs, bi, &hot[e], periodic);
            }
        }
        if (env->long_start != NULL) {
            /* The long masters whose reach box overlaps the slave's own cell. */
            int e, e0 = env->long_start[cell], e1 = env->long_start[cell + 1];
            for (e = e0; e < e1; ++e) try_master(env, w, xs, bi, &env->long_hot[env->long_items[e]], periodic);
        }
        flush_slave(env, w, i);
    }
}

static void search_range(const search_env* env, worker* w, int begin, int end) {
    const nts_scene* s = env->s;
    const master_hot* hot = env->hot;
    const int periodic = env->lx > 0.0 || env->ly > 0.0;
    int i;
    if (env->cells != NULL) {
        if (periodic) search_cells(env, w, begin, end, 1);
        else search_cells(env, w, begin, end, 0);
    } else {
        for (i = begin; i < end && w->status == NTS_OK; ++i) {
            const int bi = s->surf_body[i];
            const nts_vec2 xs = s->pos[s->surf_node[i]];
            int j;
            if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
                w->status = NTS_ECANCELLED;
                break;
            }
            if (s->body_role[bi] == NTS_ROLE_MASTER) continue;
            for (j = 0; j < s->surface_count; ++j)
                try_master(env, w, xs, bi, &hot[j], 1);
            flush_slave(env, w, i);
        }
    }
}

/* The reach length of master j: its features lie within r + max(|t_j|,
 * alpha |t_{j-1}|) of X_j (the flat part of segment j within |t_j| + r, the
 * corner within r + alpha max(|t_{j-1}|, |t_j|), the vertex within r), with
 * alpha the master body's. */
static inline double reach_length(const seg_data* seg, const nts_scene* s, int j, double alpha) {
    double lp = alpha * seg[s->surf_prev[j]].len, lj = seg[j].len;
    return lj > lp ? lj : lp;
}

static double alpha_of_body(const nts_scene* s, int b, double alpha) {
    return s->body_alpha[b] >= 0.0 ? s->body_alpha[b] : alpha;
}

/* The masters' hot records in the order the search reads them; the factor
 * 1 + 1e-9 on the reach covers the round-off of the tests it replaces. With a
 * cell list (`long_len` > 0), a master whose reach length exceeds `long_len`
 * (the cell side minus r) is searched through the long lists instead: its
 * record here offers nothing, and a copy with its real reach goes to
 * ctx->long_hot. A body with role "slave" offers nothing at all. */
static void fill_hot(nts_context* ctx, const nts_scene* s, const int* order, double alpha, double r,
                     double long_len) {
    int e;
    ctx->long_count = 0;
    for (e = 0; e < s->surface_count; ++e) {
        int j = order != NULL ? order[e] : e, b = s->surf_body[j];
        master_hot* m = &ctx->hot[e];
        double a = alpha_of_body(s, b, alpha), len = reach_length(ctx->seg, s, j, a);
        double reach = (r + len) * (1.0 + 1e-9);
        m->p = s->pos[s->surf_node[j]];
        m->t = ctx->seg[j].t;
        m->n = ctx->seg[j].n;
        m->inv_len2 = ctx->seg[j].inv_len2;
        m->reach2 = reach * reach;
        m->alpha = a;
        m->body = b;
        m->entry = j;
        if (s->body_role[b] == NTS_ROLE_SLAVE) {
            m->reach2 = -1.0;
        } else if (long_len > 0.0 && len > long_len) {
            ctx->long_hot[ctx->long_count++] = *m;
            m->reach2 = -1.0;
        }
    }
}

/* The k-th smallest of v[0..n) (v is reordered): quickselect with a
 * median-of-three pivot, and a full sort of what is left if it has not
 * converged after 2 log2(n) + 8 partitions, so the time is bounded by
 * O(n log n) whatever the values. Deterministic. */
static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

static double select_kth(double* v, int n, int k) {
    int lo = 0, hi = n - 1, rounds = 8, m;
    for (m = n; m > 1; m >>= 1) rounds += 2;
    while (hi > lo) {
        double a, b, c, pivot;
        int i = lo, j = hi;
        if (rounds-- == 0) {
            qsort(v + lo, (size_t)(hi - lo + 1), sizeof(double), cmp_double);
            break;
        }
        a = v[lo];
        b = v[lo + (hi - lo) / 2];
        c = v[hi];
        pivot = a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
        while (i <= j) { /* Hoare partition: every step moves i or j, so it ends */
            while (v[i] < pivot) ++i;
            while (v[j] > pivot) --j;
            if (i <= j) {
                double t = v[i];
                v[i] = v[j];
                v[j] = t;
                ++i;
                --j;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break; /* v[k] == pivot */
    }
    return v[k];
}

/* Cells of one axis that the interval [lo, hi] (in the grid's frame) overlaps:
 * the first one and how many; periodic grids wrap, open ones clip. */
static int cell_span(double lo, double hi, double h, int n, int periodic, int* first) {
    double flo = floor(lo / h), fhi = floor(hi / h);
    if (periodic) {
        if (!(fhi - flo + 1.0 < (double)n)) {
            *first = 0;
            return n;
        }
        *first = (int)(flo - (double)n * floor(flo / (double)n));
        return (int)(fhi - flo) + 1;
    }
    if (flo < 0.0) flo = 0.0;
    if (fhi > (double)(n - 1)) fhi = (double)(n - 1);
    if (fhi < flo) return 0;
    *first = (int)flo;
    return (int)(fhi - flo) + 1;
}

/* The reach box of long master m, as cells: the corner curve lies in the
 * triangle Xa X_j Xb and the flat part on segment j, so every feature lies
 * within r of bbox(X_j, X_j + t_j, X_j - alpha t_{j-1}); `pad` covers the
 * round-off of binning. Returns the number of cells; *cx0, *ncx (*cy0, *ncy). */
static long long long_box(const nts_cells* cl, const nts_scene* s, const seg_data* seg, const master_hot* m,
                          double r, double pad, int* cx0, int* ncx, int* cy0, int* ncy) {
    nts_vec2 tp = seg[s->surf_prev[m->entry]].t, t = m->t;
    double x = m->p.x - cl->x0, y = m->p.y - cl->y0, R = r * (1.0 + 1e-9) + pad;
    double xlo, xhi, ylo, yhi;
    if (cl->periodic) { /* the frame nts_cells_build bins in */
        x -= s->lx * floor(x / s->lx);
        y -= s->ly * floor(y / s->ly);
    }
    xlo = fmin(fmin(0.0, t.x), -m->alpha * tp.x);
    xhi = fmax(fmax(0.0, t.x), -m->alpha * tp.x);
    ylo = fmin(fmin(0.0, t.y), -m->alpha * tp.y);
    yhi = fmax(fmax(0.0, t.y), -m->alpha * tp.y);
    *ncx = cell_span(x + xlo - R, x + xhi + R, cl->hx, cl->nx, cl->periodic, cx0);
    *ncy = cell_span(y + ylo - R, y + yhi + R, cl->hy, cl->ny, cl->periodic, cy0);
    return (long long)*ncx * (long long)*ncy;
}

/* List every long master in every cell its reach box overlaps (CSR by cell,
 * masters in entry order within a cell). Returns NTS_OK, NTS_ENOMEM, or
 * NTS_ELIMIT when the lists would exceed `budget` entries (the caller then
 * coarsens the grid). */
static int build_long_lists(nts_context* ctx, const nts_scene* s, double r, double pad, long long budget) {
    const nts_cells* cl = &ctx->cells;
    int ncell = cl->nx * cl->ny, i, rc;
    long long total = 0;
    if ((rc = nts_grow((void**)&ctx->long_start, &ctx->long_start_cap, ncell + 1, sizeof(int))) != NTS_OK) return rc;
    memset(ctx->long_start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (i = 0; i < ctx->long_count; ++i) {
        int cx0, ncx, cy0, ncy;
        total += long_box(cl, s, ctx->seg, &ctx->long_hot[i], r, pad, &cx0, &ncx, &cy0, &ncy);
        if (total > budget) return NTS_ELIMIT;
    }
    if ((rc = nts_grow((void**)&ctx->long_items, &ctx->long_items_cap, (int)total, sizeof(int))) != NTS_OK) return rc;
    for (i = 0; i < ctx->long_count; ++i) { /* counts */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(cl, s, ctx->seg, &ctx->long_hot[i], r, pad, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a) ++ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx + 1];
    }
    for (i = 0; i < ncell; ++i) ctx->long_start[i + 1] += ctx->long_start[i];
    for (i = 0; i < ctx->long_count; ++i) { /* fill, in entry order */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(cl, s, ctx->seg, &ctx->long_hot[i], r, pad, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a) ctx->long_items[ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx]++] = i;
    }
    for (i = ncell; i > 0; --i) ctx->long_start[i] = ctx->long_start[i - 1];
    ctx->long_start[0] = 0;
    return NTS_OK;
}

static int eval_fail(nts_error* err, int code, int body, int node, const char* msg) {
    return nts_error_set(err, code, nts_at(body, -1, -1, node), "%s", msg);
}

int nts_evaluate(nts_context* ctx, const nts_scene* s, const nts_options* opt, nts_result* out, nts_error* err) {
    search_env env;
    double lmax = 0.0, h;
    int i, rc, nthreads = 1;
    nts_summary* sum;
    double t0 = wall_time(), t1;

    if (err != NULL) *err = nts_error_none();
    if (ctx == NULL || s == NULL || opt == NULL || out == NULL)
        return eval_fail(err, NTS_EINVALID_ARGUMENT, -1, -1, "null argument");
    if ((rc = nts_options_validate(opt, err)) != NTS_OK) return rc;
    memset(out, 0, sizeof *out);

    /* Segment data; a zero-length segment (possible after new positions) is an
     * error, never a division by zero. */
    if ((rc = nts_grow((void**)&ctx->seg, &ctx->seg_cap, s->surface_count, sizeof(seg_data))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    for (i = 0; i < s->surface_count; ++i) {
        seg_data* sd = &ctx->seg[i];
        double l2;
        sd->t = nts_scene_diff(s, s->pos[s->surf_node[s->surf_next[i]]], s->pos[s->surf_node[i]]);
        l2 = nts_length_sq(sd->t);
        /* The supported range (scene.c): nts_scene_set_positions does not check
         * it, and 1/|t|^2 must not overflow. */
        if (!(l2 >= 1e-200) || !(l2 <= 1e201)) {
            char msg[160];
            snprintf(msg, sizeof msg, "body %d: segment from node %d has length %.3g, outside [1e-100, 3e100]",
                     s->surf_body[i], s->surf_local[i], sqrt(l2));
            return eval_fail(err, NTS_EDEGENERATE_SEGMENT, s->surf_body[i], s->surf_local[i], msg);
        }
        sd->len = sqrt(l2);
        sd->inv_len2 = 1.0 / l2;
        sd->n = nts_v2(sd->t.y / sd->len, -sd->t.x / sd->len);
        if (sd->len > lmax) lmax = sd->len;
    }

    t1 = wall_time();
    ctx->phase[0] = t1 - t0;
    t0 = t1;
    env.s = s;
    env.seg = ctx->seg;
    env.alpha = opt->alpha;
    env.eps = opt->penalty;
    env.per_length = opt->penalty_scaling == NTS_PENALTY_PER_LENGTH;
    env.max_records = opt->max_candidates > 0 ? opt->max_candidates : 64LL * s->surface_count + 1000000;
    env.cancel = opt->cancel;
    env.cancel_user = opt->cancel_user;
    env.long_hot = NULL;
    env.long_start = NULL;
    env.long_items = NULL;
    /* A typical segment, not the longest, sets the default search radius and
     * the cell side, so that one long wall neither widens the search nor
     * coarsens the grid (docs/model.md, "Global search"): the median segment,
     * and the 95th percentile of the masters' reach lengths. */
    if ((rc = nts_grow((void**)&ctx->scratch, &ctx->scratch_cap, s->surface_count, sizeof(double))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    for (i = 0; i < s->surface_count; ++i) ctx->scratch[i] = ctx->seg[i].len;
    env.r = opt->search_radius < 0.0 ? select_kth(ctx->scratch, s->surface_count, (s->surface_count - 1) / 2)
                                     : opt->search_radius;
    env.solver = opt->solver;
    env.want_virial = (opt->outputs & NTS_OUT_VIRIAL) != 0u;
    h = lmax + env.r; /* every feature lies within L_max + r of its master node */
    if (s->lx > 0.0 && !(2.0 * h < s->lx && 2.0 * h < s->ly)) {
        char msg[160];
        snprintf(msg, sizeof msg, "periodic box %.6g x %.6g must exceed twice the search reach %.6g", s->lx, s->ly, h);
        rc = eval_fail(err, NTS_EBOX_TOO_SMALL, -1, -1, msg);
        if (err != NULL) snprintf(err->option, sizeof err->option, "periodic");
        return rc;
    }
    env.lx = s->lx;
    env.ly = s->ly;
    env.qx = 0.25 * s->lx;
    env.qy = 0.25 * s->ly;
    env.cell_reach2 = 0.0;
    env.cell_cull = 0;
    env.cells = NULL;
    if ((rc = nts_grow((void**)&ctx->hot, &ctx->hot_cap, s->surface_count, sizeof(master_hot))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    env.hot = ctx->hot;
    if (opt->search == NTS_SEARCH_CELLS) {
        const nts_cells* cl = &ctx->cells;
        /* At most this many (long master, cell) pairs: a few per surface node. */
        const long long budget = 4LL * s->surface_count + 4096;
        double scale, pad, hc;
        int round;
        for (i = 0; i < s->surface_count; ++i)
            ctx->scratch[i] = reach_length(ctx->seg, s, i, alpha_of_body(s, s->surf_body[i], env.alpha));
        hc = select_kth(ctx->scratch, s->surface_count, (int)(0.95 * (double)(s->surface_count - 1))) + env.r;
        if (hc > h) hc = h;
        if ((rc = nts_grow((void**)&ctx->long_hot, &ctx->long_hot_cap, s->surface_count, sizeof(master_hot))) !=
            NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        /* The cell side hc >= (typical reach) + r: masters that reach farther
         * are listed in every cell their reach box overlaps. Too many such
         * pairs: coarsen, at most until hc = L_max + r, where none is left. */
        for (round = 0;; ++round) {
            if ((rc = nts_cells_build(&ctx->cells, s, hc)) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            fill_hot(ctx, s, cl->items, env.alpha, env.r, hc < h ? hc - env.r : 0.0);
            scale = fabs(cl->x0) + fabs(cl->y0) + cl->nx * cl->hx + cl->ny * cl->hy + s->lx + s->ly;
            pad = 1e-12 * scale;
            if (ctx->long_count == 0) break;
            rc = build_long_lists(ctx, s, env.r, pad, budget);
            if (rc == NTS_OK) break;
            if (rc != NTS_ELIMIT) return eval_fail(err, rc, -1, -1, "out of memory");
            assert(round < 64);
            hc = 2.0 * hc < h ? 2.0 * hc : h;
        }
        env.cells = cl;
        if (ctx->long_count > 0) {
            env.long_hot = ctx->long_hot;
            env.long_start = ctx->long_start;
            env.long_items = ctx->long_items;
        }
        /* Whole-cell cull: exact when every stencil offset is a distinct image,
         * with an allowance for the round-off of binning (relative to the size of
         * the coordinates, not of the cells). */
        env.cell_cull = !cl->periodic || (cl->nx >= 4 && cl->ny >= 4);
        env.cell_reach2 = (hc * (1.0 + 1e-9) + pad) * (hc * (1.0 + 1e-9) + pad);
    } else {
        fill_hot(ctx, s, NULL, env.alpha, env.r, 0.0);
    }

    t1 = wall_time();
    ctx->phase[1] = t1 - t0;
    t0 = t1;
#if NTS_CONFIG_OPENMP
    if (opt->threads > 1) nthreads = opt->threads;
    if (nthreads > s->surface_count) nthreads = s->surface_count > 0 ? s->surface_count : 1;
#endif
    if ((rc = workers_prepare(ctx, nthreads, s->body_count)) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");

    /* Local search. Worker t handles the contiguous slave range t; the ranges are
     * concatenated in order below, which is the serial order. */
#if NTS_CONFIG_OPENMP
    if (nthreads > 1) {
        int t;
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
        for (t = 0; t < nthreads; ++t) {
            long long n = s->surface_count;
            search_range(&env, &ctx->workers[t], (int)(n * t / nthreads), (int)(n * (t + 1) / nthreads));
        }
    } else
#endif
    {
        search_range(&env, &ctx->workers[0], 0, s->surface_count);
    }
    {
        long long records = 0;
        int limited = 0, status = NTS_OK;
        for (i = 0; i < nthreads; ++i) {
            records += ctx->workers[i].rec_count;
            if (ctx->workers[i].status == NTS_ELIMIT) limited = 1;
            else if (ctx->workers[i].status != NTS_OK && status == NTS_OK) status = ctx->workers[i].status;
        }
        if (status == NTS_ECANCELLED || (status == NTS_OK && env.cancel != NULL && env.cancel(env.cancel_user)))
            return eval_fail(err, NTS_ECANCELLED, -1, -1, "the evaluation was cancelled (a deadline passed, or the "
                                                          "caller asked)");
        if (limited || records > env.max_records) {
            char msg[192];
            snprintf(msg, sizeof msg, "more than max_candidates = %lld closest points within the search radius: "
                     "the bodies overlap far more than contact does (or raise the limit)", env.max_records);
            rc = eval_fail(err, NTS_ELIMIT, -1, -1, msg);
            if (err != NULL) snprintf(err->option, sizeof err->option, "max_candidates");
            return rc;
        }
        if (status != NTS_OK) return eval_fail(err, status, -1, -1, "out of memory");
    }

    t1 = wall_time();
    ctx->phase[2] = t1 - t0;
    t0 = t1;
    /* Scatter in slave order (docs/model.md §6). */
    {
        const int want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
        const int want_contacts = (opt->outputs & NTS_OUT_CONTACTS) != 0u;
        const int want_gaps = (opt->outputs & NTS_OUT_GAPS) != 0u;
        const int want_stiffness = (opt->outputs & NTS_OUT_STIFFNESS) != 0u;
        int total = 0, ncontact = 0, ngap = 0, t;
        double energy = 0.0, maxpen = 0.0;
        int overflow = 0;
        nts_virial vir = {0.0, 0.0, 0.0};
        for (t = 0; t < nthreads; ++t) total += ctx->workers[t].rec_count;
        if (want_forces) {
            if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            memset(ctx->forces, 0, sizeof(nts_vec2) * (size_t)s->node_count);
        }
        if (want_gaps &&
            (rc = nts_grow((void**)&ctx->gaps, &ctx->gaps_cap, total, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        ctx->stiffness.count = 0;
        for (t = 0; t < nthreads; ++t) {
            const worker* w = &ctx->workers[t];
            int k;
            for (k = 0; k < w->rec_count; ++k) {
                const nts_contact* c = &w->recs[k];
                if (want_gaps) ctx->gaps[ngap++] = *c;
                if (!(c->gap < 0.0)) continue;
                if (want_contacts) {
                    if (ncontact == ctx->contacts_cap &&
                        (rc = nts_grow((void**)&ctx->contacts, &ctx->contacts_cap, ncontact + 1,
                                       sizeof(nts_contact))) != NTS_OK)
                        return eval_fail(err, rc, -1, -1, "out of memory");
                    ctx->contacts[ncontact] = *c;
                }
                ++ncontact;
                overflow |= !isfinite(c->penalty * c->gap) || !isfinite(c->virial.xx + c->virial.yy + c->virial.xy);
                energy += 0.5 * c->penalty * c->gap * c->gap;
                if (-c->gap > maxpen) maxpen = -c->gap;
                vir.xx += c->virial.xx;
                vir.yy += c->virial.yy;
                vir.xy += c->virial.xy;
                if (want_stiffness &&
                    (rc = nts_stiffness_add(&ctx->stiffness, s, c, alpha_of_body(s, c->master_body, env.alpha))) !=
                        NTS_OK)
                    return eval_fail(err, rc, -1, -1, "out of memory");
                if (want_forces) {
                    int sb = s->body_node_start[c->slave_body], mb = s->body_node_start[c->master_body], q;
                    double eg = c->penalty * c->gap;
                    ctx->forces[sb + c->slave_node] = nts_add(ctx->forces[sb + c->slave_node], c->force);
                    for (q = 0; q < c->master_count; ++q) {
                        /* f_k = eps g N_k n */
                        nts_vec2* f = &ctx->forces[mb + c->master_nodes[q]];
                        *f = nts_mul_add(*f, eg * c->weights[q], c->normal);
                    }
                }
            }
        }
        /* Finite input can still overflow (a huge penalty or huge coordinates):
         * NaN and infinity never leave the library, the caller gets an error. */
        overflow |= !isfinite(energy) || !isfinite(vir.xx) || !isfinite(vir.yy) || !isfinite(vir.xy);
        if (want_forces && !overflow)
            for (i = 0; i < s->node_count && !overflow; ++i) overflow = !nts_is_valid_vec2(ctx->forces[i]);
        if (overflow) {
            rc = eval_fail(err, NTS_ENONFINITE, -1, -1,
                           "the result overflows a double (penalty or coordinates too large)");
            if (err != NULL) snprintf(err->option, sizeof err->option, "penalty");
            return rc;
        }
        sum = &out->summary;
        sum->bodies = s->body_count;
        sum->surface_nodes = s->surface_count;
        sum->contacts = ncontact;
        sum->gaps = total;
        sum->energy = energy;
        sum->virial = vir;
        sum->max_penetration = maxpen;
        sum->loops_reversed = s->loops_reversed;
        sum->search_radius = env.r;
        sum->cell_size = env.cells != NULL ? (ctx->cells.hx > ctx->cells.hy ? ctx->cells.hx : ctx->cells.hy) : 0.0;
        out->forces = want_forces ? ctx->forces : NULL;
        out->contacts = want_contacts ? ctx->contacts : NULL;
        out->contact_count = want_contacts ? ncontact : 0;
        out->gaps = want_gaps ? ctx->gaps : NULL;
        out->gap_count = want_gaps ? ngap : 0;
        if (want_stiffness) {
            for (i = 0; i < ctx->stiffness.count && !overflow; ++i) overflow = !isfinite(ctx->stiffness.values[i]);
            if (overflow) {
                rc = eval_fail(err, NTS_ENONFINITE, -1, -1, "the tangent overflows a double (penalty too large)");
                if (err != NULL) snprintf(err->option, sizeof err->option, "penalty");
                return rc;
            }
            out->stiffness.rows = ctx->stiffness.rows;
            out->stiffness.cols = ctx->stiffness.cols;
            out->stiffness.values = ctx->stiffness.values;
            out->stiffness.count = ctx->stiffness.count;
            out->stiffness.size = 2 * s->node_count;
        }
    }
    ctx->phase[3] = wall_time() - t0;
    return NTS_OK;
}
