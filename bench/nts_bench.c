/* nts_bench: speed against error for the ntscontact core (issue 6).
 *
 *   nts_bench --out DIR [--quick] [--sections LIST] [--threads N] [--evals N]
 *
 * Sections (comma separated, default all): digest, disks, packing, errors,
 * smooth, scaling, threads, peer, hard; profile and profile_open (a fixed
 * workload for profilers) only when named. Every section writes one CSV into
 * DIR, named after_SECTION.csv (bench/report.py renames the previous
 * release's, built from git, to before_SECTION.csv). Times are medians of
 * repeated evaluations on a warm context, in nanoseconds per surface node.
 * bench/report.py turns the CSVs into docs/benchmarks.md and docs/hard-cases.md
 * (bench/README.md: which section feeds which table). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include <ntscontact/ntscontact.h>
#include "nts_support.h"

#ifndef NTS_BENCH_VARIANT
#define NTS_BENCH_VARIANT "after"
#endif

/* Seconds per phase of the last evaluation (segment data, cell list, local
 * search, scatter), from the public profile. (The previous release is timed
 * by its own nts_bench, built from git: this file is never built against it.) */
static void nts_context_phase_times(const nts_context* ctx, double out[4]) {
    nts_profile p = nts_context_profile(ctx);
    out[0] = p.segments;
    out[1] = p.cells;
    out[2] = p.search;
    out[3] = p.scatter;
}

static const double PI = 3.14159265358979323846;

/* ------------------------------------------------------------ utilities */

/* CPU time of the process (all threads): on a shared machine it excludes the
 * time the benchmark waited for a core. */
static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double vmax(const double* v, int n) {
    double m = 0.0;
    int i;
    for (i = 0; i < n; ++i)
        if (v[i] > m) m = v[i];
    return m;
}

static void* xmalloc(size_t n) {
    void* p = malloc(n == 0 ? 1 : n);
    if (p == NULL) {
        fprintf(stderr, "nts_bench: out of memory\n");
        exit(2);
    }
    return p;
}

/* Allocator hook: counts live bytes, the peak and the number of allocations of
 * the core (every core allocation goes through nts_set_allocator's hook). */
typedef struct alloc_stats {
    size_t live, peak;
    long long count;
} alloc_stats;
static alloc_stats g_alloc;
/* The core allocates from its worker threads too (per-worker buffers grow
 * inside the parallel search), so the counters are updated in a critical
 * section. */
static void* count_alloc(size_t size, void* user) {
    size_t* p = (size_t*)malloc(size + 16);
    (void)user;
    if (p == NULL) return NULL;
    p[0] = size;
#ifdef _OPENMP
#pragma omp critical(nts_bench_alloc)
#endif
    {
        g_alloc.live += size;
        if (g_alloc.live > g_alloc.peak) g_alloc.peak = g_alloc.live;
        ++g_alloc.count;
    }
    return (char*)p + 16;
}
static void count_free(void* ptr, void* user) {
    size_t* p = (size_t*)((char*)ptr - 16);
    (void)user;
#ifdef _OPENMP
#pragma omp critical(nts_bench_alloc)
#endif
    g_alloc.live -= p[0];
    free(p);
}

static long maxrss_kb(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

/* --------------------------------------------------------------- scenes */

/* Bodies as flat node arrays, one loop through all nodes (counter-clockwise). */
/* The scenes (support/nts_support.h, shared with the tests). */
typedef ntsx_scene scene_buf;
static void buf_free(scene_buf* b) { ntsx_scene_free(b); }

/* Scene (a): two disks of radius 1 pressed together by `overlap`, n nodes each;
 * the second disk's nodes are offset by half a step (no node-on-node contact). */
static double g_disk_phase = 0.5; /* offset of the second disk's nodes, in steps */
static void make_two_disks(scene_buf* b, int n, double overlap) { ntsx_two_disks(b, n, overlap, g_disk_phase); }

/* Scene (b): the jittered packing of deformable disks (ntsx_default_packing). */
static void make_packing(scene_buf* b, int particles, int periodic, uint64_t seed) {
    ntsx_packing_def d = ntsx_default_packing(particles, periodic, seed);
    ntsx_packing(b, &d);
}

static nts_scene* scene_from(const scene_buf* b) {
    nts_error err;
    nts_scene* s = ntsx_scene_create(b, &err);
    if (s == NULL) {
        fprintf(stderr, "nts_bench: scene: %s: %s\n", nts_status_name(err.code), err.message);
        exit(2);
    }
    return s;
}

static void eval_or_die(nts_context* ctx, const nts_scene* s, const nts_options* o, nts_result* r) {
    nts_error err;
    if (nts_evaluate(ctx, s, o, r, &err) != NTS_OK) {
        fprintf(stderr, "nts_bench: evaluate: %s: %s\n", nts_status_name(err.code), err.message);
        exit(2);
    }
}

/* ------------------------------------------------------------- timing */

typedef struct timing {
    double cells, search, eval; /* ns per surface node, medians */
    double eval_min;
    double eval_cpu; /* ns of CPU time per surface node, median */
    int reps, gaps, contacts;
    long long allocs_after_warmup; /* core allocations during the timed evaluations */
} timing;

static int g_quick = 0;
static int g_profile_evals = 5; /* --evals N: evaluations of the profile sections */

/* Median over repeated evaluations on a warm context. Repeats until `budget`
 * seconds are used, at least 3 and at most 25 times. */
static timing time_eval(const nts_scene* s, const nts_options* o, double budget) {
    nts_context* ctx = nts_context_create();
    nts_result r;
    double tc[25], ts[25], te[25], tu[25], start, ph[4];
    long long a0;
    int k, n = nts_scene_surface_node_count(s);
    timing t;
    memset(&t, 0, sizeof t);
    eval_or_die(ctx, s, o, &r); /* warm-up: buffers grow once */
    /* And the processor: a small scene's evaluations take microseconds, and
     * a core that has idled runs the first milliseconds slower. */
    start = ntsx_now();
    for (k = 0; k < 100000 && ntsx_now() - start < 0.05; ++k) eval_or_die(ctx, s, o, &r);
    a0 = g_alloc.count;
    start = ntsx_now();
    for (k = 0; k < 25; ++k) {
        double u0 = cpu_now(), t0 = ntsx_now(), t1;
        eval_or_die(ctx, s, o, &r);
        t1 = ntsx_now();
        tu[k] = 1e9 * (cpu_now() - u0) / n;
        nts_context_phase_times(ctx, ph);
        tc[k] = 1e9 * ph[1] / n;
        ts[k] = 1e9 * ph[2] / n;
        te[k] = 1e9 * (t1 - t0) / n;
        if (k >= 2 && ntsx_now() - start > budget) { ++k; break; }
    }
    t.reps = k;
    t.allocs_after_warmup = g_alloc.count - a0;
    t.gaps = r.summary.gaps;
    t.contacts = r.summary.contacts;
    t.cells = ntsx_median(tc, k);
    t.search = ntsx_median(ts, k);
    t.eval_min = te[0];
    for (n = 1; n < k; ++n)
        if (te[n] < t.eval_min) t.eval_min = te[n];
    t.eval = ntsx_median(te, k);
    t.eval_cpu = ntsx_median(tu, k);
    nts_context_destroy(ctx);
    return t;
}

static const double ALPHAS[4] = {0.0, 0.1, 0.2, 0.5};
static const char* SOLVER_NAMES[2] = {"closed_form", "newton"};
static const char* KIND_NAMES[3] = {"segment", "corner", "vertex"};

static FILE* open_csv(const char* dir, const char* name, const char* header) {
    char path[1024];
    FILE* f;
    snprintf(path, sizeof path, "%s/%s_%s.csv", dir, NTS_BENCH_VARIANT, name);
    f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "nts_bench: cannot write %s\n", path);
        exit(2);
    }
    fprintf(f, "%s\n", header);
    return f;
}

