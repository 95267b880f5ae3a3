/* The local search (docs/model.md §4, §5): for each slave node, the masters
 * of its cell's 3 x 3 stencil (and the long masters listed in its cell) offer
 * their features; the best candidate per master body is kept and written as
 * the slave's records, in master body order. */
#include <math.h>

#include "stages.h"


/* Xs - X exactly as nts_scene_diff computes it (docs/model.md §8: the
 * minimum image, nts_min_image_1), the near-pair test done once for both axes.
 * `periodic` is a compile-time constant at every call (the search loop is
 * instantiated twice), so an open scene pays nothing for the box. */
static inline nts_vec2 search_diff(const search_env* env, nts_vec2 p, nts_vec2 q, const int periodic) {
    nts_vec2 d = nts_sub(p, q);
    if (!periodic) return d;
    if (fabs(d.x) < env->qx && fabs(d.y) < env->qy) {
        d.x += 0.0;
        d.y += 0.0;
        return d;
    }
    d.x = nts_min_image_1(d.x, env->lx);
    d.y = nts_min_image_1(d.y, env->ly);
    return d;
}

/* Tie-break (docs/model.md §5): smaller |g|, then the smaller master
 * node index, then segment before corner/vertex at the same node. */
static inline int better(const nts_scene* s, const candidate* c, const candidate* b) {
    double gc = fabs(c->gap), gb = fabs(b->gap);
    int kc, kb;
    if (gc != gb) return gc < gb;
    kc = s->surf_local[c->entry];
    kb = s->surf_local[b->entry];
    if (kc != kb) return kc < kb;
    return c->kind < b->kind;
}

static inline void offer(const nts_scene* s, worker* w, const candidate* c) {
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
    } else if (better(s, c, &w->best[k])) {
        w->best[k] = *c;
    }
}

/* Try the features that master m (surface entry j) offers to a slave at xs: the
 * flat part of segment (j, j+1), and the corner (alpha > 0) or vertex (alpha = 0)
 * at j. The caller has culled by reach (every feature of the master lies
 * within its reach of X_j, fill_hot), so only masters that may offer
 * something get here; each feature test below is exact on its own, so the
 * cull decides nothing but the time. */
static inline NTS_ALWAYS_INLINE void try_master(const search_env* env, worker* w, nts_vec2 xs, const master_hot* m,
                                                const int periodic) {
    const double alpha = alpha_of_body(env->s, m->body, env->alpha), r = env->r; /* the master's alpha */
    const nts_vec2 pj = m->p;
    nts_vec2 d = search_diff(env, xs, pj, periodic); /* Xs - X0 (or Xs - X3): subtract first */
    double d2 = d.x * d.x + d.y * d.y, sj_param;
    candidate c;

    sj_param = nts_dot(d, m->t) * m->inv_len2; /* docs/model.md §12, correction 2 */

    /* Flat candidate of segment j (alpha <= s <= 1 - alpha). */
    if (sj_param >= alpha && sj_param <= 1.0 - alpha) {
        double g = nts_dot(d, seg_normal(m->t, m->len));
        if (fabs(g) <= r) {
            c.gap = g;
            c.param = sj_param;
            c.normal = seg_normal(m->t, m->len);
            c.point = nts_mul_add(pj, sj_param, m->t);
            c.body = m->body;
            c.entry = m->entry;
            c.kind = NTS_KIND_SEGMENT;
            offer(env->s, w, &c);
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
            nts_vec2 a, cc;
            double reach;
            nts_corner k;
            nts_corner_solution sol;
            if (sp_param < 1.0 - alpha) return;
            a = nts_neg(sp->t); /* X2 - X3 */
            cc = m->t;          /* X4 - X3 */
            /* Cheap reject: the curve lies in the triangle Xa X3 Xb, within
             * alpha max(|a|, |c|) of X3, so |g| >= |d| - that reach. */
            reach = alpha * (sp->len > m->len ? sp->len : m->len);
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
            c.kind = NTS_KIND_CORNER;
            offer(s, w, &c);
        } else {
            /* Vertex candidate (alpha = 0): s_{j-1} >= 1 and s_j <= 0; the sign
             * comes from the pseudo-normal n_{j-1} + n_j. */
            double dist, side;
            nts_vec2 pseudo;
            if (sp_param < 1.0) return;
            dist = sqrt(d2);
            if (!(dist <= r)) return;
            pseudo = nts_add(seg_normal(sp->t, sp->len), seg_normal(m->t, m->len));
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
            c.kind = NTS_KIND_VERTEX;
            offer(s, w, &c);
        }
    }
}

