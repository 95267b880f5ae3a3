/* Self-contact suite (issue 29, docs/model.md §16): no self-contact at rest on
 * random valid polygons (stars, combs with narrow slots, spirals, thin spikes)
 * whatever alpha, solver and radius; a horseshoe pressed shut meets itself
 * exactly where its arms overlap, with forces that are the energy's gradient
 * and a tangent that is the forces' derivative; an annulus whose hole closes;
 * a ring that meets its own periodic image; the same bits for any thread
 * count, brute force and a kept candidate list. */
#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

enum { MAXN = 4096 };
static const double PI = 3.14159265358979323846;

typedef struct shape {
    nts_vec2 p[MAXN];
    int n;
    int loop_nodes[MAXN];
    int loop_start[3];
    int loops; /* 0: one implicit loop */
} shape;

static void put(shape* s, double x, double y) {
    assert(s->n < MAXN);
    s->p[s->n++] = nts_v2(x, y);
}

/* A line from a to b in k pieces, b left out. */
static void line(shape* s, nts_vec2 a, nts_vec2 b, int k) {
    int q;
    for (q = 0; q < k; ++q) put(s, a.x + (b.x - a.x) * q / k, a.y + (b.y - a.y) * q / k);
}

/* Random star-shaped polygon: sorted angles, radii in [0.3, 1]. */
static void star(shape* s, test_rng* r, int n) {
    double t[MAXN];
    int i, j;
    s->n = 0;
    for (i = 0; i < n; ++i) t[i] = 2.0 * PI * (i + 0.9 * rng_uniform(r)) / n;
    for (i = 1; i < n; ++i) /* increasing already, by construction; keep it explicit */
        for (j = i; j > 0 && t[j] < t[j - 1]; --j) {
            double k = t[j];
            t[j] = t[j - 1];
            t[j - 1] = k;
        }
    for (i = 0; i < n; ++i) {
        double rad = 0.3 + 0.7 * rng_uniform(r);
        put(s, rad * cos(t[i]), rad * sin(t[i]));
    }
}

/* A comb: `teeth` teeth of width 1 and height 5 on a base, slots of width
 * `slot` between them, each wall in `k` pieces. Counter-clockwise. */
static void comb(shape* s, int teeth, double slot, int k) {
    const double h = 5.0, base = -1.0, pitch = 1.0 + slot;
    int t;
    s->n = 0;
    line(s, nts_v2(0.0, base), nts_v2(teeth * pitch - slot, base), k);
    for (t = teeth - 1; t >= 0; --t) {
        const double xa = t * pitch, xb = xa + 1.0;
        line(s, nts_v2(xb, t == teeth - 1 ? base : 0.0), nts_v2(xb, h), k);
        line(s, nts_v2(xb, h), nts_v2(xa, h), 2);
        line(s, nts_v2(xa, h), nts_v2(xa, t > 0 ? 0.0 : base), k);
        if (t > 0) line(s, nts_v2(xa, 0.0), nts_v2(xa - slot, 0.0), 1);
    }
}

/* A strip wound into a spiral of `turns` turns, `width` wide, gaps of 2
 * widths between its turns. Counter-clockwise. */
static void spiral(shape* s, double turns, double width, int per_turn) {
    const int m = (int)(per_turn * turns);
    int i;
    s->n = 0;
    for (i = 0; i < m; ++i) {
        const double th = 2.0 * PI * turns * i / (m - 1), r0 = 1.0 + 3.0 * width * th / (2.0 * PI);
        put(s, (r0 + width) * cos(th), (r0 + width) * sin(th));
    }
    for (i = m - 1; i >= 0; --i) {
        const double th = 2.0 * PI * turns * i / (m - 1), r0 = 1.0 + 3.0 * width * th / (2.0 * PI);
        put(s, r0 * cos(th), r0 * sin(th));
    }
}

/* `count` spikes of `deg` degrees (under 18.9, or neighbours would overlap)
 * and height 3 on a base of unit pitch, each wall in `k` pieces: a zig-zag of
 * needles with reflex corners between them. */
static void spikes(shape* s, int count, double deg, int k) {
    const double h = 3.0, half = h * tan(deg * PI / 360.0);
    int q;
    s->n = 0;
    put(s, 0.0, -1.0);
    put(s, count, -1.0);
    for (q = count - 1; q >= 0; --q) {
        const double xc = q + 0.5;
        put(s, q + 1.0, 0.0);
        line(s, nts_v2(xc + half, 0.0), nts_v2(xc, h), k);
        line(s, nts_v2(xc, h), nts_v2(xc - half, 0.0), k);
    }
}

static nts_scene* one_body(const shape* sh, int self, double lx, double ly) {
    nts_body_def d;
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    memset(&d, 0, sizeof d);
    d.nodes = sh->p;
    d.node_count = sh->n;
    if (sh->loops > 0) {
        d.loop_nodes = sh->loop_nodes;
        d.loop_start = sh->loop_start;
        d.loop_count = sh->loops;
    }
    d.self_contact = self;
    def.bodies = &d;
    def.body_count = 1;
    def.lx = lx;
    def.ly = ly;
    s = nts_scene_create(&def, &err);
    if (s == NULL) fprintf(stderr, "\n  scene: %s: %s\n", nts_status_name(err.code), err.message);
    return s;
}

static double extent(const shape* sh) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    int i;
    for (i = 0; i < sh->n; ++i) {
        x0 = fmin(x0, sh->p[i].x);
        x1 = fmax(x1, sh->p[i].x);
        y0 = fmin(y0, sh->p[i].y);
        y1 = fmax(y1, sh->p[i].y);
    }
    return fmax(x1 - x0, y1 - y0);
}

/* Active contacts and their forces' largest component. */
static int active(const nts_scene* s, const nts_options* o, nts_result* r, nts_context* ctx) {
    nts_error err;
    int rc = nts_evaluate(ctx, s, o, r, &err);
    if (rc != NTS_OK) fprintf(stderr, "\n  evaluate: %s: %s\n", nts_status_name(err.code), err.message);
    CU_ASSERT_FATAL(rc == NTS_OK);
    return r->summary.contacts;
}

