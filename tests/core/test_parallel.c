/* Parallel suite (issue 6): the local search gives bitwise the same result for
 * any number of threads; the cell-ordered search with its culls gives bitwise
 * the result of brute force in the cases the culls must get right (periodic
 * boxes with bodies across the edge, grids too narrow for the cull, far from
 * the origin); a warm context allocates nothing, whatever the thread count. */
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "suites.h"
#include "test_util.h"

/* Every output (records kept: scatter.c makes the force shares) and the
 * forces, energy and virial alone (the search keeps the shares): each
 * thread adds the shares of the chunks whose nodes reach its range. */
/* Thread counts: 1 to 7, and past the backend's blocks kept on its stack
 * (parallel_omp.c: 16); chunks of the search: 3 with 64 disks, 16 with 400
 * (more ranges than threads: each thread its block, then the others'). */
static const int thread_counts[] = {1, 2, 3, 4, 5, 6, 7, 17, 40};

static void check_threads_of(int disks, int periodic, double alpha, nts_solver solver) {
    test_packing p = make_packing(disks, 40, 1.0, 1.93, periodic, 500 + (unsigned)periodic);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    const unsigned outputs[2] = {NTS_OUT_ALL, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL};
    int t, k;
    CU_ASSERT_FATAL(s != NULL && c0 != NULL && c1 != NULL);
    o.alpha = alpha;
    o.solver = solver;
    for (k = 0; k < 2; ++k) {
        o.outputs = outputs[k];
        o.threads = 1;
        CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
        CU_ASSERT(r0.summary.contacts > 50);
        for (t = 0; t < (int)(sizeof thread_counts / sizeof thread_counts[0]); ++t) {
            const int th = thread_counts[t];
            int same;
            o.threads = th;
            CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
            same = same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE);
            if (!same)
                fprintf(stderr, "\n  threads %d differ from serial (%d disks, periodic %d alpha %g outputs %u)\n", th,
                        disks, periodic, alpha, outputs[k]);
            CU_ASSERT(same);
        }
    }
    nts_context_destroy(c0);
    nts_context_destroy(c1);
    nts_scene_destroy(s);
    free_packing(&p);
}

static void check_threads(int periodic, double alpha, nts_solver solver) {
    check_threads_of(64, periodic, alpha, solver);
    check_threads_of(400, periodic, alpha, solver);
}

static void test_threads_bitwise_open(void) {
    check_threads(0, 0.0, NTS_SOLVER_CLOSED_FORM);
    check_threads(0, 0.2, NTS_SOLVER_CLOSED_FORM);
    check_threads(0, 0.5, NTS_SOLVER_NEWTON);
}

static void test_threads_bitwise_periodic(void) {
    check_threads(1, 0.0, NTS_SOLVER_NEWTON);
    check_threads(1, 0.2, NTS_SOLVER_NEWTON);
    check_threads(1, 0.1, NTS_SOLVER_CLOSED_FORM);
}

/* Cells (cell-ordered masters, whole-cell and reach culls, fast minimum image)
 * against brute force, bitwise, on a packing moved by (dx, dy). */
static void check_cells_vs_brute(int count, int periodic, double dx, double dy, double alpha, double radius) {
    test_packing p = make_packing(count, 32, 1.0, 1.93, periodic, 900 + (unsigned)count);
    nts_scene* s;
    nts_context *cc = nts_context_create(), *cb = nts_context_create();
    nts_options o = nts_default_options();
    nts_result rc, rb;
    nts_error err;
    int b, i;
    for (b = 0; b < p.count; ++b)
        for (i = 0; i < p.bodies[b].node_count; ++i) {
            p.bodies[b].nodes[i].x += dx;
            p.bodies[b].nodes[i].y += dy;
        }
    s = make_scene(p.bodies, p.count, p.lx, p.ly);
    CU_ASSERT_FATAL(s != NULL);
    o.alpha = alpha;
    o.search_radius = radius;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(cc, s, &o, &rc, &err) == 0);
    o.search = NTS_SEARCH_BRUTE_FORCE;
    CU_ASSERT_FATAL(nts_evaluate(cb, s, &o, &rb, &err) == 0);
    CU_ASSERT(rc.contact_count > 0);
    if (!same_answer(s, &rc, &rb, NTST_SUMMARY_BUT_CELLS)) /* cell_size differs by design */
        fprintf(stderr, "\n  cells differ from brute force: %d bodies, periodic %d, shift (%g, %g)\n", count, periodic,
                dx, dy);
    CU_ASSERT(same_answer(s, &rc, &rb, NTST_SUMMARY_BUT_CELLS));
    nts_context_destroy(cc);
    nts_context_destroy(cb);
    nts_scene_destroy(s);
    free_packing(&p);
}

