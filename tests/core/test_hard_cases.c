/* Hard cases (docs/model.md §4; docs/hard-cases.md): both corner
 * solvers against a long-double reference, and no NaN ever. The reference cuts
 * [-1, 1] at the critical points of F, bisects every sign change in long
 * double, then takes the root nearest to the slave (support/reference.c). */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "nts_support.h"
#include "suites.h"
#include "test_util.h"

typedef struct ref_solution {
    long double xi;
    int roots;
} ref_solution;

/* The long-double reference (support/reference.c, shared with nts_bench): every
 * root of F on the monotone pieces of [-1, 1], bisected to the last bit, the
 * nearest one taken. */
static ref_solution reference(nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d) {
    ref_solution out;
    out.xi = ntsx_corner_xi(a, c, alpha, d, &out.roots);
    return out;
}

/* Solve with both solvers; check no NaN, agreement with the reference within
 * tol in xi, and print the measured error (docs/hard-cases.md). Returns the worse error. */
static double check_corner(const char* name, nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d, double tol,
                           int expect_roots) {
    ref_solution ref = reference(a, c, alpha, d);
    nts_corner k = nts_corner_make(a, c, alpha);
    double worst = 0.0;
    int sv;
    for (sv = 0; sv < 2; ++sv) {
        nts_corner_solution s = nts_corner_solve(k, d, (nts_solver)sv);
        double err = fabs((double)((long double)s.xi - ref.xi));
        CU_ASSERT(s.ok);
        CU_ASSERT(isfinite(s.xi) && isfinite(s.gap) && isfinite(s.normal.x) && isfinite(s.normal.y));
        CU_ASSERT(s.xi >= -1.0 && s.xi <= 1.0);
        if (!(err <= tol))
            fprintf(stderr, "\n  %s (%s): xi = %.17g, reference %.17Lg, error %.3g > %.3g\n", name,
                    sv ? "newton" : "closed_form", s.xi, ref.xi, err, tol);
        CU_ASSERT(err <= tol);
        if (expect_roots > 0 && s.roots != expect_roots)
            fprintf(stderr, "\n  %s (%s): %d roots, expected %d\n", name, sv ? "newton" : "closed_form", s.roots,
                    expect_roots);
        if (expect_roots > 0) ASSERT_INT_EQ(s.roots, expect_roots);
        if (err > worst) worst = err;
    }
    fprintf(stderr, "[hard case %-34s reference roots %d, max |xi - ref| %.3g]\n", name, ref.roots, worst);
    return worst;
}

static void test_collinear_neighbours(void) {
    /* a = -c exactly: A = 0, the cubic is the linear equation -(B.B) xi + e.B = 0. */
    check_corner("collinear", nts_v2(-1, 0), nts_v2(1, 0), 0.2, nts_v2(0.05, -0.3), 1e-14, 1);
    check_corner("collinear, inside", nts_v2(-1, 0), nts_v2(1, 0), 0.5, nts_v2(-0.13, 0.2), 1e-14, 1);
}

static void test_nearly_collinear(void) {
    double th = 1e-9;
    check_corner("nearly collinear 1e-9 rad", nts_v2(-1, 0), nts_v2(cos(th), sin(th)), 0.2, nts_v2(0.05, -0.3),
                 1e-10, 1);
    th = 1e-5;
    check_corner("nearly collinear 1e-5 rad", nts_v2(-1, 0), nts_v2(cos(th), sin(th)), 0.2, nts_v2(-0.07, 0.1),
                 1e-10, 1);
}

static void test_newton_converges_quickly_when_nearly_straight(void) {
    /* Regression: at the root, a sub-ulp Newton step landed on the bracket's
     * edge and was taken for "left the bracket", so the solver bisected away and
     * crawled back (52 steps on this case). F is nearly linear here: a handful of
     * steps must do. */
    double th = 1e-5;
    nts_corner k = nts_corner_make(nts_v2(-1, 0), nts_v2(cos(th), sin(th)), 0.2);
    nts_corner_solution s = nts_corner_solve(k, nts_v2(-0.07, 0.1), NTS_SOLVER_NEWTON);
    CU_ASSERT(s.ok);
    if (s.iterations > 8) fprintf(stderr, "\n  newton took %d steps\n", s.iterations);
    CU_ASSERT(s.iterations <= 8);
}

static void test_slave_on_alpha_boundaries(void) {
    /* Slave whose projection is exactly s = alpha on the next segment: the corner
     * root is xi = 1 (the curve's end Xb), and the flat candidate sees the same point. */
    double al = 0.25;
    nts_vec2 a = nts_v2(-1, 0), c = nts_v2(0, 1);
    /* Segment X3 -> X4 = (0,0) -> (0,1): s = y; outward normal (1, 0). */
    check_corner("on s = alpha", a, c, al, nts_v2(0.1, al), 1e-12, 0);
    check_corner("on s = 1 - alpha (previous)", a, c, al, nts_v2(-al, -0.1), 1e-12, 0);
    {
        nts_corner k = nts_corner_make(a, c, al);
        nts_corner_solution s = nts_corner_solve(k, nts_v2(0.1, al), NTS_SOLVER_NEWTON);
        ASSERT_NEAR(s.xi, 1.0, 1e-12);
        ASSERT_NEAR(s.gap, 0.1, 1e-12);
    }
}

