/* Coulomb friction of one active contact (docs/model.md §14): the
 * tangential gap from the committed anchor, stick or slip, the return of the
 * anchor, the forces, and their tangent.
 *
 * The tangent is -d f_T / dx of exactly the tangential forces below, over
 * the slave, the master nodes of the closest feature and the anchor's nodes,
 * by forward-mode differentiation (dual numbers over at most 7 nodes): the
 * closest point's parameter enters through the implicit function theorem on
 * its defining equation (7) (a segment's s is explicit), the anchor's
 * parameter is a constant (a material point). In slip the direction of the
 * traction is constant and its size mu |f_N| follows the normal gap. */
#include <math.h>
#include <string.h>

#include "corner.h"
#include "friction.h"

/* ------------------------------------------------------------ anchors */

/* The weights of a feature at param: a segment's (1 - s, s), a corner's (3),
 * a vertex's 1. Returns how many. */
static int feature_weights(int kind, double alpha, double param, double w[3]) {
    if (kind == NTS_KIND_SEGMENT) {
        w[0] = 1.0 - param;
        w[1] = param;
        return 2;
    }
    if (kind == NTS_KIND_CORNER) {
        const nts_shape3 N = corner_shape(alpha, param);
        w[0] = N.n2;
        w[1] = N.n3;
        w[2] = N.n4;
        return 3;
    }
    w[0] = 1.0;
    return 1;
}

/* X_A - Xs of anchor a (its nodes' minimum images from the slave). */
static nts_vec2 anchor_offset(const search_env* env, const nts_anchor* a, nts_vec2 xs, double alpha) {
    const nts_scene* s = env->s;
    const int off = s->body_node_start[a->master_body];
    double w[3];
    const int m = feature_weights(a->kind, alpha, a->param, w);
    nts_vec2 r = nts_v2(0.0, 0.0);
    int k;
    for (k = 0; k < m; ++k) r = nts_mul_add(r, w[k], nts_scene_diff(s, s->pos[off + a->nodes[k]], xs));
    return r;
}

/* The anchor at a record's closest point (what a new contact starts from). */
static nts_anchor anchor_here(const search_env* env, const candidate* b) {
    const nts_scene* s = env->s;
    nts_anchor a;
    int entry[3], q, m;
    double w[3];
    memset(&a, 0, sizeof a); /* its padding too: results are compared byte for byte */
    a.slave_body = s->surf_body[b->slave];
    a.slave_node = s->surf_local[b->slave];
    a.master_body = b->body;
    a.kind = (nts_kind)b->kind;
    m = record_masters(env, b, entry, w);
    for (q = 0; q < 3; ++q) a.nodes[q] = q < m ? s->surf_local[entry[q]] : -1;
    a.param = b->kind == NTS_KIND_VERTEX ? 0.0 : b->param;
    return a;
}

/* The anchor returned onto the closest feature so that the tangential gap
 * is g_e (docs/model.md (25)): a segment's s moves by -g_e / |t| (exact: the
 * segment is straight); a corner's xi by the root of
 * (A.tau) d^2 + |tau(xi)| d + g_e = 0 nearest to 0 (X(xi) is quadratic);
 * a vertex keeps itself (it has no tangential extent). */
static nts_anchor anchor_returned(const search_env* env, const candidate* b, nts_vec2 tau, double g_e, double alpha) {
    nts_anchor a = anchor_here(env, b);
    const seg_data* seg = env->seg;
    if (b->kind == NTS_KIND_SEGMENT) {
        a.param = b->param - g_e / seg[b->entry].len;
    } else if (b->kind == NTS_KIND_CORNER) {
        const nts_corner k = corner_make(nts_neg(seg[seg[b->entry].prev].t), seg[b->entry].t, alpha);
        const nts_vec2 tc = nts_corner_tangent(k, b->param);
        const double bq = nts_dot(tc, tau), aq = nts_dot(k.A, tau), disc = bq * bq - 4.0 * aq * g_e;
        double d;
        if (disc >= 0.0) d = -2.0 * g_e / (bq + sqrt(disc)); /* bq > 0: no cancellation */
        else d = -bq / (2.0 * aq);                           /* past the parabola's reach: its vertex */
        a.param = b->param + d;
    }
    return a;
}

