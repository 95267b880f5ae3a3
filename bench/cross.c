/* nts_cross: the same scenes through the public API of any release, so that
 * one program measures and compares two releases side by side. It uses only
 * what every release has (scenes of loops, options alpha, search_radius,
 * solver, outputs and threads, forces and contacts), and the scene builders of
 * support/ (this tree's, built against either release's headers).
 * bench/report.py builds it against the previous release from git and
 * against this tree, and runs both.
 *
 *   nts_cross time FILE.csv [--quick]
 *       Periodic packings of about 1e4, 1e5 and 1e6 surface nodes (the
 *       scaling section's scenes), default options with alpha 0 and 0.2,
 *       one thread: median CPU and wall time per surface node of a warm
 *       evaluation.
 *   nts_cross loop FILE.csv [--quick] [--steps S] [--rounds R] [--per-build K]
 *       kept_bench's solver loop (its scenes, about 1e4, 1e5 and 1e6 surface
 *       nodes, --quick the first two; its motion, X + A sin(w k) u with A
 *       half the default search radius and K steps between a kept list's
 *       builds; its steps: S warm (default 20), then R rounds of S (default
 *       3), round j steps jS + 1 .. (j + 1)S) on this release's default
 *       options, one thread: each step gives the positions to the scene
 *       (nts_scene_update_positions) and evaluates. One CSV row per scene:
 *       the default radius, the last step's contacts, and the wall time per
 *       surface node of the evaluations and of the steps, each round's mean
 *       over its steps, the median over the rounds: kept_bench's figures
 *       for the same steps. bench/release_loop.py runs it built against
 *       release 0.2 and against this tree, beside kept_bench (issue 27:
 *       "today's evaluation").
 *   nts_cross dump DIR
 *       For a fixed set of scenes and options, with the search radius given
 *       (the median segment, computed here, so that releases whose default
 *       radius differs search alike): every node's force and every active
 *       contact, one binary file per case (cross_dump.py reads them).
 *   nts_cross memory EVALS
 *       A periodic packing of 1,441 surface nodes, default options, 2
 *       threads, EVALS evaluations on one context: the context's bytes after
 *       the 1st, 10th, 100th, 1,000th and last, and the most, one CSV row
 *       each (bench/thread_memory.py runs it beside busy loops, whose
 *       schedule deals the threads uneven shares). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

/* Two calls that not every release has (2dc1205, report.py's default
 * "before", has neither): weak, so that nts_cross links against any
 * release, and the modes that need them say so where they are absent
 * (loop, memory); the others never call them. */
#pragma weak nts_scene_update_positions
#pragma weak nts_context_memory_bytes
int nts_scene_update_positions(nts_scene* scene, const nts_vec2* positions, nts_error* err);
size_t nts_context_memory_bytes(const nts_context* ctx);

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void die(const char* what, const nts_error* err) {
    fprintf(stderr, "nts_cross: %s: %s\n", what, err != NULL ? err->message : "");
    exit(1);
}

static nts_scene* scene_of(const ntsx_scene* b) {
    nts_error err;
    nts_scene* s = ntsx_scene_create(b, &err);
    if (s == NULL) die("scene", &err);
    return s;
}