static void test_none_at_rest(void) {
    static shape sh;
    test_rng rng = {29};
    nts_context* ctx = nts_context_create();
    int k, shapes = 0, evaluations = 0, found = 0, a, r, sv;
    const double alphas[3] = {0.0, 0.2, 0.5};
    for (k = 0; k < 1000; ++k) {
        nts_scene* s;
        const int kind = k % 4;
        if (kind == 0) star(&sh, &rng, 8 + (k == 400 || k == 800 ? 1992 : (int)(rng_uniform(&rng) * 400)));
        else if (kind == 1) comb(&sh, 2 + k % 4, 0.01 + 0.2 * rng_uniform(&rng), 1 + (int)(rng_uniform(&rng) * 60));
        else if (kind == 2) spiral(&sh, 1.2 + 1.3 * rng_uniform(&rng), 0.05 + 0.25 * rng_uniform(&rng), 20 + k % 200);
        else spikes(&sh, 1 + k % 4, k % 3 == 0 ? 1.0 : (k % 3 == 1 ? 5.0 : 15.0), 1 + (int)(rng_uniform(&rng) * 30));
        sh.loops = 0;
        s = one_body(&sh, 1, 0.0, 0.0);
        CU_ASSERT_FATAL(s != NULL);
        ++shapes;
        for (a = 0; a < 3; ++a)
            for (r = 0; r < 2; ++r)
                for (sv = 0; sv < 2; ++sv) {
                    nts_options o = nts_default_options();
                    nts_result res;
                    int c;
                    if ((k + a + r + sv) % 3 != 0 && k >= 40) continue; /* every case on the first 40, a third after */
                    o.alpha = alphas[a];
                    o.search_radius = r == 0 ? -1.0 : extent(&sh) / 10.0;
                    o.solver = sv ? NTS_SOLVER_NEWTON : NTS_SOLVER_CLOSED_FORM;
                    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
                    c = active(s, &o, &res, ctx);
                    ++evaluations;
                    if (c != 0) {
                        if (found < 5)
                            fprintf(stderr, "\n  at rest: shape %d (kind %d, %d nodes) alpha %g radius %g: %d contacts",
                                    k, kind, sh.n, o.alpha, o.search_radius, c);
                        ++found;
                    }
                }
        nts_scene_destroy(s);
    }
    CU_ASSERT(shapes == 1000 && evaluations > 4000);
    ASSERT_INT_EQ(found, 0);
    nts_context_destroy(ctx);
}

/* A horseshoe (a U of width 2R, arms of length L and thickness w) whose arms
 * are bent in above y = 0.2 until their inner walls are `gap` apart
 * (negative: overlapping by -gap). */
/* A horseshoe of arms `w` thick whose arms' inner walls lie `gap` apart
 * from y = 0.7 up (negative: overlapping). */
static void horseshoe_w(shape* s, double gap, double w) {
    const double R = 1.0, L = 2.0;
    const int arc = 40, arm = 20;
    int i;
    s->n = 0;
    s->loops = 0;
    for (i = 0; i < arc; ++i) put(s, R * cos(PI + PI * i / (arc - 1)), R * sin(PI + PI * i / (arc - 1)));
    for (i = 1; i < arm; ++i) put(s, R, L * i / (arm - 1));
    for (i = 0; i < arm; ++i) put(s, R - w, L * (arm - 1 - i) / (arm - 1));
    for (i = arc - 2; i >= 1; --i)
        put(s, (R - w) * cos(PI + PI * i / (arc - 1)), (R - w) * sin(PI + PI * i / (arc - 1)));
    for (i = 0; i < arm; ++i) put(s, -(R - w), L * i / (arm - 1));
    for (i = arm - 2; i >= 1; --i) put(s, -R, L * i / (arm - 1));
    for (i = 0; i < s->n; ++i) {
        const double y = s->p[i].y, f = y <= 0.2 ? 0.0 : (y >= 0.7 ? 1.0 : (y - 0.2) / 0.5);
        const double shift = f * ((R - w) - gap / 2.0);
        s->p[i].x -= (s->p[i].x > 0.0 ? 1.0 : -1.0) * shift;
    }
}

static void horseshoe(shape* s, double gap) { horseshoe_w(s, gap, 0.3); }

static void test_horseshoe_meets_itself_where_its_arms_overlap(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    const double gaps[4] = {0.05, 0.0, -0.02, -0.05};
    int g;
    for (g = 0; g < 4; ++g) {
        nts_scene *s, *off;
        nts_options o = nts_default_options();
        nts_result r;
        int c, k, expect = 0, i;
        horseshoe(&sh, gaps[g]);
        s = one_body(&sh, 1, 0.0, 0.0);
        off = one_body(&sh, 0, 0.0, 0.0);
        CU_ASSERT_FATAL(s != NULL && off != NULL);
        o.alpha = 0.2;
        o.search_radius = 0.3;
        o.penalty = 100.0;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
        /* The nodes of the inner walls where the arms overlap (y >= 0.7),
         * but the tips: a tip lies on the line of the other arm's end, at
         * distance 0 from its surface. */
        for (i = 0; i < sh.n; ++i)
            expect += gaps[g] < 0.0 && fabs(fabs(sh.p[i].x) - fabs(gaps[g]) / 2.0) < 1e-12 && sh.p[i].y >= 0.7 - 1e-12 &&
                      sh.p[i].y < 2.0 - 1e-12;
        c = active(s, &o, &r, ctx);
        ASSERT_INT_EQ(c, expect);
        for (k = 0; k < r.contact_count; ++k) {
            const nts_contact* ct = &r.contacts[k];
            const nts_vec2 x = sh.p[ct->slave_node];
            CU_ASSERT(ct->slave_body == 0 && ct->master_body == 0);
            /* the overlap itself where both walls are straight (the first
             * node above the bend meets the other wall's bend: less) */
            if (x.y >= 0.8) CU_ASSERT_DOUBLE_EQUAL(ct->gap, gaps[g], 1e-12);
            CU_ASSERT(ct->gap < 0.0 && ct->gap >= gaps[g] - 1e-12);
            /* pushed back towards its own arm's side: a node of the right
             * arm (now left of x = 0) goes right */
            CU_ASSERT((x.x < 0.0) == (r.forces[ct->slave_node].x > 0.0));
        }
        ASSERT_INT_EQ(active(off, &o, &r, ctx), 0); /* self-contact off: the overlap goes unseen */
        nts_scene_destroy(s);
        nts_scene_destroy(off);
    }
    nts_context_destroy(ctx);
}