#define TIMING_HEADER \
    "variant,scene,periodic,particles,surface_nodes,solver,alpha,threads,reps,cells_ns,search_ns,eval_ns,eval_min_ns,eval_cpu_ns,gaps,contacts,allocs_per_eval"

static void write_timing(FILE* f, const char* scene, int periodic, int particles, int nodes, int solver,
                         double alpha, int threads, const timing* t) {
    fprintf(f, "%s,%s,%d,%d,%d,%s,%.2f,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%.3f\n", NTS_BENCH_VARIANT, scene,
            periodic, particles, nodes, SOLVER_NAMES[solver], alpha, threads, t->reps, t->cells, t->search, t->eval,
            t->eval_min, t->eval_cpu, t->gaps, t->contacts, (double)t->allocs_after_warmup / t->reps);
    fflush(f);
}

/* (a) two pressed disks, 16..4096 nodes per disk, every solver and alpha. */
static void section_disks(const char* dir) {
    static const int sizes[] = {16, 64, 256, 1024, 4096};
    FILE* f = open_csv(dir, "disks", TIMING_HEADER);
    int si, sv, a;
    for (si = 0; si < 5; ++si) {
        scene_buf b;
        nts_scene* s;
        make_two_disks(&b, sizes[si], 0.05);
        s = scene_from(&b);
        for (sv = 0; sv < 2; ++sv)
            for (a = 0; a < 4; ++a) {
                nts_options o = nts_default_options();
                timing t;
                o.alpha = ALPHAS[a];
                o.solver = (nts_solver)sv;
                t = time_eval(s, &o, g_quick ? 0.02 : 0.1);
                write_timing(f, "disks", 0, 2, b.total, sv, o.alpha, 0, &t);
            }
        nts_scene_destroy(s);
        buf_free(&b);
    }
    fclose(f);
}

/* (b) jittered packings, 100..100,000 particles, periodic and not. Every solver
 * and alpha up to 10,000 particles; the largest size with the default options. */
static void section_packing(const char* dir) {
    static const int sizes[] = {100, 1000, 10000, 100000};
    int nsizes = g_quick ? 2 : 4;
    FILE* f = open_csv(dir, "packing", TIMING_HEADER);
    int si, per, sv, a;
    for (si = 0; si < nsizes; ++si)
        for (per = 0; per < 2; ++per) {
            scene_buf b;
            nts_scene* s;
            make_packing(&b, sizes[si], per, 1234u + (uint64_t)si);
            s = scene_from(&b);
            for (sv = 0; sv < 2; ++sv)
                for (a = 0; a < 4; ++a) {
                    nts_options o = nts_default_options();
                    timing t;
                    if (sizes[si] > 10000 && !(sv == 0 && a == 2)) continue;
                    o.alpha = ALPHAS[a];
                    o.solver = (nts_solver)sv;
                    t = time_eval(s, &o, g_quick ? 0.02 : (sizes[si] > 10000 ? 1.0 : 0.25));
                    write_timing(f, "packing", per, sizes[si], b.total, sv, o.alpha, 0, &t);
                }
            nts_scene_destroy(s);
            buf_free(&b);
        }
    fclose(f);
}

/* ------------------------------------------------- long-double reference */

/* The corner's roots come from support/reference.c (shared with the hard-case
 * tests); the rest of a contact's reference (segments, vertices, the periodic
 * image) is here. */
typedef ntsx_ld ld;
typedef ntsx_lvec lvec;
static lvec lv(ld x, ld y) { lvec v; v.x = x; v.y = y; return v; }
static lvec lsub(lvec a, lvec b) { return lv(a.x - b.x, a.y - b.y); }
static lvec ladd(lvec a, lvec b) { return lv(a.x + b.x, a.y + b.y); }
static lvec lscale(ld s, lvec a) { return lv(s * a.x, s * a.y); }
static ld ldot(lvec a, lvec b) { return a.x * b.x + a.y * b.y; }
static lvec lpos(nts_vec2 p) { return lv((ld)p.x, (ld)p.y); }
static lvec lmin_image(lvec d, double lx, double ly) {
    if (lx > 0.0) d.x -= (ld)lx * nearbyintl(d.x / (ld)lx);
    if (ly > 0.0) d.y -= (ld)ly * nearbyintl(d.y / (ld)ly);
    return d;
}

/* The reference of one closest point: same feature, long double, roots of F
 * bracketed on the monotone pieces of [-1, 1] and bisected to the last bit
 * (ntsx_corner_roots). */
typedef struct ref_point {
    ld param, gap;
    lvec normal;
} ref_point;

static double g_lx = 0.0, g_ly = 0.0; /* the periodic box of the scene under test */

static ref_point reference(const nts_scene* s, const nts_contact* c, double alpha) {
    const nts_vec2* pos = nts_scene_positions(s);
    int mb = nts_scene_body_node_offset(s, c->master_body), sb = nts_scene_body_node_offset(s, c->slave_body);
    lvec xs = lpos(pos[sb + c->slave_node]);
    ref_point rp;
    memset(&rp, 0, sizeof rp);
    if (c->kind == NTS_KIND_SEGMENT) {
        lvec x0 = lpos(pos[mb + c->master_nodes[0]]), x1 = lpos(pos[mb + c->master_nodes[1]]);
        lvec t = lmin_image(lsub(x1, x0), g_lx, g_ly), d = lmin_image(lsub(xs, x0), g_lx, g_ly);
        ld len = sqrtl(ldot(t, t));
        rp.param = ldot(d, t) / ldot(t, t);
        rp.normal = lv(t.y / len, -t.x / len);
        rp.gap = ldot(d, rp.normal);
    } else if (c->kind == NTS_KIND_VERTEX) {
        lvec x3 = lpos(pos[mb + c->master_nodes[0]]), d = lmin_image(lsub(xs, x3), g_lx, g_ly);
        ld dist = sqrtl(ldot(d, d)), sg = (c->gap < 0.0) ? -1 : 1;
        rp.param = 0;
        rp.gap = sg * dist;
        rp.normal = dist > 0 ? lscale(sg / dist, d) : lv((ld)c->normal.x, (ld)c->normal.y);
    } else {
        lvec x2 = lpos(pos[mb + c->master_nodes[0]]), x3 = lpos(pos[mb + c->master_nodes[1]]);
        lvec x4 = lpos(pos[mb + c->master_nodes[2]]);
        lvec a = lmin_image(lsub(x2, x3), g_lx, g_ly), cc = lmin_image(lsub(x4, x3), g_lx, g_ly);
        lvec d = lmin_image(lsub(xs, x3), g_lx, g_ly);
        ld al = (ld)alpha;
        lvec A = lscale(al / 4, ladd(a, cc)), B = lscale(al / 2, lsub(cc, a));
        ntsx_corner k;
        ld roots[3], xi;
        int nr;
        k.A = A;
        k.B = B;
        k.e = lsub(d, A);
        nr = ntsx_corner_roots(&k, roots);
        xi = ntsx_corner_nearest(&k, roots, nr);
        {
            lvec tau = ladd(B, lscale(2 * xi, A)), pt = ladd(A, lscale(xi, ladd(B, lscale(xi, A))));
            ld tl = sqrtl(ldot(tau, tau));
            rp.param = xi;
            rp.normal = lv(tau.y / tl, -tau.x / tl);
            rp.gap = ldot(lsub(d, pt), rp.normal);
        }
    }
    return rp;
}

