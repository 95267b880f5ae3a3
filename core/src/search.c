/* The local search (docs/model.md §4, §5): for each slave node, the masters
 * binned in its cell's 3 x 3 stencil (and the long masters listed in its
 * cell) offer their features; the best candidate per master body is kept and
 * written as the slave's records, in master body order.
 *
 * Two passes per slave. The first reads the masters' float keys four at a
 * time and keeps, without a branch, those near enough to offer something
 * (most masters a slave visits are its own body's, or out of reach, and
 * which ones is hard to predict). The second runs the exact tests in double
 * on the few kept. The first pass only saves time: its reach is wide enough
 * (masters.c) that it keeps every master the second could accept, so the
 * result is that of trying every master, bit for bit. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "corner.h"
#include "reach.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Xs - X exactly as nts_scene_diff computes it (nts_box_diff, internal.h;
 * docs/model.md §8: the minimum image), its twin for the search's hot
 * loops: the quarter box precomputed (env->qx, env->qy: 0.25 lx, 0.25 ly,
 * the same bits) and `periodic` a compile-time constant at every call (the
 * search is instantiated twice), so an open scene pays nothing for the box. */
static inline NTS_ALWAYS_INLINE nts_vec2 search_diff(const search_env* env, nts_vec2 p, nts_vec2 q, const int periodic) {
    nts_vec2 d = nts_sub(p, q);
    if (!periodic) return d;
    if (fabs(d.x) < env->qx && fabs(d.y) < env->qy) {
        d.x += 0.0;
        d.y += 0.0;
        return d;
    }
    return nts_min_image(d, env->lx, env->ly);
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

/* The slave the worker searches now, and for a body that meets itself its
 * pseudo-normal (docs/model.md §16, (N)). */
static inline void set_slave(const search_env* env, worker* w, int i, int body) {
    w->slave = i;
    w->slave_body = body;
    w->self_has = 0;
    if (env->self != NULL && env->self[body]) {
        const seg_data* seg = env->seg;
        const int ip = seg[i].prev;
        w->slave_pn = nts_add(seg_normal(seg[ip].t, seg[ip].len), seg_normal(seg[i].t, seg[i].len));
    }
}

/* Whether master j of the slave's own body, Xs - X_j = d by the minimum
 * image, lies in the slave's periodic image: the loops' own difference is
 * the minimum image's (they differ by a whole box otherwise). */
static inline int self_same_image(const search_env* env, const worker* w, int j, nts_vec2 d) {
    nts_vec2 du;
    if (env->lx <= 0.0 && env->ly <= 0.0) return 1;
    du = nts_sub(nts_sub(env->self_u[w->slave], env->self_u[j]), d);
    return fabs(du.x) <= 0.25 * env->lx && fabs(du.y) <= 0.25 * env->ly;
}

/* The edges of body b that may span heights y0 <= y1 (the frame of
 * env->self_u): [k0, k1) of the lists of the slabs between (listed), or of
 * the body's entries when it has no slabs or those lists are longer. An
 * edge that spans several slabs is listed in each. */
typedef struct self_edges {
    int k0, k1, listed;
} self_edges;

static self_edges self_edges_between(const search_env* env, int b, double y0, double y1) {
    const nts_scene* s = env->s;
    const int f = env->self_first[b], count = env->self_first[b + 1] - f;
    self_edges ed;
    ed.k0 = s->loop_start[s->body_loop_start[b]];
    ed.k1 = s->loop_start[s->body_loop_start[b + 1]];
    ed.listed = 0;
    if (count > 0) {
        const int q0 = nts_self_slab(env->self_y + 2 * b, count, y0);
        const int q1 = nts_self_slab(env->self_y + 2 * b, count, y1);
        if (env->self_start[f + q1 + 1] - env->self_start[f + q0] < ed.k1 - ed.k0) {
            ed.k0 = env->self_start[f + q0];
            ed.k1 = env->self_start[f + q1 + 1];
            ed.listed = 1;
        }
    }
    return ed;
}

/* Self-contact (docs/model.md §16). The coverage of body b at m (in the
 * frame of env->self_u): the sum of the winding numbers of its loops around
 * m, by the crossings of a ray towards +x (Sunday's rule: an upward edge
 * with m on its left counts +1, a downward one with m on its right -1). A
 * valid body covers every point at most once; where it folds onto itself,
 * twice. */
static int self_coverage(const search_env* env, int b, nts_vec2 m) {
    const nts_vec2* u = env->self_u;
    const self_edges ed = self_edges_between(env, b, m.y, m.y); /* an edge the ray crosses spans m's height */
    int k, w = 0;
    for (k = ed.k0; k < ed.k1; ++k) {
        const int e = ed.listed ? env->self_items[k] : k;
        const nts_vec2 a = nts_sub(u[e], m), c = nts_sub(u[env->seg[e].next], m);
        const double cross = a.x * c.y - a.y * c.x;
        if (a.y <= 0.0) {
            if (c.y > 0.0 && cross > 0.0) ++w;
        } else if (c.y <= 0.0 && cross < 0.0) {
            --w;
        }
    }
    return w;
}

/* Candidate c of master j, on the slave's own body (docs/model.md §16):
 * `d` is Xs - X_j and `delta` Xs minus the closest point, both by the
 * minimum image. In another periodic image the body is a master like any
 * other: offered. In the same one, (T) the feature must not contain the
 * slave node (the flats of its two segments, the corners or vertices at it
 * and its two neighbours) and (N) its normal must be opposed to the slave's
 * pseudo-normal. A gap (g >= 0) that passes both is offered; of the
 * penetrations that pass both, the closest (the rule of §5) is held, and
 * (C) decides at the slave's end (self_settle) whether it counts. Were (C)
 * asked of each penetration instead, one that fails it would hand the slave
 * to a deeper one that passes: a node on the outer face of a doubled layer,
 * whose nearest opposed face (its own layer's other face) is not in the
 * overlap, went to the far face of the other layer, whose midpoint is. */
static inline void self_offer(const search_env* env, worker* w, const candidate* c, nts_vec2 d, nts_vec2 delta) {
    const seg_data* seg = env->seg;
    const int i = w->slave, j = c->entry, ip = seg[i].prev, in = seg[i].next;
    if (!self_same_image(env, w, j, d)) {
        offer(env->s, w, c);
        return;
    }
    if (c->kind == NTS_KIND_SEGMENT ? (j == i || j == ip) : (j == ip || j == i || j == in)) return; /* (T) */
    if (!(nts_dot(w->slave_pn, c->normal) < 0.0)) return;                                           /* (N) */
    if (c->gap >= 0.0) {
        offer(env->s, w, c); /* a gap needs no coverage */
    } else if (!w->self_has || better(env->s, c, &w->self_best)) {
        w->self_best = *c;
        w->self_delta = delta;
        w->self_has = 1;
    }
}

/* The most faces the way of (C) is followed across (self_settle). */
enum { NTS_SELF_CROSSINGS = 64 };

/* Whether body b covers every point of the path p0 -> p1 (the frame of
 * env->self_u) at least twice, it covering p0 `cov0` times: the faces the
 * path crosses, but the entries skip[0..2], change the coverage by one
 * each (+1 entering a face from its outside), in the order met. A point on
 * the path's line counts as on its right (as if the path were moved an
 * infinitesimal to its left, so that a chain of faces along the path or
 * through one of its points is crossed as often as it crosses, whatever the
 * round-off); of crossings at one place the entries come first, so that a
 * path that grazes a corner does not dip (the faces read:
 * self_edges_between). A way that crosses more faces than
 * NTS_SELF_CROSSINGS is taken as not covered. */
static int self_way_covered(const search_env* env, int b, nts_vec2 p0, nts_vec2 p1, int cov0, const int skip[3]) {
    const nts_vec2* u = env->self_u;
    const self_edges ed = self_edges_between(env, b, p0.y < p1.y ? p0.y : p1.y, p0.y < p1.y ? p1.y : p0.y);
    const nts_vec2 dp = nts_sub(p1, p0);
    double at[NTS_SELF_CROSSINGS];
    int sign[NTS_SELF_CROSSINGS], edge[NTS_SELF_CROSSINGS];
    int k, q, n = 0;
    for (k = ed.k0; k < ed.k1; ++k) {
        const int e = ed.listed ? env->self_items[k] : k;
        nts_vec2 a, c, t;
        double oa, oc, lam;
        int dup = 0;
        if (e == skip[0] || e == skip[1] || e == skip[2]) continue;
        a = nts_sub(u[e], p0);
        c = nts_sub(u[env->seg[e].next], p0);
        oa = dp.x * a.y - dp.y * a.x; /* > 0: left of the path */
        oc = dp.x * c.y - dp.y * c.x;
        if ((oa > 0.0) == (oc > 0.0)) continue;
        t = nts_sub(c, a);
        lam = (a.x * t.y - a.y * t.x) / (oc - oa); /* where the face meets the path's line; oc - oa = dp x t != 0 */
        if (!(lam >= 0.0 && lam < 1.0)) continue;
        if (ed.listed) /* an edge spanning several slabs is listed in each */
            for (q = 0; q < n && !dup; ++q) dup = edge[q] == e;
        if (dup) continue;
        if (n == NTS_SELF_CROSSINGS) return 0;
        /* a face from the right of the path to its left: its inside (left
         * of the face) is behind the path's side it leaves for */
        for (q = n; q > 0 && (at[q - 1] > lam || (at[q - 1] == lam && sign[q - 1] < (oc > 0.0 ? -1 : 1))); --q) {
            at[q] = at[q - 1];
            sign[q] = sign[q - 1];
            edge[q] = edge[q - 1];
        }
        at[q] = lam;
        sign[q] = oc > 0.0 ? -1 : 1;
        edge[q] = e;
        ++n;
    }
    for (q = 0; q < n; ++q)
        if ((cov0 += sign[q]) < 2) return 0;
    return 1;
}

/* At the slave's end, its own body's closest penetration that passed (T)
 * and (N): offered when (C) holds (docs/model.md (31)): the body covers
 * itself at least twice at the slave node and all along the straight way
 * from the node to its closest point (the feature's own faces aside, which
 * the way ends on), so that the node leaves the overlap by the face it is
 * pushed through, not through a layer of its own or out of its own side.
 * Both are read a hair inside, along the node's inward pseudo-normal: the
 * node lies on the boundary, and the way runs along the node's own face or
 * through a node when the body folds square (a fold's inner corner), where
 * the count and the crossings are round-off's to decide. The hair, a billionth of
 * the node's shorter segment (and above the frame's round-off), moves
 * neither across a face that is not within a hair of it. A node at the tip
 * of a needle so sharp that its two normals cancel has no inward
 * direction: the coverage at the midpoint of the node and its closest
 * point is read instead. */
static void self_settle(const search_env* env, worker* w) {
    const candidate* c = &w->self_best;
    const seg_data* seg = env->seg;
    const int i = w->slave, j = c->entry;
    const nts_vec2 xi = env->self_u[i], pn = w->slave_pn;
    const double pl = sqrt(nts_dot(pn, pn));
    int k;
    w->self_has = 0;
    if (pl > 1e-12) {
        const double l0 = seg[seg[i].prev].len, l1 = seg[i].len;
        const double hair = 1e-9 * (l0 < l1 ? l0 : l1) + 64.0 * DBL_EPSILON * (fabs(xi.x) + fabs(xi.y));
        const nts_vec2 p0 = nts_mul_add(xi, -hair / pl, pn), p1 = nts_sub(p0, w->self_delta);
        /* the faces the way ends on: F*'s segment (and the one beyond the
         * end a flat's point lies at), a corner's or vertex's two; never the
         * node's own, which a way out of its own side crosses */
        int skip[3] = {j, -1, -1};
        if (c->kind != NTS_KIND_SEGMENT || c->param <= 0.0) skip[1] = seg[j].prev;
        if (c->kind == NTS_KIND_SEGMENT && c->param >= 1.0) skip[2] = seg[j].next;
        for (k = 0; k < 3; ++k)
            if (skip[k] == i || skip[k] == seg[i].prev) skip[k] = -1;
        const int cov0 = self_coverage(env, c->body, p0);
        if (cov0 < 2 || !self_way_covered(env, c->body, p0, p1, cov0, skip)) return;
    } else if (self_coverage(env, c->body, nts_mul_add(xi, -0.5, w->self_delta)) < 2) {
        return;
    }
    offer(env->s, w, c);
}

/* Before the exact tests of master j of the slave's own body (same image):
 * which of its features could count (self_offer and self_settle decide). Its flat's normal
 * is n_j and its corner's lies between n_{j-1} and n_j (the tangent runs
 * from a positive multiple of t_{j-1} to one of t_j, (5)), so (N) fails for
 * the flat when n_i . n_j >= 0 and for the corner when both dots are; (T)
 * rules out both features of j = i - 1 and j = i and the corner of i + 1.
 * Bit 1: the flat may count, bit 2: the corner (or vertex). */
static inline int self_may(const search_env* env, const worker* w, int j) {
    const seg_data* seg = env->seg;
    const int i = w->slave;
    const nts_vec2 pn = w->slave_pn, tj = seg[j].t, tp = seg[seg[j].prev].t;
    int flat, corner;
    if (j == seg[i].prev || j == i) return 0;
    /* n . (t_y, -t_x) / |t|: its sign without the division */
    flat = pn.x * tj.y - pn.y * tj.x < 0.0;
    corner = j != seg[i].next && (flat || pn.x * tp.y - pn.y * tp.x < 0.0);
    return flat | corner << 1;
}

/* Try the features that master j (a surface entry) offers to a slave at xs
 * within radius r (the search radius, or a widened search's): the flat part
 * of segment (j, j+1), and the corner (alpha > 0) or vertex (alpha = 0) at j.
 * Each test is exact on its own: which masters get here decides nothing but
 * the time. */
static inline NTS_ALWAYS_INLINE void try_master(const search_env* env, worker* w, nts_vec2 xs, int j, const double r,
                                                const int periodic, const int surfaces, const int selfc) {
    const seg_data* m = &env->seg[j];
    const int body = m->body;
    const double alpha = env->body_alphas ? alpha_of_body(env->s, body, env->alpha) : env->alpha; /* the master's */
    const nts_vec2 pj = m->p;
    nts_vec2 d = search_diff(env, xs, pj, periodic); /* Xs - X0 (or Xs - X3): subtract first */
    double sj_param, lo = alpha, hi = 1.0 - alpha;
    int corner = 1;
    candidate c;

    int may = 3; /* the features that may count: the flat (1), the corner or vertex (2) */
    if (selfc && body == w->slave_body && self_same_image(env, w, j, d)) {
        /* self-contact (docs/model.md §16) */
        if ((may = self_may(env, w, j)) == 0) return; /* nothing of master j could count */
        if (alpha == 0.0) {
            /* The flat reaches its ends whatever the round-off of s_j: a
             * slave whose closest point is an end that no vertex offers it
             * (a vertex (T) refuses, at a neighbour; or one whose region
             * the slave misses, lying on the line of the segment before it,
             * as a fold's corner node does on its own inner face) would
             * otherwise lose it for a farther face, or for none. */
            lo = -1e-9;
            hi = 1.0 + 1e-9;
        } else {
            /* A flat that ends at a neighbour of the slave, whose corner (T)
             * refuses, reaches that end: the slave meets the flat's line
             * there, not a face across its own layer (a fold's inner corner
             * pressed into the other arm). */
            if (j == env->seg[w->slave].next) lo = -1e-9;
            if (m->next == env->seg[w->slave].prev) hi = 1.0 + 1e-9;
        }
    }
    /* (the slave's own entry and the one before it never get here from the
     * cells' screen; from the other searches they stop in self_may) */
    sj_param = nts_dot(d, m->t) * m->inv_len2; /* docs/model.md §12, correction 2 */
    if (surfaces) {
        /* A contact surface (docs/model.md §13): no corner across its ends,
         * where the flat part reaches the end node and ext of the segment
         * beyond, so that a slave flush with the end is in contact whatever
         * its round-off. */
        const unsigned f = env->surf_flag[j];
        assert(f & NTS_SF_SEG); /* only the surface's segments are masters */
        if (!(f & NTS_SF_PREV)) {
            lo = -env->ext;
            corner = 0;
        }
        if (!(f & NTS_SF_NEXT)) hi = 1.0 + env->ext;
    }

    /* Flat candidate of segment j (alpha <= s <= 1 - alpha; at a surface's end (22)). */
    if ((may & 1) && sj_param >= lo && sj_param <= hi) {
        double g = nts_dot(d, seg_normal(m->t, m->len));
        if (fabs(g) <= r) {
            c.gap = g;
            c.param = sj_param;
            c.normal = seg_normal(m->t, m->len);
            c.point = nts_mul_add(pj, sj_param, m->t);
            c.body = body;
            c.entry = j;
            c.kind = NTS_KIND_SEGMENT;
            if (!selfc || body != w->slave_body) offer(env->s, w, &c);
            else self_offer(env, w, &c, d, nts_mul_add(d, -sj_param, m->t));
        }
    }
    if (!corner || !(may & 2) || sj_param > (alpha > 0.0 ? alpha : 0.0)) return; /* needs s_j <= alpha */
    {
        const nts_scene* s = env->s;
        const int jp = m->prev;
        const seg_data* sp = &env->seg[jp];
        const nts_vec2 dp = search_diff(env, xs, sp->p, periodic);
        const double sp_param = nts_dot(dp, sp->t) * sp->inv_len2, d2 = d.x * d.x + d.y * d.y;
        if (alpha > 0.0) {
            /* Corner candidate: s_{j-1} >= 1 - alpha and s_j <= alpha (docs/model.md §12, correction 3). */
            double reach;
            nts_corner k;
            nts_corner_solution sol;
            if (sp_param < 1.0 - alpha) return;
            /* Cheap reject: the curve lies in the triangle Xa X3 Xb, within
             * alpha max(|a|, |c|) of X3, so |g| >= |d| - that reach. */
            reach = alpha * (sp->len > m->len ? sp->len : m->len);
            if (sqrt(d2) > (r + reach) * (1.0 + 1e-12)) return;
            k = corner_make(nts_neg(sp->t), m->t, alpha); /* a = X2 - X3, c = X4 - X3 */
            sol = corner_solve(&k, d, env->solver);
            if (!sol.ok || !(fabs(sol.gap) <= r)) return;
            c.gap = sol.gap;
            c.param = sol.xi;
            c.normal = sol.normal;
            c.point = nts_add(pj, sol.point);
            c.body = body;
            c.entry = j;
            c.kind = NTS_KIND_CORNER;
            if (!selfc || body != w->slave_body) offer(s, w, &c);
            else self_offer(env, w, &c, d, nts_sub(d, sol.point));
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
            c.body = body;
            c.entry = j;
            c.kind = NTS_KIND_VERTEX;
            if (!selfc || body != w->slave_body) offer(s, w, &c);
            else self_offer(env, w, &c, d, d);
        }
    }
}

/* The first pass over keys [e0, e1): the indices of those within reach of a
 * slave at (sx, sy) (the keys' frame, the range's shift applied) and of
 * another body (an entry outside the slave's body's [own0, own1)), appended
 * to kept[]. kept needs e1 - e0 + 4 places. The keys are read 4 at a time,
 * past e1 into the next range or the padding; the index test drops those. */
#if defined(__SSE2__)
/* For each 4-bit mask, the lanes it keeps, packed to the front. */
static const int KEEP_LANES[16][4] = {{0, 0, 0, 0}, {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0},
                                      {2, 0, 0, 0}, {0, 2, 0, 0}, {1, 2, 0, 0}, {0, 1, 2, 0},
                                      {3, 0, 0, 0}, {0, 3, 0, 0}, {1, 3, 0, 0}, {0, 1, 3, 0},
                                      {2, 3, 0, 0}, {0, 2, 3, 0}, {1, 2, 3, 0}, {0, 1, 2, 3}};
static const int KEEP_COUNT[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};

/* The slave's own body as entries [lo, hi) (vlo = lo - 1, vhi = hi), and the
 * end of the range of keys. */
typedef struct own_range {
    __m128i vlo, vhi, vend;
} own_range;

static inline NTS_ALWAYS_INLINE own_range own_range_of(int own0, int own1, int e1) {
    own_range o;
    o.vlo = _mm_set1_epi32(own0 - 1);
    o.vhi = _mm_set1_epi32(own1);
    o.vend = _mm_set1_epi32(e1);
    return o;
}

/* The lanes of keys e .. e + 3 that are before the range's end and of
 * another body than the slave's (all bits of a lane set). */
static inline NTS_ALWAYS_INLINE __m128i other_lanes(const master_keys* k, const own_range* o, int e) {
    const __m128i at = _mm_add_epi32(_mm_set1_epi32(e), _mm_setr_epi32(0, 1, 2, 3));
    const __m128i entry = _mm_loadu_si128((const __m128i*)(const void*)(k->entry + e));
    const __m128i own = _mm_and_si128(_mm_cmpgt_epi32(entry, o->vlo), _mm_cmplt_epi32(entry, o->vhi));
    return _mm_andnot_si128(own, _mm_cmplt_epi32(at, o->vend));
}

/* Four keys from e on: append those kept to kept[n], return the new n. */
static inline NTS_ALWAYS_INLINE int near4(const master_keys* k, __m128 vx, __m128 vy, const own_range* o, int e,
                                          int* kept, int n) {
    const __m128 dx = _mm_sub_ps(vx, _mm_loadu_ps(k->x + e)), dy = _mm_sub_ps(vy, _mm_loadu_ps(k->y + e));
    const __m128 d2 = _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy));
    const __m128i near = _mm_castps_si128(_mm_cmple_ps(d2, _mm_loadu_ps(k->reach2 + e)));
    const __m128i in = _mm_and_si128(near, other_lanes(k, o, e));
    const int mask = _mm_movemask_ps(_mm_castsi128_ps(in));
    _mm_storeu_si128((__m128i*)(void*)(kept + n),
                     _mm_add_epi32(_mm_set1_epi32(e), _mm_loadu_si128((const __m128i*)(const void*)KEEP_LANES[mask])));
    return n + KEEP_COUNT[mask];
}

