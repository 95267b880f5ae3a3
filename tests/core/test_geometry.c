/* Geometry suite: shape functions, the corner polynomial and its solvers on
 * hand-computed cases (docs/model.md §2, "Closest point"). */
#include "suites.h"
#include "test_util.h"

#include <string.h>

static void test_shape_functions_sum_to_one(void) {
    static const double alphas[] = {0.0, 0.05, 0.2, 0.37, 0.5};
    int i, k;
    for (i = 0; i < 5; ++i)
        for (k = 0; k <= 20; ++k) {
            double xi = -1.0 + 0.1 * k;
            nts_shape3 n = nts_corner_shape(alphas[i], xi);
            ASSERT_NEAR(n.n2 + n.n3 + n.n4, 1.0, 1e-15);
        }
}

static void test_corner_endpoints_and_tangents(void) {
    /* X(-1) = Xa = X3 + alpha (X2 - X3), X(1) = Xb = X3 + alpha (X4 - X3),
     * dX/dxi(-1) = alpha (X3 - X2), dX/dxi(1) = alpha (X4 - X3) (docs/model.md §12, correction 4). */
    nts_vec2 x2 = nts_v2(-1.3, 0.2), x3 = nts_v2(0.1, -0.05), x4 = nts_v2(0.4, 1.7);
    double alphas[] = {0.1, 0.2, 0.5};
    int i;
    for (i = 0; i < 3; ++i) {
        double al = alphas[i];
        nts_corner k = nts_corner_make(nts_sub(x2, x3), nts_sub(x4, x3), al);
        nts_vec2 xa = nts_add(x3, nts_corner_point(k, -1.0)), xb = nts_add(x3, nts_corner_point(k, 1.0));
        nts_vec2 ta = nts_corner_tangent(k, -1.0), tb = nts_corner_tangent(k, 1.0);
        nts_shape3 n = nts_corner_shape(al, -1.0);
        ASSERT_NEAR(xa.x, x3.x + al * (x2.x - x3.x), 1e-15);
        ASSERT_NEAR(xa.y, x3.y + al * (x2.y - x3.y), 1e-15);
        ASSERT_NEAR(xb.x, x3.x + al * (x4.x - x3.x), 1e-15);
        ASSERT_NEAR(xb.y, x3.y + al * (x4.y - x3.y), 1e-15);
        ASSERT_NEAR(ta.x, al * (x3.x - x2.x), 1e-15);
        ASSERT_NEAR(ta.y, al * (x3.y - x2.y), 1e-15);
        ASSERT_NEAR(tb.x, al * (x4.x - x3.x), 1e-15);
        ASSERT_NEAR(tb.y, al * (x4.y - x3.y), 1e-15);
        /* The shape functions reproduce the same point at xi = -1. */
        ASSERT_NEAR(n.n2 * x2.x + n.n3 * x3.x + n.n4 * x4.x, xa.x, 1e-15);
        ASSERT_NEAR(n.n2, al, 1e-15);
        ASSERT_NEAR(n.n4, 0.0, 0.0);
    }
}

static void test_cubic_matches_product_form(void) {
    /* F(xi) = (Xs - X(xi)).tau(xi) equals the cubic (7) of docs/model.md §4.3. */
    nts_corner k = nts_corner_make(nts_v2(-1.0, 0.3), nts_v2(0.2, 1.1), 0.3);
    nts_vec2 d = nts_v2(0.4, -0.25);
    nts_cubic f = nts_corner_cubic(k, d);
    int i;
    for (i = 0; i <= 10; ++i) {
        double xi = -1.0 + 0.2 * i;
        double direct = nts_dot(nts_sub(d, nts_corner_point(k, xi)), nts_corner_tangent(k, xi));
        double poly = ((f.c3 * xi + f.c2) * xi + f.c1) * xi + f.c0;
        ASSERT_NEAR(poly, direct, 1e-14);
    }
}

/* Square corner at the origin, X2 = (-1, 0), X4 = (0, 1): convex, outward normal
 * at xi = 0 is (1, -1)/sqrt 2. A slave on the diagonal d = (t, -t) has F(0) = 0
 * and gap sqrt(2) (t + alpha/4) (C = alpha (-1, 1)/4). */
