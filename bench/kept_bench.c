/* kept_bench: a solver's loop with a kept candidate list against the same
 * loop searching from scratch (docs/benchmarks.md, "Kept candidates").
 *
 *   kept_bench [--quick] [--rounds N] [--threads N] [--steps S] [--per-build K] [--two-threads]
 *
 * Periodic benchmark packings of about 1e4, 1e5 and 1e6 surface nodes
 * (--quick: 1e4 and 1e5), default options (alpha 0.2, forces, energy,
 * virial), one thread. Every body moves along a direction of its own, and
 * each of its nodes along its own a fifth as much, back and forth: node i at
 * step k is at X_i + A sin(w k) u_i, with A half the search radius and w
 * such that a step moves a node at most 1/K of what the default skin allows
 * (docs/model.md (29)), K = 10 by default: about K steps between builds. A
 * loop of S steps (default 20) gives each step's positions to the scene and
 * evaluates. Round j runs steps jS + 1 .. (j + 1)S three ways, each on a warm
 * context of its own: from scratch, the positions given by
 * nts_scene_update_positions and then nts_evaluate (timed apart); from
 * scratch in one call, nts_evaluate_positions (the positions checked in the
 * segment pass, as a session's binary step takes them); and with a kept list,
 * nts_evaluate_positions again (a session's step). The same positions, the
 * same contacts: every step's energy and the last step's forces checked
 * equal bit for bit.
 * Prints a Markdown table: nodes, contacts, builds per loop, ns per surface
 * node of the evaluation from scratch, of the step from scratch (update +
 * evaluation, and in one call) and of the kept step, and, round by round
 * (median, range), the ratio of the step in one call to the evaluation from
 * scratch (issue 27 §3) and of the kept step to it (§1).
 *
 * --two-threads (issue 27 §4, a solver's loop): each round also runs the
 * kept loop on 2 threads (a warm context and a list of its own; the build's
 * OpenMP backend, pinned by OMP_PROC_BIND=true), checked bit for bit as
 * above, and, as threads_bench does for an evaluation, two kept loops of one
 * thread at once, each on its own context, list and positions, one on each
 * of two threads of the bench: what the machine gives two threads on this
 * work (twice the round's kept loop over the pair's wall time). Adds the
 * kept step's time on 2 threads, its speed-up over the kept step (median;
 * range), the pair's gain (median; range) and the speed-up over it. The
 * one-thread side is the kept loop as --threads asks (default 0: serial). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(_OPENMP)
#include <omp.h>
#endif

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

static void die(const char* what, const nts_error* err) {
    fprintf(stderr, "kept_bench: %s: %s\n", what, err != NULL ? err->message : "");
    exit(1);
}

typedef struct loop {
    nts_scene* s;
    const nts_vec2* base;
    const nts_vec2* dir;
    nts_vec2* pos;
    int nodes, surface, steps;
    double amp, omega;
} loop;

/* Steps first + 1 .. first + S on ctx: seconds of the evaluations alone and
 * of the steps (update + evaluation, or nts_evaluate_positions when `fused`:
 * both times are the call's); each step's energy into energy[] and the last
 * step's forces into forces, or checked against them (check). */