/* Most ranges hold at most 8 keys (a stencil row of three small cells): two
 * groups of 4 whatever the count, so that the loop's end is not a branch to
 * mispredict (the index test drops the keys past e1); longer ranges loop. */
static inline NTS_ALWAYS_INLINE int near_keys(const master_keys* k, float sx, float sy, int own0, int own1, int e0,
                                              int e1, int* kept) {
    const __m128 vx = _mm_set1_ps(sx), vy = _mm_set1_ps(sy);
    const own_range o = own_range_of(own0, own1, e1);
    int e, n = 0;
    n = near4(k, vx, vy, &o, e0, kept, n);
    n = near4(k, vx, vy, &o, e0 + 4, kept, n);
    for (e = e0 + 8; e < e1; e += 4) n = near4(k, vx, vy, &o, e, kept, n);
    return n;
}
#else
static inline int near_keys(const master_keys* k, float sx, float sy, int own0, int own1, int e0, int e1,
                            int* kept) {
    int e, n = 0;
    for (e = e0; e < e1; ++e) {
        const float dx = sx - k->x[e], dy = sy - k->y[e];
        kept[n] = e;
        n += (dx * dx + dy * dy <= k->reach2[e]) & (k->entry[e] < own0 || k->entry[e] >= own1);
    }
    return n;
}
#endif


