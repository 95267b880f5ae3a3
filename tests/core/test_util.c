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
    test_packing p;
    test_rng rng = {seed * 0x9E3779B97F4A7C15ULL + 1ULL};
    int side = (int)ceil(sqrt((double)count)), i;
    p.bodies = (test_body*)calloc((size_t)count, sizeof(test_body));
    p.count = count;
    p.lx = periodic ? side * spacing : 0.0;
    p.ly = periodic ? side * spacing : 0.0;
    for (i = 0; i < count; ++i) {
        int gx = i % side, gy = i / side, k;
        nts_vec2 c = nts_v2((gx + 0.5) * spacing + 0.1 * spacing * (rng_uniform(&rng) - 0.5),
                            (gy + 0.5) * spacing + 0.1 * spacing * (rng_uniform(&rng) - 0.5));
        double r = radius * (1.0 + 0.08 * (rng_uniform(&rng) - 0.5));
        make_polygon(&p.bodies[i], nodes, r, c, 6.283185307179586 * rng_uniform(&rng));
        /* Deform: jitter the radius of every node a little. */
        for (k = 0; k < nodes; ++k) {
            nts_vec2 d = nts_sub(p.bodies[i].nodes[k], c);
            double f = 1.0 + 0.04 * (rng_uniform(&rng) - 0.5);
            p.bodies[i].nodes[k] = nts_add(c, nts_scale(f, d));
        }
    }
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