/* Forces against -dE/dx and the tangent against -df/dx, by central
 * differences, on the pressed horseshoe. */
static void test_horseshoe_forces_and_tangent_by_differences(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_scene* s;
    nts_result r;
    nts_error err;
    nts_csr csr;
    const double h = 1e-6;
    int n, dofs, j, i, checked = 0;
    double *f0, *K, emax = 0.0, fmaxv = 0.0, kmax = 0.0, kerr = 0.0;
    nts_vec2* x;
    horseshoe(&sh, -0.03);
    s = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    n = nts_scene_node_count(s);
    dofs = 2 * n;
    o.alpha = 0.2;
    o.search_radius = 0.3;
    o.penalty = 100.0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_STIFFNESS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(r.summary.contacts > 0);
    f0 = malloc(sizeof(double) * (size_t)dofs);
    K = calloc((size_t)dofs * (size_t)dofs, sizeof(double));
    x = malloc(sizeof(nts_vec2) * (size_t)n);
    for (i = 0; i < n; ++i) {
        f0[2 * i] = r.forces[i].x;
        f0[2 * i + 1] = r.forces[i].y;
        x[i] = sh.p[i];
    }
    CU_ASSERT_FATAL(nts_triplets_to_csr(&r.stiffness, &csr, &err) == 0);
    for (i = 0; i < dofs; ++i)
        for (j = csr.row_start[i]; j < csr.row_start[i + 1]; ++j) K[(size_t)i * dofs + csr.cols[j]] = csr.values[j];
    nts_csr_free(&csr);
    for (i = 0; i < dofs * dofs; ++i) kmax = fmax(kmax, fabs(K[i]));
    for (i = 0; i < dofs; ++i) fmaxv = fmax(fmaxv, fabs(f0[i]));
    for (j = 0; j < dofs; ++j) {
        double ep = 0.0, em = 0.0, fp[2 * MAXN], fm[2 * MAXN];
        const double keep = j % 2 ? x[j / 2].y : x[j / 2].x;
        int side;
        if (fabs(f0[j]) == 0.0 && j % 7 != 0) continue; /* the nodes in contact, and a sample of the rest */
        for (side = 0; side < 2; ++side) {
            nts_result rr;
            nts_options oo = o;
            if (j % 2) x[j / 2].y = keep + (side ? -h : h);
            else x[j / 2].x = keep + (side ? -h : h);
            CU_ASSERT_FATAL(nts_scene_set_positions(s, 0, x, &err) == 0);
            oo.outputs = NTS_OUT_FORCES;
            CU_ASSERT_FATAL(nts_evaluate(ctx, s, &oo, &rr, &err) == 0);
            if (side) em = rr.summary.energy;
            else ep = rr.summary.energy;
            for (i = 0; i < n; ++i) {
                (side ? fm : fp)[2 * i] = rr.forces[i].x;
                (side ? fm : fp)[2 * i + 1] = rr.forces[i].y;
            }
        }
        if (j % 2) x[j / 2].y = keep;
        else x[j / 2].x = keep;
        emax = fmax(emax, fabs(-(ep - em) / (2.0 * h) - f0[j]));
        for (i = 0; i < dofs; ++i) kerr = fmax(kerr, fabs(-(fp[i] - fm[i]) / (2.0 * h) - K[(size_t)i * dofs + j]));
        ++checked;
    }
    CU_ASSERT_FATAL(nts_scene_set_positions(s, 0, x, &err) == 0);
    CU_ASSERT(checked > 20);
    if (!(emax <= 1e-6 * fmaxv && kerr <= 1e-6 * kmax))
        fprintf(stderr, "\n  horseshoe: |f + dE/dx| %.3g of %.3g, |K + df/dx| %.3g of %.3g", emax, fmaxv, kerr, kmax);
    CU_ASSERT(emax <= 1e-6 * fmaxv);
    CU_ASSERT(kerr <= 1e-6 * kmax);
    free(f0);
    free(K);
    free(x);
    nts_scene_destroy(s);
    nts_context_destroy(ctx);
}

/* An annulus (outer circle radius 1, hole radius `hole`), squeezed along y by
 * `sq` (y scaled by sq): below hole / 1 the hole closes, its walls overlap. */
static void annulus(shape* s, double hole, double sq, int n) {
    int i;
    s->n = 0;
    for (i = 0; i < n; ++i) put(s, cos(2.0 * PI * i / n), sq * sin(2.0 * PI * i / n));
    for (i = 0; i < n; ++i) put(s, hole * cos(-2.0 * PI * i / n), sq * hole * sin(-2.0 * PI * i / n) - 0.0);
    for (i = 0; i < 2 * n; ++i) s->loop_nodes[i] = i;
    s->loop_start[0] = 0;
    s->loop_start[1] = n;
    s->loop_start[2] = 2 * n;
    s->loops = 2;
}

static void test_annulus_whose_hole_closes(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_scene* s;
    int k, n = 64;
    o.alpha = 0.2;
    o.search_radius = 0.2;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    annulus(&sh, 0.5, 1.0, n); /* at rest */
    s = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(active(s, &o, &r, ctx), 0);
    nts_scene_destroy(s);
    /* The hole pinched through itself in the middle: y scaled by
     * 1 - 1.1 (1 - (x / 0.5)^2), -0.1 at x = 0, so that its top and bottom
     * walls cross and overlap there while its ends stay open. */
    annulus(&sh, 0.5, 1.0, n);
    for (k = n; k < 2 * n; ++k) sh.p[k].y *= 1.0 - 1.1 * (1.0 - (sh.p[k].x / 0.5) * (sh.p[k].x / 0.5));
    s = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT(active(s, &o, &r, ctx) > 0);
    for (k = 0; k < r.contact_count; ++k) {
        const nts_contact* c = &r.contacts[k];
        CU_ASSERT(c->slave_node >= n && c->master_body == 0); /* inner-loop nodes */
        CU_ASSERT(c->gap < 0.0);
    }
    nts_scene_destroy(s);
    nts_context_destroy(ctx);
}