/* -------------------------------------------------------- the law (24)-(27) */

void nts_friction_eval(const search_env* env, const candidate* b, friction_out* out, int* hint) {
    const nts_scene* s = env->s;
    const int i = b->slave, sb = s->surf_body[i], sn = s->surf_local[i];
    const double alpha = alpha_of_body(s, b->body, env->alpha);
    const double eps = record_penalty(env, b);
    const double eg = eps * b->gap, fn = law_slave_normal(eg); /* |f_N| = -eps g */
    const nts_vec2 n = b->normal;
    const nts_anchor* a;
    memset(out, 0, sizeof *out);
    out->tau = nts_v2(-n.y, n.x);
    out->mu = friction_pair_mu(s, sb, b->body, env->mu);
    out->eps_t = law_penalty(env->eps_t, env->per_length, s->surf_trib, i);
    out->anchor = anchor_here(env, b);
    out->from = out->anchor;
    out->f = law_slave_force(eg, n);
    out->state = out->mu > 0.0 ? NTS_STICK : NTS_FRICTIONLESS;
    if (!(out->mu > 0.0)) return;
    a = env->history != NULL ? nts_history_find(env->history, sb, sn, b->body, hint) : NULL;
    if (a == NULL) return; /* new: sticking where it is, g_T = 0 */
    out->found = 1;
    out->from = *a;
    {
        /* g_T = (X - X_A).tau, and X - Xs = -g n is normal to tau (23) */
        const double gt = -nts_dot(anchor_offset(env, a, env->seg[i].p, alpha), out->tau);
        const double trial = -out->eps_t * gt, limit = out->mu * fn;
        double ge = gt;
        if (fabs(trial) <= limit) {
            out->t = trial;
            out->anchor = *a;
        } else {
            out->t = trial > 0.0 ? limit : -limit;
            out->state = NTS_SLIP;
            ge = -out->t / out->eps_t;
            out->slip = fabs(gt) - fabs(ge);
            out->dissipation = limit * out->slip;
            out->anchor = anchor_returned(env, b, out->tau, ge, alpha);
        }
        out->energy_t = 0.5 * out->eps_t * ge * ge;
        out->f = nts_mul_add(out->f, out->t, out->tau);
    }
}

/* ------------------------------------------------- the tangent (dual numbers) */

/* A number and its derivatives along the contact's local degrees of freedom
 * (2 per node: the slave, up to 3 master nodes, up to 3 anchor nodes). */
enum { DN = 14 };
typedef struct dual {
    double v;
    double d[DN];
} dual;
typedef struct dvec {
    dual x, y;
} dvec;

