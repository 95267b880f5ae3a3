/* Invariants on random packings: zero net force and torque, forces = -grad E by
 * central differences, virial = -sum f (X - Xs) = eps g^2 n n; and metamorphic
 * tests (translation, rotation, scaling, body permutation, loop start shift,
 * clockwise input). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

typedef struct flat_result {
    nts_vec2* f;
    int n;
    double energy;
    nts_virial vir;
    int contacts;
} flat_result;

static flat_result run(const test_body* bodies, int count, double lx, double ly, const nts_options* o) {
    flat_result fr;
    nts_scene* s = make_scene(bodies, count, lx, ly);
    nts_result r;
    nts_context* ctx = NULL;
    memset(&fr, 0, sizeof fr);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT_FATAL(eval_scene(s, o, &r, &ctx) == 0);
    fr.n = nts_scene_node_count(s);
    fr.f = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)fr.n);
    memcpy(fr.f, r.forces, sizeof(nts_vec2) * (size_t)fr.n);
    fr.energy = r.summary.energy;
    fr.vir = r.summary.virial;
    fr.contacts = r.summary.contacts;
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    return fr;
}

static nts_options opts(double alpha, nts_solver solver) {
    nts_options o = nts_default_options();
    o.alpha = alpha;
    o.solver = solver;
    o.penalty = 50.0;
    o.outputs = NTS_OUT_ALL;
    return o;
}

static const double alphas[] = {0.0, 0.2, 0.5};

static void test_net_force_and_torque_vanish(void) {
    int ia, sv;
    for (ia = 0; ia < 3; ++ia)
        for (sv = 0; sv < 2; ++sv) {
            test_packing p = make_packing(25, 40, 1.0, 1.93, 0, 11 + ia);
            nts_options o = opts(alphas[ia], (nts_solver)sv);
            flat_result fr = run(p.bodies, p.count, 0, 0, &o);
            double fx = 0, fy = 0, tq = 0, fmax = 0;
            int b, k, g = 0;
            CU_ASSERT(fr.contacts > 20);
            for (b = 0; b < p.count; ++b)
                for (k = 0; k < p.bodies[b].node_count; ++k, ++g) {
                    nts_vec2 x = p.bodies[b].nodes[k], f = fr.f[g];
                    fx += f.x;
                    fy += f.y;
                    tq += nts_cross(nts_sub(x, nts_v2(5, 5)), f);
                    if (nts_length(f) > fmax) fmax = nts_length(f);
                }
            ASSERT_NEAR(fx, 0.0, 1e-13 * fmax * fr.n);
            ASSERT_NEAR(fy, 0.0, 1e-13 * fmax * fr.n);
            ASSERT_NEAR(tq, 0.0, 1e-12 * fmax * fr.n);
            free(fr.f);
            free_packing(&p);
        }
}

static void test_forces_are_minus_energy_gradient(void) {
    int ia;
    for (ia = 0; ia < 3; ++ia) {
        test_packing p = make_packing(9, 32, 1.0, 1.93, 0, 21 + ia);
        nts_options o = opts(alphas[ia], NTS_SOLVER_CLOSED_FORM);
        flat_result fr = run(p.bodies, p.count, 0, 0, &o);
        const double h = 1e-7;
        int b, k, g = 0, checked = 0;
        double worst = 0.0;
        for (b = 0; b < p.count; ++b)
            for (k = 0; k < p.bodies[b].node_count; ++k, ++g) {
                int axis;
                if (nts_length(fr.f[g]) == 0.0 && (g % 7) != 0) continue; /* all loaded nodes, some free ones */
                for (axis = 0; axis < 2; ++axis) {
                    double* c = axis == 0 ? &p.bodies[b].nodes[k].x : &p.bodies[b].nodes[k].y;
                    double x0 = *c, ep, em, fd, an;
                    nts_scene* s;
                    *c = x0 + h;
                    s = make_scene(p.bodies, p.count, 0, 0);
                    ep = scene_energy(s, &o);
                    nts_scene_destroy(s);
                    *c = x0 - h;
                    s = make_scene(p.bodies, p.count, 0, 0);
                    em = scene_energy(s, &o);
                    nts_scene_destroy(s);
                    *c = x0;
                    fd = -(ep - em) / (2 * h);
                    an = axis == 0 ? fr.f[g].x : fr.f[g].y;
                    if (fabs(fd - an) > worst) worst = fabs(fd - an);
                    ASSERT_NEAR(an, fd, 1e-5 * (1.0 + fabs(an)));
                    ++checked;
                }
            }
        CU_ASSERT(checked > 20);
        free(fr.f);
        free_packing(&p);
    }
}