static void evaluate(nts_context* ctx, const nts_scene* s, const nts_options* o, nts_result* r) {
    nts_error err;
    if (nts_evaluate(ctx, s, o, r, &err) != 0) die("evaluate", &err);
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

/* ------------------------------------------------------------------ time */

static int run_time(const char* path, int quick) {
    static const int particles[] = {208, 2083, 20833}; /* about 48 surface nodes each */
    static const double alphas[] = {0.0, 0.2};
    FILE* f = fopen(path, "w");
    int i, a;
    if (f == NULL) {
        fprintf(stderr, "nts_cross: cannot write %s\n", path);
        return 1;
    }
    fprintf(f, "surface_nodes,alpha,reps,eval_ns,eval_cpu_ns,contacts\n");
    for (i = 0; i < 3; ++i) {
        ntsx_scene b;
        ntsx_packing_def def = ntsx_default_packing(particles[i], 1, 779u + 2u * (unsigned)i);
        nts_scene* s;
        ntsx_packing(&b, &def);
        s = scene_of(&b);
        for (a = 0; a < 2; ++a) {
            nts_context* ctx = nts_context_create();
            nts_options o = nts_default_options();
            nts_result r;
            double wall[25], cpu[25], t0;
            const double n = (double)nts_scene_surface_node_count(s), budget = quick ? 0.05 : 0.5;
            int k;
            o.alpha = alphas[a];
            evaluate(ctx, s, &o, &r); /* warm-up: the buffers grow once */
            /* and the processor, for 50 ms (an idle core starts slower) */
            t0 = ntsx_now();
            for (k = 0; k < 100000 && ntsx_now() - t0 < 0.05; ++k) evaluate(ctx, s, &o, &r);
            t0 = ntsx_now();
            for (k = 0; k < 25; ++k) {
                const double w0 = ntsx_now(), c0 = cpu_now();
                evaluate(ctx, s, &o, &r);
                cpu[k] = 1e9 * (cpu_now() - c0) / n;
                wall[k] = 1e9 * (ntsx_now() - w0) / n;
                if (k >= 2 && ntsx_now() - t0 > budget) {
                    ++k;
                    break;
                }
            }
            qsort(cpu, (size_t)k, sizeof(double), cmp_double);
            fprintf(f, "%d,%.2f,%d,%.3f,%.3f,%d\n", (int)n, o.alpha, k, ntsx_median(wall, k), cpu[k / 2],
                    r.summary.contacts);
            fflush(f);
            nts_context_destroy(ctx);
        }
        nts_scene_destroy(s);
        ntsx_scene_free(&b);
    }
    fclose(f);
    return 0;
}

/* ------------------------------------------------------------------ loop */

static int run_loop(const char* path, int quick, int steps, int rounds, double per_build) {
    static const int targets[] = {10000, 100000, 1000000}; /* kept_bench's */
    FILE* f;
    int t;
    if (nts_scene_update_positions == NULL) {
        fprintf(stderr, "nts_cross: loop needs nts_scene_update_positions, which this release does not have\n");
        return 2;
    }
    f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "nts_cross: cannot write %s\n", path);
        return 1;
    }
    fprintf(f, "surface_nodes,search_radius,contacts,steps,rounds,eval_ns,step_ns\n");
    for (t = 0; t < (quick ? 2 : 3); ++t) {
        ntsx_scene b;
        ntsx_packing_def def = ntsx_default_packing(targets[t] / 48, 1, 2026u + (uint64_t)t);
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r;
        nts_error err;
        nts_vec2 *base, *dir, *pos;
        double *te, *ts, amp, omega, radius;
        int n, k, i;
        ntsx_packing(&b, &def);
        s = scene_of(&b);
        n = nts_scene_node_count(s);
        base = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
        dir = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
        pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
        te = (double*)calloc((size_t)rounds, sizeof(double));
        ts = (double*)calloc((size_t)rounds, sizeof(double));
        if (!ctx || !base || !dir || !pos || !te || !ts) die("out of memory", NULL);
        memcpy(base, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
        ntsx_motion_directions(b.counts, b.body_count, 77u + (uint64_t)t, dir); /* kept_bench's */
        evaluate(ctx, s, &o, &r);
        radius = r.summary.search_radius;
        amp = 0.5 * radius;
        omega = 0.3 * radius / (3.0 + 2.0 * o.alpha) / per_build / (1.2 * amp); /* as kept_bench */
        for (k = 1; k <= (rounds + 1) * steps; ++k) { /* steps 1..S warm, then round j: jS+1..(j+1)S */
            const double a = amp * sin(omega * k), per = 1e9 / steps / nts_scene_surface_node_count(s);
            double t0, t1, t2;
            for (i = 0; i < n; ++i) pos[i] = nts_v2(base[i].x + a * dir[i].x, base[i].y + a * dir[i].y);
            t0 = ntsx_now();
            if (nts_scene_update_positions(s, pos, &err) != 0) die("update", &err);
            t1 = ntsx_now();
            evaluate(ctx, s, &o, &r);
            t2 = ntsx_now();
            if (k > steps) {
                te[(k - 1) / steps - 1] += per * (t2 - t1);
                ts[(k - 1) / steps - 1] += per * (t2 - t0);
            }
        }
        fprintf(f, "%d,%.17g,%d,%d,%d,%.3f,%.3f\n", nts_scene_surface_node_count(s), radius, r.summary.contacts,
                steps, rounds, ntsx_median(te, rounds), ntsx_median(ts, rounds));
        fflush(f);
        free(base);
        free(dir);
        free(pos);
        free(te);
        free(ts);
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        ntsx_scene_free(&b);
    }
    fclose(f);
    return 0;
}

