/* deep_bench: what a deep slave costs the default search (issue 22).
 *
 *   deep_bench [MASTER_NODES [SLAVE_NODES]]
 *
 * A fine disk (SLAVE_NODES, default 2e4, radius 0.6) pushed into a fine unit
 * disk (MASTER_NODES, default 1e5) by 0.002, 0.3 and 1.0. For each: the best
 * of 3 warm evaluations (wall) with the default radius (every active contact
 * at any depth: docs/model.md §4.5), the contacts and how many are deeper
 * than the radius; then the same radius given explicitly (the deep ones left
 * out, and counted in the warnings) and a radius of 0 (the smallest search).
 * Figures go to docs/benchmarks.md ("The default radius"). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

static const double PI = 3.14159265358979323846;

static double best_of_3(const nts_scene* s, double radius, nts_result* r) {
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_error err;
    double best = HUGE_VAL;
    int k;
    if (c == NULL) exit(1);
    o.search_radius = radius;
    for (k = 0; k < 4; ++k) { /* the first warms the context */
        const double t0 = ntsx_now();
        if (nts_evaluate(c, s, &o, r, &err) != NTS_OK) {
            fprintf(stderr, "deep_bench: %s\n", err.message);
            exit(1);
        }
        if (k > 0 && ntsx_now() - t0 < best) best = ntsx_now() - t0;
    }
    nts_context_destroy(c);
    return best;
}

int main(int argc, char** argv) {
    const int N = argc > 1 ? atoi(argv[1]) : 100000, M = argc > 2 ? atoi(argv[2]) : 20000;
    const double rs = 0.6, overlaps[3] = {0.002, 0.3, 1.0};
    int q;
    if (N < 8 || M < 8 || N > 10000000 || M > 10000000) {
        fprintf(stderr, "usage: deep_bench [MASTER_NODES [SLAVE_NODES]]\n");
        return 2;
    }
    printf("| overlap | default | contacts | deeper than r | r | r given | warnings | r = 0 |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (q = 0; q < 3; ++q) {
        ntsx_scene x;
        nts_scene* s;
        nts_error err;
        nts_result r;
        double t_def, t_r, t_0, rr;
        int i, contacts, deep;
        ntsx_scene_init(&x, 2);
        x.counts[0] = N;
        x.nodes[0] = calloc((size_t)N, sizeof(nts_vec2));
        x.counts[1] = M;
        x.nodes[1] = calloc((size_t)M, sizeof(nts_vec2));
        if (x.nodes[0] == NULL || x.nodes[1] == NULL) return 1;
        for (i = 0; i < N; ++i) x.nodes[0][i] = nts_v2(cos(2 * PI * i / N), sin(2 * PI * i / N));
        for (i = 0; i < M; ++i)
            x.nodes[1][i] = nts_v2(1.0 + rs - overlaps[q] + rs * cos(2 * PI * i / M + 0.1),
                                   rs * sin(2 * PI * i / M + 0.1));
        x.total = N + M;
        if ((s = ntsx_scene_create(&x, &err)) == NULL) {
            fprintf(stderr, "deep_bench: %s\n", err.message);
            return 1;
        }
        t_def = best_of_3(s, -1.0, &r);
        rr = r.summary.search_radius;
        contacts = r.summary.contacts;
        deep = r.summary.deep_contacts;
        t_r = best_of_3(s, rr, &r);
        printf("| %.3f | %.4f s | %d | %d | %.2g | %.4f s | %lld |", overlaps[q], t_def, contacts, deep, rr, t_r,
               r.warning_count > 0 ? r.warnings[0].count : 0LL);
        t_0 = best_of_3(s, 0.0, &r);
        printf(" %.4f s |\n", t_0);
        nts_scene_destroy(s);
        ntsx_scene_free(&x);
    }
    return 0;
}