/* Keep an item for the reach's growth (reach.c), growing the worker's room
 * when needed; NULL when that fails (w->status is NTS_ENOMEM). */
static reach_item* push_item(worker* w, int kind, int slave, int body, int from, double value) {
    reach_item* it;
    if (w->item_count == w->item_cap &&
        nts_grow((void**)&w->items, &w->item_cap, w->item_count + 1, sizeof(reach_item)) != NTS_OK) {
        w->status = NTS_ENOMEM;
        return NULL;
    }
    it = &w->items[w->item_count++];
    it->slave = slave;
    it->body = body;
    it->kind = (unsigned char)kind;
    it->from = (unsigned char)from;
    it->value = value;
    it->pad = 0;
    it->nx = it->ny = 0.0f;
    return it;
}

static inline int has_body(const candidate* c, int n, int body) {
    int k;
    for (k = 0; k < n; ++k)
        if (c[k].body == body) return 1;
    return 0;
}

/* Slave k, l from its neighbour on side `from` along the loop, with no
 * closest point within r on c->body while the neighbour has c there: ask
 * for a widened search when k could lie deeper than r (reach_may_be_deeper). */
static void reach_ask(const search_env* env, worker* w, int k, int from, const candidate* c, double l) {
    reach_item* it;
    if (!reach_may_be_deeper(l, c->gap, env->r)) return;
    if ((it = push_item(w, REACH_ASK, k, c->body, from, fabs(c->gap) + l)) != NULL) {
        it->nx = (float)c->normal.x;
        it->ny = (float)c->normal.y;
    }
}

/* A closest point of slave i whose neighbour on side `from` is across the
 * end of the chunk or of the loop: reach.c compares the two. */
static void reach_edge(worker* w, int i, int from, const candidate* c) {
    reach_item* it = push_item(w, REACH_EDGE, i, c->body, from, c->gap);
    if (it != NULL) {
        it->nx = (float)c->normal.x;
        it->ny = (float)c->normal.y;
    }
}

/* The reach's growth starts here (reach.c): slave i's closest points (in
 * w->best, by body) against those of the slave before it along the loop,
 * which the search did just before (w->last): each asks for the other where
 * the other has none on that body. A neighbour across the chunk's end is
 * compared in reach.c (an edge). The pair that closes a loop, its last slave
 * and its first, is compared the same way when it crosses a chunk's end, and
 * needs no comparison when the loop lies in the chunk: a chain of slaves
 * deep in a body has two ends, and when one is that pair the other is a pair
 * the search compares (or the chain is the whole loop: then nothing of it
 * is near the surface); but not for a body that meets itself (below).
 * Then i's become the last (the two buffers swap: nothing copied). */