/* The virial of a contact is eps g^2 n n (docs/model.md §6, eq. (11)); that
 * it is also -sum_k f_k (X_k - Xs) over the contact's nodes holds only at a
 * true closest point (Xs - X = g n) with weights that reproduce X: recomputed
 * here from the contact's nodes, weights and forces (minimum image), it
 * checks the closest points. The summary is the sum over the contacts. */
static void test_virial_identities(void) {
    int ia;
    for (ia = 0; ia < 3; ++ia) {
        test_packing p = make_packing(16, 36, 1.0, 1.93, 1, 31 + ia);
        nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
        nts_options o = opts(alphas[ia], NTS_SOLVER_NEWTON);
        nts_result r;
        nts_context* ctx;
        nts_virial sum = {0, 0, 0, 0};
        const nts_vec2* pos;
        int i, q;
        CU_ASSERT_FATAL(s != NULL);
        CU_ASSERT_FATAL(eval_scene(s, &o, &r, &ctx) == 0);
        CU_ASSERT(r.contact_count > 10);
        pos = nts_scene_positions(s);
        for (i = 0; i < r.contact_count; ++i) {
            const nts_contact* c = &r.contacts[i];
            const nts_vec2 xs = pos[nts_scene_body_node_offset(s, c->slave_body) + c->slave_node];
            const double e = o.penalty * c->gap * c->gap, scale = e + 1e-300, eg = o.penalty * c->gap;
            double wxx = 0.0, wyy = 0.0, wxy = 0.0, wyx = 0.0;
            for (q = 0; q < c->master_count; ++q) {
                const nts_vec2 x = pos[nts_scene_body_node_offset(s, c->master_body) + c->master_nodes[q]];
                const nts_vec2 rel = nts_min_image(nts_sub(x, xs), p.lx, p.ly);
                const nts_vec2 f = nts_scale(eg * c->weights[q], c->normal); /* f_k = eps g N_k n */
                wxx -= f.x * rel.x;
                wyy -= f.y * rel.y;
                wxy -= f.x * rel.y;
                wyx -= f.y * rel.x;
            }
            ASSERT_NEAR(c->virial.xx, e * c->normal.x * c->normal.x, 1e-15 * scale);
            ASSERT_NEAR(c->virial.yy, e * c->normal.y * c->normal.y, 1e-15 * scale);
            ASSERT_NEAR(c->virial.xy, e * c->normal.x * c->normal.y, 1e-15 * scale);
            ASSERT_NEAR(c->virial.xx, wxx, 1e-9 * scale);
            ASSERT_NEAR(c->virial.yy, wyy, 1e-9 * scale);
            ASSERT_NEAR(c->virial.xy, wxy, 1e-9 * scale);
            ASSERT_NEAR(c->virial.xy, wyx, 1e-9 * scale);
            sum.xx += c->virial.xx;
            sum.yy += c->virial.yy;
            sum.xy += c->virial.xy;
        }
        ASSERT_NEAR(r.summary.virial.xx, sum.xx, 1e-12 * fabs(sum.xx));
        ASSERT_NEAR(r.summary.virial.yy, sum.yy, 1e-12 * fabs(sum.yy));
        ASSERT_NEAR(r.summary.virial.xy, sum.xy, 1e-12 * (fabs(sum.xx) + fabs(sum.yy)));
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        free_packing(&p);
    }
}

typedef nts_vec2 (*xform_fn)(nts_vec2 x, double a);
static nts_vec2 translate(nts_vec2 x, double a) { return nts_add(x, nts_v2(a, -0.5 * a)); }
static nts_vec2 rotate(nts_vec2 x, double a) {
    return nts_v2(cos(a) * x.x - sin(a) * x.y, sin(a) * x.x + cos(a) * x.y);
}
static nts_vec2 scale(nts_vec2 x, double a) { return nts_scale(a, x); }