static void test_cells_equal_brute_force(void) {
    /* Open scenes, near and far from the origin (the cull's round-off allowance). */
    check_cells_vs_brute(49, 0, 0.0, 0.0, 0.2, -1.0);
    check_cells_vs_brute(49, 0, 1e6, -3e5, 0.2, -1.0);
    check_cells_vs_brute(49, 0, -7.25, 1e3, 0.0, -1.0);
    /* Periodic: bodies across the box edge (shifted by half a lattice step), with
     * coordinates outside the box (shifted by a box length and more). */
    check_cells_vs_brute(49, 1, 0.97, 0.5, 0.2, -1.0);
    check_cells_vs_brute(49, 1, -13.51, 27.0, 0.0, -1.0);
    check_cells_vs_brute(64, 1, 1e4 + 0.3, -0.9, 0.5, -1.0);
    /* Periodic grids too narrow for the whole-cell cull (fewer than 4 cells). */
    check_cells_vs_brute(4, 1, 0.5, 0.5, 0.2, 0.9);
    check_cells_vs_brute(9, 1, -0.5, 0.25, 0.1, 1.5);
}

/* Allocation counting through the allocator hook. */
static long long g_allocs;
static void* counting_alloc(size_t n, void* user) {
    (void)user;
    /* Called from the worker threads too when options.threads > 1. */
#ifdef _OPENMP
#pragma omp atomic
#endif
    ++g_allocs;
    return malloc(n);
}
static void counting_free(void* p, void* user) {
    (void)user;
    free(p);
}

static void test_warm_context_allocates_nothing(void) {
    test_packing p = make_packing(36, 40, 1.0, 1.93, 1, 77);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* c;
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int k, th;
    CU_ASSERT_FATAL(s != NULL);
    nts_set_allocator(counting_alloc, counting_free, NULL);
    c = nts_context_create();
    CU_ASSERT_FATAL(c != NULL);
    for (th = 0; th <= 2; th += 2) {
        long long before;
        o.threads = th;
        o.outputs = NTS_OUT_ALL;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0); /* warm-up: buffers grow */
        before = g_allocs;
        for (k = 0; k < 5; ++k) {
            o.alpha = 0.1 * k;
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        }
        ASSERT_INT_EQ(g_allocs - before, 0);
    }
    nts_context_destroy(c);
    nts_set_allocator(NULL, NULL, NULL);
    nts_scene_destroy(s);
    free_packing(&p);
}

#ifdef _OPENMP
/* Bytes outstanding through the allocator hook and their peak: each block
 * carries its size in a header (16 bytes, so the block stays aligned for
 * doubles; the context aligns its cache-line buffers itself). */
static long long g_bytes, g_peak;
static void* tracking_alloc(size_t n, void* user) {
    size_t* p = (size_t*)malloc(n + 16);
    long long now;
    (void)user;
    if (p == NULL) return NULL;
    *p = n;
#pragma omp atomic
    ++g_allocs;
#pragma omp atomic capture
    now = g_bytes += (long long)n;
#pragma omp critical(nts_test_peak)
    if (now > g_peak) g_peak = now;
    return (char*)p + 16;
}
static void tracking_free(void* q, void* user) {
    size_t* p;
    (void)user;
    if (q == NULL) return;
    p = (size_t*)(void*)((char*)q - 16);
#pragma omp atomic
    g_bytes -= (long long)*p;
    free(p);
}

/* A cancel hook that cancels nothing but slows one thread down: the search
 * asks it once per chunk, so that thread runs few chunks and the other most. */
static int g_slow_thread;
static int slow_one_thread(void* user) {
    (void)user;
    if (omp_get_thread_num() == g_slow_thread) {
        const struct timespec pause = {0, 500000};
        nanosleep(&pause, NULL);
    }
    return 0;
}