static void reach_neighbours(const search_env* env, worker* w, int i, int end) {
    const seg_data* seg = env->seg;
    const int n = w->best_count, prev = seg[i].prev, next = seg[i].next, before = w->last_slave;
    /* A body that meets itself: its closing pair compared too (as edges,
     * reach.c). The argument above fails there: (T), (N) and (C) can leave
     * a slave in the middle of a deep chain with no closest point, so a
     * chain's far end need not be a pair the search compares, and what was
     * found depended on which node the loop starts at. */
    const int closes = env->self != NULL && env->self[seg[i].body];
    int k;
    candidate* t;
    w->last_slave = i;
    if (prev != i - 1) w->first_slave = i; /* the loop's first slave */
    if (prev == i - 1 && before == prev) {
        const double l = seg[prev].len;
        for (k = 0; k < w->last_count; ++k)
            if (!has_body(w->best, n, w->last[k].body)) reach_ask(env, w, i, SIDE_PREV, &w->last[k], l);
        for (k = 0; k < n; ++k)
            if (!has_body(w->last, w->last_count, w->best[k].body))
                reach_ask(env, w, prev, SIDE_NEXT, &w->best[k], l);
    } else if (prev == i - 1 || prev >= end || closes) {
        /* across the chunk's start, or a loop ending past its end (or a
         * body that meets itself: its loop's closing pair) */
        for (k = 0; k < n; ++k) reach_edge(w, i, SIDE_PREV, &w->best[k]);
    }
    if (next == i + 1 ? i + 1 == end : (next != w->first_slave || closes)) /* across the chunk's end */
        for (k = 0; k < n; ++k) reach_edge(w, i, SIDE_NEXT, &w->best[k]);
    w->last_count = n;
    if (n == 0) return;
    t = w->last;
    w->last = w->best;
    w->best = t;
    k = w->last_cap;
    w->last_cap = w->best_cap;
    w->best_cap = k;
    w->best_count = 0;
}

/* Move the current slave's best candidates to the worker's records (all of
 * them, or the active ones: search_env.keep_all) and reset the slot map.
 * Candidates are kept in increasing master body order (determinism
 * independent of visiting order). Then the reach's growth compares them with
 * the slave before (reach_neighbours); `end`: the chunk's end. */
static void flush_slave(const search_env* env, worker* w, int i, int end) {
    int k, m, need;
    if (env->seg[i].len > env->coarse) {
        /* The two ends of a long segment: the reach's growth searches them
         * widened (each once: the next one, unless its own segment is long). */
        const int next = env->seg[i].next;
        push_item(w, REACH_COARSE, i, -1, 0, 0.0);
        if (!(env->seg[next].len > env->coarse)) push_item(w, REACH_COARSE, next, -1, 0, 0.0);
    }
    if (w->best_count > 0) {
        if (w->best_count > w->best_most) w->best_most = w->best_count;
        w->gaps += w->best_count;
        if (env->owned != NULL && env->owned[i]) w->owned_gaps += w->best_count;
        need = w->rec_count + w->best_count;
        if (w->gaps > env->max_records) {
            /* Over the budget in this worker alone, so the total is too (the caller
             * checks the sum as well: the verdict does not depend on threads). */
            w->status = NTS_ELIMIT;
        } else if (env->shares ? env->want_forces && w->share_count + w->best_count > w->share_cap &&
                                     nts_grow((void**)&w->shares, &w->share_cap, w->share_count + w->best_count,
                                              sizeof(force_shares)) != NTS_OK
                               : !env->direct && need > w->rec_cap &&
                                     nts_grow((void**)&w->recs, &w->rec_cap, need, sizeof(candidate)) != NTS_OK) {
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
            candidate* b = &w->best[k];
            w->slot[b->body] = -1;
            if (w->status != NTS_OK || !(env->keep_all || b->gap < 0.0)) continue;
            b->slave = i;
            /* One of the scatter's three paths (search.h). */
            if (env->direct) scatter_direct(env, w, b);
            else if (env->shares) scatter_share(env, w, b);
            else scatter_record(w, b);
        }
    }
    reach_neighbours(env, w, i, end);
}


/* A node off the contact surface (docs/model.md §13) is no slave: the
 * reach's comparisons along the loop see it as a slave with nothing found
 * (and never ask for it: reach.c). */
static inline void not_a_slave(worker* w, const search_env* env, int i) {
    w->last_slave = i;
    w->last_count = 0;
    if (env->seg[i].prev != i - 1) w->first_slave = i;
}

/* The masters the first pass keeps: every key of the stencil's ranges and 4
 * lanes past each, or a batch of keys of one range and 4 past it. */
enum { KEPT = 512 };

/* The stencil of a slave at `at`. Inside the grid: three rows of three
 * cells, no shift, read again for every slave (cheaper than asking whether
 * the cell changed, a branch that consecutive slaves take at random); a
 * border cell's, with its wraps and clips, only when the cell changes
 * (*last_cell). */
static inline NTS_ALWAYS_INLINE void slave_stencil(const nts_cells* cl, nts_cell_place at, nts_stencil* st,
                                                   int* last_cell) {
    if (at.cx >= 1 && at.cx + 1 < cl->nx && at.cy >= 1 && at.cy + 1 < cl->ny) {
        const int* cs = cl->cell_start + (at.cell - cl->nx - 1);
        *last_cell = at.cell;
        st->n = 3;
        st->begin[0] = cs[0];
        st->end[0] = cs[3];
        cs += cl->nx;
        st->begin[1] = cs[0];
        st->end[1] = cs[3];
        cs += cl->nx;
        st->begin[2] = cs[0];
        st->end[2] = cs[3];
        st->shift_x[0] = st->shift_x[1] = st->shift_x[2] = 0.0;
        st->shift_y[0] = st->shift_y[1] = st->shift_y[2] = 0.0;
        st->keys = (st->end[0] - st->begin[0]) + (st->end[1] - st->begin[1]) + (st->end[2] - st->begin[2]);
    } else if (at.cell != *last_cell) {
        *last_cell = at.cell;
        nts_cells_stencil(cl, at.cell, st);
    }
}

/* The local search of slaves [begin, end) with the cell list, in slave order.
 * An inner cell's stencil is read for every slave; a border cell's, with its
 * wraps and clips, only when the cell changes (consecutive slaves of a loop
 * mostly share it). */
static inline NTS_ALWAYS_INLINE void search_cells(const search_env* env, worker* w, int begin, int end,
                                                  const int periodic, const int surfaces, const int selfc) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    const master_keys* keys = env->keys;
    const double scale = cl->scale;
    int kept[KEPT];
    nts_stencil st;
    int last_cell = -1, i, q;
    st.n = 0;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = env->seg[i].body, self = selfc && self_body(env, bi);
        /* The own body's keys are skipped; when it meets itself, only those
         * of the slave and the entry before it (docs/model.md §16 (T): none
         * of their features counts). */
        const int own0 = self ? (env->seg[i].prev == i - 1 ? i - 1 : i) : s->loop_start[s->body_loop_start[bi]];
        const int own1 = self ? i + 1 : s->loop_start[s->body_loop_start[bi + 1]];
        nts_vec2 xs;
        nts_cell_place at;
        double sx, sy;
        if (selfc) set_slave(env, w, i, bi);
        if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
            w->status = NTS_ECANCELLED;
            break;
        }
        if (s->body_role[bi] == NTS_ROLE_MASTER) continue; /* an obstacle's nodes are never slaves */
        if (surfaces && !(env->surf_flag[i] & NTS_SF_NODE)) { /* off the contact surface: as nothing found */
            not_a_slave(w, env, i);
            continue;
        }
        xs = env->seg[i].p;
        at = nts_cells_place(cl, xs);
        slave_stencil(cl, at, &st, &last_cell);
        sx = at.x * scale;
        sy = at.y * scale;
        if (st.keys + 4 * st.n <= KEPT) {
            /* Usually: the first pass over every range, then the second over
             * every master kept. */
            int n = 0, k;
            for (q = 0; q < st.n; ++q)
                n += near_keys(keys, (float)(sx - st.shift_x[q]), (float)(sy - st.shift_y[q]), own0, own1,
                               st.begin[q], st.end[q], kept + n);
            /* Their segment data are scattered over memory (other bodies'
             * entries): ask for all before the first is needed, with the
             * entry before each (its previous segment, for the corner or
             * vertex tests, except at the start of a loop). */
            for (k = 0; k < n; ++k) {
                const int j = keys->entry[kept[k]];
                kept[k] = j;
                NTS_PREFETCH(&env->seg[j]);
                NTS_PREFETCH(&env->seg[j - (j > 0)]);
            }
            for (k = 0; k < n; ++k) try_master(env, w, xs, kept[k], env->r, periodic, surfaces, selfc);
        } else {
            /* A crowded stencil: a batch of keys at a time. */
            for (q = 0; q < st.n; ++q) {
                const float fx = (float)(sx - st.shift_x[q]), fy = (float)(sy - st.shift_y[q]);
                int e0 = st.begin[q];
                while (e0 < st.end[q]) {
                    const int e1 = st.end[q] - e0 > KEPT - 4 ? e0 + KEPT - 4 : st.end[q];
                    const int n = near_keys(keys, fx, fy, own0, own1, e0, e1, kept);
                    int k;
                    for (k = 0; k < n; ++k)
                        try_master(env, w, xs, keys->entry[kept[k]], env->r, periodic, surfaces, selfc);
                    e0 = e1;
                }
            }
        }
        if (env->long_start != NULL) {
            /* The long masters whose reach box overlaps the slave's own cell. */
            int e, e0 = env->long_start[last_cell], e1 = env->long_start[last_cell + 1];
            for (e = e0; e < e1; ++e) {
                const long_master* lm = &env->long_m[env->long_items[e]];
                const int j = lm->entry, b = env->seg[j].body;
                const nts_vec2 d = search_diff(env, xs, env->seg[j].p, periodic);
                if (d.x * d.x + d.y * d.y <= lm->reach2 && (b != bi || self))
                    try_master(env, w, xs, j, env->r, periodic, surfaces, selfc);
            }
        }
        if (selfc && w->self_has) self_settle(env, w);
        if ((w->best_count | w->last_count) != 0 || env->seg[i].len > env->coarse) {
            flush_slave(env, w, i, end);
        } else { /* most slaves: nothing here, nothing before */
            w->last_slave = i;
            if (env->seg[i].prev != i - 1) w->first_slave = i;
        }
    }
}

