/* Search suite: the cell list finds exactly the contacts brute force finds (the
 * search-radius rule makes the answer independent of binning); continuity of
 * the force direction along a path past a corner. */
#include <stdlib.h>
#include <string.h>

#include <ntscontact/distributed.h>

#include "suites.h"
#include "test_util.h"

static void compare_cells_and_brute(int periodic, double alpha, nts_solver solver, double radius) {
    /* 100 bodies x 24 nodes = 2,400 surface nodes. */
    test_packing p = make_packing(100, 24, 1.0, 1.93, periodic, 71 + (unsigned)periodic);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_options o = nts_default_options();
    nts_result rc, rb;
    nts_context *cc = nts_context_create(), *cb = nts_context_create();
    nts_error err;
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT(nts_scene_surface_node_count(s) >= 2000);
    o.alpha = alpha;
    o.solver = solver;
    o.search_radius = radius;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(cc, s, &o, &rc, &err) == 0);
    o.search = NTS_SEARCH_BRUTE_FORCE;
    CU_ASSERT_FATAL(nts_evaluate(cb, s, &o, &rb, &err) == 0);
    CU_ASSERT(rc.summary.cell_size > 0.0);
    CU_ASSERT(rc.gap_count > rc.contact_count);
    CU_ASSERT(rc.contact_count > 100);
    ASSERT_INT_EQ(rc.gap_count, rb.gap_count);
    ASSERT_INT_EQ(rc.contact_count, rb.contact_count);
    /* Same records, bitwise, in the same order. */
    CU_ASSERT(rc.gap_count == rb.gap_count &&
              memcmp(rc.gaps, rb.gaps, sizeof(nts_contact) * (size_t)rc.gap_count) == 0);
    CU_ASSERT(memcmp(rc.forces, rb.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s)) == 0);
    CU_ASSERT(rc.summary.energy == rb.summary.energy);
    nts_context_destroy(cc);
    nts_context_destroy(cb);
    nts_scene_destroy(s);
    free_packing(&p);
}

static void test_cells_equal_brute_force_open(void) {
    compare_cells_and_brute(0, 0.2, NTS_SOLVER_CLOSED_FORM, -1.0);
    compare_cells_and_brute(0, 0.0, NTS_SOLVER_CLOSED_FORM, -1.0);
    compare_cells_and_brute(0, 0.5, NTS_SOLVER_NEWTON, 0.6);
}

static void test_cells_equal_brute_force_periodic(void) {
    compare_cells_and_brute(1, 0.2, NTS_SOLVER_CLOSED_FORM, -1.0);
    compare_cells_and_brute(1, 0.0, NTS_SOLVER_NEWTON, 0.05);
    compare_cells_and_brute(1, 0.1, NTS_SOLVER_NEWTON, 1.5);
}

