/* threads_bench: one thread against two on the same evaluation, paired
 * (docs/benchmarks.md, "Two threads").
 *
 *   threads_bench [--rounds N] [--sizes LIST]
 *
 * Periodic benchmark packings (ntsx_default_packing) of about 1e5 and 1e6
 * surface nodes (--sizes in surface nodes), default options. Each round
 * evaluates on a warm 1-thread context and then on a warm 2-thread context
 * (the build's OpenMP backend; pin it with OMP_PROC_BIND=true); the speed-up
 * of a round is the ratio of the two. Prints, per size, the medians of the
 * rounds (ns per surface node), the median speed-up and its range, and each
 * phase's median (nts_context_profile) with 1 and 2 threads. The results are
 * checked equal bit for bit (energy and forces), the pair's below too.
 *
 * What the machine gives two threads, in the same rounds: two one-thread
 * evaluations of the same scene at once, each on its own warm context, one on
 * each of two threads of the bench (pinned like the library's by
 * OMP_PROC_BIND). Twice the round's one-thread time over the pair's wall time
 * is the throughput two threads of this machine reach on this work with no
 * serial part and no hand-over: 2 on two free cores, less when the two
 * share a core (SMT siblings) or its caches and memory. A reference, not a
 * bound: the pair reads two contexts' buffers where one evaluation's two
 * threads share one. The last column is the speed-up over it, round by
 * round. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(_OPENMP)
#include <omp.h>
#endif

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

static void die(const char* what, const nts_error* err) {
    fprintf(stderr, "threads_bench: %s: %s\n", what, err != NULL ? err->message : "");
    exit(1);
}

enum { MAX_ROUNDS = 101 };

/* Whether two answers of the scene are the same bits (energy and forces). */
static int same_bits(const nts_result* a, const nts_result* b, int nodes) {
    return memcmp(&a->summary.energy, &b->summary.energy, sizeof(double)) == 0 &&
           memcmp(a->forces, b->forces, sizeof(nts_vec2) * (size_t)nodes) == 0;
}

/* The wall time of two one-thread evaluations at once, pair[0] on one
 * thread and pair[1] on another; -1 without OpenMP or with one thread
 * allowed (OMP_THREAD_LIMIT=1): not measured then. */
static double pair_seconds(nts_context* pair[2], const nts_scene* s, const nts_options* o1, nts_result out[2]) {
#if defined(_OPENMP)
    double t0, t1;
    int ok = 1, team = 2;
    t0 = ntsx_now();
#pragma omp parallel num_threads(2) reduction(&& : ok) reduction(min : team)
    {
        nts_error err;
        const int me = omp_get_thread_num();
        team = omp_get_num_threads();
        ok = nts_evaluate(pair[me], s, o1, &out[me], &err) == NTS_OK;
    }
    t1 = ntsx_now();
    if (!ok) die("two one-thread evaluations at once", NULL);
    return team == 2 ? t1 - t0 : -1.0; /* (a thread limit of 1: no pair) */
#else
    (void)pair;
    (void)s;
    (void)o1;
    (void)out;
    return -1.0;
#endif
}

