/* Stiffness suite (issue 11): the tangent K = d2E/dx2 = -df/dx against central
 * finite differences of the forces, column by column, on every active contact
 * kind (segment, corner, vertex), alpha in {0, 0.1, 0.2, 0.5}, both solvers,
 * open and periodic scenes and hard corners; symmetric to round-off; K v
 * against the directional derivative of the forces on random directions; the
 * CSR helper sums duplicates; a warm context allocates nothing. */
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

typedef struct fd_case {
    test_body* b;
    int count;
    double lx, ly;
    double alpha;
    nts_solver solver;
} fd_case;

static void positions(const fd_case* c, double* x) {
    int b, i, k = 0;
    for (b = 0; b < c->count; ++b)
        for (i = 0; i < c->b[b].node_count; ++i) {
            x[k++] = c->b[b].nodes[i].x;
            x[k++] = c->b[b].nodes[i].y;
        }
}

static void set_positions(nts_scene* s, const fd_case* c, const double* x) {
    nts_vec2 buf[4096];
    int b, i, k = 0;
    nts_error err;
    for (b = 0; b < c->count; ++b) {
        for (i = 0; i < c->b[b].node_count; ++i, k += 2) buf[i] = nts_v2(x[k], x[k + 1]);
        CU_ASSERT_FATAL(nts_scene_set_positions(s, b, buf, &err) == 0);
    }
}

/* Forces (2N) at x, and the kinds of the active contacts seen. */
static void forces_at(nts_context* ctx, nts_scene* s, const fd_case* c, const nts_options* o, const double* x,
                      double* f, unsigned* kinds) {
    nts_result r;
    nts_error err;
    int i, n = nts_scene_node_count(s);
    nts_options oo = *o;
    set_positions(s, c, x);
    oo.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &oo, &r, &err) == 0);
    for (i = 0; i < n; ++i) {
        f[2 * i] = r.forces[i].x;
        f[2 * i + 1] = r.forces[i].y;
    }
    if (kinds)
        for (i = 0; i < r.contact_count; ++i) *kinds |= 1u << r.contacts[i].kind;
}

/* The dense tangent at x (from the CSR helper, so duplicates are summed). */
static void tangent_at(nts_context* ctx, nts_scene* s, const fd_case* c, const nts_options* o, const double* x,
                       double* K, int dofs) {
    nts_result r;
    nts_error err;
    nts_csr csr;
    nts_options oo = *o;
    int row, k;
    set_positions(s, c, x);
    oo.outputs = NTS_OUT_STIFFNESS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &oo, &r, &err) == 0);
    ASSERT_INT_EQ(r.stiffness.size, dofs);
    CU_ASSERT_FATAL(nts_triplets_to_csr(&r.stiffness, &csr, &err) == 0);
    memset(K, 0, sizeof(double) * (size_t)dofs * (size_t)dofs);
    for (row = 0; row < dofs; ++row)
        for (k = csr.row_start[row]; k < csr.row_start[row + 1]; ++k) {
            if (k > csr.row_start[row]) CU_ASSERT(csr.cols[k] > csr.cols[k - 1]); /* sorted, each once */
            K[(size_t)row * dofs + csr.cols[k]] = csr.values[k];
        }
    nts_csr_free(&csr);
}

/* Every column of K against -(f(x + h e_j) - f(x - h e_j)) / 2h; returns the
 * kinds of the active contacts at x. */