/* The local search of slaves [begin, end) from the kept lists (docs/model.md
 * §15): each slave tries the masters its list holds within the inner radius,
 * which hold every master the cells could give it (the list is valid:
 * candidates.c), so the same candidates, the same records, bit for bit. */
enum { KEPT_AHEAD = 4 };

/* Eq. (32), for a slave at d from X_j on segment t of length len
 * (p = d . t, L2 = len^2): whether s = p / L2 stays above h (side 1) or
 * below it (side -1) at any positions where every node lies within mu of
 * where it lies now. f = side (d - h t) . t > 0 loses at most
 * 2 mu |d - h t| + c mu |t| + 2 c mu^2: d - h t, the slave less an affine
 * combination of the segment's ends with weights 1 - h and h, moves at most
 * c mu, c = 1 + |1 - h| + |h| <= 2 + 2 ext, and t at most 2 mu. `ra` bounds
 * |d - h t| (from the distances to the ends, |d| + |h| len or
 * |d - t| + |1 - h| len), `cb` is the rest (stays_rest), each with the
 * allowances for the round-off of the product the exact test computes. */
static inline int param_stays(double p, double L2, double h, double side, double ra, double mu, double cb) {
    return side * (p - h * L2) > (2.0 * mu * ra + cb) * (1.0 + 1e-9);
}

/* param_stays's bound on |d - h t|, D and E bounds on |d| and |d - t|
 * (norm_above; plus the positions' round-off, slack). */
static inline double stays_ra(double D, double E, double len, double h, double slack) {
    const double a0 = D + fabs(h) * len, a1 = E + fabs(1.0 - h) * len;
    return (a0 < a1 ? a0 : a1) + slack;
}

/* param_stays's other terms for a segment of length len, the slave D from
 * its first node: c mu (len + 2 mu) with c its largest, and the round-off
 * of f. */
static inline double stays_rest(double len, double D, double mu, double ext) {
    return (2.0 + 2.0 * ext) * mu * (len + 2.0 * mu) + 1e-9 * (D + len) * len;
}

/* An upper bound on |v| without a root (at most 8% above it): the larger
 * coordinate plus (sqrt 2 - 1) the smaller, which squared exceeds |v|^2 by
 * 2 (sqrt 2 - 1) (max min - min^2) >= 0 (the factor rounded up). */
static inline double norm_above(nts_vec2 v) {
    const double x = fabs(v.x), y = fabs(v.y);
    return (x > y ? x : y) + 0.41421357 * (x > y ? y : x);
}

/* Eq. (32): whether master j offers a slave at xs nothing at any positions
 * within mu of the build's, by try_master's own conditions: no flat (s_j
 * stays above hi or below lo), and no corner or vertex (none at X_j, or s_j
 * stays above max(alpha, 0), or s_{j-1} below 1 - alpha). Most masters the
 * reach around the middle keeps are so: the neighbours of the segment a
 * slave faces. X_{j-1} + t_{j-1} is X_j (up to the round-off in slack): the
 * slave's distance to X_j serves both segments. */
static inline NTS_ALWAYS_INLINE int kept_dead(const search_env* env, double mu, double slack, nts_vec2 xs, int j,
                                              const int periodic, const int surfaces) {
    const seg_data* m = &env->seg[j];
    const double alpha = alpha_of_body(env->s, m->body, env->alpha), ext = env->ext;
    const nts_vec2 d = search_diff(env, xs, m->p, periodic), e = nts_sub(d, m->t);
    const double D = norm_above(d), E = norm_above(e), p = nts_dot(d, m->t), L2 = m->len * m->len;
    const double cb = stays_rest(m->len, D, mu, ext);
    const double ac = alpha > 0.0 ? alpha : 0.0, hp = 1.0 - alpha;
    double lo = alpha, hi = 1.0 - alpha;
    int corner = 1;
    if (surfaces) { /* (as try_master: a contact surface's ends, docs/model.md §13) */
        const unsigned f = env->surf_flag[j];
        if (!(f & NTS_SF_PREV)) {
            lo = -ext;
            corner = 0;
        }
        if (!(f & NTS_SF_NEXT)) hi = 1.0 + ext;
    }
    if (!(param_stays(p, L2, hi, 1.0, stays_ra(D, E, m->len, hi, slack), mu, cb) |
          param_stays(p, L2, lo, -1.0, stays_ra(D, E, m->len, lo, slack), mu, cb)))
        return 0; /* a flat may offer */
    if (!corner || param_stays(p, L2, ac, 1.0, stays_ra(D, E, m->len, ac, slack), mu, cb)) return 1;
    {
        /* the previous segment's record only now (it may be out of cache) */
        const seg_data* sp = &env->seg[m->prev];
        const nts_vec2 dp = search_diff(env, xs, sp->p, periodic);
        const double DP = norm_above(dp);
        return param_stays(nts_dot(dp, sp->t), sp->len * sp->len, hp, -1.0, stays_ra(DP, D, sp->len, hp, 2.0 * slack), mu,
                           stays_rest(sp->len, DP, mu, ext));
    }
}

enum { KEPT_PRUNE = 64 };
/* Slave i's inner masters that offer nothing while the list holds go to
 * the outer ring, which only the widened searches read (eq. (32)): done by
 * the build's own replay, just before it tries those left (their records
 * then in cache). The order of the tries decides nothing (try_master).
 * Returns how many went. */
static inline NTS_ALWAYS_INLINE int kept_prune(const search_env* env, nts_candidates* kc, int i, const int periodic,
                                               const int surfaces) {
    int* buf = kept_chunk_of(kc, i);
    int* mid = kc->span + env->s->surface_count;
    const nts_vec2 xs = env->seg[i].p;
    /* (the largest displacement the lists hold for, with the frame's round-off) */
    const double mu = kept_hold(kc) * (1.0 + 1e-9) + 2.0 * kc->pad, slack = 2.0 * kc->pad;
    const int lo = kc->span[i], n = mid[i] - lo;
    int gone[KEPT_PRUNE], q, alive = lo, dead = 0;
    if (n > KEPT_PRUNE) return 0; /* (a slave among more masters than that: kept as they are) */
    /* the live ones to the front in their order, the dead after them: every
     * write made, the places moved by the verdicts (hard to predict) */
    for (q = lo; q < lo + n; ++q) {
        const int j = buf[q], v = kept_dead(env, mu, slack, xs, j, periodic, surfaces);
        buf[alive] = j;
        gone[dead] = j;
        alive += !v;
        dead += v;
    }
    for (q = 0; q < dead; ++q) buf[alive + dead - 1 - q] = gone[q]; /* (a few: no library call) */
    mid[i] = alive;
    return dead;
}

static inline NTS_ALWAYS_INLINE void search_kept(const search_env* env, worker* w, int begin, int end,
                                                 const int periodic, const int surfaces, const int selfc,
                                                 const int ahead_on) {
    const nts_scene* s = env->s;
    const nts_candidates* kc = env->kept;
    const int *lo = kept_lo(kc), *mid = kept_mid(kc);
    int i, k;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = env->seg[i].body;
        const int* items = kept_chunk_of(kc, i);
        const nts_vec2 xs = env->seg[i].p;
        if (selfc) set_slave(env, w, i, bi);
        if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
            w->status = NTS_ECANCELLED;
            break;
        }
        if (i == begin && ahead_on)
            for (k = 1; k < KEPT_AHEAD && i + k < end; ++k) { /* the first slaves' masters */
                const int a = i + k;
                int q;
                for (q = lo[a]; q < mid[a]; ++q) NTS_PREFETCH(&env->seg[kept_chunk_of(kc, a)[q]]);
            }
        if (s->body_role[bi] == NTS_ROLE_MASTER) continue;
        if (surfaces && !(env->surf_flag[i] & NTS_SF_NODE)) {
            not_a_slave(w, env, i);
            continue;
        }
        /* The masters' segment data are scattered over memory (other
         * bodies' entries): asked for KEPT_AHEAD slaves ahead, so that they
         * arrive while the slaves between are searched. */
        if (ahead_on && i + KEPT_AHEAD < end) {
            const int a = i + KEPT_AHEAD;
            const int* ahead = kept_chunk_of(kc, a);
            for (k = lo[a]; k < mid[a]; ++k) {
                NTS_PREFETCH(&env->seg[ahead[k]]);
                NTS_PREFETCH(&env->seg[ahead[k] - (ahead[k] > 0)]);
            }
        }
        /* (at the build: first out of the inner list what cannot offer,
         * there at any positions the list holds for, so here too) */
        if (env->kept_prune != NULL) w->pruned += kept_prune(env, env->kept_prune, i, periodic, surfaces);
        for (k = lo[i]; k < mid[i]; ++k) try_master(env, w, xs, items[k], env->r, periodic, surfaces, selfc);
        if (selfc && w->self_has) self_settle(env, w);
        if ((w->best_count | w->last_count) != 0 || env->seg[i].len > env->coarse) {
            flush_slave(env, w, i, end);
        } else {
            w->last_slave = i;
            if (env->seg[i].prev != i - 1) w->first_slave = i;
        }
    }
}