/* Errors of every closest point (gaps output) of one evaluation against the
 * long-double reference: param (xi or s), gap, force (penalty 1). */
typedef struct err_stats {
    double xi_max, xi_med, gap_max, gap_med, f_max, f_med;
    int n, corners;
} err_stats;

static err_stats solver_errors(const nts_scene* s, const nts_result* r, double alpha, double eps) {
    int n = r->gap_count, i, nc = 0;
    double* ex = (double*)xmalloc(sizeof(double) * (size_t)(n + 1));
    double* eg = (double*)xmalloc(sizeof(double) * (size_t)(n + 1));
    double* ef = (double*)xmalloc(sizeof(double) * (size_t)(n + 1));
    err_stats st;
    for (i = 0; i < n; ++i) {
        const nts_contact* c = &r->gaps[i];
        ref_point rp = reference(s, c, alpha);
        ld fx = 0, fy = 0;
        double fxd = 0.0, fyd = 0.0;
        if (rp.gap < 0) { fx = -(ld)eps * rp.gap * rp.normal.x; fy = -(ld)eps * rp.gap * rp.normal.y; }
        if (c->gap < 0.0) { fxd = -eps * c->gap * c->normal.x; fyd = -eps * c->gap * c->normal.y; }
        ex[i] = (double)fabsl((ld)c->param - rp.param);
        eg[i] = (double)fabsl((ld)c->gap - rp.gap);
        ef[i] = (double)sqrtl(((ld)fxd - fx) * ((ld)fxd - fx) + ((ld)fyd - fy) * ((ld)fyd - fy));
        nc += c->kind == NTS_KIND_CORNER;
    }
    st.n = n;
    st.corners = nc;
    st.xi_max = vmax(ex, n);
    st.gap_max = vmax(eg, n);
    st.f_max = vmax(ef, n);
    st.xi_med = ntsx_median(ex, n);
    st.gap_med = ntsx_median(eg, n);
    st.f_med = ntsx_median(ef, n);
    free(ex);
    free(eg);
    free(ef);
    return st;
}

/* Solver error and discretisation error. Two disks at every resolution (the
 * exact circles are known), and one packing. */
static void section_errors(const char* dir) {
    static const int sizes[] = {16, 32, 64, 128, 256, 1024, 4096};
    FILE* f = open_csv(dir, "errors",
                       "scene,surface_nodes,solver,alpha,records,corners,xi_max,xi_median,gap_max,gap_median,"
                       "force_max,force_median");
    FILE* g = open_csv(dir, "discretisation",
                       "nodes_per_disk,solver,alpha,records,gap_err_max,gap_err_median,normal_err_max_rad,"
                       "normal_err_median_rad");
    int si, sv, a, i, per;
    for (si = 0; si < 7; ++si) {
        scene_buf b;
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        g_disk_phase = 0.381966011250105; /* the golden section: slaves land anywhere on the master's segments */
        make_two_disks(&b, sizes[si], 0.05);
        g_disk_phase = 0.5;
        s = scene_from(&b);
        for (sv = 0; sv < 2; ++sv)
            for (a = 0; a < 4; ++a) {
                nts_options o = nts_default_options();
                nts_result r;
                err_stats st;
                double *ge, *ne;
                int m = 0;
                o.alpha = ALPHAS[a];
                o.solver = (nts_solver)sv;
                o.outputs = NTS_OUT_ALL;
                eval_or_die(ctx, s, &o, &r);
                st = solver_errors(s, &r, o.alpha, o.penalty);
                fprintf(f, "disks,%d,%s,%.2f,%d,%d,%.3e,%.3e,%.3e,%.3e,%.3e,%.3e\n", b.total, SOLVER_NAMES[sv],
                        o.alpha, st.n, st.corners, st.xi_max, st.xi_med, st.gap_max, st.gap_med, st.f_max,
                        st.f_med);
                /* Discretisation: every closest point within r against the exact circles. */
                ge = (double*)xmalloc(sizeof(double) * (size_t)(r.gap_count + 1));
                ne = (double*)xmalloc(sizeof(double) * (size_t)(r.gap_count + 1));
                for (i = 0; i < r.gap_count; ++i) {
                    const nts_contact* c = &r.gaps[i];
                    nts_vec2 xs = b.nodes[c->slave_body][c->slave_node];
                    double dx = xs.x - b.cx[c->master_body], dy = xs.y - b.cy[c->master_body];
                    double dist = sqrt(dx * dx + dy * dy), gex = dist - b.R[c->master_body];
                    double cosang = (c->normal.x * dx + c->normal.y * dy) / dist;
                    if (cosang > 1.0) cosang = 1.0;
                    ge[m] = fabs(c->gap - gex);
                    ne[m] = acos(cosang);
                    ++m;
                }
                fprintf(g, "%d,%s,%.2f,%d,%.3e,%.3e,%.3e,%.3e\n", sizes[si], SOLVER_NAMES[sv], o.alpha, m,
                        vmax(ge, m), ntsx_median(ge, m), vmax(ne, m), ntsx_median(ne, m));
                free(ge);
                free(ne);
            }
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        buf_free(&b);
    }
    for (per = 0; per < 2; ++per) {
        scene_buf b;
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        make_packing(&b, g_quick ? 100 : 1000, per, 99u);
        s = scene_from(&b);
        g_lx = b.lx;
        g_ly = b.ly;
        for (sv = 0; sv < 2; ++sv)
            for (a = 0; a < 4; ++a) {
                nts_options o = nts_default_options();
                nts_result r;
                err_stats st;
                o.alpha = ALPHAS[a];
                o.solver = (nts_solver)sv;
                o.outputs = NTS_OUT_ALL;
                eval_or_die(ctx, s, &o, &r);
                st = solver_errors(s, &r, o.alpha, o.penalty);
                fprintf(f, "%s,%d,%s,%.2f,%d,%d,%.3e,%.3e,%.3e,%.3e,%.3e,%.3e\n",
                        per ? "packing_periodic" : "packing_open", b.total, SOLVER_NAMES[sv],
                        o.alpha, st.n, st.corners, st.xi_max, st.xi_med, st.gap_max, st.gap_med, st.f_max,
                        st.f_med);
            }
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        buf_free(&b);
        g_lx = g_ly = 0.0;
    }
    fclose(f);
    fclose(g);
}