static unsigned check_fd(const fd_case* c, double tol) {
    nts_body_def defs[16];
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    int b, dofs, j, i;
    double *x, *K, *fp, *fm, kmax = 0.0, emax = 0.0, smax = 0.0, h = 1e-6;
    unsigned kinds = 0;
    memset(defs, 0, sizeof defs);
    for (b = 0; b < c->count; ++b) {
        defs[b].nodes = c->b[b].nodes;
        defs[b].node_count = c->b[b].node_count;
    }
    def.bodies = defs;
    def.body_count = c->count;
    def.lx = c->lx;
    def.ly = c->ly;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    dofs = 2 * nts_scene_node_count(s);
    o.alpha = c->alpha;
    o.solver = c->solver;
    o.penalty = 1000.0;
    o.search_radius = 0.5;
    x = malloc(sizeof(double) * (size_t)dofs);
    fp = malloc(sizeof(double) * (size_t)dofs);
    fm = malloc(sizeof(double) * (size_t)dofs);
    K = malloc(sizeof(double) * (size_t)dofs * (size_t)dofs);
    positions(c, x);
    forces_at(ctx, s, c, &o, x, fp, &kinds);
    tangent_at(ctx, s, c, &o, x, K, dofs);
    for (i = 0; i < dofs * dofs; ++i) kmax = fmax(kmax, fabs(K[i]));
    CU_ASSERT(kmax > 0.0);
    for (j = 0; j < dofs; ++j) {
        double keep = x[j];
        x[j] = keep + h;
        forces_at(ctx, s, c, &o, x, fp, NULL);
        x[j] = keep - h;
        forces_at(ctx, s, c, &o, x, fm, NULL);
        x[j] = keep;
        for (i = 0; i < dofs; ++i) {
            double fd = -(fp[i] - fm[i]) / (2.0 * h);
            emax = fmax(emax, fabs(fd - K[(size_t)i * dofs + j]));
        }
    }
    for (i = 0; i < dofs; ++i)
        for (j = 0; j < i; ++j)
            smax = fmax(smax, fabs(K[(size_t)i * dofs + j] - K[(size_t)j * dofs + i]));
    if (!(emax <= tol * kmax))
        fprintf(stderr, "\n  alpha %g solver %d periodic %d: |K - FD| = %.3g of max |K| = %.3g\n", c->alpha,
                (int)c->solver, c->lx > 0.0, emax / kmax, kmax);
    CU_ASSERT(emax <= tol * kmax);
    CU_ASSERT(smax <= 1e-13 * kmax); /* symmetric by construction */
    /* K v against the directional derivative of the forces, random v. */
    {
        test_rng rng = {2024};
        int t;
        for (t = 0; t < 3; ++t) {
            double* v = malloc(sizeof(double) * (size_t)dofs);
            double* xv = malloc(sizeof(double) * (size_t)dofs);
            double dmax = 0.0, kvmax = 0.0;
            for (i = 0; i < dofs; ++i) v[i] = rng_uniform(&rng) - 0.5;
            for (i = 0; i < dofs; ++i) xv[i] = x[i] + h * v[i];
            forces_at(ctx, s, c, &o, xv, fp, NULL);
            for (i = 0; i < dofs; ++i) xv[i] = x[i] - h * v[i];
            forces_at(ctx, s, c, &o, xv, fm, NULL);
            for (i = 0; i < dofs; ++i) {
                double kv = 0.0;
                for (j = 0; j < dofs; ++j) kv += K[(size_t)i * dofs + j] * v[j];
                kvmax = fmax(kvmax, fabs(kv));
                dmax = fmax(dmax, fabs(kv + (fp[i] - fm[i]) / (2.0 * h)));
            }
            CU_ASSERT(dmax <= tol * kvmax);
            free(v);
            free(xv);
        }
    }
    free(x);
    free(fp);
    free(fm);
    free(K);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    return kinds;
}

/* Two pressed polygons; the second rotated so that nodes meet segments and
 * corners, not nodes. */
static void two_disks(test_body* b, double ox, double oy) {
    make_polygon(&b[0], 20, 1.0, nts_v2(ox, oy), 0.0);
    make_polygon(&b[1], 14, 1.0, nts_v2(ox + 1.93, oy + 0.07), 0.13);
}

/* A disk in the concave corner of an L-shaped body: vertex contacts (alpha =
 * 0) or corner contacts on a reflex corner, active inside the body. */
static void disk_in_l(test_body* b) {
    nts_vec2 l[6] = {{-2, -2}, {2, -2}, {2, 0}, {0, 0}, {0, 2}, {-2, 2}};
    memset(&b[0], 0, sizeof b[0]);
    memcpy(b[0].nodes, l, sizeof l);
    b[0].node_count = 6;
    make_polygon(&b[1], 24, 0.6, nts_v2(0.4, 0.41), 0.02); /* 0.2 into each wall, a node near the corner */
}

static void test_every_kind_alpha_and_solver(void) {
    static const double alphas[4] = {0.0, 0.1, 0.2, 0.5};
    test_body b[2];
    int a, sv;
    for (a = 0; a < 4; ++a)
        for (sv = 0; sv < 2; ++sv) {
            fd_case c = {b, 2, 0.0, 0.0, alphas[a], sv ? NTS_SOLVER_NEWTON : NTS_SOLVER_CLOSED_FORM};
            unsigned kinds;
            two_disks(b, 0.0, 0.0);
            kinds = check_fd(&c, 1e-6);
            disk_in_l(b);
            kinds |= check_fd(&c, 1e-6);
            /* At alpha = 0.5 the flat part of a segment is its midpoint only. */
            if (alphas[a] < 0.5) CU_ASSERT(kinds & (1u << NTS_KIND_SEGMENT));
            CU_ASSERT(kinds & (1u << (alphas[a] > 0.0 ? NTS_KIND_CORNER : NTS_KIND_VERTEX)));
        }
}

static void test_periodic_across_the_edge(void) {
    test_body b[2];
    int sv;
    for (sv = 0; sv < 2; ++sv) {
        fd_case c = {b, 2, 6.0, 6.0, 0.2, sv ? NTS_SOLVER_NEWTON : NTS_SOLVER_CLOSED_FORM};
        two_disks(b, 5.4, 5.8); /* the second disk lies across the box's corner */
        CU_ASSERT(check_fd(&c, 1e-6) != 0);
        c.alpha = 0.0;
        CU_ASSERT(check_fd(&c, 1e-6) != 0);
    }
}

/* Hard corners (docs/hard-cases.md): a sharp convex corner (a thin wedge's
 * tip) pressed into a disk, and a disk pressed into the concave corner of an
 * L-shaped body, at several alphas. */