/* Whether master j goes in the kept list of a slave at xs (eq. (30)): 2
 * when its middle lies within its reach (around the middle, masters.h) plus
 * the inner radius, 1 within the slave's ring, else 0. */
static inline int kept_ring(const search_env* env, const nts_candidates* kc, nts_vec2 xs, double ring, int j,
                            const int periodic) {
    const seg_data* m = &env->seg[j];
    const double reach = reach_at_middle(env->seg, j, alpha_of_body(env->s, m->body, env->alpha), env->ext);
    const nts_vec2 d = nts_mul_add(search_diff(env, xs, m->p, periodic), -0.5, m->t); /* Xs - M_j */
    const double dist = sqrt(d.x * d.x + d.y * d.y);
    if (dist <= reach_allowed(reach, kc->inner, kc->pad)) return 2;
    return dist <= reach_allowed(reach, ring, kc->pad);
}

/* kept_ring from the keys [e0, e1) of a stencil's range, for a slave at
 * (fx, fy) in the keys' frame (masters.h), with the inner radius and the
 * slave's ring in that frame: a key's reach is the cells' radius
 * (kc->outer) plus the master's reach, widened, so the master's own reach
 * plus either radius is the key's less the difference: base[e]
 * (nts_kept_key_bases, with an allowance for the round-off of this test in
 * float). Reads no segment data (scattered over memory), takes no square
 * root, and decides without a branch (whether a master is kept, and in which
 * ring, is hard to predict): a master kept that the exact test would not
 * keep costs a try, never an answer. The keys (not their entries) within
 * the inner radius are appended at in[*ni], those within the ring alone at
 * out[*no], each in key order; a slave's own body's keys are left out (but
 * a body that meets itself: own0 = own1 = 0). Each side is written 4 lanes at
 * a time, so both need 4 places past what they keep. */
#if defined(__SSE2__)
static inline NTS_ALWAYS_INLINE void ring4(const master_keys* k, const float* base, __m128 vx, __m128 vy, __m128 vin,
                                           __m128 vring, const own_range* o, int e, int* in, int* ni, int* out,
                                           int* no) {
    const __m128 dx = _mm_sub_ps(vx, _mm_loadu_ps(k->x + e)), dy = _mm_sub_ps(vy, _mm_loadu_ps(k->y + e));
    const __m128 d2 = _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy));
    const __m128 b = _mm_loadu_ps(base + e), zero = _mm_setzero_ps();
    const __m128 ri = _mm_add_ps(b, vin), ro = _mm_add_ps(b, vring);
    const __m128 wi = _mm_and_ps(_mm_cmpge_ps(ri, zero), _mm_cmple_ps(d2, _mm_mul_ps(ri, ri)));
    const __m128 wo = _mm_and_ps(_mm_cmpge_ps(ro, zero), _mm_cmple_ps(d2, _mm_mul_ps(ro, ro)));
    const __m128 valid = _mm_castsi128_ps(other_lanes(k, o, e));
    const int mi = _mm_movemask_ps(_mm_and_ps(wi, valid));
    const int mo = _mm_movemask_ps(_mm_andnot_ps(wi, _mm_and_ps(wo, valid)));
    const __m128i ve = _mm_set1_epi32(e);
    _mm_storeu_si128((__m128i*)(void*)(in + *ni),
                     _mm_add_epi32(ve, _mm_loadu_si128((const __m128i*)(const void*)KEEP_LANES[mi])));
    _mm_storeu_si128((__m128i*)(void*)(out + *no),
                     _mm_add_epi32(ve, _mm_loadu_si128((const __m128i*)(const void*)KEEP_LANES[mo])));
    *ni += KEEP_COUNT[mi];
    *no += KEEP_COUNT[mo];
}

static inline NTS_ALWAYS_INLINE void ring_keys(const master_keys* k, const float* base, float fx, float fy, float inner,
                                               float ring, int own0, int own1, int e0, int e1, int* in, int* ni,
                                               int* out, int* no) {
    const __m128 vx = _mm_set1_ps(fx), vy = _mm_set1_ps(fy), vin = _mm_set1_ps(inner), vring = _mm_set1_ps(ring);
    const own_range o = own_range_of(own0, own1, e1);
    int e;
    for (e = e0; e < e1; e += 4) ring4(k, base, vx, vy, vin, vring, &o, e, in, ni, out, no);
}
#else
static inline void ring_keys(const master_keys* k, const float* base, float fx, float fy, float inner, float ring,
                             int own0, int own1, int e0, int e1, int* in, int* ni, int* out, int* no) {
    int e;
    for (e = e0; e < e1; ++e) {
        const float dx = fx - k->x[e], dy = fy - k->y[e], d2 = dx * dx + dy * dy;
        const float ri = base[e] + inner, ro = base[e] + ring;
        const int other = k->entry[e] < own0 || k->entry[e] >= own1;
        const int wi = other & (ri >= 0.0f) & (d2 <= ri * ri), wo = other & !wi & (ro >= 0.0f) & (d2 <= ro * ro);
        in[*ni] = e;
        out[*no] = e;
        *ni += wi;
        *no += wo;
    }
}
#endif

/* Master j in `ring` (kept_ring: 0, not kept) appended to a slave's list,
 * buf[from .. *at), the inner ones first (up to *inner), growing its room
 * when needed: j appended, then swapped with the first outer one when inner
 * (the lists' order decides no answer). */
static inline int kept_add(int** buf, int* cap, int* at, int* inner, int j, int ring) {
    if (ring == 0) return NTS_OK;
    if (*at >= *cap && nts_grow((void**)buf, cap, *at + 1, sizeof(int)) != NTS_OK) return NTS_ENOMEM;
    (*buf)[*at] = j;
    if (ring == 2) {
        (*buf)[*at] = (*buf)[*inner];
        (*buf)[(*inner)++] = j;
    }
    ++*at;
    return NTS_OK;
}

#ifndef NDEBUG
/* (asserts on) ring_keys keeps every master of another body in the
 * stencil that the exact test keeps (kept_ring), in the inner part (the
 * list's first ni) when that test says inner. It costs the stencil's keys
 * times the list's length a slave: for the asserts-on builds alone. */
static void kept_check(const search_env* env, const nts_candidates* kc, int i, const nts_stencil* st, int own0,
                       int own1, const int* list, int ni, int no, const int periodic) {
    int q, e, k;
    for (q = 0; q < st->n; ++q)
        for (e = st->begin[q]; e < st->end[q]; ++e) {
            const int j = env->keys->entry[e];
            const int want = j >= own0 && j < own1 ? 0 : kept_ring(env, kc, env->seg[i].p, kc->ring[i], j, periodic);
            int at = -1;
            for (k = 0; k < ni + no && at < 0; ++k)
                if (list[k] == j) at = k;
            assert(want == 0 || (at >= 0 && (want == 1 || at < ni)));
            (void)want;
            (void)at;
        }
}
#endif

/* A slave's ring masters, held until its inner ones are all written: on
 * the stack, and past that on the heap (given back when the chunk is done).
 * It grows with what is kept, never with the stencil's keys. */
typedef struct kept_stage {
    int* p;
    int cap;
    int local[512];
} kept_stage;

static int stage_room(kept_stage* sg, int need) {
    int* p;
    if (need <= sg->cap) return NTS_OK;
    if (sg->p != sg->local) return nts_grow((void**)&sg->p, &sg->cap, need, sizeof(int));
    if ((p = (int*)nts_alloc(sizeof(int) * (size_t)need * 2)) == NULL) return NTS_ENOMEM;
    memcpy(p, sg->local, sizeof sg->local);
    sg->p = p;
    sg->cap = need * 2;
    return NTS_OK;
}

