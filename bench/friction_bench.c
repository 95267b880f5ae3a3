/* friction_bench: what friction costs (docs/benchmarks.md, "Friction").
 *
 *   friction_bench [--quick] [--rounds N] [--threads N]
 *
 * Periodic benchmark packings of about 1e4, 1e5 and 1e6 surface nodes
 * (--quick: 1e4 and 1e5), default options with alpha 0.2, one thread. The
 * history is committed at the packing as built; every node is then moved by
 * a small shear (so that contacts stick and slip), and the evaluation at
 * the sheared positions is timed frictionless and with friction
 * (coefficient 0.3, the committed history), on two warm contexts, in
 * interleaved rounds: the same scene, the same contacts. Prints a Markdown
 * table: nodes, contacts (sticking, slipping), ns per surface node without
 * and with friction (medians), the ratio round by round (median, range),
 * and the history's bytes per active contact. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

static void die(const char* what, const nts_error* err) {
    fprintf(stderr, "friction_bench: %s: %s\n", what, err != NULL ? err->message : "");
    exit(1);
}

static double eval_ns(nts_context* ctx, const nts_scene* s, const nts_options* o, nts_result* r, int n) {
    nts_error err;
    const double t0 = ntsx_now();
    if (nts_evaluate(ctx, s, o, r, &err) != NTS_OK) die("evaluate", &err);
    return 1e9 * (ntsx_now() - t0) / n;
}

int main(int argc, char** argv) {
    static const int targets[] = {10000, 100000, 1000000};
    int quick = 0, rounds = 15, threads = 0, i, t;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--rounds") == 0 && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) threads = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--quick] [--rounds N] [--threads N]\n", argv[0]);
            return 2;
        }
    }
    if (rounds < 3) rounds = 3;
    printf("| surface nodes | contacts | sticking | slipping | frictionless ns/node | friction ns/node | "
           "friction/frictionless (median; range) | history bytes per contact |\n");
    printf("|---:|---:|---:|---:|---:|---:|---|---:|\n");
    for (t = 0; t < (quick ? 2 : 3); ++t) {
        ntsx_scene b;
        ntsx_packing_def d = ntsx_default_packing(targets[t] / 48, 1, 2026u + (uint64_t)t);
        nts_scene* s;
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
        nts_history* h = nts_history_create();
        nts_options o0 = nts_default_options(), o1;
        nts_result r0, r1;
        nts_error err;
        double* ta = (double*)malloc(sizeof(double) * (size_t)rounds);
        double* tb = (double*)malloc(sizeof(double) * (size_t)rounds);
        double* ratio = (double*)malloc(sizeof(double) * (size_t)rounds);
        int k, n, body;
        ntsx_packing(&b, &d);
        s = ntsx_scene_create(&b, &err);
        if (s == NULL) die("scene", &err);
        n = nts_scene_surface_node_count(s);
        o0.threads = threads;
        o1 = o0;
        o1.friction = 0.3;
        o1.history = h;
        if (nts_evaluate(c1, s, &o1, &r1, &err) != NTS_OK) die("evaluate", &err);
        if (nts_history_commit(h, &r1) != NTS_OK) die("commit", NULL);
        /* a shear: each node moved by 2% of a body's radius along x, by its height */
        for (body = 0; body < b.body_count; ++body) {
            nts_vec2* x = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)b.counts[body]);
            for (k = 0; k < b.counts[body]; ++k) x[k] = nts_v2(b.nodes[body][k].x + 0.004 * b.nodes[body][k].y, b.nodes[body][k].y);
            if (nts_scene_set_positions(s, body, x, &err) != NTS_OK) die("positions", &err);
            free(x);
        }
        /* warm both contexts */
        eval_ns(c0, s, &o0, &r0, n);
        eval_ns(c1, s, &o1, &r1, n);
        if (r0.summary.contacts != r1.summary.contacts) die("the same contacts", NULL);
        for (k = 0; k < rounds; ++k) {
            ta[k] = eval_ns(c0, s, &o0, &r0, n);
            tb[k] = eval_ns(c1, s, &o1, &r1, n);
            ratio[k] = tb[k] / ta[k];
        }
        {
            double lo, hi;
            ntsx_range(ratio, rounds, &lo, &hi);
            printf("| %d | %d | %d | %d | %.1f | %.1f | %.3f (%.3f-%.3f) | %.1f |\n", n, r1.summary.contacts,
                   r1.summary.sticking, r1.summary.slipping, ntsx_median(ta, rounds), ntsx_median(tb, rounds),
                   ntsx_median(ratio, rounds), lo, hi,
                   (double)nts_history_bytes(h) / (r1.summary.contacts > 0 ? r1.summary.contacts : 1));
            fflush(stdout);
        }
        free(ta);
        free(tb);
        free(ratio);
        nts_history_destroy(h);
        nts_context_destroy(c0);
        nts_context_destroy(c1);
        nts_scene_destroy(s);
        ntsx_scene_free(&b);
    }
    return 0;
}