static void test_corner_hand_computed(void) {
    double alphas[] = {0.2, 0.5};
    int i, sv;
    for (i = 0; i < 2; ++i)
        for (sv = 0; sv < 2; ++sv) {
            double al = alphas[i], t = 0.1;
            nts_corner k = nts_corner_make(nts_v2(-1.0, 0.0), nts_v2(0.0, 1.0), al);
            nts_corner_solution s = nts_corner_solve(k, nts_v2(t, -t), (nts_solver)sv);
            CU_ASSERT(s.ok);
            ASSERT_NEAR(s.xi, 0.0, 1e-14);
            ASSERT_NEAR(s.gap, sqrt(2.0) * (t + al / 4.0), 1e-14);
            ASSERT_NEAR(s.normal.x, 1.0 / sqrt(2.0), 1e-15);
            ASSERT_NEAR(s.normal.y, -1.0 / sqrt(2.0), 1e-15);
            /* t = -0.1, within the radius of curvature at xi = 0 (about 1.41 alpha),
             * so xi = 0 is still the nearest root. */
            s = nts_corner_solve(k, nts_v2(-0.1, 0.1), (nts_solver)sv);
            ASSERT_NEAR(s.xi, 0.0, 1e-14);
            ASSERT_NEAR(s.gap, sqrt(2.0) * (-0.1 + al / 4.0), 1e-14);
        }
}

/* A node over a flat segment, and a node near a corner for alpha in {0, 0.2, 0.5},
 * through the whole evaluation. Master: the square [0,2]^2 (counter-clockwise).
 * Slave body: a small triangle whose first node pokes into the square. */
static void eval_one(double alpha, nts_vec2 tip, nts_result* res, nts_context** ctx, nts_scene** sc) {
    static test_body b[2];
    nts_options opt = nts_default_options();
    memset(b, 0, sizeof b);
    b[0].nodes[0] = nts_v2(0, 0); b[0].nodes[1] = nts_v2(2, 0);
    b[0].nodes[2] = nts_v2(2, 2); b[0].nodes[3] = nts_v2(0, 2);
    b[0].node_count = 4;
    b[1].nodes[0] = tip;
    b[1].nodes[1] = nts_add(tip, nts_v2(0.3, -1.0));
    b[1].nodes[2] = nts_add(tip, nts_v2(-0.3, -1.0));
    /* Triangle counter-clockwise: tip, lower-left, lower-right. */
    b[1].nodes[1] = nts_add(tip, nts_v2(-0.3, -1.0));
    b[1].nodes[2] = nts_add(tip, nts_v2(0.3, -1.0));
    b[1].node_count = 3;
    *sc = make_scene(b, 2, 0, 0);
    opt.alpha = alpha;
    opt.penalty = 10.0;
    opt.search_radius = 0.5;
    opt.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(*sc != NULL);
    CU_ASSERT_FATAL(eval_scene(*sc, &opt, res, ctx) == NTS_OK);
}

static const nts_contact* find_contact(const nts_result* r, int slave_body, int slave_node) {
    int i;
    for (i = 0; i < r->contact_count; ++i)
        if (r->contacts[i].slave_body == slave_body && r->contacts[i].slave_node == slave_node) return &r->contacts[i];
    return NULL;
}