static void transformed_forces_match(xform_fn fn, double a, int kind) {
    int ia;
    for (ia = 0; ia < 3; ++ia) {
        test_packing p = make_packing(16, 32, 1.0, 1.93, 0, 41 + ia);
        test_packing q = make_packing(16, 32, 1.0, 1.93, 0, 41 + ia);
        nts_options o = opts(alphas[ia], NTS_SOLVER_CLOSED_FORM);
        flat_result r0, r1;
        int b, k, g;
        double fmax = 0.0;
        for (b = 0; b < q.count; ++b)
            for (k = 0; k < q.bodies[b].node_count; ++k) q.bodies[b].nodes[k] = fn(q.bodies[b].nodes[k], a);
        r0 = run(p.bodies, p.count, 0, 0, &o);
        if (kind == 2) o.search_radius = -1.0; /* the median segment scales too */
        r1 = run(q.bodies, q.count, 0, 0, &o);
        ASSERT_INT_EQ(r1.contacts, r0.contacts);
        for (g = 0; g < r0.n; ++g) if (nts_length(r0.f[g]) > fmax) fmax = nts_length(r0.f[g]);
        for (g = 0; g < r0.n; ++g) {
            nts_vec2 expect = r0.f[g];
            if (kind == 1) expect = rotate(expect, a);
            if (kind == 2) expect = nts_scale(a, expect); /* f = eps g n: g scales */
            /* Translation by 1e6 loses the digits of the coordinates: 1e6 * eps
             * relative to segment lengths ~0.2, so about 1e-9 of the force scale. */
            ASSERT_NEAR(r1.f[g].x, expect.x, (kind == 0 ? 1e-7 : 1e-10) * fmax * (kind == 2 ? a : 1.0));
            ASSERT_NEAR(r1.f[g].y, expect.y, (kind == 0 ? 1e-7 : 1e-10) * fmax * (kind == 2 ? a : 1.0));
        }
        if (kind == 2) ASSERT_NEAR(r1.energy, a * a * r0.energy, 1e-9 * a * a * r0.energy);
        else ASSERT_NEAR(r1.energy, r0.energy, (kind == 0 ? 1e-6 : 1e-10) * r0.energy);
        free(r0.f);
        free(r1.f);
        free_packing(&p);
        free_packing(&q);
    }
}

static void test_translation_invariance(void) {
    transformed_forces_match(translate, 3.25, 0);
    transformed_forces_match(translate, 1e6, 0);
}
static void test_rotation_covariance(void) { transformed_forces_match(rotate, 0.7, 1); }
static void test_scaling(void) {
    transformed_forces_match(scale, 3.0, 2);
    transformed_forces_match(scale, 1e-3, 2);
}

static void test_permuting_bodies(void) {
    test_packing p = make_packing(12, 32, 1.0, 1.93, 0, 51);
    test_body* rev = (test_body*)malloc(sizeof(test_body) * (size_t)p.count);
    nts_options o = opts(0.2, NTS_SOLVER_CLOSED_FORM);
    flat_result r0, r1;
    int b, k;
    for (b = 0; b < p.count; ++b) rev[b] = p.bodies[p.count - 1 - b];
    r0 = run(p.bodies, p.count, 0, 0, &o);
    r1 = run(rev, p.count, 0, 0, &o);
    ASSERT_INT_EQ(r1.contacts, r0.contacts);
    ASSERT_NEAR(r1.energy, r0.energy, 1e-13 * r0.energy);
    for (b = 0; b < p.count; ++b)
        for (k = 0; k < 32; ++k) {
            nts_vec2 f0 = r0.f[32 * b + k], f1 = r1.f[32 * (p.count - 1 - b) + k];
            ASSERT_NEAR(f1.x, f0.x, 1e-12);
            ASSERT_NEAR(f1.y, f0.y, 1e-12);
        }
    free(r0.f);
    free(r1.f);
    free(rev);
    free_packing(&p);
}

static void test_loop_start_and_direction(void) {
    /* The same loops given from another start node, and clockwise: identical
     * forces (the features and their tie-break keys are the same). */
    test_packing p = make_packing(9, 30, 1.0, 1.93, 0, 61);
    test_packing q = make_packing(9, 30, 1.0, 1.93, 0, 61);
    test_packing w = make_packing(9, 30, 1.0, 1.93, 0, 61);
    nts_options o = opts(0.2, NTS_SOLVER_CLOSED_FORM);
    flat_result r0, r1, r2;
    int b, k;
    for (b = 0; b < q.count; ++b) {
        q.bodies[b].loop_count = 1;
        q.bodies[b].loop_start[0] = 0;
        q.bodies[b].loop_start[1] = 30;
        w.bodies[b].loop_count = 1;
        w.bodies[b].loop_start[0] = 0;
        w.bodies[b].loop_start[1] = 30;
        for (k = 0; k < 30; ++k) {
            q.bodies[b].loop_nodes[k] = (k + 7 + b) % 30;   /* shifted start */
            w.bodies[b].loop_nodes[k] = (30 - k + b) % 30;  /* clockwise */
        }
    }
    r0 = run(p.bodies, p.count, 0, 0, &o);
    r1 = run(q.bodies, q.count, 0, 0, &o);
    r2 = run(w.bodies, w.count, 0, 0, &o);
    ASSERT_INT_EQ(r1.contacts, r0.contacts);
    ASSERT_INT_EQ(r2.contacts, r0.contacts);
    for (k = 0; k < r0.n; ++k) {
        ASSERT_NEAR(r1.f[k].x, r0.f[k].x, 1e-13);
        ASSERT_NEAR(r1.f[k].y, r0.f[k].y, 1e-13);
        ASSERT_NEAR(r2.f[k].x, r0.f[k].x, 1e-13);
        ASSERT_NEAR(r2.f[k].y, r0.f[k].y, 1e-13);
    }
    free(r0.f);
    free(r1.f);
    free(r2.f);
    free_packing(&p);
    free_packing(&q);
    free_packing(&w);
}

