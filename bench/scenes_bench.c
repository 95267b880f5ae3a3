/* scenes_bench: scenes as users build them (issue 12).
 *
 *   scenes_bench [SIDE [REPEATS]]
 *
 * SIDE x SIDE pressed disks (32 nodes, radius 1) in a square container whose
 * walls are either four long segments (the inner loop of the container body)
 * or the same walls cut into disk-sized pieces (collinear nodes every ~2
 * units). Both run with the container's own alpha = 0 (sharp inner corners)
 * and with the scene's alpha = 0.2 everywhere, default search radius. Prints
 * the median wall time of warm evaluations per variant, the cell side used,
 * the contacts, and how far the forces on the disks differ between the long
 * and the cut walls (relative to the largest force): the same answer up to
 * round-off is the contract. Figures go to docs/benchmarks.md ("Long walls"). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

typedef struct built {
    nts_scene* scene;
    int disk_offset; /* first global node of the disks */
} built;

/* The container (support/scenes.c, shared with tests/core/test_scenes.c):
 * side x side disks of 32 nodes in an outer square and an inner (hole) square
 * whose sides are cut into `pieces` collinear segments each. */
static built build(int side, int pieces, int sharp) {
    ntsx_scene b;
    nts_error err;
    built out;
    ntsx_container(&b, side, pieces, 32, sharp);
    out.scene = ntsx_scene_create(&b, &err);
    out.disk_offset = b.counts[0];
    ntsx_scene_free(&b);
    if (out.scene == NULL) {
        fprintf(stderr, "scenes_bench: %s: %s\n", nts_status_name(err.code), err.message);
        exit(2);
    }
    return out;
}

typedef struct timed {
    double ms, cell;
    int contacts;
    nts_vec2* forces; /* the disks' (owned) */
} timed;

static timed run(const built* b, double alpha, int repeats) {
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    double* t = malloc(sizeof(double) * (size_t)repeats);
    int k, n = nts_scene_node_count(b->scene) - b->disk_offset;
    timed out;
    o.alpha = alpha;
    o.penalty = 100.0;
    if (nts_evaluate(ctx, b->scene, &o, &r, &err) != 0) {
        fprintf(stderr, "scenes_bench: %s\n", err.message);
        exit(2);
    }
    for (k = 0; k < repeats; ++k) {
        double t0 = ntsx_now();
        nts_evaluate(ctx, b->scene, &o, &r, &err);
        t[k] = ntsx_now() - t0;
    }
    out.ms = 1e3 * ntsx_median(t, repeats);
    out.cell = r.summary.cell_size;
    out.contacts = r.summary.contacts;
    out.forces = malloc(sizeof(nts_vec2) * (size_t)n);
    memcpy(out.forces, r.forces + b->disk_offset, sizeof(nts_vec2) * (size_t)n);
    free(t);
    nts_context_destroy(ctx);
    return out;
}

int main(int argc, char** argv) {
    int side = argc > 1 ? atoi(argv[1]) : 30, repeats = argc > 2 ? atoi(argv[2]) : 9, sharp;
    if (side < 2 || side > 1000 || repeats < 1 || repeats > 1000) {
        fprintf(stderr, "usage: scenes_bench [SIDE [REPEATS]]\n");
        return 2;
    }
    printf("| container walls | alpha | wall time | cell side | contacts | max force difference on the disks |\n");
    printf("|---|---|---:|---:|---:|---:|\n");
    for (sharp = 1; sharp >= 0; --sharp) {
        built lw = build(side, 1, sharp), cw = build(side, side, sharp);
        timed a = run(&lw, 0.2, repeats), c = run(&cw, 0.2, repeats);
        int n = nts_scene_node_count(lw.scene) - lw.disk_offset, i;
        double fbig = 0.0, dmax = 0.0;
        for (i = 0; i < n; ++i) {
            double f = fmax(fabs(c.forces[i].x), fabs(c.forces[i].y));
            double d = fmax(fabs(a.forces[i].x - c.forces[i].x), fabs(a.forces[i].y - c.forces[i].y));
            if (f > fbig) fbig = f;
            if (d > dmax) dmax = d;
        }
        printf("| 4 long segments | %s | %.2f ms | %.3f | %d | %.2g |\n", sharp ? "walls 0, disks 0.2" : "0.2 everywhere",
               a.ms, a.cell, a.contacts, dmax / fbig);
        printf("| cut into %d pieces each | %s | %.2f ms | %.3f | %d | (reference) |\n", side,
               sharp ? "walls 0, disks 0.2" : "0.2 everywhere", c.ms, c.cell, c.contacts);
        printf("| ratio long / cut | | %.2f | | | |\n", a.ms / c.ms);
        free(a.forces);
        free(c.forces);
        nts_scene_destroy(lw.scene);
        nts_scene_destroy(cw.scene);
    }
    return 0;
}