/* Smoothness: a slave node slides at constant depth inside a 16-gon of radius 1
 * around the corner at angle 0; the direction of its contact force per step. */
static void section_smooth(const char* dir) {
    const int N = 16, steps = 400;
    const double depth = 0.02, rho = cos(PI / N) - depth;
    FILE* f = open_csv(dir, "smooth", "solver,alpha,step,theta,force_angle,gap,kind");
    FILE* g = open_csv(dir, "smooth_summary", "solver,alpha,steps,max_step_change_rad,total_turn_rad");
    nts_vec2 poly[16], tri[3];
    nts_body_def defs[2];
    nts_scene_def def = nts_default_scene_def();
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_error err;
    int i, a, sv, k;
    for (i = 0; i < N; ++i) poly[i] = nts_v2(cos(2.0 * PI * i / N), sin(2.0 * PI * i / N));
    memset(defs, 0, sizeof defs);
    defs[0].nodes = poly;
    defs[0].node_count = N;
    defs[1].nodes = tri;
    defs[1].node_count = 3;
    def.bodies = defs;
    def.body_count = 2;
    for (sv = 0; sv < 2; ++sv)
        for (a = 0; a < 4; ++a) {
            double prev = 0.0, maxd = 0.0, first = 0.0, last = 0.0;
            int have = 0;
            for (k = 0; k <= steps; ++k) {
                double th = -PI / N + 2.0 * PI / N * k / steps;
                nts_vec2 p = nts_v2(rho * cos(th), rho * sin(th)), u = nts_v2(cos(th), sin(th));
                nts_vec2 v = nts_v2(-sin(th), cos(th));
                nts_options o = nts_default_options();
                nts_result r;
                int q;
                /* A tiny triangle whose node 0 is the probe (counter-clockwise). */
                tri[0] = p;
                tri[1] = nts_v2(p.x - 1e-3 * u.x - 1e-3 * v.x, p.y - 1e-3 * u.y - 1e-3 * v.y);
                tri[2] = nts_v2(p.x - 1e-3 * u.x + 1e-3 * v.x, p.y - 1e-3 * u.y + 1e-3 * v.y);
                s = nts_scene_create(&def, &err);
                if (s == NULL) { fprintf(stderr, "smooth: %s\n", err.message); exit(2); }
                o.alpha = ALPHAS[a];
                o.solver = (nts_solver)sv;
                o.outputs = NTS_OUT_ALL;
                o.search_radius = 0.5;
                eval_or_die(ctx, s, &o, &r);
                for (q = 0; q < r.contact_count; ++q) {
                    const nts_contact* c = &r.contacts[q];
                    if (c->slave_body == 1 && c->slave_node == 0 && c->master_body == 0) {
                        double ang = atan2(c->force.y, c->force.x);
                        fprintf(f, "%s,%.2f,%d,%.9f,%.12f,%.6e,%s\n", SOLVER_NAMES[sv], o.alpha, k, th, ang, c->gap,
                                KIND_NAMES[c->kind]);
                        if (have) {
                            double dd = fabs(ang - prev);
                            if (dd > PI) dd = 2.0 * PI - dd;
                            if (dd > maxd) maxd = dd;
                        } else {
                            first = ang;
                        }
                        last = ang;
                        prev = ang;
                        have = 1;
                    }
                }
                nts_scene_destroy(s);
            }
            fprintf(g, "%s,%.2f,%d,%.6e,%.6e\n", SOLVER_NAMES[sv], ALPHAS[a], steps, maxd, last - first);
        }
    nts_context_destroy(ctx);
    fclose(f);
    fclose(g);
}

/* Scaling: time and peak memory per node, 1e3..1e6 surface nodes (periodic
 * packing, default options, serial). Peak memory counts the core's own
 * allocations (scene + context) through the allocator hook. */
static void section_scaling(const char* dir) {
    static const int targets[] = {1000, 3000, 10000, 30000, 100000, 300000, 1000000};
    int nt = g_quick ? 5 : 7, i;
    FILE* f = open_csv(dir, "scaling", TIMING_HEADER ",peak_bytes,bytes_per_node,maxrss_kb");
    for (i = 0; i < nt; ++i) {
        scene_buf b;
        nts_scene* s;
        nts_options o = nts_default_options();
        timing t;
        size_t peak;
        int particles = targets[i] / 48;
        if (particles < 4) particles = 4;
        make_packing(&b, particles, 1, 777u + (uint64_t)i);
        g_alloc.peak = g_alloc.live;
        s = scene_from(&b);
        t = time_eval(s, &o, g_quick ? 0.05 : 0.5);
        peak = g_alloc.peak;
        write_timing(f, "packing", 1, particles, b.total, o.solver, o.alpha, 0, &t);
        fseek(f, -1, SEEK_CUR);
        fprintf(f, ",%zu,%.1f,%ld\n", peak, (double)peak / b.total, maxrss_kb());
        fflush(f);
        nts_scene_destroy(s);
        buf_free(&b);
    }
    fclose(f);
}

/* Threads: bitwise identical results for 0..4 threads, and the speed-up. */
/* How many cores this process really gets now: CPU time over wall time of a
 * 2-thread busy loop (2.0 on an idle 2-core machine; about 1 when another
 * process keeps one core busy). The threads table reports it next to the
 * speed-ups, which cannot exceed it. */
static double cores_available(void) {
#ifdef _OPENMP
    double x = 0.0, t0 = ntsx_now(), u0 = cpu_now();
    long i;
#pragma omp parallel for num_threads(2) reduction(+ : x) schedule(static)
    for (i = 0; i < 60000000L; ++i) x += 1e-9 * (double)i;
    if (!(x > 0.0)) return 0.0;
    return (cpu_now() - u0) / (ntsx_now() - t0);
#else
    return 1.0;
#endif
}