/* With a contact surface (docs/model.md §13) the rule applies to the
 * surface's features and nodes: the horseshoe's inner walls as its surface
 * meet each other as before, its other walls take part in nothing. */
static void test_self_contact_on_a_contact_surface(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_body_def d;
    nts_scene_def def = nts_default_scene_def();
    nts_result r, whole;
    nts_error err;
    nts_scene *s, *w;
    int pairs[2 * MAXN], count = 0, i, k;
    horseshoe(&sh, -0.03);
    /* the inner walls: the segments whose both ends lie on x = +-0.015 above y = 0.7 */
    for (i = 0; i < sh.n; ++i) {
        const int j = (i + 1) % sh.n;
        if (fabs(fabs(sh.p[i].x) - 0.015) < 1e-9 && fabs(fabs(sh.p[j].x) - 0.015) < 1e-9 && sh.p[i].y > 0.69 &&
            sh.p[j].y > 0.69) {
            pairs[2 * count] = i;
            pairs[2 * count + 1] = j;
            ++count;
        }
    }
    CU_ASSERT_FATAL(count > 10);
    memset(&d, 0, sizeof d);
    d.nodes = sh.p;
    d.node_count = sh.n;
    d.self_contact = 1;
    d.surface = pairs;
    d.surface_count = count;
    def.bodies = &d;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    w = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL && w != NULL);
    o.alpha = 0.2;
    o.search_radius = 0.3;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    CU_ASSERT(active(s, &o, &r, ctx) > 0);
    for (k = 0; k < r.contact_count; ++k) CU_ASSERT_DOUBLE_EQUAL(r.contacts[k].gap, -0.03, 0.03);
    {
        nts_context* c2 = nts_context_create();
        CU_ASSERT(active(w, &o, &whole, c2) >= r.contact_count); /* the whole boundary finds these and more */
        nts_context_destroy(c2);
    }
    nts_scene_destroy(s);
    nts_scene_destroy(w);
    nts_context_destroy(ctx);
}

/* A ring in a periodic box: none while the box is wider than the ring, its
 * own image once the box is narrower. */
static void test_ring_meets_its_own_image(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    const double boxes[2] = {2.1, 1.96};
    int b, k, n = 96;
    o.alpha = 0.2;
    o.search_radius = 0.05;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    for (b = 0; b < 2; ++b) {
        nts_scene* s;
        annulus(&sh, 0.8, 1.0, n);
        s = one_body(&sh, 1, boxes[b], 6.0);
        CU_ASSERT_FATAL(s != NULL);
        if (b == 0) {
            ASSERT_INT_EQ(active(s, &o, &r, ctx), 0);
        } else {
            CU_ASSERT(active(s, &o, &r, ctx) > 0);
            for (k = 0; k < r.contact_count; ++k) {
                const nts_vec2 x = sh.p[r.contacts[k].slave_node];
                CU_ASSERT(r.contacts[k].master_body == 0 && r.contacts[k].slave_node < n && fabs(x.x) > 0.9);
            }
        }
        nts_scene_destroy(s);
    }
    nts_context_destroy(ctx);
}

/* Threads, brute force and a kept candidate list: the same bits. */
static void test_same_bits_every_way(void) {
    static shape sh;
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_candidates* kc = nts_candidates_create(-1.0);
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    nts_scene* s;
    int th, step;
    horseshoe(&sh, -0.04);
    s = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL && kc != NULL);
    o.alpha = 0.2;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    CU_ASSERT(r0.summary.contacts > 0);
    for (th = 1; th <= 3; ++th) {
        o.threads = th;
        CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
        CU_ASSERT(same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE));
    }
    /* with friction and a body's own alpha too (the records path) */
    {
        nts_options of = o;
        nts_scene* s2;
        nts_body_def d;
        nts_scene_def def = nts_default_scene_def();
        memset(&d, 0, sizeof d);
        d.nodes = sh.p;
        d.node_count = sh.n;
        d.self_contact = 1;
        d.has_alpha = 1;
        d.alpha = 0.35;
        def.bodies = &d;
        def.body_count = 1;
        s2 = nts_scene_create(&def, &err);
        CU_ASSERT_FATAL(s2 != NULL);
        of.friction = 0.3;
        of.threads = 0;
        CU_ASSERT_FATAL(nts_evaluate(c0, s2, &of, &r0, &err) == 0);
        CU_ASSERT(r0.summary.contacts > 0 && r0.anchor_count == r0.summary.contacts);
        for (th = 1; th <= 3; ++th) {
            of.threads = th;
            CU_ASSERT_FATAL(nts_evaluate(c1, s2, &of, &r1, &err) == 0);
            CU_ASSERT(same_answer(s2, &r0, &r1, NTST_SUMMARY_WHOLE));
        }
        nts_scene_destroy(s2);
        CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0); /* the reference again */
    }
    o.threads = 0;
    o.search = NTS_SEARCH_BRUTE_FORCE;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    CU_ASSERT(same_answer(s, &r0, &r1, NTST_SUMMARY_BUT_CELLS));
    o.search = NTS_SEARCH_CELLS;
    /* a walk with a kept list against searches from scratch */
    for (step = 0; step < 6; ++step) {
        test_rng rng = {100 + (unsigned long long)step};
        nts_vec2 x[MAXN];
        int i;
        for (i = 0; i < sh.n; ++i) x[i] = nts_v2(sh.p[i].x + 0.002 * (rng_uniform(&rng) - 0.5), sh.p[i].y + 0.002 * (rng_uniform(&rng) - 0.5));
        CU_ASSERT_FATAL(nts_scene_set_positions(s, 0, x, &err) == 0);
        o.candidates = NULL;
        CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
        o.candidates = kc;
        CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
        CU_ASSERT(same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE));
        CU_ASSERT(r0.summary.contacts > 0);
    }
    nts_candidates_destroy(kc);
    nts_scene_destroy(s);
    nts_context_destroy(c0);
    nts_context_destroy(c1);
}

/* Friction's anchors of a body on itself (the horseshoe's arms rubbing):
 * an evaluation gives them, and nts_history_set takes them back, as a
 * stateless request's "history" or `ntscontact --history-in` gives what
 * `--history-out` wrote (it refused them: "no such pair of bodies", and
 * a distributed scene, which carries its history that way, failed its
 * second step); the next step with the set history is the committed one's,
 * bit for bit. A body without self-contact still has no pair with itself,
 * and no own feature may hold the slave node ((T) of §16). */