/* A result does not depend on what the context evaluated before: an empty
 * array is NULL (contacts, gaps, the tangent's triplets, friction's
 * anchors), on a fresh context as on one whose buffers held the last
 * evaluation's many (they were that evaluation's stale pointers). */
static void check_empty_arrays(const nts_result* r, const char* where) {
    if (!(r->contacts == NULL && r->gaps == NULL && r->stiffness.rows == NULL && r->stiffness.cols == NULL &&
          r->stiffness.values == NULL && r->anchors == NULL))
        fprintf(stderr, "\n  %s: an empty array is not NULL\n", where);
    ASSERT_INT_EQ(r->contact_count + r->gap_count + r->stiffness.count + r->anchor_count, 0);
    CU_ASSERT(r->contacts == NULL && r->gaps == NULL && r->anchors == NULL);
    CU_ASSERT(r->stiffness.rows == NULL && r->stiffness.cols == NULL && r->stiffness.values == NULL);
    CU_ASSERT(r->forces != NULL && r->pressure != NULL); /* asked, and never empty */
}

static void test_empty_arrays_whatever_came_before(void) {
    const nts_vec2 a[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}}, near[4] = {{0.2, 0.9}, {1.2, 0.9}, {1.2, 1.9}, {0.2, 1.9}},
                   far[4] = {{5, 5}, {6, 5}, {6, 6}, {5, 6}};
    nts_body_def d[2];
    nts_scene_def sd = nts_default_scene_def();
    nts_scene *apart, *pressed;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error e;
    memset(d, 0, sizeof d);
    d[0].nodes = a;
    d[0].node_count = 4;
    d[1].nodes = far;
    d[1].node_count = 4;
    sd.bodies = d;
    sd.body_count = 2;
    apart = nts_scene_create(&sd, &e);
    d[1].nodes = near;
    pressed = nts_scene_create(&sd, &e);
    CU_ASSERT_FATAL(apart != NULL && pressed != NULL && c != NULL);
    o.outputs = NTS_OUT_ALL;
    o.friction = 0.3;
    CU_ASSERT_FATAL(nts_evaluate(c, apart, &o, &r, &e) == NTS_OK);
    check_empty_arrays(&r, "a fresh context");
    CU_ASSERT_FATAL(nts_evaluate(c, pressed, &o, &r, &e) == NTS_OK);
    CU_ASSERT(r.contact_count > 0 && r.gap_count > 0 && r.stiffness.count > 0 && r.anchor_count > 0);
    CU_ASSERT(r.contacts != NULL && r.gaps != NULL && r.stiffness.rows != NULL && r.anchors != NULL);
    CU_ASSERT_FATAL(nts_evaluate(c, apart, &o, &r, &e) == NTS_OK);
    check_empty_arrays(&r, "after an evaluation with contacts");
    o.threads = 2;
    CU_ASSERT_FATAL(nts_evaluate(c, pressed, &o, &r, &e) == NTS_OK);
    CU_ASSERT_FATAL(nts_evaluate(c, apart, &o, &r, &e) == NTS_OK);
    check_empty_arrays(&r, "two threads, after an evaluation with contacts");
    nts_context_destroy(c);
    nts_scene_destroy(apart);
    nts_scene_destroy(pressed);
}

void register_invariants_suite(void) {
    CU_pSuite s = CU_add_suite("invariants", NULL, NULL);
    ADD_TEST(s, test_net_force_and_torque_vanish);
    ADD_TEST(s, test_forces_are_minus_energy_gradient);
    ADD_TEST(s, test_virial_identities);
    ADD_TEST(s, test_translation_invariance);
    ADD_TEST(s, test_rotation_covariance);
    ADD_TEST(s, test_scaling);
    ADD_TEST(s, test_permuting_bodies);
    ADD_TEST(s, test_loop_start_and_direction);
    ADD_TEST(s, test_empty_arrays_whatever_came_before);
}
