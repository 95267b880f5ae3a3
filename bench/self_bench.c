/* self_bench: what self-contact costs (docs/benchmarks.md, "Self-contact").
 *
 *   self_bench [--quick] [--rounds N] [--threads N]
 *
 * Periodic benchmark packings of about 1e4, 1e5 and 1e6 surface nodes
 * (--quick: 1e4 and 1e5), default options with alpha 0.2, one thread, built
 * twice: without self-contact, and with it on for every body. The packing is
 * at rest, so turning it on must change nothing: the two answers are checked
 * bitwise equal (forces, energy, virial, contacts), then timed on two warm
 * contexts in interleaved rounds. Prints a Markdown table: nodes, contacts,
 * ns per surface node without and with (medians), the ratio round by round
 * (median, range). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

static void die(const char* what, const nts_error* err) {
    fprintf(stderr, "self_bench: %s: %s\n", what, err != NULL ? err->message : "");
    exit(1);
}

static double eval_ns(nts_context* ctx, const nts_scene* s, const nts_options* o, nts_result* r, int n) {
    nts_error err;
    const double t0 = ntsx_now();
    if (nts_evaluate(ctx, s, o, r, &err) != NTS_OK) die("evaluate", &err);
    return 1e9 * (ntsx_now() - t0) / n;
}

/* The packing as a scene, every body with self-contact or none. */
static nts_scene* scene_of(ntsx_scene* b, int self) {
    nts_error err;
    nts_scene* s;
    b->self_contact = self;
    s = ntsx_scene_create(b, &err);
    if (s == NULL) die("scene", &err);
    return s;
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
    printf("| surface nodes | contacts | without ns/node | with ns/node | with/without (median; range) |\n");
    printf("|---:|---:|---:|---:|---|\n");
    for (t = 0; t < (quick ? 2 : 3); ++t) {
        ntsx_scene b;
        ntsx_packing_def d = ntsx_default_packing(targets[t] / 48, 1, 2026u + (uint64_t)t);
        nts_scene *s0, *s1;
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r0, r1;
        double* ta = (double*)malloc(sizeof(double) * (size_t)rounds);
        double* tb = (double*)malloc(sizeof(double) * (size_t)rounds);
        double* ratio = (double*)malloc(sizeof(double) * (size_t)rounds);
        int k, n;
        ntsx_packing(&b, &d);
        s0 = scene_of(&b, 0);
        s1 = scene_of(&b, 1);
        n = nts_scene_surface_node_count(s0);
        o.threads = threads;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
        eval_ns(c0, s0, &o, &r0, n);
        eval_ns(c1, s1, &o, &r1, n);
        /* at rest: self-contact finds nothing, so the answer is the same, bit for bit */
        if (r0.summary.contacts != r1.summary.contacts || memcmp(&r0.summary.energy, &r1.summary.energy, sizeof(double)) != 0 ||
            memcmp(&r0.summary.virial, &r1.summary.virial, sizeof r0.summary.virial) != 0 ||
            memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s0)) != 0)
            die("the same answer with self-contact on at rest", NULL);
        for (k = 0; k < rounds; ++k) {
            ta[k] = eval_ns(c0, s0, &o, &r0, n);
            tb[k] = eval_ns(c1, s1, &o, &r1, n);
            ratio[k] = tb[k] / ta[k];
        }
        {
            double lo, hi;
            ntsx_range(ratio, rounds, &lo, &hi);
            printf("| %d | %d | %.1f | %.1f | %.3f (%.3f-%.3f) |\n", n, r0.summary.contacts, ntsx_median(ta, rounds),
                   ntsx_median(tb, rounds), ntsx_median(ratio, rounds), lo, hi);
            fflush(stdout);
        }
        free(ta);
        free(tb);
        free(ratio);
        nts_context_destroy(c0);
        nts_context_destroy(c1);
        nts_scene_destroy(s0);
        nts_scene_destroy(s1);
        ntsx_scene_free(&b);
    }
    return 0;
}
