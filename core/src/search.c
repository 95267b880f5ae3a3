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
            c.kind = NTS_KIND_VERTEX;
            offer(s, w, &c);
        }
    }
}

/* The masters e0..e1 (cell order) offered to a slave in two passes: first the
 * cheap reject over the compact keys, the survivors appended without a branch
 * (most masters a slave visits are its own body's or out of reach, and their
 * verdict is hard to predict); then the features of the few survivors.
 * try_master repeats the same reject with the same arithmetic, so the
 * survivors and every result are those of a single pass, bitwise. */
static inline NTS_ALWAYS_INLINE void try_range(const search_env* env, worker* w, nts_vec2 xs, int slave_body,
                                               int e0, int e1, const int periodic) {
    enum { CHUNK = 128 };
    const master_key* keys = env->keys;
    int kept[CHUNK];
    while (e0 < e1) {
        const int stop = e1 - e0 > CHUNK ? e0 + CHUNK : e1;
        int e, n = 0;
        for (e = e0; e < stop; ++e) {
            const master_key* k = &keys[e];
            nts_vec2 d = search_diff(env, xs, k->p, periodic);
            double d2 = d.x * d.x + d.y * d.y;
            kept[n] = e;
            n += (d2 <= k->reach2) & (k->body != slave_body);
        }
        for (e = 0; e < n; ++e) try_master(env, w, xs, slave_body, &env->hot[kept[e]], periodic);
        e0 = stop;
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
    const nts_cells* cl = env->cells;
    const int nx = cl->nx, ny = cl->ny;
    const double reach2 = env->cell_reach2;
    nts_stencil st;
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
            if (!env->cell_cull) nts_cells_stencil(cl, cell, &st);
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
            for (q = 0; q < nr; ++q) try_range(env, w, xs, bi, rb[q], re[q], periodic);
        } else {
            for (q = 0; q < st.n; ++q)
                try_range(env, w, xs, bi, cl->cell_start[st.cell[q]], cl->cell_start[st.cell[q] + 1], periodic);
        }
        if (env->long_start != NULL) {
            /* The long masters whose reach box overlaps the slave's own cell. */
            int e, e0 = env->long_start[cell], e1 = env->long_start[cell + 1];
            for (e = e0; e < e1; ++e) try_master(env, w, xs, bi, &env->long_hot[env->long_items[e]], periodic);
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
            for (j = 0; j < s->surface_count; ++j)
                try_master(env, w, xs, bi, &hot[j], 1);
            flush_slave(env, w, i);
        }
    }
}