static void run_loop(const loop* L, nts_context* ctx, const nts_options* o, int first, int fused, double* eval_s,
                     double* step_s, double* energy, nts_vec2* forces, int check) {
    nts_result r;
    nts_error err;
    int k, i;
    *eval_s = *step_s = 0.0;
    for (k = 1; k <= L->steps; ++k) {
        const double a = L->amp * sin(L->omega * (first + k));
        double t0, t1, t2;
        for (i = 0; i < L->nodes; ++i) {
            L->pos[i].x = L->base[i].x + a * L->dir[i].x;
            L->pos[i].y = L->base[i].y + a * L->dir[i].y;
        }
        t0 = ntsx_now();
        if (fused) {
            if (nts_evaluate_positions(ctx, L->s, L->pos, o, &r, &err) != NTS_OK) die("evaluate_positions", &err);
            t1 = t0;
        } else {
            if (nts_scene_update_positions(L->s, L->pos, &err) != NTS_OK) die("update", &err);
            t1 = ntsx_now();
            if (nts_evaluate(ctx, L->s, o, &r, &err) != NTS_OK) die("evaluate", &err);
        }
        t2 = ntsx_now();
        *eval_s += t2 - t1;
        *step_s += t2 - t0;
        if (check) {
            if (memcmp(&energy[k - 1], &r.summary.energy, sizeof(double)) != 0) die("the same energy", NULL);
            if (k == L->steps && memcmp(forces, r.forces, sizeof(nts_vec2) * (size_t)L->nodes) != 0)
                die("the same forces", NULL);
        } else {
            energy[k - 1] = r.summary.energy;
            if (k == L->steps) memcpy(forces, r.forces, sizeof(nts_vec2) * (size_t)L->nodes);
        }
    }
}

/* The wall time of two kept loops of steps first + 1 .. first + S at once,
 * one thread each (pair[k] on its own context, list and positions), every
 * step checked against energy[] and forces as run_loop checks; -1 without
 * OpenMP or with one thread allowed (OMP_THREAD_LIMIT=1): not measured. */
static double pair_seconds(const loop pair[2], nts_context* ctx[2], const nts_options o[2], int first,
                           double* energy, nts_vec2* forces) {
#if defined(_OPENMP)
    double t0, t1;
    int team = 2;
    t0 = ntsx_now();
#pragma omp parallel num_threads(2) reduction(min : team)
    {
        const int me = omp_get_thread_num();
        double e, st;
        team = omp_get_num_threads();
        run_loop(&pair[me], ctx[me], &o[me], first, 1, &e, &st, energy, forces, 1);
    }
    t1 = ntsx_now();
    return team == 2 ? t1 - t0 : -1.0;
#else
    (void)pair;
    (void)ctx;
    (void)o;
    (void)first;
    (void)energy;
    (void)forces;
    return -1.0;
#endif
}