static void test_self_contact_history_round_trip(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_history *h = nts_history_create(), *back = nts_history_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    nts_scene *s, *off;
    const nts_anchor* a;
    nts_anchor bad;
    int count = 0, k, self_pairs = 0, i;
    nts_vec2 x[MAXN];
    horseshoe(&sh, -0.03);
    s = one_body(&sh, 1, 0.0, 0.0);
    off = one_body(&sh, 0, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL && off != NULL && ctx != NULL && h != NULL && back != NULL);
    o.alpha = 0.2;
    o.search_radius = 0.3;
    o.penalty = 100.0;
    o.friction = 0.3;
    o.outputs = NTS_OUT_ALL;
    o.history = h;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r0, &err) == 0);
    CU_ASSERT_FATAL(nts_history_commit(h, &r0) == 0);
    a = nts_history_anchors(h, &count);
    for (k = 0; k < count; ++k) self_pairs += a[k].slave_body == 0 && a[k].master_body == 0;
    CU_ASSERT_FATAL(count > 0 && self_pairs == count);
    ASSERT_INT_EQ(nts_history_set(back, s, a, count, &err), NTS_OK);
    /* a step on: slid along the arms, the committed history and the set one */
    for (i = 0; i < sh.n; ++i) x[i] = nts_v2(sh.p[i].x, sh.p[i].y + (sh.p[i].x > 0.0 ? 0.01 : 0.0));
    CU_ASSERT_FATAL(nts_scene_set_positions(s, 0, x, &err) == 0);
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r0, &err) == 0);
    o.history = back;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r1, &err) == 0);
    CU_ASSERT(same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE));
    CU_ASSERT(r1.summary.contacts > 0);
    o.history = NULL; /* (the history matters: without it, other forces) */
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r1, &err) == 0);
    CU_ASSERT(!same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE));
    /* refused: the same anchor on the body without self-contact, and one
     * whose feature holds its slave node */
    bad = a[0];
    ASSERT_INT_EQ(nts_history_set(back, off, &bad, 1, &err), NTS_EINVALID_HISTORY);
    CU_ASSERT(strstr(err.message, "no such pair of bodies") != NULL);
    bad.nodes[0] = bad.slave_node;
    bad.nodes[1] = (bad.slave_node + 1) % sh.n;
    bad.nodes[2] = -1;
    bad.kind = NTS_KIND_SEGMENT;
    ASSERT_INT_EQ(nts_history_set(back, s, &bad, 1, &err), NTS_EINVALID_HISTORY);
    CU_ASSERT(strstr(err.message, "holds the slave node") != NULL);
    nts_history_destroy(h);
    nts_history_destroy(back);
    nts_scene_destroy(s);
    nts_scene_destroy(off);
    nts_context_destroy(ctx);
}

/* A strip `width` thick wound 1.5 turns, its radius growing by `width -
 * overlap` a turn: along its last half turn the outer layer lies `overlap`
 * into the inner one. Counter-clockwise. */
static void coil(shape* s, double width, double overlap, int per_turn) {
    const double turns = 1.5, pitch = width - overlap;
    const int m = (int)(per_turn * turns);
    int i;
    s->n = 0;
    s->loops = 0;
    for (i = 0; i < m; ++i) {
        const double th = 2.0 * PI * turns * i / (m - 1), r0 = 1.0 + pitch * th / (2.0 * PI);
        put(s, (r0 + width) * cos(th), (r0 + width) * sin(th));
    }
    for (i = m - 1; i >= 0; --i) {
        const double th = 2.0 * PI * turns * i / (m - 1), r0 = 1.0 + pitch * th / (2.0 * PI);
        put(s, r0 * cos(th), r0 * sin(th));
    }
}

/* The doubled layer of a coil (docs/model.md §16): a node on either outer
 * face lies behind the far face of the other layer, with opposed normals,
 * and the midpoint of the two is in the overlap (coverage 2); but its
 * nearest opposed face is its own layer's other face, whose midpoint is
 * not: it has no self-contact. Only the overlap itself is in contact, the
 * same contacts and energy whatever the radius (the default's growth
 * included) and alpha's corners, and the energy grows from zero as the
 * layers first touch. (Asking (C) of each feature found the far faces:
 * gaps of -(2 width - overlap), energies 100 times the overlap's, and a
 * default radius that missed some.) */
static void test_coil_meets_itself_only_in_its_overlap(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_candidates* kc = nts_candidates_create(-1.0);
    const double width = 0.3, overlaps[3] = {0.05, 0.005, 0.0005}, radii[4] = {-1.0, 0.3, 0.6, 2.0};
    const double alphas[2] = {0.0, 0.2};
    int v, a, q;
    for (v = 0; v < 3; ++v)
        for (a = 0; a < 2; ++a) {
            nts_scene* s;
            double e0 = 0.0;
            int c0 = -1;
            coil(&sh, width, overlaps[v], 120);
            s = one_body(&sh, 1, 0.0, 0.0);
            CU_ASSERT_FATAL(s != NULL);
            for (q = 0; q < 5; ++q) {
                nts_options o = nts_default_options();
                nts_result r;
                int c, k;
                o.alpha = alphas[a];
                o.search_radius = radii[q < 4 ? q : 3];
                o.penalty = 100.0;
                o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS | NTS_OUT_ENERGY;
                if (q == 4) o.candidates = kc; /* built at the largest radius, then replayed */
                c = active(s, &o, &r, ctx);
                if (q == 4) c = active(s, &o, &r, ctx);
                CU_ASSERT(c > 0);
                for (k = 0; k < r.contact_count; ++k) {
                    /* within the overlap (and the chords' sag), never through a layer */
                    CU_ASSERT(r.contacts[k].gap < 0.0 && r.contacts[k].gap > -(overlaps[v] + 0.01));
                    CU_ASSERT(r.contacts[k].slave_body == 0 && r.contacts[k].master_body == 0);
                }
                if (q == 0) {
                    c0 = c;
                    e0 = r.summary.energy;
                    /* eps g^2 / 2 a node of the overlap, at most */
                    CU_ASSERT(e0 <= c * 0.5 * o.penalty * (overlaps[v] + 0.01) * (overlaps[v] + 0.01));
                } else {
                    ASSERT_INT_EQ(c, c0);
                    CU_ASSERT_DOUBLE_EQUAL(r.summary.energy, e0, 1e-12 * e0);
                }
            }
            nts_candidates_clear(kc);
            nts_scene_destroy(s);
        }
    nts_candidates_destroy(kc);
    nts_context_destroy(ctx);
}