int main(int argc, char** argv) {
    int sizes[8] = {100000, 1000000}, nsizes = 2, rounds = 15, i, t, k, th;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--rounds") == 0 && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (strcmp(argv[i], "--sizes") == 0 && i + 1 < argc) {
            char* p = argv[++i];
            for (nsizes = 0; nsizes < 8 && *p;) {
                sizes[nsizes++] = (int)strtol(p, &p, 10);
                if (*p == ',') ++p;
            }
        } else {
            fprintf(stderr, "usage: %s [--rounds N] [--sizes N,N]\n", argv[0]);
            return 2;
        }
    }
    if (rounds < 3) rounds = 3;
    if (rounds > MAX_ROUNDS) rounds = MAX_ROUNDS;
    printf("| surface nodes | 1 thread ns/node | 2 threads ns/node | speed-up (median; range) | phases, 1 thread "
           "(segments, cells, search, scatter) | phases, 2 threads | two at once (median; range) | speed-up / "
           "two at once (median) |\n|---:|---:|---:|---|---|---|---|---|\n");
    for (t = 0; t < nsizes; ++t) {
        ntsx_scene b;
        ntsx_packing_def d = ntsx_default_packing(sizes[t] / 48, 1, 2026u);
        nts_context *c[2], *pair[2];
        nts_options o[2];
        nts_result r[2], rp[2];
        nts_error err;
        nts_scene* s;
        static double tm[2][MAX_ROUNDS], ratio[MAX_ROUNDS], ph[2][4][MAX_ROUNDS], pair_gain[MAX_ROUNDS], share[MAX_ROUNDS];
        double lo, hi, plo, phi;
        int n;
        ntsx_packing(&b, &d);
        if ((s = ntsx_scene_create(&b, &err)) == NULL) die("scene", &err);
        n = nts_scene_surface_node_count(s);
        for (th = 0; th < 2; ++th) {
            c[th] = nts_context_create();
            o[th] = nts_default_options();
            o[th].threads = th + 1;
            if (nts_evaluate(c[th], s, &o[th], &r[th], &err) != NTS_OK) die("evaluate", &err);
            if ((pair[th] = nts_context_create()) == NULL ||
                nts_evaluate(pair[th], s, &o[0], &rp[th], &err) != NTS_OK)
                die("evaluate", &err);
        }
        for (k = 0; k < rounds; ++k) {
            double both;
            for (th = 0; th < 2; ++th) {
                const double t0 = ntsx_now();
                nts_profile p;
                if (nts_evaluate(c[th], s, &o[th], &r[th], &err) != NTS_OK) die("evaluate", &err);
                tm[th][k] = 1e9 * (ntsx_now() - t0) / n;
                p = nts_context_profile(c[th]);
                ph[th][0][k] = 1e9 * p.segments / n;
                ph[th][1][k] = 1e9 * p.cells / n;
                ph[th][2][k] = 1e9 * p.search / n;
                ph[th][3][k] = 1e9 * p.scatter / n;
            }
            ratio[k] = tm[0][k] / tm[1][k];
            if (!same_bits(&r[0], &r[1], nts_scene_node_count(s))) die("the same bits with 1 and 2 threads", NULL);
            both = pair_seconds(pair, s, &o[0], rp);
            pair_gain[k] = both > 0.0 ? 2.0 * tm[0][k] * 1e-9 * n / both : -1.0;
            share[k] = pair_gain[k] > 0.0 ? ratio[k] / pair_gain[k] : -1.0;
            if (both > 0.0 && !(same_bits(&rp[0], &r[0], nts_scene_node_count(s)) &&
                                same_bits(&rp[1], &r[0], nts_scene_node_count(s))))
                die("the same bits from two evaluations at once", NULL);
        }
        ntsx_range(ratio, rounds, &lo, &hi);
        ntsx_range(pair_gain, rounds, &plo, &phi);
        printf("| %d | %.1f | %.1f | %.3f (%.3f-%.3f) |", n, ntsx_median(tm[0], rounds), ntsx_median(tm[1], rounds),
               ntsx_median(ratio, rounds), lo, hi);
        for (th = 0; th < 2; ++th)
            printf(" %.1f, %.1f, %.1f, %.1f |", ntsx_median(ph[th][0], rounds), ntsx_median(ph[th][1], rounds),
                   ntsx_median(ph[th][2], rounds), ntsx_median(ph[th][3], rounds));
        if (plo > 0.0)
            printf(" %.3f (%.3f-%.3f) | %.3f |", ntsx_median(pair_gain, rounds), plo, phi, ntsx_median(share, rounds));
        else
            printf(" (not measured: no OpenMP, or one thread allowed) | |");
        printf("\n");
        fflush(stdout);
        for (th = 0; th < 2; ++th) {
            nts_context_destroy(c[th]);
            nts_context_destroy(pair[th]);
        }
        nts_scene_destroy(s);
        ntsx_scene_free(&b);
    }
    return 0;
}