static void test_hard_corners(void) {
    test_body b[2];
    static const double alphas[3] = {0.0, 0.2, 0.5};
    int a;
    for (a = 0; a < 3; ++a) {
        fd_case c = {b, 2, 0.0, 0.0, alphas[a], NTS_SOLVER_CLOSED_FORM};
        /* wedge: tip at (0.95, 0.02), opening 20 degrees, pointing at the disk */
        memset(&b[0], 0, sizeof b[0]);
        b[0].nodes[0] = nts_v2(-1.0, 0.4);
        b[0].nodes[1] = nts_v2(-1.0, -0.35);
        b[0].nodes[2] = nts_v2(1.08, 0.02);
        b[0].node_count = 3;
        make_polygon(&b[1], 24, 1.0, nts_v2(2.0, 0.0), 0.05);
        check_fd(&c, 1e-6);
        disk_in_l(b);
        c.solver = NTS_SOLVER_NEWTON;
        check_fd(&c, 1e-6);
    }
}

static void test_csr_sums_duplicates_in_order(void) {
    int rows[6] = {0, 1, 0, 1, 0, 2};
    int cols[6] = {1, 1, 1, 0, 0, 2};
    double vals[6] = {1.0, 2.0, 10.0, 3.0, 4.0, 5.0};
    nts_triplets t = {rows, cols, vals, 6, 3};
    nts_csr csr;
    nts_error err;
    CU_ASSERT_FATAL(nts_triplets_to_csr(&t, &csr, &err) == 0);
    ASSERT_INT_EQ(csr.nnz, 5);
    ASSERT_INT_EQ(csr.row_start[1], 2);
    ASSERT_INT_EQ(csr.cols[0], 0);
    ASSERT_NEAR(csr.values[0], 4.0, 0.0);
    ASSERT_NEAR(csr.values[1], 11.0, 0.0);
    ASSERT_NEAR(csr.values[2], 3.0, 0.0);
    ASSERT_NEAR(csr.values[3], 2.0, 0.0);
    ASSERT_NEAR(csr.values[4], 5.0, 0.0);
    nts_csr_free(&csr);
    rows[5] = 3; /* out of the 3 x 3 matrix */
    ASSERT_INT_EQ(nts_triplets_to_csr(&t, &csr, &err), NTS_EINVALID_ARGUMENT);
}

/* Deterministic for any thread count; asking for it changes nothing else. */
static void test_threads_and_other_outputs(void) {
    test_packing p = make_packing(25, 32, 1.0, 1.93, 1, 31);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    int th;
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    CU_ASSERT(r1.stiffness.count == 0 && r1.stiffness.rows == NULL);
    o.outputs |= NTS_OUT_STIFFNESS;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    CU_ASSERT(r0.stiffness.count > 0);
    CU_ASSERT(memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s)) == 0);
    for (th = 2; th <= 4; ++th) {
        o.threads = th;
        CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
        ASSERT_INT_EQ(r1.stiffness.count, r0.stiffness.count);
        CU_ASSERT(memcmp(r0.stiffness.rows, r1.stiffness.rows, sizeof(int) * (size_t)r0.stiffness.count) == 0);
        CU_ASSERT(memcmp(r0.stiffness.values, r1.stiffness.values, sizeof(double) * (size_t)r0.stiffness.count) == 0);
    }
    nts_context_destroy(c0);
    nts_context_destroy(c1);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* Asked for with no contact active, from the C door too: the empty 2N x 2N
 * tangent (no triplets, size 2N), and CSR of it, for any thread count. A
 * Newton loop that starts apart gets a matrix (issue 22 §5). */
static void test_no_contact_gives_the_empty_tangent(void) {
    test_body b[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    nts_csr csr;
    int th, k;
    make_polygon(&b[0], 16, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&b[1], 12, 1.0, nts_v2(5.0, 0.0), 0.1);
    s = make_scene(b, 2, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_FORCES | NTS_OUT_STIFFNESS;
    for (th = 0; th <= 2; th += 2) {
        o.threads = th;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        ASSERT_INT_EQ(r.summary.contacts, 0);
        ASSERT_INT_EQ(r.stiffness.count, 0);
        ASSERT_INT_EQ(r.stiffness.size, 2 * 28);
        ASSERT_INT_EQ(nts_triplets_to_csr(&r.stiffness, &csr, &err), 0);
        ASSERT_INT_EQ(csr.size, 2 * 28);
        ASSERT_INT_EQ(csr.nnz, 0);
        for (k = 0; k <= csr.size; ++k) ASSERT_INT_EQ(csr.row_start[k], 0);
        nts_csr_free(&csr);
    }
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

void register_stiffness_suite(void) {
    CU_pSuite s = CU_add_suite("stiffness", NULL, NULL);
    ADD_TEST(s, test_every_kind_alpha_and_solver);
    ADD_TEST(s, test_periodic_across_the_edge);
    ADD_TEST(s, test_hard_corners);
    ADD_TEST(s, test_csr_sums_duplicates_in_order);
    ADD_TEST(s, test_threads_and_other_outputs);
    ADD_TEST(s, test_no_contact_gives_the_empty_tangent);
}