/* The masters e0..e1 (cell order) offered to a slave in two passes: first the
 * cheap reject over the compact keys, the survivors appended without a branch
 * (most masters a slave visits are its own body's or out of reach, and their
 * verdict is hard to predict); then the features of the few survivors. The
 * first pass works in the cell frame, (sx, sy) being the slave there minus
 * the image shift of the range, so it needs no minimum image per master; its
 * reach carries the frame's round-off (fill_hot), so it keeps every master
 * that the exact arithmetic of try_master could accept. */
static inline NTS_ALWAYS_INLINE void try_range(const search_env* env, worker* w, nts_vec2 xs, double sx, double sy,
                                               int slave_body, int e0, int e1, const int periodic) {
    enum { CHUNK = 128 };
    const master_key* keys = env->keys;
    int kept[CHUNK];
    while (e0 < e1) {
        const int stop = e1 - e0 > CHUNK ? e0 + CHUNK : e1;
        int e, n = 0;
        for (e = e0; e < stop; ++e) {
            const master_key* k = &keys[e];
            const double dx = sx - k->x, dy = sy - k->y;
            kept[n] = e;
            n += (dx * dx + dy * dy <= k->reach2) & (k->body != slave_body);
        }
        for (e = 0; e < n; ++e) try_master(env, w, xs, &env->hot[kept[e]], periodic);
        e0 = stop;
    }
}

/* The same for a grid whose stencil repeats images (a periodic box of fewer
 * than 4 cells a side): the minimum image per master. */
static void try_range_wrapped(const search_env* env, worker* w, nts_vec2 xs, double sx, double sy, int slave_body,
                              int e0, int e1) {
    int e;
    for (e = e0; e < e1; ++e) {
        const master_key* k = &env->keys[e];
        nts_vec2 d = nts_scene_diff(env->s, nts_v2(sx, sy), nts_v2(k->x, k->y));
        if (d.x * d.x + d.y * d.y <= k->reach2 && k->body != slave_body) try_master(env, w, xs, &env->hot[e], 1);
    }
}

/* Move the current slave's best candidates to the worker's records (all of
 * them, or the active ones: search_env.keep_all) and reset the slot map.
 * Candidates are kept in increasing master body order (determinism
 * independent of visiting order). */
static void flush_slave(const search_env* env, worker* w, int i) {
    int k, m, need;
    if (w->best_count == 0) return;
    w->gaps += w->best_count;
    need = w->rec_count + w->best_count;
    if (w->gaps > env->max_records) {
        /* Over the budget in this worker alone, so the total is too (the caller
         * checks the sum as well: the verdict does not depend on threads). */
        w->status = NTS_ELIMIT;
    } else if (need > w->rec_cap && nts_grow((void**)&w->recs, &w->rec_cap, need, sizeof(candidate)) != NTS_OK) {
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
        w->slot[b->body] = -1;
        if (w->status != NTS_OK || !(env->keep_all || b->gap < 0.0)) continue;
        w->recs[w->rec_count] = *b;
        w->recs[w->rec_count++].slave = i;
    }
    w->best_count = 0;
}

/* The key ranges of a cell's 3 x 3 stencil: in each row the three cells are
 * consecutive in cell order, so one range, or two where the row wraps around
 * the periodic box; each with the image shift (kx lx, ky ly) that brings its
 * masters next to the slave. Open grids clip at the edges. */
typedef struct stencil_ranges {
    int n;
    int begin[6], end[6];
    double shift_x[6], shift_y[6];
} stencil_ranges;