static inline NTS_ALWAYS_INLINE int kept_collect(const search_env* env, nts_candidates* kc, int c, kept_stage* sg,
                                                 const int periodic, const int surfaces) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    const master_keys* keys = env->keys;
    const int begin = c * KEPT_CHUNK, end = begin + KEPT_CHUNK < s->surface_count ? begin + KEPT_CHUNK : s->surface_count;
    int* lo = kc->span;
    int* mid = kc->span + s->surface_count;
    int* hi = kc->span + 2 * s->surface_count;
    nts_stencil st;
    int last_cell = -1, i, q, at = 0;
    st.n = 0;
    for (i = begin; i < end; ++i) {
        const int bi = env->seg[i].body, self = self_body(env, bi);
        const int own0 = self ? 0 : s->loop_start[s->body_loop_start[bi]];
        const int own1 = self ? 0 : s->loop_start[s->body_loop_start[bi + 1]];
        const nts_vec2 xs = env->seg[i].p;
        const float inner_s = (float)(kc->inner * cl->scale), ring_s = (float)(kc->ring[i] * cl->scale);
        nts_cell_place p;
        int inner = at, ni = 0, no = 0, k;
        int* buf;
        lo[i] = mid[i] = at;
        hi[i] = -1;
        if (s->body_role[bi] == NTS_ROLE_MASTER || (surfaces && !(env->surf_flag[i] & NTS_SF_NODE))) continue;
        p = nts_cells_place(cl, xs);
        slave_stencil(cl, p, &st, &last_cell);
        /* The inner ones from `at` on, the ring's staged, then put after
         * them; the room asked for a batch of keys at a time (each side 4
         * past what it keeps), so that it follows what is kept. */
        for (q = 0; q < st.n; ++q) {
            const float fx = (float)(p.x * cl->scale - st.shift_x[q]), fy = (float)(p.y * cl->scale - st.shift_y[q]);
            int e0, e1;
            for (e0 = st.begin[q]; e0 < st.end[q]; e0 = e1) {
                e1 = st.end[q] - e0 > KEPT - 4 ? e0 + KEPT - 4 : st.end[q];
                if ((at + ni + (e1 - e0) + 4 >= kc->chunk_cap[c] &&
                     nts_grow((void**)&kc->chunk[c], &kc->chunk_cap[c], at + ni + (e1 - e0) + 5, sizeof(int)) !=
                         NTS_OK) ||
                    stage_room(sg, no + (e1 - e0) + 4) != NTS_OK)
                    return NTS_ENOMEM;
                ring_keys(keys, kc->key_base, fx, fy, inner_s, ring_s, own0, own1, e0, e1, kc->chunk[c] + at, &ni, sg->p,
                          &no);
            }
        }
        if (at + ni + no >= kc->chunk_cap[c] &&
            nts_grow((void**)&kc->chunk[c], &kc->chunk_cap[c], at + ni + no + 1, sizeof(int)) != NTS_OK)
            return NTS_ENOMEM;
        /* keys to entries */
        buf = kc->chunk[c];
        for (k = 0; k < ni; ++k) buf[at + k] = keys->entry[buf[at + k]];
        for (k = 0; k < no; ++k) buf[at + ni + k] = keys->entry[sg->p[k]];
#ifndef NDEBUG
        kept_check(env, kc, i, &st, own0, own1, buf + at, ni, no, periodic);
#endif
        inner = at + ni;
        at += ni + no;
        if (env->long_start != NULL) {
            int e;
            for (e = env->long_start[last_cell]; e < env->long_start[last_cell + 1]; ++e) {
                const long_master* lm = &env->long_m[env->long_items[e]];
                const int j = lm->entry;
                const nts_vec2 d = search_diff(env, xs, env->seg[j].p, periodic);
                if (d.x * d.x + d.y * d.y <= lm->reach2 && (env->seg[j].body != bi || self) &&
                    kept_add(&kc->chunk[c], &kc->chunk_cap[c], &at, &inner, j, kept_ring(env, kc, xs, kc->ring[i], j, periodic)) !=
                        NTS_OK)
                    return NTS_ENOMEM;
            }
        }
        mid[i] = inner;
        hi[i] = at;
        if (at > KEPT_CHUNK_BUDGET) return NTS_ELIMIT;
    }
    kc->chunk_used[c] = at;
    return NTS_OK;
}

int nts_kept_collect(const search_env* env, nts_candidates* kc, int c) {
    const int periodic = env->lx > 0.0 || env->ly > 0.0;
    kept_stage sg;
    int rc;
    assert(env->cells != NULL);
    sg.p = sg.local;
    sg.cap = (int)(sizeof sg.local / sizeof sg.local[0]);
    if (env->surf_flag != NULL)
        rc = periodic ? kept_collect(env, kc, c, &sg, 1, 1) : kept_collect(env, kc, c, &sg, 0, 1);
    else
        rc = periodic ? kept_collect(env, kc, c, &sg, 1, 0) : kept_collect(env, kc, c, &sg, 0, 0);
    if (sg.p != sg.local) nts_free(sg.p);
    return rc;
}

/* Brute force (for tests): every master of every other body, culled only by
 * an exact reach test in double around X_j (with the round-off allowance of
 * the minimum image, env->brute_pad). */
static inline NTS_ALWAYS_INLINE void search_brute(const search_env* env, worker* w, int begin, int end,
                                                  const int periodic) {
    const nts_scene* s = env->s;
    int i, j;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = s->surf_body[i], self = self_body(env, bi);
        const nts_vec2 xs = env->seg[i].p;
        set_slave(env, w, i, bi);
        if (((i - begin) & 1023) == 1023 && env->cancel != NULL && env->cancel(env->cancel_user)) {
            w->status = NTS_ECANCELLED;
            break;
        }
        if (s->body_role[bi] == NTS_ROLE_MASTER) continue;
        if (env->surf_flag != NULL && !(env->surf_flag[i] & NTS_SF_NODE)) {
            not_a_slave(w, env, i);
            continue;
        }
        for (j = 0; j < s->surface_count; ++j) {
            const int b = s->surf_body[j];
            nts_vec2 d;
            double R;
            if ((b == bi && !self) || s->body_role[b] == NTS_ROLE_SLAVE || !nts_on_surface(s, j)) continue;
            d = search_diff(env, xs, env->seg[j].p, periodic);
            R = reach_allowed(reach_at_node(env->seg, j, alpha_of_body(s, b, env->alpha), env->ext), env->r,
                              env->brute_pad);
            if (d.x * d.x + d.y * d.y <= R * R)
                try_master(env, w, xs, j, env->r, periodic, env->surf_flag != NULL, env->self != NULL);
        }
        if (w->self_has) self_settle(env, w);
        if ((w->best_count | w->last_count) != 0 || env->seg[i].len > env->coarse) {
            flush_slave(env, w, i, end);
        } else { /* most slaves: nothing here, nothing before */
            w->last_slave = i;
            if (env->seg[i].prev != i - 1) w->first_slave = i;
        }
    }
}

/* The cell search's four instances (an open or periodic box, with or
 * without contact surfaces), each a function of its own, so that one's code
 * does not change how the compiler treats another's: a scene without
 * surfaces pays nothing for them. */
#if defined(__GNUC__)
#define NTS_NOINLINE __attribute__((noinline))
#else
#define NTS_NOINLINE
#endif
static NTS_NOINLINE void cells_open(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 0, 0, 0);
}
static NTS_NOINLINE void cells_periodic(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 1, 0, 0);
}
static NTS_NOINLINE void cells_open_surfaces(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 0, 1, 0);
}
static NTS_NOINLINE void cells_periodic_surfaces(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 1, 1, 0);
}
/* (with and without the lines asked for ahead: search_env.kept_ahead) */
static NTS_NOINLINE void kept_open(const search_env* env, worker* w, int begin, int end) {
    if (env->kept_ahead) search_kept(env, w, begin, end, 0, 0, 0, 1);
    else search_kept(env, w, begin, end, 0, 0, 0, 0);
}
static NTS_NOINLINE void kept_periodic(const search_env* env, worker* w, int begin, int end) {
    if (env->kept_ahead) search_kept(env, w, begin, end, 1, 0, 0, 1);
    else search_kept(env, w, begin, end, 1, 0, 0, 0);
}
static NTS_NOINLINE void kept_surfaces(const search_env* env, worker* w, int begin, int end) {
    if (env->lx > 0.0 || env->ly > 0.0) search_kept(env, w, begin, end, 1, 1, 0, env->kept_ahead);
    else search_kept(env, w, begin, end, 0, 1, 0, env->kept_ahead);
}
/* A scene where some body meets itself (docs/model.md §16): instances of
 * their own, so that every other scene runs the code it ran before. */
static NTS_NOINLINE void cells_self_open(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 0, 0, 1);
}
static NTS_NOINLINE void cells_self_periodic(const search_env* env, worker* w, int begin, int end) {
    search_cells(env, w, begin, end, 1, 0, 1);
}
static NTS_NOINLINE void cells_self(const search_env* env, worker* w, int begin, int end) {
    const int periodic = env->lx > 0.0 || env->ly > 0.0;
    if (env->surf_flag == NULL) {
        if (periodic) cells_self_periodic(env, w, begin, end);
        else cells_self_open(env, w, begin, end);
    } else if (periodic) {
        search_cells(env, w, begin, end, 1, 1, 1);
    } else {
        search_cells(env, w, begin, end, 0, 1, 1);
    }
}
static NTS_NOINLINE void kept_self(const search_env* env, worker* w, int begin, int end) {
    if (env->lx > 0.0 || env->ly > 0.0) search_kept(env, w, begin, end, 1, env->surf_flag != NULL, 1, env->kept_ahead);
    else search_kept(env, w, begin, end, 0, env->surf_flag != NULL, 1, env->kept_ahead);
}