/* ------------------------------------------------------------------ dump */

/* The median segment length of the scene's loops (with the periodic box's
 * minimum image): the radius both releases are given. */
static double median_segment(const nts_scene* s, double lx, double ly) {
    const nts_vec2* pos = nts_scene_positions(s);
    int b, l, k, count = 0, cap = nts_scene_node_count(s) + 16;
    double* len = (double*)malloc(sizeof(double) * (size_t)cap), m;
    for (b = 0; b < nts_scene_body_count(s); ++b) {
        const int off = nts_scene_body_node_offset(s, b);
        for (l = 0; l < nts_scene_body_loop_count(s, b); ++l) {
            const int* loop;
            const int n = nts_scene_body_loop(s, b, l, &loop);
            for (k = 0; k < n; ++k) {
                nts_vec2 d = nts_sub(pos[off + loop[(k + 1) % n]], pos[off + loop[k]]);
                if (lx > 0.0) d.x -= lx * nearbyint(d.x / lx);
                if (ly > 0.0) d.y -= ly * nearbyint(d.y / ly);
                if (count == cap) {
                    cap *= 2;
                    len = (double*)realloc(len, sizeof(double) * (size_t)cap);
                }
                len[count++] = sqrt(d.x * d.x + d.y * d.y);
            }
        }
    }
    qsort(len, (size_t)count, sizeof(double), cmp_double);
    m = len[(count - 1) / 2];
    free(len);
    return m;
}

static void dump_case(const char* dir, const char* name, const nts_scene* s, double lx, double ly) {
    static const double alphas[] = {0.0, 0.1, 0.2, 0.5};
    static const char* solvers[] = {"closed_form", "newton"};
    const double r = median_segment(s, lx, ly);
    nts_context* ctx = nts_context_create();
    int a, sv;
    for (sv = 0; sv < 2; ++sv)
        for (a = 0; a < 4; ++a) {
            nts_options o = nts_default_options();
            nts_result res;
            char path[512];
            FILE* f;
            int n = nts_scene_node_count(s), c;
            o.alpha = alphas[a];
            o.solver = (nts_solver)sv;
            o.search_radius = r;
            o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS;
            evaluate(ctx, s, &o, &res);
            snprintf(path, sizeof path, "%s/%s_%s_%.1f.bin", dir, name, solvers[sv], o.alpha);
            if ((f = fopen(path, "wb")) == NULL) {
                fprintf(stderr, "nts_cross: cannot write %s\n", path);
                exit(1);
            }
            fwrite(&n, sizeof n, 1, f);
            fwrite(res.forces, sizeof(nts_vec2), (size_t)n, f);
            fwrite(&res.contact_count, sizeof(int), 1, f);
            for (c = 0; c < res.contact_count; ++c) {
                const nts_contact* k = &res.contacts[c];
                const int key[4] = {k->slave_body, k->slave_node, k->master_body, (int)k->kind};
                fwrite(key, sizeof key, 1, f);
                fwrite(&k->gap, sizeof(double), 1, f);
            }
            fclose(f);
        }
    nts_context_destroy(ctx);
}