/* A strip folded into a U whose upper arm is tilted down into the lower
 * one: the overlap grows from o0 at the fold to o1 at the upper arm's end
 * (x = end), far deeper than the default radius there. The lower arm
 * spans y in [-w, 0] and x in [0, 2], the upper arm's lower face runs from
 * (0, -o0) to (end, -o1), each face in `k` pieces. Counter-clockwise. */
/* A loop through corners[0..count) (back to the first), each side in
 * pieces[f] pieces. (Not line(): inlined with a constant count, GCC 12.2's
 * vectoriser miscompiled that loop here at -O2 and -O3.) */
static void polygon_in_pieces(shape* s, const double (*corners)[2], const int* pieces, int count) {
    int f, q;
    s->n = 0;
    s->loops = 0;
    for (f = 0; f < count; ++f) {
        const double* a = corners[f];
        const double* b = corners[(f + 1) % count];
        for (q = 0; q < pieces[f]; ++q)
            put(s, a[0] + (b[0] - a[0]) * q / pieces[f], a[1] + (b[1] - a[1]) * q / pieces[f]);
    }
}

static void tilted_fold(shape* s, double o0, double o1, double end) {
    const double w = 0.3, L = 2.0;
    const double corner[8][2] = {{L, 0.0}, {0.0, 0.0}, {0.0, -o0}, {end, -o1}, {end, w - o1}, {-w, w - o0}, {-w, -w}, {L, -w}};
    static const int pieces[8] = {20, 2, 20, 4, 20, 6, 20, 4};
    polygon_in_pieces(s, corner, pieces, 8);
}

/* dst: src turned by th about the origin, scaled and moved by (shift, -3 shift). */
static void turned(shape* dst, const shape* src, double th, double scale, double shift) {
    int k;
    dst->n = 0;
    dst->loops = 0;
    for (k = 0; k < src->n; ++k)
        put(dst, shift + scale * (src->p[k].x * cos(th) - src->p[k].y * sin(th)),
            -3.0 * shift + scale * (src->p[k].x * sin(th) + src->p[k].y * cos(th)));
}

/* A loop that meets itself deeper than the search radius: the same contacts
 * and energy whichever node the loop starts at. The pair that closes the
 * loop was not compared for the growth of the reach (search.c,
 * reach_neighbours): the tilted fold then gave 4 starts of its 96 (two at
 * each alpha) other answers (29, 37, 21 or 25 contacts). Every contact lies
 * in the overlap: a node of the lower arm's upper face under the upper arm,
 * pushed out through the upper arm's lower face, or one of that face over
 * the lower arm, pushed out through y = 0. */
static void test_a_fold_is_the_same_from_any_start(void) {
    static shape sh, turned;
    const double alphas[2] = {0.0, 0.2}, o0 = 0.02, o1 = 0.25, end = 1.55;
    nts_context* ctx = nts_context_create();
    int a, off, k;
    tilted_fold(&sh, o0, o1, end);
    for (a = 0; a < 2; ++a) {
        double e0 = 0.0;
        int c0 = -1;
        for (off = 0; off < sh.n; ++off) {
            nts_options o = nts_default_options();
            nts_result r;
            nts_scene* s;
            int c;
            turned.n = 0;
            turned.loops = 0;
            for (k = 0; k < sh.n; ++k) put(&turned, sh.p[(k + off) % sh.n].x, sh.p[(k + off) % sh.n].y);
            s = one_body(&turned, 1, 0.0, 0.0);
            CU_ASSERT_FATAL(s != NULL);
            o.alpha = alphas[a];
            o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
            c = active(s, &o, &r, ctx);
            if (off == 0) {
                c0 = c;
                e0 = r.summary.energy;
                CU_ASSERT(c >= 30 && r.summary.deep_contacts >= 10);
                for (k = 0; k < r.contact_count; ++k) {
                    const nts_contact* ct = &r.contacts[k];
                    const nts_vec2 x = turned.p[ct->slave_node];
                    const double under = -o0 + (o0 - o1) * x.x / end; /* the upper arm's lower face */
                    CU_ASSERT(ct->slave_body == 0 && ct->master_body == 0 && ct->gap < 0.0);
                    CU_ASSERT(x.x >= -1e-12 && x.x <= end + 1e-12 && x.y <= 1e-12 && x.y >= under - 1e-12);
                    /* no deeper than the overlap where the node lies */
                    CU_ASSERT(ct->gap >= under - 1e-9);
                }
            } else {
                ASSERT_INT_EQ(c, c0);
                CU_ASSERT_DOUBLE_EQUAL(r.summary.energy, e0, 1e-12 * e0);
            }
            nts_scene_destroy(s);
        }
    }
    nts_context_destroy(ctx);
}

/* (C) at a fold's corners (docs/model.md §16). A strip folded into a U whose
 * arms overlap by 0.05 (8 nodes): at alpha 0 the three nodes of the overlap,
 * each at -0.05, at every angle of 72 and with the body moved by 1e7 and
 * scaled by 1e6 (the midpoint rule gave 15 sets of contacts over the angles,
 * among them the lower arm's end node at -3 against the fold's inner
 * segment, whose midpoint lies on the arm's own face); the same refined. At
 * alpha 0.1 the same three, at the default radius and at 3 (the midpoint
 * rule gave none; the first rule of a way covered twice held the fold's
 * inner corner at -2.5 against the upper arm's end, along the overlap,
 * when the flat it meets stopped short of the neighbour's corner).
 * And a ten-node fold whose node 9 lies where the body covers itself once
 * (it penetrates nothing) has no contact there, from any start (the
 * midpoint rule gave it -0.087 against a corner across a layer). */