void nts_search_range(const search_env* env, worker* w, int begin, int end) {
    const int periodic = env->lx > 0.0 || env->ly > 0.0;
    if (env->self != NULL && (env->kept != NULL || env->cells != NULL)) {
        if (env->kept != NULL) kept_self(env, w, begin, end);
        else cells_self(env, w, begin, end);
    } else if (env->kept != NULL) {
        if (env->surf_flag != NULL) kept_surfaces(env, w, begin, end);
        else if (periodic) kept_periodic(env, w, begin, end);
        else kept_open(env, w, begin, end);
    } else if (env->cells != NULL) {
        if (env->surf_flag != NULL) {
            if (periodic) cells_periodic_surfaces(env, w, begin, end);
            else cells_open_surfaces(env, w, begin, end);
        } else {
            if (periodic) cells_periodic(env, w, begin, end);
            else cells_open(env, w, begin, end);
        }
    } else {
        if (periodic) search_brute(env, w, begin, end, 1);
        else search_brute(env, w, begin, end, 0);
    }
    if (env->direct && env->forces != NULL) scatter_direct_drain(env, w);
}

/* A widened search tries master j of body b (not the slave's own, offering
 * a surface, the one asked for if any) within radius rho, or for every body
 * (body < 0) min(rho, the body's depth) when its circle holds the slave,
 * culled by an exact reach test in double around X_j. */
static inline NTS_ALWAYS_INLINE void wide_try(const search_env* env, worker* w, nts_vec2 xs, int own, int j,
                                              int body, double rho, double* shape, const int periodic) {
    const seg_data* m = &env->seg[j];
    const int b = m->body;
    double rb = rho, R, d2;
    nts_vec2 d;
    if ((b == own && !self_body(env, own)) || (body >= 0 && b != body) || env->s->body_role[b] == NTS_ROLE_SLAVE ||
        !nts_on_surface(env->s, j))
        return;
    if (body < 0) {
        const double depth = nts_body_shape(env, shape, b)[3] * (1.0 + 1e-9) + env->wide_pad; /* with round-off */
        if (nts_outside_bounds(env, shape, b, xs)) return; /* outside the body: no active contact there */
        if (depth < rb) rb = depth;
    }
    d = search_diff(env, xs, m->p, periodic);
    d2 = d.x * d.x + d.y * d.y;
    /* Every reach around a node is at most L_max (reach_at_node): most
     * masters are out of that first. */
    R = reach_allowed(env->wide_lmax, rb, env->wide_pad);
    if (d2 > R * R) return;
    R = reach_allowed(reach_at_node(env->seg, j, alpha_of_body(env->s, b, env->alpha), env->ext), rb, env->wide_pad);
    if (d2 <= R * R) try_master(env, w, xs, j, rb, periodic, env->surf_flag != NULL, env->self != NULL);
}

/* The entries of body b: consecutive. */
static inline void body_entries(const nts_scene* s, int b, int* e0, int* e1) {
    *e0 = s->loop_start[s->body_loop_start[b]];
    *e1 = s->loop_start[s->body_loop_start[b + 1]];
}

/* The columns (or rows) of the cells within `reach` of frame coordinate q:
 * [*first, *first + count), wrapped in a periodic grid (each column once). */
static int wide_span(double q, double reach, double inv_h, int n, int periodic, int* first) {
    const double lo = floor((q - reach) * inv_h), hi = floor((q + reach) * inv_h);
    if (periodic) {
        if (!(hi - lo + 1.0 < (double)n)) {
            *first = 0;
            return n;
        }
        *first = (int)(lo - (double)n * floor(lo / (double)n));
        return (int)(hi - lo) + 1;
    }
    *first = lo < 0.0 ? 0 : (lo > (double)(n - 1) ? n - 1 : (int)lo);
    return (hi > (double)(n - 1) ? n - 1 : (hi < 0.0 ? 0 : (int)hi)) - *first + 1;
}

static inline NTS_ALWAYS_INLINE void wide(const search_env* env, worker* w, int k, int body, double rho,
                                          double* shape, const int periodic) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    const int own = env->seg[k].body;
    const nts_vec2 xs = env->seg[k].p;
    int e0 = 0, e1 = s->surface_count, j;
    set_slave(env, w, k, own);
    if (kept_covers(env, k, rho)) {
        /* The slave's kept list holds every master that could offer a
         * feature within rho (eq. (30)): the same candidates as the cells. */
        const nts_candidates* kc = env->kept;
        const int* items = kept_chunk_of(kc, k);
        const int hi = kept_hi(kc)[k];
        if (body < 0) {
            for (j = kept_lo(kc)[k]; j < hi; ++j) wide_try(env, w, xs, own, items[j], body, rho, shape, periodic);
        } else {
            /* A body's entries are consecutive: the others' are passed by
             * their number, without reading their records (scattered). */
            body_entries(s, body, &e0, &e1);
            for (j = kept_lo(kc)[k]; j < hi; ++j)
                if (items[j] >= e0 && items[j] < e1) wide_try(env, w, xs, own, items[j], body, rho, shape, periodic);
        }
        return;
    }
    if (body >= 0) body_entries(s, body, &e0, &e1);
    /* A body of few entries: all of them, without placing the cells. */
    if (cl != NULL && (body < 0 || e1 - e0 > 64)) {
        /* A binned master's middle lies within its reach, at most a cell's
         * side, of its features: the cells within rho + that of the slave
         * hold every master that could offer a feature within rho. */
        const double reach = rho + (cl->hx > cl->hy ? cl->hx : cl->hy) + env->wide_pad;
        const nts_cell_place q = nts_cells_place(cl, xs);
        int cx0, ncx, cy0, ncy, a, b;
        ncx = wide_span(q.x, reach, cl->inv_hx, cl->nx, cl->periodic, &cx0);
        ncy = wide_span(q.y, reach, cl->inv_hy, cl->ny, cl->periodic, &cy0);
        /* One body asked for and few entries: try them all instead. */
        /* the cells' cost: a range of keys per row, and the keys in them */
        if (body < 0 || (long long)ncy * cl->nx * cl->ny + (long long)ncx * ncy * (cl->cell_start[cl->nx * cl->ny] + 1) <
                            (long long)(e1 - e0) * cl->nx * cl->ny) {
            for (b = 0; b < ncy; ++b) {
                const int row = ((cy0 + b) % cl->ny) * cl->nx;
                int run, e;
                /* The row's cells are consecutive, and so are their keys: one
                 * range (two where the row wraps around the box), whatever
                 * the empty cells inside a deep slave's range. */
                for (run = 0; run < 2; ++run) {
                    const int c0 = run == 0 ? cx0 : 0;
                    const int c1 = run == 0 ? (cx0 + ncx < cl->nx ? cx0 + ncx : cl->nx) : cx0 + ncx - cl->nx;
                    if (c1 <= c0) continue;
                    for (e = cl->cell_start[row + c0]; e < cl->cell_start[row + c1]; ++e) {
                        j = env->keys->entry[e];
                        if (j >= e0 && j < e1) wide_try(env, w, xs, own, j, body, rho, shape, periodic);
                    }
                }
                if (env->long_start != NULL)
                    for (a = 0; a < ncx; ++a) {
                        const int cell = row + (cx0 + a) % cl->nx;
                        for (e = env->long_start[cell]; e < env->long_start[cell + 1]; ++e) {
                            j = env->long_m[env->long_items[e]].entry;
                            if (j >= e0 && j < e1) wide_try(env, w, xs, own, j, body, rho, shape, periodic);
                        }
                    }
            }
            return;
        }
    }
    if (body < 0) {
        for (j = e0; j < e1; ++j) wide_try(env, w, xs, own, j, body, rho, shape, periodic);
        return;
    }
    if ((body == own && !self_body(env, own)) || s->body_role[body] == NTS_ROLE_SLAVE) return;
    {
        /* One body, all its entries: the bound of wide_try first. */
        const double alpha = alpha_of_body(s, body, env->alpha);
        const double Rmax = reach_allowed(env->wide_lmax, rho, env->wide_pad), Rmax2 = Rmax * Rmax;
        for (j = e0; j < e1; ++j) {
            const nts_vec2 d = search_diff(env, xs, env->seg[j].p, periodic);
            const double d2 = d.x * d.x + d.y * d.y;
            double R;
            if (d2 > Rmax2 || !nts_on_surface(s, j)) continue;
            R = reach_allowed(reach_at_node(env->seg, j, alpha, env->ext), rho, env->wide_pad);
            if (d2 <= R * R) try_master(env, w, xs, j, rho, periodic, env->surf_flag != NULL, env->self != NULL);
        }
    }
}

void nts_search_wide(const search_env* env, worker* w, int k, int body, double rho, double* shape) {
    if (env->lx > 0.0 || env->ly > 0.0) wide(env, w, k, body, rho, shape, 1);
    else wide(env, w, k, body, rho, shape, 0);
    if (w->self_has) self_settle(env, w); /* (its own body's feature, docs/model.md §16) */
}

void nts_search_wide_done(worker* w) {
    int k;
    for (k = 0; k < w->best_count; ++k) w->slot[w->best[k].body] = -1;
    w->best_count = 0;
}