static void section_threads(const char* dir, int max_threads) {
    FILE* f = open_csv(dir, "threads",
                       TIMING_HEADER ",speedup,speedup_best,bitwise_identical,cores_available,speedup_paired");
    scene_buf b;
    nts_scene* s;
    nts_context* c0 = nts_context_create();
    nts_context* ct[8];
    nts_result r0, r1;
    int th, sv, a, k;
    if (max_threads > 8) max_threads = 8;
    for (th = 0; th < max_threads; ++th) ct[th] = nts_context_create();
    make_packing(&b, g_quick ? 1000 : 4000, 1, 4242u);
    s = scene_from(&b);
    for (sv = 0; sv < 2; ++sv)
        for (a = 0; a < 4; ++a) {
            nts_options o = nts_default_options();
            enum { REPS = 15 };
            double te[8][REPS], tu[8][REPS], best[8], cores;
            int same[8], reps = g_quick ? 5 : REPS, n = nts_scene_surface_node_count(s);
            if (!(a == 0 || a == 2) && sv == 1) continue;
            if (g_quick && !(a == 2 && sv == 0)) continue;
            o.alpha = ALPHAS[a];
            o.solver = (nts_solver)sv;
            o.outputs = NTS_OUT_ALL;
            eval_or_die(c0, s, &o, &r0);
            for (th = 1; th <= max_threads; ++th) {
                o.threads = th;
                o.outputs = NTS_OUT_ALL;
                eval_or_die(ct[th - 1], s, &o, &r1);
                same[th - 1] =
                    r1.gap_count == r0.gap_count && r1.contact_count == r0.contact_count &&
                    memcmp(r1.gaps, r0.gaps, sizeof(nts_contact) * (size_t)r0.gap_count) == 0 &&
                    memcmp(r1.contacts, r0.contacts, sizeof(nts_contact) * (size_t)r0.contact_count) == 0 &&
                    memcmp(r1.forces, r0.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s)) == 0 &&
                    memcmp(&r1.summary, &r0.summary, sizeof r0.summary) == 0;
                o.outputs = nts_default_options().outputs;
                eval_or_die(ct[th - 1], s, &o, &r1); /* warm with the timed outputs */
            }
            cores = cores_available();
            /* Interleaved: every round times 1, 2, ..., max threads in turn, so a
             * burst of load from other processes hits every count alike. */
            for (k = 0; k < reps; ++k)
                for (th = 1; th <= max_threads; ++th) {
                    double u0 = cpu_now(), t0 = ntsx_now();
                    o.threads = th;
                    eval_or_die(ct[th - 1], s, &o, &r1);
                    te[th - 1][k] = 1e9 * (ntsx_now() - t0) / n;
                    tu[th - 1][k] = 1e9 * (cpu_now() - u0) / n;
                }
            for (th = 1; th <= max_threads; ++th) {
                timing t;
                double ph[4], ratio[REPS];
                memset(&t, 0, sizeof t);
                nts_context_phase_times(ct[th - 1], ph);
                t.reps = reps;
                t.cells = 1e9 * ph[1] / n; /* last evaluation's phases */
                t.search = 1e9 * ph[2] / n;
                best[th - 1] = te[th - 1][0];
                for (k = 1; k < reps; ++k)
                    if (te[th - 1][k] < best[th - 1]) best[th - 1] = te[th - 1][k];
                t.eval_min = best[th - 1];
                t.eval = ntsx_median(te[th - 1], reps);
                t.eval_cpu = ntsx_median(tu[th - 1], reps);
                t.gaps = r1.summary.gaps;
                t.contacts = r1.summary.contacts;
                write_timing(f, "packing", 1, b.body_count, b.total, sv, o.alpha, th, &t);
                fseek(f, -1, SEEK_CUR);
                /* Paired: each round's 1-thread time over its own n-thread time, timed
                 * back to back, so load that comes and goes between rounds cancels. */
                for (k = 0; k < reps; ++k) ratio[k] = te[0][k] / te[th - 1][k];
                fprintf(f, ",%.3f,%.3f,%d,%.2f,%.3f\n", ntsx_median(te[0], reps) / t.eval, best[0] / best[th - 1],
                        same[th - 1], cores, ntsx_median(ratio, reps));
                fflush(f);
            }
        }
    nts_context_destroy(c0);
    for (th = 0; th < max_threads; ++th) nts_context_destroy(ct[th]);
    nts_scene_destroy(s);
    buf_free(&b);
    fclose(f);
}

/* ns per surface node of a solver's step with a kept candidate list on
 * scene s (its bodies as in b), options o: as build-bench/bin/kept_bench
 * moves them (each body along a direction of its own, each node a fifth as
 * much along its own, back and forth, a step moving a node 1/10 of what the
 * default skin allows), each step's positions given in one call
 * (nts_evaluate_positions). The median of `steps` timed steps after as many
 * untimed (the list's first build among them); the builds the list makes
 * between are in the timed steps (about one in ten), so the median is a
 * step between builds: *mean, the mean of the same steps, counts the
 * builds' share too. The scene is given its first positions back. */