static void test_a_fold_is_the_same_at_every_angle(void) {
    static const double u[8][2] = {{3.0, 0.0},  {0.0, 0.0},  {0.0, -0.05}, {2.5, -0.05},
                                   {2.5, 0.2},  {-0.3, 0.2}, {-0.3, -0.3}, {3.0, -0.3}};
    static const double xy[10][2] = {{3.797, 0.738}, {2.679, 0.727}, {3.996, 0.724}, {4.066, 0.724},
                                     {3.787, 0.778}, {3.572, 0.684}, {3.628, 0.684}, {3.684, 0.684},
                                     {3.741, 0.684}, {3.797, 0.684}};
    static const int ones[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    static shape sh, ref;
    nts_context* ctx = nts_context_create();
    int v, q, k, off;
    polygon_in_pieces(&ref, u, ones, 8);
    for (v = 0; v < 2; ++v)
        for (q = 0; q < 72; ++q) {
            nts_options o = nts_default_options();
            nts_result r;
            nts_scene* s;
            const double scale = v ? 1e6 : 1.0;
            int seen[8] = {0};
            turned(&sh, &ref, 5.0 * q * PI / 180.0, scale, v ? 1e7 : 0.0);
            s = one_body(&sh, 1, 0.0, 0.0);
            CU_ASSERT_FATAL(s != NULL);
            o.alpha = 0.0;
            o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
            ASSERT_INT_EQ(active(s, &o, &r, ctx), 3);
            for (k = 0; k < r.contact_count; ++k) {
                CU_ASSERT_DOUBLE_EQUAL(r.contacts[k].gap, -0.05 * scale, 1e-9 * scale);
                seen[r.contacts[k].slave_node] = 1;
            }
            CU_ASSERT(seen[1] && seen[2] && seen[3]);
            nts_scene_destroy(s);
        }
    /* The same U refined (faces of 10 pieces, the fold's inner face of two,
     * bowed so that no normal is square to another): its corner nodes' closest
     * points are the inner face's far end, a neighbour's neighbour, which no
     * vertex offers them (each lies on the line of the segment before that
     * end); their flats reach that end whatever the round-off. The same 19
     * contacts at every angle and frame, among them both corners. */
    {
        static const double c[9][2] = {{2.0, 0.0},   {0.0, 0.0},   {-0.002, -0.012}, {0.0, -0.03}, {1.55, -0.03},
                                       {1.55, 0.27}, {-0.3, 0.27}, {-0.3, -0.3},     {2.0, -0.3}};
        static const int pieces[9] = {10, 1, 1, 10, 3, 10, 4, 10, 3};
        int first[64], count0 = -1;
        polygon_in_pieces(&ref, c, pieces, 9);
        CU_ASSERT_FATAL(ref.n <= 64);
        for (v = 0; v < 2; ++v)
            for (q = 0; q < 72; ++q) {
                nts_options o = nts_default_options();
                nts_result r;
                nts_scene* s;
                const double scale = v ? 1e6 : 1.0;
                int master[64];
                turned(&sh, &ref, 5.0 * q * PI / 180.0, scale, v ? 1e7 : 0.0);
                s = one_body(&sh, 1, 0.0, 0.0);
                CU_ASSERT_FATAL(s != NULL);
                o.alpha = 0.0;
                o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
                for (k = 0; k < ref.n; ++k) master[k] = -1;
                ASSERT_INT_EQ(active(s, &o, &r, ctx), 19);
                for (k = 0; k < r.contact_count; ++k) {
                    CU_ASSERT_DOUBLE_EQUAL(r.contacts[k].gap, -0.03 * scale, 1e-9 * scale);
                    master[r.contacts[k].slave_node] = r.contacts[k].master_nodes[0];
                }
                CU_ASSERT(master[10] == 12 && master[12] == 9); /* the corners: (0, 0) and (0, -0.03) */
                if (count0 < 0) {
                    count0 = r.contact_count;
                    memcpy(first, master, sizeof master);
                } else {
                    CU_ASSERT(memcmp(first, master, sizeof master) == 0);
                }
                nts_scene_destroy(s);
            }
    }
    {
        nts_options o = nts_default_options();
        nts_result r;
        nts_scene* s;
        polygon_in_pieces(&ref, u, ones, 8);
        s = one_body(&ref, 1, 0.0, 0.0);
        CU_ASSERT_FATAL(s != NULL);
        o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
        for (v = 0; v < 2; ++v) { /* alpha 0.1 at the default radius and at 3, past the arm's length */
            int seen[8] = {0};
            o.alpha = 0.1;
            o.search_radius = v ? 3.0 : -1.0;
            ASSERT_INT_EQ(active(s, &o, &r, ctx), 3);
            for (k = 0; k < r.contact_count; ++k) {
                CU_ASSERT(r.contacts[k].kind == NTS_KIND_SEGMENT);
                CU_ASSERT_DOUBLE_EQUAL(r.contacts[k].gap, -0.05, 1e-12);
                seen[r.contacts[k].slave_node] = 1;
            }
            CU_ASSERT(seen[1] && seen[2] && seen[3]);
        }
        nts_scene_destroy(s);
    }
    for (off = 0; off < 10; ++off) {
        nts_options o = nts_default_options();
        nts_result r;
        nts_scene* s;
        sh.n = 0;
        sh.loops = 0;
        for (k = 0; k < 10; ++k) put(&sh, xy[(k + off) % 10][0], xy[(k + off) % 10][1]);
        s = one_body(&sh, 1, 0.0, 0.0);
        CU_ASSERT_FATAL(s != NULL);
        o.alpha = 0.2;
        o.penalty = 10.0;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
        ASSERT_INT_EQ(active(s, &o, &r, ctx), 1);
        CU_ASSERT(r.contacts[0].slave_node == (10 - off) % 10); /* the first node of the list, xy[0] */
        CU_ASSERT_DOUBLE_EQUAL(r.contacts[0].gap, -0.01355, 1e-5);
        nts_scene_destroy(s);
    }
    nts_context_destroy(ctx);
}

/* Two ways (C) must not take (docs/model.md §16), found by an adversarial
 * try of its first version. A coarse U whose upper arm is tilted into the
 * lower one (overlap 0.1 to 0.2, alpha 0.2): its fold's corners were held
 * at -2 against the upper arm's end, a way along the overlap, covered twice
 * all its length, because the flat they meet stopped short of their
 * neighbour's corner; no contact may be deeper than the overlap. And two
 * self-crossing snakes (alpha 0 and 0.1) where a node was held against the
 * vertex or corner two nodes before it, its way out through its own side
 * (the face it leaves by was taken for one of the feature's), where the
 * mirror image had none: none in either. */
static void test_no_way_through_a_layer(void) {
    static const double tilted[8][2] = {{3.0, 0.0}, {0.0, 0.0},  {0.0, -0.1},  {2.0, -0.2},
                                        {2.0, 0.2}, {-0.4, 0.3}, {-0.4, -0.4}, {3.0, -0.4}};
    static const double snake_v[7][2] = {{-0.11, 0.23}, {-0.99, -0.39}, {0.34, -0.58}, {-0.41, 0.99},
                                         {-0.06, -0.27}, {-0.49, -0.3}, {0.11, -0.23}};
    static const double snake_c[6][2] = {{2.88, -3.189}, {4.237, -2.502}, {3.286, -2.19},
                                         {3.658, -2.457}, {3.29, -2.778},  {3.694, -2.337}};
    static shape sh;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_scene* s;
    int k, m, c;
    sh.n = 0;
    sh.loops = 0;
    for (k = 0; k < 8; ++k) put(&sh, tilted[k][0], tilted[k][1]);
    s = one_body(&sh, 1, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    o.alpha = 0.2;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    c = active(s, &o, &r, ctx);
    CU_ASSERT(c >= 1);
    for (k = 0; k < r.contact_count; ++k) CU_ASSERT(r.contacts[k].gap >= -0.2 - 1e-12);
    nts_scene_destroy(s);
    for (m = 0; m < 4; ++m) { /* each snake and its mirror image */
        const int n = m < 2 ? 7 : 6;
        sh.n = 0;
        for (k = 0; k < n; ++k) {
            /* the mirror (x -> -x) reverses the loop: its nodes taken backwards keep it counter-clockwise */
            const double* q = m < 2 ? snake_v[m == 0 ? k : n - 1 - k] : snake_c[m == 2 ? k : n - 1 - k];
            put(&sh, m % 2 ? -q[0] : q[0], q[1]);
        }
        s = one_body(&sh, 1, 0.0, 0.0);
        CU_ASSERT_FATAL(s != NULL);
        o = nts_default_options();
        o.alpha = m < 2 ? 0.0 : 0.1;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
        ASSERT_INT_EQ(active(s, &o, &r, ctx), 0);
        nts_scene_destroy(s);
    }
    nts_context_destroy(ctx);
}

/* Arms thinner than the opening between them: a node of an arm's inner
 * wall lies behind its own arm's outer wall (a penetration of 0.05 that
 * (C) refuses) and 0.2 in front of the other arm's inner wall, a gap that
 * needs no coverage: its record is that gap (the gaps output), as without
 * the thin wall. (Holding the closest of all candidates for (C) lost it.) */
static void test_thin_arms_keep_their_gap_across_the_opening(void) {
    static shape sh;
    nts_context* ctx = nts_context_create();
    const double alphas[2] = {0.0, 0.2};
    int a, k, i, want = 0, found;
    horseshoe_w(&sh, 0.2, 0.05);
    for (i = 0; i < sh.n; ++i) want += fabs(fabs(sh.p[i].x) - 0.1) < 1e-12 && sh.p[i].y >= 0.8 && sh.p[i].y < 1.9;
    CU_ASSERT_FATAL(want >= 10);
    for (a = 0; a < 2; ++a) {
        nts_scene* s = one_body(&sh, 1, 0.0, 0.0);
        nts_options o = nts_default_options();
        nts_result r;
        nts_error err;
        CU_ASSERT_FATAL(s != NULL);
        o.alpha = alphas[a];
        o.search_radius = 0.3;
        o.outputs = NTS_OUT_GAPS | NTS_OUT_CONTACTS;
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == NTS_OK);
        ASSERT_INT_EQ(r.contact_count, 0);
        found = 0;
        for (i = 0; i < sh.n; ++i) {
            int got = 0;
            if (!(fabs(fabs(sh.p[i].x) - 0.1) < 1e-12 && sh.p[i].y >= 0.8 && sh.p[i].y < 1.9)) continue;
            for (k = 0; k < r.gap_count; ++k)
                if (r.gaps[k].slave_node == i && r.gaps[k].master_body == 0 && fabs(r.gaps[k].gap - 0.2) < 1e-9) got = 1;
            found += got;
        }
        ASSERT_INT_EQ(found, want);
        nts_scene_destroy(s);
    }
    nts_context_destroy(ctx);
}

static void test_self_contact_is_zero_or_one(void) {
    static shape sh;
    nts_body_def d;
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    star(&sh, &(test_rng){7}, 12);
    memset(&d, 0, sizeof d);
    d.nodes = sh.p;
    d.node_count = sh.n;
    d.self_contact = 2;
    def.bodies = &d;
    def.body_count = 1;
    CU_ASSERT(nts_scene_create(&def, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_EINVALID_OPTION);
    CU_ASSERT(strcmp(err.option, "self_contact") == 0);
}

void register_self_contact_suite(void) {
    CU_pSuite s = CU_add_suite("self_contact", NULL, NULL);
    ADD_TEST(s, test_none_at_rest);
    ADD_TEST(s, test_horseshoe_meets_itself_where_its_arms_overlap);
    ADD_TEST(s, test_horseshoe_forces_and_tangent_by_differences);
    ADD_TEST(s, test_coil_meets_itself_only_in_its_overlap);
    ADD_TEST(s, test_thin_arms_keep_their_gap_across_the_opening);
    ADD_TEST(s, test_a_fold_is_the_same_from_any_start);
    ADD_TEST(s, test_a_fold_is_the_same_at_every_angle);
    ADD_TEST(s, test_no_way_through_a_layer);
    ADD_TEST(s, test_annulus_whose_hole_closes);
    ADD_TEST(s, test_self_contact_on_a_contact_surface);
    ADD_TEST(s, test_ring_meets_its_own_image);
    ADD_TEST(s, test_same_bits_every_way);
    ADD_TEST(s, test_self_contact_is_zero_or_one);
    ADD_TEST(s, test_self_contact_history_round_trip);
}