static void test_far_apart_bodies_bounded_grid(void) {
    /* Two bodies 1e9 apart with unit segments: the grid stays O(N) (it would
     * need 1e18 cells at h = L + r), and no contact is found. */
    test_body b[2];
    nts_scene* s;
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx;
    make_polygon(&b[0], 8, 1.0, nts_v2(0, 0), 0.0);
    make_polygon(&b[1], 8, 1.0, nts_v2(1e9, 1e9), 0.0);
    s = make_scene(b, 2, 0, 0);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT_FATAL(eval_scene(s, &o, &r, &ctx) == 0);
    ASSERT_INT_EQ(r.summary.gaps, 0);
    CU_ASSERT(r.summary.cell_size > 1e7);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

/* A slave node slides along a path that passes a corner of the master at a
 * constant depth, in small steps; returns the largest change of the force
 * direction (radians) between consecutive steps. The master is a square with
 * one corner convex (at (0,0)) and a notch with a concave corner. */
static double max_turn(double alpha, int concave, int steps, double* jump_at_corner) {
    test_body b[2];
    nts_options o = nts_default_options();
    double worst = 0.0, prev_angle = 0.0;
    int i, have_prev = 0;
    memset(b, 0, sizeof b);
    if (!concave) {
        /* Master square [0,1]^2; the slave moves around the corner (0, 0) on the
         * circle of radius 0.05 (inside) from angle 180 to 270 degrees, offset to
         * stay inside: centre (0.08, 0.08). */
        b[0].nodes[0] = nts_v2(0, 0); b[0].nodes[1] = nts_v2(1, 0);
        b[0].nodes[2] = nts_v2(1, 1); b[0].nodes[3] = nts_v2(0, 1);
        b[0].node_count = 4;
    } else {
        /* L-shaped master with a reflex (concave) corner at (0.5, 0.5). */
        b[0].nodes[0] = nts_v2(0, 0); b[0].nodes[1] = nts_v2(1, 0);
        b[0].nodes[2] = nts_v2(1, 0.5); b[0].nodes[3] = nts_v2(0.5, 0.5);
        b[0].nodes[4] = nts_v2(0.5, 1); b[0].nodes[5] = nts_v2(0, 1);
        b[0].node_count = 6;
    }
    *jump_at_corner = 0.0;
    for (i = 0; i <= steps; ++i) {
        double u = (double)i / steps;
        nts_vec2 tip;
        nts_scene* s;
        nts_result r;
        nts_context* ctx;
        int k;
        if (!concave) {
            /* Straight line y = x - 0.3 ... crossing under the corner region: a
             * path parallel to the diagonal's normal at depth 0.02 inside. */
            tip = nts_v2(0.02 + 0.3 * (u - 0.5), 0.02 - 0.3 * (u - 0.5));
            tip = nts_add(tip, nts_v2(0.25 * alpha, 0.25 * alpha));
        } else {
            /* Along the line x + y = 1 - 0.04 near the reflex corner, inside. */
            tip = nts_v2(0.48 + 0.3 * (u - 0.5), 0.48 - 0.3 * (u - 0.5));
        }
        b[1].nodes[0] = tip;
        b[1].nodes[1] = nts_add(tip, nts_v2(-0.3, -1.0));
        b[1].nodes[2] = nts_add(tip, nts_v2(0.3, -1.0));
        if (concave) {
            /* Poke from outside the L into the notch: triangle pointing down-left. */
            b[1].nodes[1] = nts_add(tip, nts_v2(1.0, 0.3));
            b[1].nodes[2] = nts_add(tip, nts_v2(0.3, 1.0));
        } else {
            b[1].nodes[1] = nts_add(tip, nts_v2(-1.0, -0.3));
            b[1].nodes[2] = nts_add(tip, nts_v2(-0.3, -1.0));
        }
        b[1].node_count = 3;
        s = make_scene(b, 2, 0, 0);
        CU_ASSERT_FATAL(s != NULL);
        o.alpha = alpha;
        o.search_radius = 0.2;
        o.outputs = NTS_OUT_ALL;
        CU_ASSERT_FATAL(eval_scene(s, &o, &r, &ctx) == 0);
        for (k = 0; k < r.contact_count; ++k) {
            const nts_contact* c = &r.contacts[k];
            if (c->slave_body == 1 && c->slave_node == 0) {
                double ang = atan2(c->force.y, c->force.x);
                if (have_prev) {
                    double d = fabs(ang - prev_angle);
                    if (d > 3.14159265358979) d = 2 * 3.14159265358979 - d;
                    if (d > worst) worst = d;
                }
                prev_angle = ang;
                have_prev = 1;
            }
        }
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
    }
    *jump_at_corner = worst;
    return worst;
}

static void test_force_direction_is_continuous_with_smoothing(void) {
    int concave;
    for (concave = 0; concave < 2; ++concave) {
        double j0, j1, j2, jlin;
        double t1 = max_turn(0.2, concave, 200, &j1);
        double t2 = max_turn(0.2, concave, 400, &j2);
        double tl = max_turn(0.0, concave, 400, &jlin);
        (void)j0;
        /* Smoothed: the turn per step is O(step): halving the step halves it. */
        CU_ASSERT(t1 < 0.1);
        CU_ASSERT(t2 < 0.6 * t1);
        if (!concave) {
            /* Linear NTS at a convex corner: the normal jumps by 90 degrees between
             * the two segments whatever the step (the problem the smoothing fixes). */
            CU_ASSERT(tl > 1.5);
        } else {
            /* Inside a reflex corner linear NTS falls back on the vertex, whose
             * normal is radial: no jump, but it turns 90 degrees over a distance of
             * the order of the depth, several times faster than the smoothed one. */
            CU_ASSERT(tl > 3.0 * t2);
        }
        fprintf(stderr, "[continuity %s: alpha 0.2 max turn %.4g rad (200 steps), %.4g (400); alpha 0: %.4g]\n",
                concave ? "concave" : "convex", t1, t2, tl);
    }
}

/* nts_scene_frame without the median and the cells (a distributed host's
 * own bodies: a radius given, the brute-force search) takes the lengths and
 * extremes alone, without the segment data: the same lengths and extremes,
 * bit for bit, as the full pass, and the same error at a bad segment. */
static int same_bits(const void* a, const void* b, size_t n) { return memcmp(a, b, n) == 0; }

static void test_frame_lengths_alone(void) {
    int periodic, size;
    for (periodic = 0; periodic < 2; ++periodic)
        for (size = 0; size < 2; ++size) {
            /* 3 disks: fewer entries than the pass's 64 slices; 400: many in each */
            test_packing p = make_packing(size ? 400 : 3, 48, 1.0, 1.93, periodic, 990u + (unsigned)(2 * size + periodic));
            nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
            nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
            nts_options full = nts_default_options(), light = nts_default_options();
            const int n = nts_scene_surface_node_count(s);
            double* l0 = (double*)malloc(sizeof(double) * (size_t)n);
            double* l1 = (double*)malloc(sizeof(double) * (size_t)n);
            nts_frame f0, f1, f2;
            nts_error e0, e1;
            nts_vec2 node[48];
            light.search_radius = 0.0;
            light.search = NTS_SEARCH_BRUTE_FORCE;
            CU_ASSERT_FATAL(s != NULL && c0 != NULL && c1 != NULL && l0 != NULL && l1 != NULL);
            CU_ASSERT_EQUAL(nts_scene_frame(c0, s, &full, &f0, l0, &e0), NTS_OK);
            CU_ASSERT_EQUAL(nts_scene_frame(c1, s, &light, &f1, l1, &e1), NTS_OK);
            CU_ASSERT_EQUAL(nts_scene_frame(c1, s, &light, &f2, NULL, &e1), NTS_OK);
            CU_ASSERT(same_bits(l0, l1, sizeof(double) * (size_t)n));
            CU_ASSERT(same_bits(&f0.lmax, &f1.lmax, sizeof(double)) && same_bits(&f0.coord_max, &f1.coord_max, sizeof(double)));
            CU_ASSERT(same_bits(&f0.xmin, &f1.xmin, sizeof(double)) && same_bits(&f0.xmax, &f1.xmax, sizeof(double)));
            CU_ASSERT(same_bits(&f0.ymin, &f1.ymin, sizeof(double)) && same_bits(&f0.ymax, &f1.ymax, sizeof(double)));
            CU_ASSERT(same_bits(&f1, &f2, sizeof f1));
            CU_ASSERT(f0.median > 0.0 && f0.cell_size > 0.0);
            CU_ASSERT(f1.median == 0.0 && f1.cell_size == 0.0);
            CU_ASSERT_EQUAL(f1.surface_nodes, n);
            /* a segment of zero length in the last body (set_positions checks coordinates only) */
            memcpy(node, p.bodies[p.count - 1].nodes, sizeof node);
            node[7] = node[6];
            CU_ASSERT_EQUAL(nts_scene_set_positions(s, p.count - 1, node, NULL), NTS_OK);
            CU_ASSERT_EQUAL(nts_scene_frame(c0, s, &full, &f0, l0, &e0), NTS_EDEGENERATE_SEGMENT);
            CU_ASSERT_EQUAL(nts_scene_frame(c1, s, &light, &f1, l1, &e1), NTS_EDEGENERATE_SEGMENT);
            CU_ASSERT(e0.body == p.count - 1 && e1.body == e0.body && e1.node == e0.node && e0.node == 6);
            free(l0);
            free(l1);
            nts_context_destroy(c0);
            nts_context_destroy(c1);
            nts_scene_destroy(s);
            free_packing(&p);
        }
}

void register_search_suite(void) {
    CU_pSuite s = CU_add_suite("search", NULL, NULL);
    ADD_TEST(s, test_cells_equal_brute_force_open);
    ADD_TEST(s, test_cells_equal_brute_force_periodic);
    ADD_TEST(s, test_far_apart_bodies_bounded_grid);
    ADD_TEST(s, test_force_direction_is_continuous_with_smoothing);
    ADD_TEST(s, test_frame_lengths_alone);
}