static double kept_step_ns(nts_scene* s, const scene_buf* b, const nts_options* o0, int steps, double* mean) {
    const int n = nts_scene_node_count(s), ns = nts_scene_surface_node_count(s);
    nts_vec2* base = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    nts_vec2* dir = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    nts_vec2* pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    double* dt = (double*)malloc(sizeof(double) * (size_t)steps);
    nts_context* ctx = nts_context_create();
    nts_candidates* kc = nts_candidates_create(-1.0);
    nts_options o = *o0;
    nts_result r;
    nts_error err;
    double amp, omega, med;
    int k, i;
    if (!base || !dir || !pos || !dt || !ctx || !kc) { fprintf(stderr, "out of memory\n"); exit(2); }
    memcpy(base, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    ntsx_motion_directions(b->counts, b->body_count, 4242u, dir);
    o.candidates = kc;
    amp = 0.5 * o.search_radius;
    omega = 0.3 * o.search_radius / (3.0 + 2.0 * o.alpha) / 10.0 / (1.2 * amp); /* eq. (29), K = 10 */
    for (k = 1; k <= 2 * steps; ++k) {
        const double a = amp * sin(omega * k);
        double t0;
        for (i = 0; i < n; ++i) pos[i] = nts_v2(base[i].x + a * dir[i].x, base[i].y + a * dir[i].y);
        t0 = ntsx_now();
        if (nts_evaluate_positions(ctx, s, pos, &o, &r, &err) != NTS_OK) {
            fprintf(stderr, "kept step: %s\n", err.message);
            exit(1);
        }
        if (k > steps) dt[k - steps - 1] = ntsx_now() - t0;
    }
    *mean = 0.0;
    for (k = 0; k < steps; ++k) *mean += dt[k];
    *mean = 1e9 * *mean / steps / ns;
    med = 1e9 * ntsx_median(dt, steps) / ns;
    if (nts_scene_update_positions(s, base, &err) != NTS_OK) { fprintf(stderr, "back: %s\n", err.message); exit(1); }
    nts_candidates_destroy(kc);
    nts_context_destroy(ctx);
    free(base);
    free(dir);
    free(pos);
    free(dt);
    return med;
}

/* Peer input: a non-periodic packing with our alpha = 0 gaps and time, for
 * bench/shapely_peer.py. */
static void section_peer(const char* dir) {
    static const int sizes[] = {100, 1000, 10000};
    int ns = g_quick ? 2 : 3, si, i, k;
    for (si = 0; si < ns; ++si) {
        scene_buf b;
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r;
        timing t, tg;
        double kept, kept_mean;
        char path[1024];
        FILE* f;
        make_packing(&b, sizes[si], 0, 555u + (uint64_t)si);
        s = scene_from(&b);
        o.alpha = 0.0;
        /* Like for like with Shapely's dwithin r: the median segment given
         * explicitly, so that the gaps are those within r (the default adds
         * every active contact deeper than r, which a query within r cannot
         * see: docs/model.md §4.5). */
        o.outputs = 0u;
        eval_or_die(ctx, s, &o, &r);
        o.search_radius = r.summary.search_radius;
        o.outputs = NTS_OUT_GAPS;
        tg = time_eval(s, &o, g_quick ? 0.05 : 0.3);
        o.outputs = nts_default_options().outputs;
        t = time_eval(s, &o, g_quick ? 0.05 : 0.3);
        kept = kept_step_ns(s, &b, &o, g_quick ? 5 : 20, &kept_mean);
        o.outputs = NTS_OUT_GAPS;
        eval_or_die(ctx, s, &o, &r);
        snprintf(path, sizeof path, "%s/peer_scene_%d.txt", dir, sizes[si]);
        f = fopen(path, "w");
        if (f == NULL) { fprintf(stderr, "cannot write %s\n", path); exit(2); }
        /* header: bodies, search radius, ns per node with the gaps output (wall,
         * median), with the default outputs (wall), surface nodes, ns per node
         * with the gaps output (CPU time, median), active contacts (g < 0) of
         * the evaluation with the default outputs, ns per node of a solver's
         * step with a kept list (wall, median; kept_step_ns) with them, and
         * the mean of the same steps, builds included (for
         * bench/pymunk_peer.py) */
        fprintf(f, "%d %.17g %.3f %.3f %d %.3f %d %.3f %.3f\n", b.body_count, r.summary.search_radius, tg.eval, t.eval,
                b.total, tg.eval_cpu, t.contacts, kept, kept_mean);
        for (k = 0; k < b.body_count; ++k) {
            fprintf(f, "%d\n", b.counts[k]);
            for (i = 0; i < b.counts[k]; ++i) fprintf(f, "%.17g %.17g\n", b.nodes[k][i].x, b.nodes[k][i].y);
        }
        fclose(f);
        snprintf(path, sizeof path, "%s/peer_gaps_%d.csv", dir, sizes[si]);
        f = fopen(path, "w");
        if (f == NULL) { fprintf(stderr, "cannot write %s\n", path); exit(2); }
        fprintf(f, "slave_body,slave_node,master_body,kind,gap\n");
        for (i = 0; i < r.gap_count; ++i)
            fprintf(f, "%d,%d,%d,%s,%.17g\n", r.gaps[i].slave_body, r.gaps[i].slave_node, r.gaps[i].master_body,
                    KIND_NAMES[r.gaps[i].kind], r.gaps[i].gap);
        fclose(f);
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        buf_free(&b);
    }
}

/* ------------------------------------------------------------ hard cases */

typedef struct hard_case {
    const char* test; /* the CUnit test that covers it (tests/core/test_hard_cases.c) */
    const char* name;
    nts_vec2 a, c, d;
    double alpha;
} hard_case;

/* One corner case, both solvers: xi error and gap error against the long-double
 * reference, roots and iterations, and the CPU time of one solve. */
static void hard_row(FILE* f, const hard_case* h) {
    int sv, nref = 0;
    ld xr = ntsx_corner_xi(h->a, h->c, h->alpha, h->d, &nref);
    nts_corner k = nts_corner_make(h->a, h->c, h->alpha);
    for (sv = 0; sv < 2; ++sv) {
        nts_corner_solution s = nts_corner_solve(k, h->d, (nts_solver)sv);
        /* Gap of the reference point, in long double, on the same curve. */
        lvec A = lv((ld)k.A.x, (ld)k.A.y), B = lv((ld)k.B.x, (ld)k.B.y);
        lvec pt = ladd(A, lscale(xr, ladd(B, lscale(xr, A))));
        lvec tau = ladd(B, lscale(2 * xr, A));
        ld tl = sqrtl(ldot(tau, tau));
        ld gref = ldot(lsub(lpos(h->d), pt), lv(tau.y / tl, -tau.x / tl));
        double t0 = cpu_now(), dt;
        int it, reps = 20000;
        volatile double sink = 0.0;
        for (it = 0; it < reps; ++it) sink += nts_corner_solve(k, h->d, (nts_solver)sv).xi;
        dt = (cpu_now() - t0) / reps;
        (void)sink;
        fprintf(f, "%s,\"%s\",%s,%.2f,%d,%d,%d,%d,%.17g,%.3e,%.3e,%.1f,%d\n", h->test, h->name, SOLVER_NAMES[sv],
                h->alpha, s.ok, s.roots, nref, s.iterations, s.xi, (double)fabsl((ld)s.xi - xr),
                (double)fabsl((ld)s.gap - gref), 1e9 * dt,
                isfinite(s.xi) && isfinite(s.gap) && isfinite(s.normal.x) && isfinite(s.normal.y));
    }
}

static void section_hard(const char* dir) {
    const double deg = PI / 180.0, q = 0.70710678118654752;
    FILE* f = open_csv(dir, "hard",
                       "test,case,solver,alpha,ok,roots,reference_roots,iterations,xi,xi_error,gap_error,ns_per_solve,"
                       "finite");
    FILE* g;
    hard_case cases[] = {
        {"test_collinear_neighbours", "collinear (A = 0)", {-1, 0}, {1, 0}, {0.05, -0.3}, 0.2},
        {"test_collinear_neighbours", "collinear; slave inside; alpha 0.5", {-1, 0}, {1, 0}, {-0.13, 0.2}, 0.5},
        {"test_nearly_collinear", "nearly collinear: 1e-9 rad", {-1, 0}, {0, 0}, {0.05, -0.3}, 0.2},
        {"test_nearly_collinear", "nearly collinear: 1e-5 rad", {-1, 0}, {0, 0}, {-0.07, 0.1}, 0.2},
        {"test_slave_on_alpha_boundaries", "projection exactly s = alpha", {-1, 0}, {0, 1}, {0.1, 0.25}, 0.25},
        {"test_slave_on_alpha_boundaries", "projection exactly s = 1 - alpha (previous)", {-1, 0}, {0, 1},
         {-0.25, -0.1}, 0.25},
        {"test_slave_exactly_on_node", "slave exactly on the corner node", {-1, 0}, {0, 1}, {0, 0}, 0.2},
        {"test_evolute_several_roots", "beyond the evolute (three roots)", {-1, 0}, {-1.2 * q, 1.2 * q},
         {-0.42, 0.15}, 0.5},
        {"test_one_degree_spike_and_reflex", "1 degree spike; slave outside", {-1, 0}, {0, 0}, {0.05, 0.001}, 0.2},
        {"test_one_degree_spike_and_reflex", "359 degree reflex corner", {-1, 0}, {0, 0}, {0.05, 0.0005}, 0.2},
        {"test_newton_converges_quickly_when_nearly_straight", "nearly straight: 1e-5 rad (step count)", {-1, 0},
         {0, 0}, {-0.07, 0.1}, 0.2},
    };
    int i, n = (int)(sizeof cases / sizeof cases[0]), sv;
    cases[2].c = nts_v2(cos(1e-9), sin(1e-9));
    cases[3].c = nts_v2(cos(1e-5), sin(1e-5));
    cases[8].c = nts_v2(-cos(deg), sin(deg));
    cases[9].c = nts_v2(-cos(deg), -sin(deg));
    cases[10].c = nts_v2(cos(1e-5), sin(1e-5));
    for (i = 0; i < n; ++i) hard_row(f, &cases[i]);
    fclose(f);

    /* The random sweep of test_random_corners_against_reference (same generator
     * rule, our own RNG): both solvers, error distribution, iterations, time. */
    g = open_csv(dir, "hard_sweep",
                 "solver,corners,xi_error_max,xi_error_median,dist_error_max,iterations_mean,iterations_max,"
                 "ns_per_solve,fallback_or_nan");
    for (sv = 0; sv < 2; ++sv) {
        enum { MAXC = 4000 };
        static nts_vec2 A_[MAXC], C_[MAXC], D_[MAXC];
        static double AL_[MAXC], ex[MAXC], ed[MAXC];
        int m = 0, itmax = 0, bad = 0, rep;
        double itsum = 0.0, t0, dt;
        volatile double sink = 0.0;
        uint64_t rng = 12345u;
        while (m < (g_quick ? 500 : MAXC)) {
            double th1 = 2 * PI * ntsx_urand(&rng), th2 = 2 * PI * ntsx_urand(&rng), al = 0.05 + 0.45 * ntsx_urand(&rng);
            nts_vec2 a = nts_scale(0.5 + ntsx_urand(&rng), nts_v2(cos(th1), sin(th1)));
            nts_vec2 c = nts_scale(0.5 + ntsx_urand(&rng), nts_v2(cos(th2), sin(th2)));
            nts_vec2 d = nts_v2(0.6 * (ntsx_urand(&rng) - 0.5), 0.6 * (ntsx_urand(&rng) - 0.5));
            double sp, sj;
            if (fabs(nts_cross(a, c)) < 1e-3 && nts_dot(a, c) > 0) continue;
            sp = nts_dot(nts_sub(d, a), nts_neg(a)) / nts_dot(a, a);
            sj = nts_dot(d, c) / nts_dot(c, c);
            if (!(sp >= 1.0 - al && sj <= al)) continue;
            A_[m] = a; C_[m] = c; D_[m] = d; AL_[m] = al;
            ++m;
        }
        for (i = 0; i < m; ++i) {
            int nr;
            ld xr = ntsx_corner_xi(A_[i], C_[i], AL_[i], D_[i], &nr);
            nts_corner k = nts_corner_make(A_[i], C_[i], AL_[i]);
            nts_corner_solution s = nts_corner_solve(k, D_[i], (nts_solver)sv);
            nts_vec2 ps = nts_corner_point(k, s.xi);
            lvec A = lv((ld)k.A.x, (ld)k.A.y), B = lv((ld)k.B.x, (ld)k.B.y);
            lvec pr = ladd(A, lscale(xr, ladd(B, lscale(xr, A))));
            ld dsx = (ld)D_[i].x - ps.x, dsy = (ld)D_[i].y - ps.y;
            lvec dr = lsub(lpos(D_[i]), pr);
            ex[i] = (double)fabsl((ld)s.xi - xr);
            /* Where two roots are equally near, either is right: compare distances too. */
            ed[i] = (double)fabsl(sqrtl(dsx * dsx + dsy * dsy) - sqrtl(ldot(dr, dr)));
            itsum += s.iterations;
            if (s.iterations > itmax) itmax = s.iterations;
            bad += !isfinite(s.xi) || !s.ok;
        }
        t0 = cpu_now();
        for (rep = 0; rep < (g_quick ? 20 : 100); ++rep)
            for (i = 0; i < m; ++i) {
                nts_corner k = nts_corner_make(A_[i], C_[i], AL_[i]);
                sink += nts_corner_solve(k, D_[i], (nts_solver)sv).xi;
            }
        dt = (cpu_now() - t0) / ((g_quick ? 20 : 100) * (double)m);
        (void)sink;
        fprintf(g, "%s,%d,%.3e,%.3e,%.3e,%.2f,%d,%.1f,%d\n", SOLVER_NAMES[sv], m, vmax(ex, m), ntsx_median(ex, m),
                vmax(ed, m), itsum / m, itmax, 1e9 * dt, bad);
    }
    fclose(g);

    /* Scene-level hard cases: offset 1e6 with 1e-3 segments; 1e-9 and 1e9 scales. */
    g = open_csv(dir, "hard_scenes", "test,case,solver,contacts,max_gap_difference,relative_energy_difference,all_finite");
    for (sv = 0; sv < 2; ++sv) {
        scene_buf b0, b1;
        nts_scene *s0, *s1;
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r0, r1;
        double worst = 0.0, sc;
        int k, j, fin = 1, si;
        o.solver = (nts_solver)sv;
        o.outputs = NTS_OUT_ALL;
        o.penalty = 1e4;
        for (si = 0; si < 2; ++si) {
            ntsx_scene_init(&b0, 2);
            ntsx_scene_init(&b1, 2);
            for (k = 0; k < 2; ++k) {
                b0.counts[k] = b1.counts[k] = 64;
                b0.nodes[k] = (nts_vec2*)xmalloc(sizeof(nts_vec2) * 64);
                b1.nodes[k] = (nts_vec2*)xmalloc(sizeof(nts_vec2) * 64);
                for (j = 0; j < 64; ++j) {
                    double th = 2 * PI * j / 64 + (k ? 0.03 : 0.0);
                    nts_vec2 p = k ? nts_v2(0.0199 + 0.01 * cos(th), 0.0003 + 0.01 * sin(th))
                                   : nts_v2(0.01 * cos(th), 0.01 * sin(th));
                    b0.nodes[k][j] = p;
                    b1.nodes[k][j] = nts_add(p, nts_v2(1e6, -1e6));
                }
            }
            if (si == 1) {
                /* scale instead of offset */
                for (k = 0; k < 2; ++k)
                    for (j = 0; j < 64; ++j) b1.nodes[k][j] = nts_scale(1e9, b0.nodes[k][j]);
            }
            s0 = scene_from(&b0);
            s1 = scene_from(&b1);
            eval_or_die(c0, s0, &o, &r0);
            eval_or_die(c1, s1, &o, &r1);
            sc = si == 1 ? 1e9 : 1.0;
            worst = 0.0;
            fin = 1;
            for (k = 0; k < r0.contact_count && k < r1.contact_count; ++k) {
                double dd = fabs(r1.contacts[k].gap / sc - r0.contacts[k].gap);
                if (dd > worst) worst = dd;
                fin &= isfinite(r1.contacts[k].gap) && isfinite(r1.contacts[k].param);
            }
            fprintf(g, "%s,%s,%s,%d/%d,%.3e,%.3e,%d\n",
                    si ? "test_extreme_scales" : "test_large_offset_small_segments",
                    si ? "two disks of radius 0.01 scaled by 1e9 (gaps compared after dividing by 1e9)"
                       : "two disks of radius 0.01 (1e-3 segments) moved to (1e6; -1e6)",
                    SOLVER_NAMES[sv], r1.contact_count, r0.contact_count, worst,
                    fabs(r1.summary.energy / (sc * sc) - r0.summary.energy) / r0.summary.energy, fin);
            nts_scene_destroy(s0);
            nts_scene_destroy(s1);
            buf_free(&b0);
            buf_free(&b1);
        }
        nts_context_destroy(c0);
        nts_context_destroy(c1);
    }
    fclose(g);
}

/* Digest: an FNV-1a hash of every output value (summary, forces, contacts, gaps;
 * then the summary and forces with the default outputs) for a set of scenes,
 * solvers, alphas, searches and thread counts. The "before" and "after"
 * binaries must print the same digests: the faster core changes no bit of any
 * result. */
static uint64_t fnv(uint64_t h, const void* p, size_t n) {
    const unsigned char* b = (const unsigned char*)p;
    size_t i;
    for (i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

/* Field by field, not the structs' bytes: a struct that grows (friction's
 * fields, zero without it) or pads differently changes no digest; the values
 * are what must not change. */
static uint64_t fnv_int(uint64_t h, int v) { return fnv(h, &v, sizeof v); }
static uint64_t fnv_double(uint64_t h, double v) { return fnv(h, &v, sizeof v); }
static uint64_t fnv_virial(uint64_t h, nts_virial v) {
    return fnv_double(fnv_double(fnv_double(fnv_double(h, v.xx), v.yy), v.xy), v.yx);
}

static uint64_t fnv_summary(uint64_t h, const nts_summary* m) {
    h = fnv_int(fnv_int(fnv_int(fnv_int(fnv_int(h, m->bodies), m->surface_nodes), m->contacts), m->gaps),
                m->deep_contacts);
    h = fnv_virial(fnv_double(h, m->energy), m->virial);
    h = fnv_int(fnv_double(h, m->max_penetration), m->loops_reversed);
    h = fnv_double(h, m->search_radius); /* cell_size: how the search ran, not a result */
    return fnv_int(fnv_int(fnv_double(h, m->dissipation), m->sticking), m->slipping);
}

static uint64_t fnv_contacts(uint64_t h, const nts_contact* c, int n) {
    int i, k;
    for (i = 0; i < n; ++i, ++c) {
        h = fnv_int(fnv_int(fnv_int(fnv_int(fnv_int(h, c->slave_body), c->slave_node), c->master_body), (int)c->kind),
                    c->master_count);
        for (k = 0; k < 3; ++k) h = fnv_double(fnv_int(h, c->master_nodes[k]), c->weights[k]);
        h = fnv_double(fnv_double(h, c->param), c->gap);
        h = fnv(h, &c->normal, sizeof c->normal);
        h = fnv(h, &c->point, sizeof c->point);
        h = fnv(h, &c->force, sizeof c->force);
        h = fnv_double(fnv_virial(h, c->virial), c->penalty);
        h = fnv(h, &c->tangential_force, sizeof c->tangential_force);
        h = fnv_int(fnv_double(h, c->slip), c->state);
    }
    return h;
}

static void section_digest(const char* dir) {
    FILE* f = open_csv(dir, "digest", "scene,periodic,bodies,surface_nodes,solver,alpha,search,threads,gaps,digest");
    int sc, sv, a, se, th;
    for (sc = 0; sc < 9; ++sc) {
        scene_buf b;
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        const char* name = sc < 3 ? "disks" : (sc < 7 ? "packing" : "container");
        int per = sc >= 5 && sc < 7;
        if (sc < 3) make_two_disks(&b, sc == 0 ? 16 : (sc == 1 ? 100 : 1000), 0.05 + 0.1 * sc);
        else if (sc < 7) make_packing(&b, sc % 2 ? 30 : 200, per, 31u + (uint64_t)sc);
        else ntsx_container(&b, 12, sc == 7 ? 4 : 1, 24, 0); /* long walls (long lists), or cut short */
        s = scene_from(&b);
        for (sv = 0; sv < 2; ++sv)
            for (a = 0; a < 4; ++a)
                for (se = 0; se < 2; ++se)
                    for (th = 0; th <= 3; ++th) {
                        nts_options o = nts_default_options();
                        nts_result r;
                        uint64_t h = 1469598103934665603ull;
                        if (se == 1 && (th > 0 || b.total > 3000)) continue;
                        o.alpha = ALPHAS[a];
                        o.solver = (nts_solver)sv;
                        o.search = (nts_search)se;
                        o.threads = th;
                        o.outputs = NTS_OUT_ALL;
                        int gap_count;
                        eval_or_die(ctx, s, &o, &r);
                        h = fnv_summary(h, &r.summary);
                        h = fnv(h, r.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s));
                        h = fnv_contacts(h, r.contacts, r.contact_count);
                        h = fnv_contacts(h, r.gaps, r.gap_count);
                        gap_count = r.gap_count;
                        /* The default outputs too: the core keeps no per-candidate
                         * records for them, and must give the same bits. */
                        o.outputs = nts_default_options().outputs;
                        eval_or_die(ctx, s, &o, &r);
                        h = fnv_summary(h, &r.summary);
                        h = fnv(h, r.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s));
                        fprintf(f, "%s,%d,%d,%d,%s,%.2f,%s,%d,%d,%016llx\n", name, per, b.body_count, b.total,
                                SOLVER_NAMES[sv], o.alpha, se ? "brute_force" : "cells", th, gap_count,
                                (unsigned long long)h);
                    }
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        buf_free(&b);
    }
    fclose(f);
}

/* A fixed workload for profilers (callgrind, perf): 5 evaluations of a packing
 * of 2,000 particles with the default options (periodic, or open with
 * --sections profile_open). */
static void section_profile(int periodic) {
    scene_buf b;
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    int k;
    make_packing(&b, 2000, periodic, 2024u);
    s = scene_from(&b);
    for (k = 0; k < g_profile_evals; ++k) eval_or_die(ctx, s, &o, &r);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    buf_free(&b);
}

static int has_section(const char* list, const char* name) {
    const char* p = list;
    size_t n = strlen(name);
    if (list == NULL) return 1;
    while ((p = strstr(p, name)) != NULL) {
        if ((p == list || p[-1] == ',') && (p[n] == '\0' || p[n] == ',')) return 1;
        p += n;
    }
    return 0;
}

int main(int argc, char** argv) {
    const char* dir = "bench/results";
    const char* sections = NULL;
    int i, max_threads = 4;
    double t0 = ntsx_now();
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--quick") == 0) g_quick = 1;
        else if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) dir = argv[++i];
        else if (strcmp(argv[i], "--sections") == 0 && i + 1 < argc) sections = argv[++i];
        else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) max_threads = atoi(argv[++i]);
        else if (strcmp(argv[i], "--evals") == 0 && i + 1 < argc) g_profile_evals = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--quick] [--out DIR] [--sections LIST] [--threads N] [--evals N]\n", argv[0]);
            return 2;
        }
    }
    nts_set_allocator(count_alloc, count_free, NULL);
#define RUN(name, call)                                                                  \
    if (has_section(sections, name)) {                                                   \
        double ts = ntsx_now();                                                               \
        call;                                                                            \
        fprintf(stderr, "[%s] %s: %.1f s, core bytes still allocated %lld\n", NTS_BENCH_VARIANT, name, \
                ntsx_now() - ts, (long long)g_alloc.live);                                    \
    }
    if (sections != NULL && has_section(sections, "profile")) section_profile(1);
    if (sections != NULL && has_section(sections, "profile_open")) section_profile(0);
    RUN("digest", section_digest(dir));
    RUN("disks", section_disks(dir));
    RUN("packing", section_packing(dir));
    RUN("errors", section_errors(dir));
    RUN("smooth", section_smooth(dir));
    RUN("scaling", section_scaling(dir));
    RUN("threads", section_threads(dir, max_threads));
    RUN("peer", section_peer(dir));
    RUN("hard", section_hard(dir));
#undef RUN
    fprintf(stderr, "[%s] total %.1f s\n", NTS_BENCH_VARIANT, ntsx_now() - t0);
    return 0;
}