/* The chunks go to whichever thread is free, so each evaluation may deal the
 * workers different shares of the records. A context's memory is sized by
 * the scene's needs, never by the schedule: once warm, 1,000 evaluations
 * with the slowed thread alternating allocate nothing, the peak of the bytes
 * held does not move, and the answer is the same bits each time (every
 * output asked for, so every record is kept; then the default outputs, so
 * only force shares). Issue 22: the workers' candidate buffers were sized by
 * each other's capacity and grew by an eighth at every evaluation (10 kB to
 * 125 MB in 100 evaluations, out of memory at 119). */
static void test_warm_context_with_uneven_threads(void) {
    test_packing p = make_packing(64, 48, 1.0, 1.93, 0, 91);
    nts_scene* s;
    nts_context *c = NULL, *c0 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r, r0;
    nts_error err;
    int k, outputs, differ, b;
    /* Only the first chunk's bodies touch (the others are moved apart), so
     * whichever worker runs the other chunks meets no candidate at all: the
     * workers' needs differ in every schedule. */
    for (b = 21; b < p.count; ++b)
        for (k = 0; k < p.bodies[b].node_count; ++k) p.bodies[b].nodes[k].x += 10.0 * b;
    s = make_scene(p.bodies, p.count, p.lx, p.ly);
    CU_ASSERT_FATAL(s != NULL && c0 != NULL);
    CU_ASSERT_FATAL(nts_scene_surface_node_count(s) > 2 * 1024); /* several chunks */
    for (outputs = 0; outputs < 2; ++outputs) {
        long long before, peak;
        size_t held;
        o.outputs = outputs == 0 ? NTS_OUT_ALL : nts_default_options().outputs; /* records; force shares */
        o.threads = 1;
        o.cancel = NULL;
        CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
        g_bytes = g_peak = 0;
        nts_set_allocator(tracking_alloc, tracking_free, NULL);
        c = nts_context_create();
        CU_ASSERT_FATAL(c != NULL);
        o.threads = 2;
        o.cancel = slow_one_thread;
        g_slow_thread = 0;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0); /* warm-up: buffers grow */
        before = g_allocs;
        peak = g_peak;
        held = nts_context_memory_bytes(c);
        differ = 0;
        for (k = 1; k <= 1000; ++k) {
            g_slow_thread = k % 2;
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
            differ += !same_answer(s, &r0, &r, NTST_SUMMARY_WHOLE);
        }
        ASSERT_INT_EQ(differ, 0);
        ASSERT_INT_EQ(g_allocs - before, 0);
        ASSERT_INT_EQ(g_peak, peak);
        CU_ASSERT(nts_context_memory_bytes(c) == held);
        nts_context_destroy(c);
        ASSERT_INT_EQ(g_bytes, 0);
        nts_set_allocator(NULL, NULL, NULL);
    }
    nts_context_destroy(c0);
    nts_scene_destroy(s);
    free_packing(&p);
}
#endif

/* One context moved between thread counts gives the serial answer each time. */
static void test_context_reuse_across_threads(void) {
    test_packing p = make_packing(25, 48, 1.0, 1.93, 0, 4321);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context *c = nts_context_create(), *ref = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r, r0;
    nts_error err;
    static const int order[] = {3, 0, 2, 1, 4, 0};
    int k;
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(ref, s, &o, &r0, &err) == 0);
    for (k = 0; k < 6; ++k) {
        o.threads = order[k];
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        CU_ASSERT(same_answer(s, &r0, &r, NTST_SUMMARY_WHOLE));
    }
    nts_context_destroy(c);
    nts_context_destroy(ref);
    nts_scene_destroy(s);
    free_packing(&p);
}

void register_parallel_suite(void) {
    CU_pSuite s = CU_add_suite("parallel", NULL, NULL);
    ADD_TEST(s, test_threads_bitwise_open);
    ADD_TEST(s, test_threads_bitwise_periodic);
    ADD_TEST(s, test_cells_equal_brute_force);
    ADD_TEST(s, test_warm_context_allocates_nothing);
#ifdef _OPENMP
    ADD_TEST(s, test_warm_context_with_uneven_threads);
#endif
    ADD_TEST(s, test_context_reuse_across_threads);
}
