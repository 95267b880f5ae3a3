/* kept_bench: a solver's loop with a kept candidate list against the same
 * loop searching from scratch (docs/benchmarks.md, "Kept candidates").
 *
 *   kept_bench [--quick] [--rounds N] [--threads N] [--steps S] [--per-build K]
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
 * scratch (issue 27 §3) and of the kept step to it (§1). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

int main(int argc, char** argv) {
    static const int targets[] = {10000, 100000, 1000000};
    int quick = 0, rounds = 7, threads = 0, steps = 20, i, t;
    double per_build = 10.0;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--rounds") == 0 && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) threads = atoi(argv[++i]);
        else if (strcmp(argv[i], "--steps") == 0 && i + 1 < argc) steps = atoi(argv[++i]);
        else if (strcmp(argv[i], "--per-build") == 0 && i + 1 < argc) per_build = atof(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--quick] [--rounds N] [--threads N] [--steps S] [--per-build K]\n", argv[0]);
            return 2;
        }
    }
    if (rounds < 3) rounds = 3;
    if (steps < 1) steps = 1;
    printf("| surface nodes | contacts | builds per %d steps | scratch: evaluation ns/node | scratch: update + "
           "evaluation ns/node | scratch: one call ns/node | kept: one call ns/node | one call / evaluation (median; "
           "range) | kept / scratch evaluation (median; range) | list bytes per node |\n",
           steps);
    printf("|---:|---:|---:|---:|---:|---:|---:|---|---|---:|\n");
    for (t = 0; t < (quick ? 2 : 3); ++t) {
        ntsx_scene b;
        ntsx_packing_def d = ntsx_default_packing(targets[t] / 48, 1, 2026u + (uint64_t)t);
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create(), *c2 = nts_context_create();
        nts_candidates* kc = nts_candidates_create(-1.0);
        nts_options o0 = nts_default_options(), o1;
        nts_result r;
        nts_error err;
        loop L;
        nts_vec2 *base, *dir, *forces;
        double *energy, *ta, *tsa, *tf, *tb, *ratio, *door, e0, s0, e1, s1, e2, s2, radius;
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
        }
        {
            double lo = ratio[0], hi = ratio[0], dlo = door[0], dhi = door[0];
            for (k = 1; k < rounds; ++k) {
                lo = ratio[k] < lo ? ratio[k] : lo;
                hi = ratio[k] > hi ? ratio[k] : hi;
                dlo = door[k] < dlo ? door[k] : dlo;
                dhi = door[k] > dhi ? door[k] : dhi;
            }
            if (nts_evaluate(c0, L.s, &o0, &r, &err) != NTS_OK) die("evaluate", &err);
            printf("| %d | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.3f (%.3f-%.3f) | %.3f (%.3f-%.3f) | %.1f |\n",
                   L.surface, r.summary.contacts, (double)(nts_candidates_get_info(kc).builds - builds0) / rounds,
                   ntsx_median(ta, rounds), ntsx_median(tsa, rounds), ntsx_median(tf, rounds), ntsx_median(tb, rounds),
                   ntsx_median(door, rounds), dlo, dhi, ntsx_median(ratio, rounds), lo, hi,
                   (double)nts_candidates_bytes(kc) / L.surface);
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
        nts_candidates_destroy(kc);
        nts_context_destroy(c0);
        nts_context_destroy(c1);
        nts_context_destroy(c2);
        nts_scene_destroy(L.s);
        ntsx_scene_free(&b);
    }
    return 0;
}