static void stencil_ranges_of(const search_env* env, int cell, stencil_ranges* st) {
    const nts_cells* cl = env->cells;
    const int nx = cl->nx, ny = cl->ny, cx = cell % nx, cy = cell / nx;
    int dy;
    st->n = 0;
    for (dy = -1; dy <= 1; ++dy) {
        int yy = cy + dy, lo = cx - 1, hi = cx + 1, row;
        double sy = 0.0;
        if (yy < 0 || yy >= ny) {
            if (!cl->periodic) continue;
            sy = yy < 0 ? -env->ly : env->ly;
            yy += yy < 0 ? ny : -ny;
        }
        row = yy * nx;
        if (!cl->periodic) {
            if (lo < 0) lo = 0;
            if (hi > nx - 1) hi = nx - 1;
        } else if (lo < 0) { /* column nx - 1, one box to the left */
            st->begin[st->n] = cl->cell_start[row + nx - 1];
            st->end[st->n] = cl->cell_start[row + nx];
            st->shift_x[st->n] = -env->lx;
            st->shift_y[st->n++] = sy;
            lo = 0;
        } else if (hi > nx - 1) { /* column 0, one box to the right */
            st->begin[st->n] = cl->cell_start[row];
            st->end[st->n] = cl->cell_start[row + 1];
            st->shift_x[st->n] = env->lx;
            st->shift_y[st->n++] = sy;
            hi = nx - 1;
        }
        st->begin[st->n] = cl->cell_start[row + lo];
        st->end[st->n] = cl->cell_start[row + hi + 1];
        st->shift_x[st->n] = 0.0;
        st->shift_y[st->n++] = sy;
    }
}

/* The local search of slaves [begin, end) with the cell list, in slave order.
 * The stencil's ranges are worked out once per cell (consecutive slaves of a
 * loop mostly share theirs); the slave's own key gives its place in the cell
 * frame. */
static inline NTS_ALWAYS_INLINE void search_cells(const search_env* env, worker* w, int begin, int end,
                                                  const int periodic) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    stencil_ranges st;
    nts_stencil wide;
    int last_cell = -1, i, q;
    st.n = 0;
    wide.n = 0;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = s->surf_body[i];
        const master_key* me;
        nts_vec2 xs;
        if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
            w->status = NTS_ECANCELLED;
            break;
        }
        if (s->body_role[bi] == NTS_ROLE_MASTER) continue; /* an obstacle's nodes are never slaves */
        me = &env->keys[cl->rank[i]];
        xs = s->pos[s->surf_node[i]];
        if (me->cell != last_cell) {
            last_cell = me->cell;
            if (env->cell_shift) stencil_ranges_of(env, last_cell, &st);
            else nts_cells_stencil(cl, last_cell, &wide);
        }
        if (env->cell_shift) {
            for (q = 0; q < st.n; ++q)
                try_range(env, w, xs, me->x - st.shift_x[q], me->y - st.shift_y[q], bi, st.begin[q], st.end[q],
                          periodic);
        } else {
            for (q = 0; q < wide.n; ++q)
                try_range_wrapped(env, w, xs, me->x, me->y, bi, cl->cell_start[wide.cell[q]],
                                  cl->cell_start[wide.cell[q] + 1]);
        }
        if (env->long_start != NULL) {
            /* The long masters whose reach box overlaps the slave's own cell. */
            int e, e0 = env->long_start[last_cell], e1 = env->long_start[last_cell + 1];
            for (e = e0; e < e1; ++e) {
                const long_master* lm = &env->long_m[env->long_items[e]];
                const master_hot* m = &env->hot[lm->hot];
                nts_vec2 d = search_diff(env, xs, m->p, periodic);
                if (d.x * d.x + d.y * d.y <= lm->reach2 && m->body != bi) try_master(env, w, xs, m, periodic);
            }
        }
        flush_slave(env, w, i);
    }
}

void nts_search_range(const search_env* env, worker* w, int begin, int end) {
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
            for (j = 0; j < s->surface_count; ++j) {
                /* The keys hold the positions themselves here: the exact reach. */
                const master_key* k = &env->keys[j];
                nts_vec2 d = nts_scene_diff(s, xs, hot[j].p);
                if (d.x * d.x + d.y * d.y <= k->reach2 && k->body != bi) try_master(env, w, xs, &hot[j], 1);
            }
            flush_slave(env, w, i);
        }
    }
}