static dual dconst(double v) {
    dual r;
    memset(&r, 0, sizeof r);
    r.v = v;
    return r;
}
static dual dadd(dual a, dual b) {
    int k;
    a.v += b.v;
    for (k = 0; k < DN; ++k) a.d[k] += b.d[k];
    return a;
}
static dual dsub(dual a, dual b) {
    int k;
    a.v -= b.v;
    for (k = 0; k < DN; ++k) a.d[k] -= b.d[k];
    return a;
}
static dual dmul(dual a, dual b) {
    dual r;
    int k;
    r.v = a.v * b.v;
    for (k = 0; k < DN; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
    return r;
}
static dual dscale(double s, dual a) {
    int k;
    a.v *= s;
    for (k = 0; k < DN; ++k) a.d[k] *= s;
    return a;
}
static dual ddiv(dual a, dual b) {
    dual r;
    int k;
    r.v = a.v / b.v;
    for (k = 0; k < DN; ++k) r.d[k] = (a.d[k] - r.v * b.d[k]) / b.v;
    return r;
}
static dual dsqrt(dual a) {
    dual r;
    int k;
    r.v = sqrt(a.v);
    for (k = 0; k < DN; ++k) r.d[k] = a.v > 0.0 ? 0.5 * a.d[k] / r.v : 0.0;
    return r;
}
static dvec vadd(dvec a, dvec b) {
    dvec r;
    r.x = dadd(a.x, b.x);
    r.y = dadd(a.y, b.y);
    return r;
}
static dvec vsub(dvec a, dvec b) {
    dvec r;
    r.x = dsub(a.x, b.x);
    r.y = dsub(a.y, b.y);
    return r;
}
static dvec vscale(dual s, dvec a) {
    dvec r;
    r.x = dmul(s, a.x);
    r.y = dmul(s, a.y);
    return r;
}
static dvec vscalec(double s, dvec a) {
    dvec r;
    r.x = dscale(s, a.x);
    r.y = dscale(s, a.y);
    return r;
}
static dual vdot(dvec a, dvec b) { return dadd(dmul(a.x, b.x), dmul(a.y, b.y)); }
static dvec vzero(void) {
    dvec r;
    r.x = dconst(0.0);
    r.y = dconst(0.0);
    return r;
}

/* The contact's nodes: the slave, the closest feature's, then the anchor's
 * not among them; node positions relative to the slave, seeded. */
typedef struct local_nodes {
    int n;
    int node[7];   /* global */
    dvec d[7];     /* X_k - Xs (minimum image), with d(X_k - Xs)/dx */
} local_nodes;

static int local_slot(local_nodes* L, const nts_scene* s, int node, nts_vec2 xs) {
    int k;
    for (k = 0; k < L->n; ++k)
        if (L->node[k] == node) return k;
    assert(L->n < 7);
    k = L->n++;
    L->node[k] = node;
    {
        const nts_vec2 r = nts_scene_diff(s, s->pos[node], xs);
        L->d[k].x = dconst(r.x);
        L->d[k].y = dconst(r.y);
        if (k > 0) {
            L->d[k].x.d[2 * k] = 1.0;
            L->d[k].y.d[2 * k + 1] = 1.0;
            L->d[k].x.d[0] = -1.0; /* the slave's own move */
            L->d[k].y.d[1] = -1.0;
        }
    }
    return k;
}

int nts_friction_tangent_add(nts_kbuf* kb, const search_env* env, const candidate* b, const friction_out* fo) {
    const nts_scene* s = env->s;
    const double alpha = alpha_of_body(s, b->body, env->alpha);
    const double eps = record_penalty(env, b);
    const nts_vec2 xs = env->seg[b->slave].p;
    const int off = s->body_node_start[b->body];
    local_nodes L;
    int entry[3], slot[3], aslot[3], m, ma, k, q, a, j, rc;
    double w[3], wa[3];
    dvec rc_, n, tau, ra, f, force[4];
    dual N[3], g, gt, t;
    if (fo->state == NTS_FRICTIONLESS || !fo->found) return NTS_OK; /* t is 0 wherever the nodes go */
    memset(&L, 0, sizeof L);
    L.n = 1;
    L.node[0] = s->surf_node[b->slave];
    L.d[0] = vzero();
    m = record_masters(env, b, entry, w);
    for (k = 0; k < m; ++k) slot[k] = local_slot(&L, s, env->seg[entry[k]].node, xs);
    ma = feature_weights(fo->from.kind, alpha, fo->from.param, wa);
    for (k = 0; k < ma; ++k) aslot[k] = local_slot(&L, s, off + fo->from.nodes[k], xs);

    /* The closest point X - Xs, its weights and normal, as functions of the nodes. */
    if (b->kind == NTS_KIND_SEGMENT) {
        const dvec d0 = L.d[slot[0]], tv = vsub(L.d[slot[1]], d0);
        const dual tt = vdot(tv, tv), len = dsqrt(tt);
        const dual sp = ddiv(dscale(-1.0, vdot(d0, tv)), tt); /* s = (Xs - X0).t / |t|^2 */
        rc_ = vadd(d0, vscale(sp, tv));
        N[0] = dsub(dconst(1.0), sp);
        N[1] = sp;
        n.x = ddiv(tv.y, len);
        n.y = ddiv(dscale(-1.0, tv.x), len);
    } else if (b->kind == NTS_KIND_CORNER) {
        /* a = X2 - X3, c = X4 - X3; X(xi) - Xs = d3 + A xi^2 + B xi + C (4);
         * F(xi) = (Xs - X(xi)).tau(xi) = 0 (7) gives dxi/dx = -F_x / F_xi. */
        const dvec d3 = L.d[slot[1]], av = vsub(L.d[slot[0]], d3), cv = vsub(L.d[slot[2]], d3);
        const dvec A = vscalec(0.25 * alpha, vadd(av, cv)), B = vscalec(0.5 * alpha, vsub(cv, av));
        dual xi = dconst(b->param), F, xi2;
        dvec r0, tv;
        double Fxi;
        xi2 = dmul(xi, xi);
        r0 = vadd(vadd(d3, vscale(xi2, A)), vadd(vscale(xi, B), A)); /* X - Xs at fixed xi */
        tv = vadd(vscale(dscale(2.0, xi), A), B);
        F = dscale(-1.0, vdot(r0, tv));
        Fxi = -(tv.x.v * tv.x.v + tv.y.v * tv.y.v) - 2.0 * (r0.x.v * A.x.v + r0.y.v * A.y.v);
        if (fabs(Fxi) > 1e-12 * (tv.x.v * tv.x.v + tv.y.v * tv.y.v)) /* not on the evolute (§7) */
            for (k = 0; k < DN; ++k) xi.d[k] = -F.d[k] / Fxi;
        xi2 = dmul(xi, xi);
        rc_ = vadd(vadd(d3, vscale(xi2, A)), vadd(vscale(xi, B), A));
        tv = vadd(vscale(dscale(2.0, xi), A), B);
        {
            const dual len = dsqrt(vdot(tv, tv));
            const dual om = dsub(dconst(1.0), xi), op = dadd(dconst(1.0), xi);
            n.x = ddiv(tv.y, len);
            n.y = ddiv(dscale(-1.0, tv.x), len);
            N[0] = dscale(0.25 * alpha, dmul(om, om));
            N[1] = dsub(dconst(1.0), dscale(0.5 * alpha, dadd(dconst(1.0), xi2)));
            N[2] = dscale(0.25 * alpha, dmul(op, op));
        }
    } else {
        /* the vertex: Xs - X_j = g n with g < 0 */
        const dual len = dsqrt(vdot(L.d[slot[0]], L.d[slot[0]]));
        rc_ = L.d[slot[0]];
        n.x = ddiv(rc_.x, len);
        n.y = ddiv(rc_.y, len);
        N[0] = dconst(1.0);
    }
    tau.x = dscale(-1.0, n.y);
    tau.y = n.x;
    /* the anchor, a material point: its weights are constants */
    ra = vzero();
    for (k = 0; k < ma; ++k) ra = vadd(ra, vscalec(wa[k], L.d[aslot[k]]));
    gt = vdot(vsub(rc_, ra), tau);              /* (23) */
    g = dscale(-1.0, vdot(rc_, n));             /* (8): Xs - X = g n */
    if (fo->state == NTS_STICK) t = dscale(-fo->eps_t, gt);
    else t = dscale(fo->t > 0.0 ? -fo->mu * eps : fo->mu * eps, g); /* +-mu |f_N|, |f_N| = -eps g */
    f = vscale(t, tau);
    force[0] = f;
    for (k = 0; k < m; ++k) force[k + 1] = vscale(dscale(-1.0, N[k]), f);
    /* -d f / dx, rows over the slave and the master nodes, columns over every local node */
    if ((rc = nts_kbuf_reserve(kb, 2 * (m + 1) * 2 * L.n)) != NTS_OK) return rc;
    for (q = 0; q <= m; ++q) {
        const int row_node = q == 0 ? L.node[0] : L.node[slot[q - 1]];
        for (a = 0; a < 2; ++a) {
            const dual* fa = a == 0 ? &force[q].x : &force[q].y;
            for (j = 0; j < 2 * L.n; ++j) {
                kb->rows[kb->count] = 2 * row_node + a;
                kb->cols[kb->count] = 2 * L.node[j / 2] + j % 2;
                kb->values[kb->count] = -fa->d[j];
                ++kb->count;
            }
        }
    }
    (void)w;
    return NTS_OK;
}
