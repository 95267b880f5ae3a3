/* Pressure suite (the `pressure` output, docs/model.md (21)): on packings
 * (open, periodic, with deep contacts), with both penalty scalings, each
 * node's pressure times its tributary length is the sum of the magnitudes of
 * its slave forces (to 1e-12), and its pressure is bitwise the sum of -eps g
 * over its contacts, in their order, divided by that length; nodes in no
 * contact have 0; the pressure is bitwise the same for 1 to 4 threads, and
 * asking for it changes no other output's bits. */
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

/* Each node's tributary length as the scene measures it (§10: half of its two
 * segments, minimum image, at creation); 0 for a node on no loop. */
static double* tributary(const nts_scene* s, double lx, double ly) {
    const nts_vec2* x = nts_scene_positions(s);
    double* l = (double*)calloc((size_t)nts_scene_node_count(s), sizeof(double));
    int b, lp, k;
    for (b = 0; b < nts_scene_body_count(s); ++b) {
        const int off = nts_scene_body_node_offset(s, b);
        for (lp = 0; lp < nts_scene_body_loop_count(s, b); ++lp) {
            const int* loop;
            const int m = nts_scene_body_loop(s, b, lp, &loop);
            for (k = 0; k < m; ++k) {
                const nts_vec2 xi = x[off + loop[k]], xp = x[off + loop[(k + m - 1) % m]],
                               xn = x[off + loop[(k + 1) % m]];
                l[off + loop[k]] = 0.5 * (nts_length(nts_min_image(nts_sub(xi, xp), lx, ly)) +
                                          nts_length(nts_min_image(nts_sub(xn, xi), lx, ly)));
            }
        }
    }
    return l;
}

static void check_pressure(const nts_scene* s, double lx, double ly, nts_penalty_scaling scaling) {
    const int n = nts_scene_node_count(s);
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    double* l = tributary(s, lx, ly);
    double* fsum = (double*)calloc((size_t)n, sizeof(double));
    double* egsum = (double*)calloc((size_t)n, sizeof(double));
    int* count = (int*)calloc((size_t)n, sizeof(int));
    int i, th, bad = 0, single = 0;
    CU_ASSERT_FATAL(c0 != NULL && c1 != NULL && l != NULL && fsum != NULL && egsum != NULL && count != NULL);
    o.penalty = 1000.0;
    o.penalty_scaling = scaling;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS | NTS_OUT_PRESSURE;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    CU_ASSERT_FATAL(r0.pressure != NULL);
    CU_ASSERT(r0.contact_count > 20);
    /* The contacts are in slave order, then master body: the pressure's order. */
    for (i = 0; i < r0.contact_count; ++i) {
        const nts_contact* c = &r0.contacts[i];
        const int g = nts_scene_body_node_offset(s, c->slave_body) + c->slave_node;
        fsum[g] += nts_length(c->force);
        egsum[g] += -(c->penalty * c->gap);
        ++count[g];
    }
    for (i = 0; i < n; ++i) {
        if (count[i] == 0) {
            bad += r0.pressure[i] != 0.0;
            continue;
        }
        CU_ASSERT_FATAL(l[i] > 0.0);
        bad += r0.pressure[i] != egsum[i] / l[i]; /* bitwise: the same sum, the same length */
        ASSERT_NEAR(r0.pressure[i] * l[i], fsum[i], 1e-12 * fsum[i]);
        CU_ASSERT(r0.pressure[i] > 0.0);
        if (scaling == NTS_PENALTY_PER_LENGTH && count[i] == 1) {
            /* one contact: p = -eps g, the pressure stiffness's definition */
            const nts_contact* c = NULL;
            int k;
            for (k = 0; k < r0.contact_count && c == NULL; ++k)
                if (nts_scene_body_node_offset(s, r0.contacts[k].slave_body) + r0.contacts[k].slave_node == i)
                    c = &r0.contacts[k];
            ASSERT_NEAR(r0.pressure[i], -o.penalty * c->gap, 1e-12 * r0.pressure[i]);
            ++single;
        }
    }
    ASSERT_INT_EQ(bad, 0);
    if (scaling == NTS_PENALTY_PER_LENGTH) CU_ASSERT(single > 0);
    /* Asking for it changes no other output's bits; any threads, the same bits. */
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    CU_ASSERT(r1.pressure == NULL);
    CU_ASSERT(memcmp(&r0.summary, &r1.summary, sizeof r0.summary) == 0);
    CU_ASSERT(memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    CU_ASSERT(r0.contact_count == r1.contact_count &&
              memcmp(r0.contacts, r1.contacts, sizeof(nts_contact) * (size_t)r0.contact_count) == 0);
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    CU_ASSERT(memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    o.outputs = NTS_OUT_PRESSURE;
    for (th = 1; th <= 4; ++th) {
        o.threads = th;
        CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
        CU_ASSERT_FATAL(r1.pressure != NULL);
        if (memcmp(r0.pressure, r1.pressure, sizeof(double) * (size_t)n) != 0) {
            fprintf(stderr, "\n  the pressure with %d threads differs\n", th);
            CU_FAIL("pressure differs with the threads");
        }
    }
    free(l);
    free(fsum);
    free(egsum);
    free(count);
    nts_context_destroy(c0);
    nts_context_destroy(c1);
}

static void test_pressure_on_packings(void) {
    /* open; deep contacts (spacing 1.7 for radius 1); periodic */
    static const struct { int count, nodes; double spacing; int periodic; unsigned seed; } cases[] = {
        {36, 40, 1.93, 0, 700}, {25, 48, 1.7, 0, 811}, {36, 40, 1.93, 1, 701}};
    int k, scaling;
    for (k = 0; k < 3; ++k) {
        test_packing p = make_packing(cases[k].count, cases[k].nodes, 1.0, cases[k].spacing, cases[k].periodic,
                                      cases[k].seed);
        nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
        CU_ASSERT_FATAL(s != NULL);
        for (scaling = NTS_PENALTY_PER_NODE; scaling <= NTS_PENALTY_PER_LENGTH; ++scaling)
            check_pressure(s, p.lx, p.ly, (nts_penalty_scaling)scaling);
        nts_scene_destroy(s);
        free_packing(&p);
    }
}

/* No contact: every node's pressure is 0 (an array, not NULL). */
static void test_no_contact_gives_zero_pressure(void) {
    test_body b[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int i;
    make_polygon(&b[0], 24, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&b[1], 24, 1.0, nts_v2(3.0, 0.0), 0.0);
    s = make_scene(b, 2, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL && c != NULL);
    o.outputs = NTS_OUT_PRESSURE;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(r.pressure != NULL);
    for (i = 0; i < nts_scene_node_count(s); ++i) CU_ASSERT(r.pressure[i] == 0.0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

void register_pressure_suite(void) {
    CU_pSuite s = CU_add_suite("pressure", NULL, NULL);
    ADD_TEST(s, test_pressure_on_packings);
    ADD_TEST(s, test_no_contact_gives_zero_pressure);
}