static void test_slave_exactly_on_node(void) {
    /* d = 0: the slave sits on the corner node (inside the smoothed curve). */
    check_corner("exactly on the node", nts_v2(-1, 0), nts_v2(0, 1), 0.2, nts_v2(0, 0), 1e-13, 1);
}

static void test_evolute_several_roots(void) {
    /* Deep inside an acute (45 degree) convex corner, beyond the evolute of the
     * curve: F has three roots in [-1, 1] (about -0.786, -0.042 and 0.509); the
     * one nearest to the slave is the answer. Asymmetric legs (1 and 1.2) so the
     * nearest root is unique. */
    const double q = 0.70710678118654752;
    double worst = check_corner("evolute (three roots)", nts_v2(-1, 0), nts_v2(-1.2 * q, 1.2 * q), 0.5,
                                nts_v2(-0.42, 0.15), 1e-10, 3);
    CU_ASSERT(worst <= 1e-10);
}

static void test_one_degree_spike_and_reflex(void) {
    const double deg = 3.14159265358979323846 / 180.0;
    nts_vec2 a = nts_v2(-1, 0);
    nts_vec2 c1 = nts_v2(-cos(deg), sin(deg));    /* 1 degree spike */
    nts_vec2 c359 = nts_v2(-cos(deg), -sin(deg)); /* 359 degree reflex corner */
    check_corner("1 degree spike, outside", a, c1, 0.2, nts_v2(0.05, 0.001), 1e-10, 0);
    check_corner("359 degree reflex corner", a, c359, 0.2, nts_v2(0.05, 0.0005), 1e-10, 0);
}

static void test_large_offset_small_segments(void) {
    /* Coordinates offset by 1e6 with 1e-3 segments: the core subtracts first, so
     * the local problem is the same as at the origin to about 1e6 eps / 1e-3. */
    test_body b[2];
    nts_scene *s0, *s1;
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_context *c0, *c1;
    int i;
    make_polygon(&b[0], 64, 0.01, nts_v2(0, 0), 0.0);
    make_polygon(&b[1], 64, 0.01, nts_v2(0.0199, 0.0003), 0.03);
    s0 = make_scene(b, 2, 0, 0);
    for (i = 0; i < 64; ++i) {
        b[0].nodes[i] = nts_add(b[0].nodes[i], nts_v2(1e6, -1e6));
        b[1].nodes[i] = nts_add(b[1].nodes[i], nts_v2(1e6, -1e6));
    }
    s1 = make_scene(b, 2, 0, 0);
    CU_ASSERT_FATAL(s0 != NULL && s1 != NULL);
    o.outputs = NTS_OUT_ALL;
    o.penalty = 1e4;
    CU_ASSERT_FATAL(eval_scene(s0, &o, &r0, &c0) == 0);
    CU_ASSERT_FATAL(eval_scene(s1, &o, &r1, &c1) == 0);
    CU_ASSERT(r0.contact_count > 0);
    ASSERT_INT_EQ(r1.contact_count, r0.contact_count);
    for (i = 0; i < r0.contact_count && i < r1.contact_count; ++i) {
        /* The input itself carries the error: one ulp of 1e6 is 1.16e-10, so the
         * nodes are only known to that; a few ulps is the best any method can do. */
        ASSERT_NEAR(r1.contacts[i].gap, r0.contacts[i].gap, 4.0 * 1.1641532182693481e-10);
        CU_ASSERT(isfinite(r1.contacts[i].gap));
    }
    fprintf(stderr, "[hard case offset 1e6, 1e-3 segments: energy %.6g vs %.6g at origin]\n", r1.summary.energy,
            r0.summary.energy);
    nts_context_destroy(c0);
    nts_context_destroy(c1);
    nts_scene_destroy(s0);
    nts_scene_destroy(s1);
}