static int run_dump(const char* dir) {
    int i;
    for (i = 0; i < 7; ++i) {
        ntsx_scene b;
        nts_scene* s;
        char name[64];
        if (i < 3) {
            const int n = i == 0 ? 16 : (i == 1 ? 100 : 1000);
            ntsx_two_disks(&b, n, 0.05 + 0.1 * i, 0.5);
            snprintf(name, sizeof name, "disks%d", n);
        } else if (i < 6) {
            const int parts = i == 5 ? 2000 : 200, periodic = i != 3;
            ntsx_packing_def def = ntsx_default_packing(parts, periodic, 31u + (unsigned)i);
            ntsx_packing(&b, &def);
            snprintf(name, sizeof name, "packing%d%s", parts, periodic ? "_periodic" : "");
        } else {
            ntsx_container(&b, 12, 4, 24, 0);
            snprintf(name, sizeof name, "container");
        }
        s = scene_of(&b);
        dump_case(dir, name, s, b.lx, b.ly);
        nts_scene_destroy(s);
        ntsx_scene_free(&b);
    }
    return 0;
}

static int run_memory(int evals) {
    ntsx_scene b;
    ntsx_packing_def def = ntsx_default_packing(30, 1, 7);
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    size_t most = 0;
    nts_scene* s;
    int k;
    if (nts_context_memory_bytes == NULL) {
        fprintf(stderr, "nts_cross: memory needs nts_context_memory_bytes, which this release does not have\n");
        nts_context_destroy(ctx);
        return 2;
    }
    ntsx_packing(&b, &def);
    s = scene_of(&b);
    if (ctx == NULL) die("context", NULL);
    o.threads = 2;
    printf("surface_nodes,eval,bytes,most\n");
    for (k = 1; k <= evals; ++k) {
        size_t held;
        if (nts_evaluate(ctx, s, &o, &r, &err) != NTS_OK) {
            printf("%d,%d,error,%zu\n", nts_scene_surface_node_count(s), k, most);
            fprintf(stderr, "nts_cross: evaluation %d: %s\n", k, err.message);
            return 1;
        }
        held = nts_context_memory_bytes(ctx);
        most = held > most ? held : most;
        if (k == 1 || k == 10 || k == 100 || k == 1000 || k == evals)
            printf("%d,%d,%zu,%zu\n", nts_scene_surface_node_count(s), k, held, most);
        fflush(stdout);
    }
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    ntsx_scene_free(&b);
    return 0;
}

int main(int argc, char** argv) {
    if (argc == 3 && strcmp(argv[1], "memory") == 0) return run_memory(atoi(argv[2]) > 0 ? atoi(argv[2]) : 1);
    if (argc >= 3 && strcmp(argv[1], "time") == 0) return run_time(argv[2], argc > 3 && strcmp(argv[3], "--quick") == 0);
    if (argc == 3 && strcmp(argv[1], "dump") == 0) return run_dump(argv[2]);
    if (argc >= 3 && strcmp(argv[1], "loop") == 0) {
        int quick = 0, steps = 20, rounds = 3, i;
        double per_build = 10.0;
        for (i = 3; i < argc; ++i) {
            if (strcmp(argv[i], "--quick") == 0) quick = 1;
            else if (strcmp(argv[i], "--steps") == 0 && i + 1 < argc) steps = atoi(argv[++i]);
            else if (strcmp(argv[i], "--rounds") == 0 && i + 1 < argc) rounds = atoi(argv[++i]);
            else if (strcmp(argv[i], "--per-build") == 0 && i + 1 < argc) per_build = atof(argv[++i]);
            else break;
        }
        if (i == argc && steps >= 1 && rounds >= 1 && per_build > 0.0)
            return run_loop(argv[2], quick, steps, rounds, per_build);
    }
    fprintf(stderr, "usage: %s time FILE.csv [--quick] | loop FILE.csv [--quick] [--steps S] [--rounds R] [--per-build K] | dump DIR | memory EVALS\n", argv[0]);
    return 2;
}