static void test_node_over_flat_segment(void) {
    nts_result r;
    nts_context* ctx;
    nts_scene* s;
    const nts_contact* c;
    eval_one(0.2, nts_v2(0.7, 0.05), &r, &ctx, &s);
    c = find_contact(&r, 1, 0);
    CU_ASSERT_FATAL(c != NULL);
    CU_ASSERT(c->kind == NTS_KIND_SEGMENT);
    ASSERT_NEAR(c->gap, -0.05, 1e-15);
    ASSERT_NEAR(c->param, 0.35, 1e-15);
    ASSERT_NEAR(c->normal.y, -1.0, 0.0);
    ASSERT_NEAR(c->weights[0], 0.65, 1e-15);
    ASSERT_NEAR(c->force.y, -10.0 * -0.05 * -1.0, 1e-15); /* -eps g n: pushes down, out */
    ASSERT_NEAR(r.summary.energy, 0.5 * 10.0 * 0.05 * 0.05, 1e-16);
    /* Master nodes 0 and 1 get eps g N_k n. */
    ASSERT_NEAR(r.forces[0].y, 10.0 * -0.05 * 0.65 * -1.0, 1e-15);
    ASSERT_NEAR(r.forces[1].y, 10.0 * -0.05 * 0.35 * -1.0, 1e-15);
    ASSERT_NEAR(r.contacts[0].virial.yy, 10.0 * 0.05 * 0.05, 1e-15);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

static void test_node_near_corner(void) {
    /* Tip just inside the corner (0, 0) of the square, on its diagonal. */
    double alphas[] = {0.0, 0.2, 0.5};
    int i;
    for (i = 0; i < 3; ++i) {
        nts_result r;
        nts_context* ctx;
        nts_scene* s;
        const nts_contact* c;
        double al = alphas[i], t = 0.02;
        /* With alpha > 0 the curve cuts the corner: at xi = 0 it passes through
         * C = alpha (a + c)/4 = (alpha/2, alpha/2) for legs a = (0, 2), c = (2, 0),
         * with outward normal -(1, 1)/sqrt 2. A tip at (alpha/2 + t)(1, 1) is t sqrt 2
         * inside it. */
        double tip = al / 2.0 + t;
        eval_one(al, nts_v2(tip, tip), &r, &ctx, &s);
        c = find_contact(&r, 1, 0);
        CU_ASSERT_FATAL(c != NULL);
        if (al == 0.0) {
            /* Linear NTS: both segments give g = -t; the tie goes to the segment
             * that starts at the smaller node index (node 0: the bottom edge). */
            CU_ASSERT(c->kind == NTS_KIND_SEGMENT);
            ASSERT_INT_EQ(c->master_nodes[0], 0);
            ASSERT_NEAR(c->gap, -t, 1e-15);
        } else {
            CU_ASSERT(c->kind == NTS_KIND_CORNER);
            ASSERT_NEAR(c->param, 0.0, 1e-14);
            ASSERT_NEAR(c->normal.x, -1.0 / sqrt(2.0), 1e-14);
            ASSERT_NEAR(c->normal.y, -1.0 / sqrt(2.0), 1e-14);
            ASSERT_NEAR(c->gap, -sqrt(2.0) * t, 1e-14);
            ASSERT_NEAR(c->weights[0] + c->weights[1] + c->weights[2], 1.0, 1e-15);
            ASSERT_NEAR(c->weights[1], 1.0 - al / 2.0, 1e-15); /* N3(0) = 1 - alpha/2 */
        }
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
    }
}

static void test_vertex_candidate_outside(void) {
    /* alpha = 0, slave outside the corner (-0.1, -0.1): vertex, g = +0.1 sqrt 2. */
    nts_result r;
    nts_context* ctx;
    nts_scene* s;
    int i, found = 0;
    eval_one(0.0, nts_v2(-0.1, -0.1), &r, &ctx, &s);
    for (i = 0; i < r.gap_count; ++i) {
        const nts_contact* c = &r.gaps[i];
        if (c->slave_body == 1 && c->slave_node == 0) {
            found = 1;
            CU_ASSERT(c->kind == NTS_KIND_VERTEX);
            ASSERT_NEAR(c->gap, 0.1 * sqrt(2.0), 1e-15);
            ASSERT_NEAR(c->normal.x, -1.0 / sqrt(2.0), 1e-15);
        }
    }
    CU_ASSERT(found);
    ASSERT_INT_EQ(r.summary.contacts, 0);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

void register_geometry_suite(void) {
    CU_pSuite s = CU_add_suite("geometry", NULL, NULL);
    ADD_TEST(s, test_shape_functions_sum_to_one);
    ADD_TEST(s, test_corner_endpoints_and_tangents);
    ADD_TEST(s, test_cubic_matches_product_form);
    ADD_TEST(s, test_corner_hand_computed);
    ADD_TEST(s, test_node_over_flat_segment);
    ADD_TEST(s, test_node_near_corner);
    ADD_TEST(s, test_vertex_candidate_outside);
}