static void test_extreme_scales(void) {
    /* The same packing at 1e-9 and 1e9 scale: gaps scale exactly (up to round-off),
     * every number finite. */
    double scales[] = {1e-9, 1e9};
    int si;
    test_packing p = make_packing(9, 32, 1.0, 1.93, 0, 81);
    nts_scene* s = make_scene(p.bodies, p.count, 0, 0);
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* c;
    double e1;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(eval_scene(s, &o, &r, &c) == 0);
    e1 = r.summary.energy;
    CU_ASSERT(r.contact_count > 0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    for (si = 0; si < 2; ++si) {
        test_packing q = make_packing(9, 32, 1.0, 1.93, 0, 81);
        int b, k, i;
        for (b = 0; b < q.count; ++b)
            for (k = 0; k < q.bodies[b].node_count; ++k) q.bodies[b].nodes[k] = nts_scale(scales[si], q.bodies[b].nodes[k]);
        s = make_scene(q.bodies, q.count, 0, 0);
        CU_ASSERT_FATAL(s != NULL);
        CU_ASSERT_FATAL(eval_scene(s, &o, &r, &c) == 0);
        ASSERT_NEAR(r.summary.energy / (scales[si] * scales[si]), e1, 1e-9 * e1);
        for (i = 0; i < nts_scene_node_count(s); ++i) CU_ASSERT(nts_is_valid_vec2(r.forces[i]));
        for (i = 0; i < r.contact_count; ++i) CU_ASSERT(isfinite(r.contacts[i].gap) && isfinite(r.contacts[i].param));
        nts_context_destroy(c);
        nts_scene_destroy(s);
        free_packing(&q);
    }
    free_packing(&p);
}

static void test_random_corners_against_reference(void) {
    /* A sweep: random corners and slaves inside the corner's candidate region. */
    test_rng rng = {12345};
    int i, tried = 0;
    double worst = 0.0;
    for (i = 0; i < 3000 && tried < 800; ++i) {
        double th1 = 6.283185307179586 * rng_uniform(&rng), th2 = 6.283185307179586 * rng_uniform(&rng);
        double al = 0.05 + 0.45 * rng_uniform(&rng);
        nts_vec2 a = nts_scale(0.5 + rng_uniform(&rng), nts_v2(cos(th1), sin(th1)));
        nts_vec2 c = nts_scale(0.5 + rng_uniform(&rng), nts_v2(cos(th2), sin(th2)));
        nts_vec2 d = nts_v2(0.6 * (rng_uniform(&rng) - 0.5), 0.6 * (rng_uniform(&rng) - 0.5));
        double sp, sj;
        ref_solution ref;
        nts_corner k;
        int sv;
        if (fabs(nts_cross(a, c)) < 1e-3 && nts_dot(a, c) > 0) continue; /* spike: rejected by validation */
        /* Candidate region (docs/model.md §12, correction 3): s_{j-1} >= 1 - alpha and s_j <= alpha. */
        sp = nts_dot(nts_sub(d, a), nts_neg(a)) / nts_dot(a, a);
        sj = nts_dot(d, c) / nts_dot(c, c);
        if (!(sp >= 1.0 - al && sj <= al)) continue;
        ++tried;
        ref = reference(a, c, al, d);
        k = nts_corner_make(a, c, al);
        for (sv = 0; sv < 2; ++sv) {
            nts_corner_solution s = nts_corner_solve(k, d, (nts_solver)sv);
            long double rx, ry, sx, sy;
            double err = fabs((double)((long double)s.xi - ref.xi));
            /* Compare distances too: where two roots are equally near (a symmetric
             * evolute point) either is right. */
            nts_vec2 ps = nts_corner_point(k, s.xi);
            nts_vec2 pr = nts_corner_point(k, (double)ref.xi);
            sx = (long double)d.x - ps.x; sy = (long double)d.y - ps.y;
            rx = (long double)d.x - pr.x; ry = (long double)d.y - pr.y;
            CU_ASSERT(isfinite(s.xi) && isfinite(s.gap));
            if (err > 1e-10 && fabsl(sqrtl(sx * sx + sy * sy) - sqrtl(rx * rx + ry * ry)) > 1e-14) {
                fprintf(stderr, "\n  sweep %d (%s): xi %.17g ref %.17Lg\n", i, sv ? "newton" : "closed_form", s.xi,
                        ref.xi);
                CU_FAIL("corner solver disagrees with the long-double reference");
            } else if (err > worst && err <= 1e-10) {
                worst = err;
            }
        }
    }
    CU_ASSERT(tried > 200);
    fprintf(stderr, "[hard case random sweep: %d corners, max |xi - ref| %.3g]\n", tried, worst);
}

void register_hard_cases_suite(void) {
    CU_pSuite s = CU_add_suite("hard_cases", NULL, NULL);
    ADD_TEST(s, test_collinear_neighbours);
    ADD_TEST(s, test_nearly_collinear);
    ADD_TEST(s, test_newton_converges_quickly_when_nearly_straight);
    ADD_TEST(s, test_slave_on_alpha_boundaries);
    ADD_TEST(s, test_slave_exactly_on_node);
    ADD_TEST(s, test_evolute_several_roots);
    ADD_TEST(s, test_one_degree_spike_and_reflex);
    ADD_TEST(s, test_large_offset_small_segments);
    ADD_TEST(s, test_extreme_scales);
    ADD_TEST(s, test_random_corners_against_reference);
}