int main(int argc, char** argv) {
    static const int targets[] = {10000, 100000, 1000000};
    int quick = 0, rounds = 7, threads = 0, steps = 20, two = 0, i, t;
    double per_build = 10.0;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--rounds") == 0 && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) threads = atoi(argv[++i]);
        else if (strcmp(argv[i], "--steps") == 0 && i + 1 < argc) steps = atoi(argv[++i]);
        else if (strcmp(argv[i], "--per-build") == 0 && i + 1 < argc) per_build = atof(argv[++i]);
        else if (strcmp(argv[i], "--two-threads") == 0) two = 1;
        else {
            fprintf(stderr, "usage: %s [--quick] [--rounds N] [--threads N] [--steps S] [--per-build K] [--two-threads]\n",
                    argv[0]);
            return 2;
        }
    }
    if (rounds < 3) rounds = 3;
    if (steps < 1) steps = 1;
    printf("| surface nodes | contacts | builds per %d steps | scratch: evaluation ns/node | scratch: update + "
           "evaluation ns/node | scratch: one call ns/node | kept: one call ns/node | one call / evaluation (median; "
           "range) | kept / scratch evaluation (median; range) | list bytes per node |%s\n",
           steps,
           two ? " kept, 2 threads: one call ns/node | kept: speed-up, 2 threads (median; range) | two kept loops at "
                 "once (median; range) | speed-up / two at once (median) |"
               : "");
    printf("|---:|---:|---:|---:|---:|---:|---:|---|---|---:|%s\n", two ? "---:|---|---|---:|" : "");
    for (t = 0; t < (quick ? 2 : 3); ++t) {
        ntsx_scene b;
        ntsx_packing_def d = ntsx_default_packing(targets[t] / 48, 1, 2026u + (uint64_t)t);
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create(), *c2 = nts_context_create();
        nts_candidates* kc = nts_candidates_create(-1.0);
        /* --two-threads: the kept loop on 2 threads, and the pair's two of one */
        nts_context *c3 = NULL, *cp[2] = {NULL, NULL};
        nts_candidates *kc3 = NULL, *kp[2] = {NULL, NULL};
        loop Lp[2];
        nts_options o0 = nts_default_options(), o1, o3, op[2];
        nts_result r;
        nts_error err;
        loop L;
        nts_vec2 *base, *dir, *forces;
        double *energy, *ta, *tsa, *tf, *tb, *ratio, *door, *t2, *gain2, *pairg, *share, e0, s0, e1, s1, e2, s2, radius;
        long long builds0;
        int k;
        ntsx_packing(&b, &d);
        L.s = ntsx_scene_create(&b, &err);
        if (L.s == NULL) die("scene", &err);
        L.nodes = nts_scene_node_count(L.s);
        L.surface = nts_scene_surface_node_count(L.s);
        L.steps = steps;
        base = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)L.nodes);
        dir = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)L.nodes);
        forces = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)L.nodes);
        L.pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)L.nodes);
        energy = (double*)malloc(sizeof(double) * (size_t)steps);
        ta = (double*)malloc(sizeof(double) * (size_t)rounds);
        tsa = (double*)malloc(sizeof(double) * (size_t)rounds);
        tf = (double*)malloc(sizeof(double) * (size_t)rounds);
        tb = (double*)malloc(sizeof(double) * (size_t)rounds);
        ratio = (double*)malloc(sizeof(double) * (size_t)rounds);
        door = (double*)malloc(sizeof(double) * (size_t)rounds);
        t2 = (double*)malloc(sizeof(double) * (size_t)rounds);
        gain2 = (double*)malloc(sizeof(double) * (size_t)rounds);
        pairg = (double*)malloc(sizeof(double) * (size_t)rounds);
        share = (double*)malloc(sizeof(double) * (size_t)rounds);
        memcpy(base, nts_scene_positions(L.s), sizeof(nts_vec2) * (size_t)L.nodes);
        ntsx_motion_directions(b.counts, b.body_count, 77u + (uint64_t)t, dir);
        L.base = base;
        L.dir = dir;
        o0.threads = threads;
        o1 = o0;
        o1.candidates = kc;
        if (nts_evaluate(c0, L.s, &o0, &r, &err) != NTS_OK) die("evaluate", &err);
        radius = r.summary.search_radius;
        /* eq. (29): the default skin 0.3 r over c = 3 + 2 alpha, K steps of
         * at most A w |u| each */
        L.amp = 0.5 * radius;
        L.omega = 0.3 * radius / (3.0 + 2.0 * o0.alpha) / per_build / (1.2 * L.amp);
        /* warm both, then interleaved rounds */
        run_loop(&L, c0, &o0, 0, 0, &e0, &s0, energy, forces, 0);
        run_loop(&L, c2, &o0, 0, 1, &e2, &s2, energy, forces, 1);
        run_loop(&L, c1, &o1, 0, 1, &e1, &s1, energy, forces, 1);
        if (two) {
            c3 = nts_context_create();
            kc3 = nts_candidates_create(-1.0);
            o3 = o1;
            o3.threads = 2;
            o3.candidates = kc3;
            run_loop(&L, c3, &o3, 0, 1, &e1, &s1, energy, forces, 1);
            for (i = 0; i < 2; ++i) {
                cp[i] = nts_context_create();
                kp[i] = nts_candidates_create(-1.0);
                op[i] = o1;
                op[i].threads = threads;
                op[i].candidates = kp[i];
                Lp[i] = L;
                Lp[i].pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)L.nodes);
                run_loop(&Lp[i], cp[i], &op[i], 0, 1, &e1, &s1, energy, forces, 1);
            }
        }
        builds0 = nts_candidates_get_info(kc).builds;
        for (k = 0; k < rounds; ++k) {
            run_loop(&L, c0, &o0, (k + 1) * steps, 0, &e0, &s0, energy, forces, 0);
            run_loop(&L, c2, &o0, (k + 1) * steps, 1, &e2, &s2, energy, forces, 1);
            run_loop(&L, c1, &o1, (k + 1) * steps, 1, &e1, &s1, energy, forces, 1);
            ta[k] = 1e9 * e0 / steps / L.surface;
            tsa[k] = 1e9 * s0 / steps / L.surface;
            tf[k] = 1e9 * s2 / steps / L.surface;
            tb[k] = 1e9 * s1 / steps / L.surface;
            door[k] = tf[k] / ta[k];
            ratio[k] = tb[k] / ta[k];
            if (two) {
                double both;
                run_loop(&L, c3, &o3, (k + 1) * steps, 1, &e1, &s1, energy, forces, 1);
                t2[k] = 1e9 * s1 / steps / L.surface;
                gain2[k] = tb[k] / t2[k];
                both = pair_seconds(Lp, cp, op, (k + 1) * steps, energy, forces);
                pairg[k] = both > 0.0 ? 2.0 * tb[k] * 1e-9 * steps * L.surface / both : -1.0;
                share[k] = both > 0.0 ? gain2[k] / pairg[k] : -1.0;
            }
        }
        {
            double lo, hi, dlo, dhi;
            ntsx_range(ratio, rounds, &lo, &hi);
            ntsx_range(door, rounds, &dlo, &dhi);
            if (nts_evaluate(c0, L.s, &o0, &r, &err) != NTS_OK) die("evaluate", &err);
            printf("| %d | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.3f (%.3f-%.3f) | %.3f (%.3f-%.3f) | %.1f |",
                   L.surface, r.summary.contacts, (double)(nts_candidates_get_info(kc).builds - builds0) / rounds,
                   ntsx_median(ta, rounds), ntsx_median(tsa, rounds), ntsx_median(tf, rounds), ntsx_median(tb, rounds),
                   ntsx_median(door, rounds), dlo, dhi, ntsx_median(ratio, rounds), lo, hi,
                   (double)nts_candidates_bytes(kc) / L.surface);
            if (two) {
                double glo, ghi, plo, phi;
                ntsx_range(gain2, rounds, &glo, &ghi);
                ntsx_range(pairg, rounds, &plo, &phi);
                printf(" %.1f | %.3f (%.3f-%.3f) |", ntsx_median(t2, rounds), ntsx_median(gain2, rounds), glo, ghi);
                if (plo > 0.0)
                    printf(" %.3f (%.3f-%.3f) | %.3f |", ntsx_median(pairg, rounds), plo, phi,
                           ntsx_median(share, rounds));
                else
                    printf(" (not measured: no OpenMP, or one thread allowed) | |");
            }
            printf("\n");
            fflush(stdout);
            {
                nts_candidates_info ki = nts_candidates_get_info(kc);
                fprintf(stderr, "kept_bench: %lld evaluations, %lld builds, %lld needed the cells\n", ki.evaluations,
                        ki.builds, ki.cell_builds);
            }
        }
        free(base);
        free(dir);
        free(forces);
        free(L.pos);
        free(energy);
        free(ta);
        free(tsa);
        free(tf);
        free(tb);
        free(ratio);
        free(door);
        free(t2);
        free(gain2);
        free(pairg);
        free(share);
        if (two) {
            for (i = 0; i < 2; ++i) {
                free(Lp[i].pos);
                nts_candidates_destroy(kp[i]);
                nts_context_destroy(cp[i]);
            }
            nts_candidates_destroy(kc3);
            nts_context_destroy(c3);
        }
        nts_candidates_destroy(kc);
        nts_context_destroy(c0);
        nts_context_destroy(c1);
        nts_context_destroy(c2);
        nts_scene_destroy(L.s);
        ntsx_scene_free(&b);
    }
    return 0;
}
