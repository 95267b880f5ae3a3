#include <stdint.h>

#include "nts_support.h"
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

double rng_uniform(test_rng* r) {
    unsigned long long x = r->s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    return (double)((x * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
}

void make_polygon(test_body* b, int n, double r, nts_vec2 c, double phase) {
    const double pi = 3.14159265358979323846;
    int i;
    memset(b, 0, sizeof *b);
    for (i = 0; i < n; ++i) {
        double th = phase + 2.0 * pi * i / n;
        b->nodes[i] = nts_v2(c.x + r * cos(th), c.y + r * sin(th));
    }
    b->node_count = n;
    b->loop_count = 0;
}

nts_scene* make_scene(const test_body* bodies, int count, double lx, double ly) {
    nts_body_def* defs = (nts_body_def*)calloc((size_t)count, sizeof(nts_body_def));
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    int i;
    for (i = 0; i < count; ++i) {
        defs[i].nodes = bodies[i].nodes;
        defs[i].node_count = bodies[i].node_count;
        if (bodies[i].loop_count > 0) {
            defs[i].loop_nodes = bodies[i].loop_nodes;
            defs[i].loop_start = bodies[i].loop_start;
            defs[i].loop_count = bodies[i].loop_count;
        }
    }
    def.bodies = defs;
    def.body_count = count;
    def.lx = lx;
    def.ly = ly;
    s = nts_scene_create(&def, &err);
    if (s == NULL) fprintf(stderr, "\n  make_scene: %s: %s\n", nts_status_name(err.code), err.message);
    free(defs);
    return s;
}

test_packing make_packing(int count, int nodes, double radius, double spacing, int periodic, unsigned long long seed) {
    /* The benchmarks' generator (support/scenes.c) with the tests' spread:
     * centres +- 5% of the spacing, radii +- 4%, node radii +- 2%, no angle jitter. */
    ntsx_packing_def d = ntsx_default_packing(count, periodic, (uint64_t)seed);
    ntsx_scene x;
    test_packing p;
    int i, k;
    d.nodes_min = d.nodes_max = nodes;
    d.spacing = spacing;
    d.radius = radius;
    d.centre_jitter = 0.1 * spacing;
    d.radius_jitter = 0.08 * radius;
    d.angle_jitter = 0.0;
    d.node_jitter = 0.04;
    ntsx_packing(&x, &d);
    p.bodies = (test_body*)calloc((size_t)count, sizeof(test_body));
    p.count = count;
    p.lx = x.lx;
    p.ly = x.ly;
    for (i = 0; i < count; ++i) {
        p.bodies[i].node_count = x.counts[i];
        for (k = 0; k < x.counts[i]; ++k) p.bodies[i].nodes[k] = x.nodes[i][k];
    }
    ntsx_scene_free(&x);
    return p;
}

void free_packing(test_packing* p) {
    free(p->bodies);
    p->bodies = NULL;
}

int eval_scene(const nts_scene* s, const nts_options* opt, nts_result* res, nts_context** ctx_out) {
    nts_error err;
    nts_context* ctx = nts_context_create();
    int rc = nts_evaluate(ctx, s, opt, res, &err);
    if (rc != NTS_OK) fprintf(stderr, "\n  evaluate: %s: %s\n", nts_status_name(err.code), err.message);
    *ctx_out = ctx;
    return rc;
}

double scene_energy(const nts_scene* s, const nts_options* opt) {
    nts_result res;
    nts_context* ctx = NULL;
    double e = 0.0;
    if (eval_scene(s, opt, &res, &ctx) == NTS_OK) e = res.summary.energy;
    nts_context_destroy(ctx);
    return e;
}

/* memcmp of n items, where a count of zero needs no pointer. */
static int same_bytes(const void* a, const void* b, size_t count, size_t size) {
    if (count == 0) return 1;
    if (a == NULL || b == NULL) return a == b;
    return memcmp(a, b, count * size) == 0;
}

int same_answer(const nts_scene* s, const nts_result* a, const nts_result* b, int summary) {
    const size_t nodes = (size_t)nts_scene_node_count(s);
    nts_summary sa = a->summary, sb = b->summary;
    if (summary != NTST_SUMMARY_WHOLE) sa.cell_size = sb.cell_size = 0.0;
    if (memcmp(&sa, &sb, sizeof sa) != 0) return 0;
    if (a->gap_count != b->gap_count || a->contact_count != b->contact_count ||
        a->stiffness.count != b->stiffness.count || a->anchor_count != b->anchor_count)
        return 0;
    if ((a->forces == NULL) != (b->forces == NULL) || (a->pressure == NULL) != (b->pressure == NULL)) return 0;
    return same_bytes(a->gaps, b->gaps, (size_t)a->gap_count, sizeof(nts_contact)) &&
           same_bytes(a->contacts, b->contacts, (size_t)a->contact_count, sizeof(nts_contact)) &&
           same_bytes(a->stiffness.rows, b->stiffness.rows, (size_t)a->stiffness.count, sizeof(int)) &&
           same_bytes(a->stiffness.cols, b->stiffness.cols, (size_t)a->stiffness.count, sizeof(int)) &&
           same_bytes(a->stiffness.values, b->stiffness.values, (size_t)a->stiffness.count, sizeof(double)) &&
           same_bytes(a->anchors, b->anchors, (size_t)a->anchor_count, sizeof(nts_anchor)) &&
           same_bytes(a->forces, b->forces, a->forces != NULL ? nodes : 0, sizeof(nts_vec2)) &&
           same_bytes(a->pressure, b->pressure, a->pressure != NULL ? nodes : 0, sizeof(double));
}

int update_both(nts_scene* s, const nts_vec2* pos, nts_error* err) {
    const size_t n = (size_t)nts_scene_node_count(s);
    nts_vec2* before = (nts_vec2*)malloc(sizeof(nts_vec2) * (n ? n : 1));
    nts_vec2* fused = (nts_vec2*)malloc(sizeof(nts_vec2) * (n ? n : 1));
    nts_context *c1 = nts_context_create(), *c2 = nts_context_create();
    nts_options opt = nts_default_options();
    nts_result r1, r2;
    nts_error e1, e2;
    int rc1, rc;
    CU_ASSERT_FATAL(before != NULL && fused != NULL && c1 != NULL && c2 != NULL);
    opt.outputs = NTS_OUT_ALL;
    memcpy(before, nts_scene_positions(s), sizeof(nts_vec2) * n);
    rc1 = nts_evaluate_positions(c1, s, pos, &opt, &r1, &e1);
    memcpy(fused, nts_scene_positions(s), sizeof(nts_vec2) * n);
    if (rc1 == NTS_OK) CU_ASSERT(nts_scene_update_positions(s, before, &e2) == NTS_OK); /* back, for the update */
    rc = nts_scene_update_positions(s, pos, err);
    if (rc != rc1)
        fprintf(stderr, "\n  update: %d (%s), evaluate_positions: %d (%s)\n", rc, err != NULL ? err->message : "",
                rc1, e1.message);
    CU_ASSERT(rc == rc1);
    /* the same error, named the same way, and the same positions taken (or kept) */
    if (rc != NTS_OK && err != NULL) CU_ASSERT(memcmp(err, &e1, sizeof e1) == 0);
    CU_ASSERT(memcmp(fused, nts_scene_positions(s), sizeof(nts_vec2) * n) == 0);
    if (rc == NTS_OK && rc1 == NTS_OK) {
        CU_ASSERT(nts_evaluate(c2, s, &opt, &r2, &e2) == NTS_OK);
        CU_ASSERT(same_answer(s, &r1, &r2, NTST_SUMMARY_WHOLE));
    }
    nts_context_destroy(c1);
    nts_context_destroy(c2);
    free(before);
    free(fused);
    return rc;
}
