/* Allocation failure (libuv's test-loop-oom.c, for our core): through the
 * allocator hook (nts_set_allocator) fail the Nth allocation, for every N, of
 * scene creation and of evaluation. Each failing call must return
 * NTS_ENOMEM (never another error, never a crash), leave no block behind once
 * its objects are destroyed, and a context whose evaluation failed must give
 * the right answer on the next try. The allocator counts live blocks itself,
 * so a leak shows as a count, with or without a sanitizer. */
#include <stdlib.h>
#include <string.h>

#include <CUnit/CUnit.h>

#include <ntscontact/ntscontact.h>

#include "suites.h"

/* ------------------------------------------------------------ allocator */

typedef struct failing_alloc {
    long calls;   /* allocations asked for since the last reset */
    long fail_at; /* 1-based call that fails; 0 = never */
    long failed;  /* how many were refused */
    long live;    /* blocks handed out and not yet freed */
} failing_alloc;

static failing_alloc g_fa;

/* The OpenMP workers allocate too: the counters are updated atomically. */
static void* fa_alloc(size_t size, void* user) {
    failing_alloc* fa = (failing_alloc*)user;
    long n = __atomic_add_fetch(&fa->calls, 1, __ATOMIC_SEQ_CST);
    void* p;
    if (fa->fail_at > 0 && n == fa->fail_at) {
        __atomic_add_fetch(&fa->failed, 1, __ATOMIC_SEQ_CST);
        return NULL;
    }
    p = malloc(size);
    if (p != NULL) __atomic_add_fetch(&fa->live, 1, __ATOMIC_SEQ_CST);
    return p;
}

static void fa_free(void* ptr, void* user) {
    failing_alloc* fa = (failing_alloc*)user;
    if (ptr == NULL) return;
    __atomic_sub_fetch(&fa->live, 1, __ATOMIC_SEQ_CST);
    free(ptr);
}

static void fa_install(long fail_at) {
    memset(&g_fa, 0, sizeof g_fa);
    g_fa.fail_at = fail_at;
    nts_set_allocator(fa_alloc, fa_free, &g_fa);
}

static void fa_remove(void) { nts_set_allocator(NULL, NULL, NULL); }

/* ------------------------------------------------------------ scenes */

#define DISK_NODES 24
#define PI 3.14159265358979323846

/* Storage of one test scene (the defs point into it). */
typedef struct test_scene {
    nts_vec2 disk_a[DISK_NODES], disk_b[DISK_NODES];
    nts_vec2 ring[2 * DISK_NODES];
    int ring_loops[2 * DISK_NODES], ring_start[3];
    nts_vec2 mesh[9];
    int mesh_tri[8 * 3];
    nts_body_def bodies[4];
    nts_scene_def def;
} test_scene;

static void disk(nts_vec2* out, int n, double cx, double cy, double r, double phase) {
    int i;
    for (i = 0; i < n; ++i) {
        double th = 2.0 * PI * i / n + phase;
        out[i] = nts_v2(cx + r * cos(th), cy + r * sin(th));
    }
}

/* Two pressed disks (one clockwise, so a loop gets reversed), an annulus given
 * by two explicit loops pressing on disk b, and a 3x3-node triangle mesh square
 * pressing on disk a: every way a body can be given, with active contacts. */
static void make_scene(test_scene* t, double lx, double ly) {
    int i, k;
    memset(t, 0, sizeof *t);
    disk(t->disk_a, DISK_NODES, 0.0, 0.0, 1.0, 0.0);
    disk(t->disk_b, DISK_NODES, 1.95, 0.0, 1.0, PI / DISK_NODES);
    for (i = 0; i < DISK_NODES / 2; ++i) { /* clockwise twin of disk b */
        nts_vec2 s = t->disk_b[i];
        t->disk_b[i] = t->disk_b[DISK_NODES - 1 - i];
        t->disk_b[DISK_NODES - 1 - i] = s;
    }
    disk(t->ring, DISK_NODES, 1.95, 1.65, 0.7, 0.0);           /* outer loop */
    disk(t->ring + DISK_NODES, DISK_NODES, 1.95, 1.65, 0.4, 0.1); /* hole */
    for (i = 0; i < DISK_NODES; ++i) {
        t->ring_loops[i] = i;
        t->ring_loops[DISK_NODES + i] = 2 * DISK_NODES - 1 - i; /* hole, clockwise */
    }
    t->ring_start[0] = 0;
    t->ring_start[1] = DISK_NODES;
    t->ring_start[2] = 2 * DISK_NODES;
    for (k = 0; k < 9; ++k) t->mesh[k] = nts_v2(-0.5 + 0.5 * (k % 3), -0.95 - 0.5 * (k / 3));
    for (k = 0, i = 0; i < 4; ++i) {
        int x = i % 2, y = i / 2, n0 = 3 * y + x;
        /* Triangles (n0, n0+1, n0+4) and (n0, n0+4, n0+3): y grows downwards, so
         * these run clockwise; the core orients each triangle itself. */
        t->mesh_tri[k++] = n0; t->mesh_tri[k++] = n0 + 1; t->mesh_tri[k++] = n0 + 4;
        t->mesh_tri[k++] = n0; t->mesh_tri[k++] = n0 + 4; t->mesh_tri[k++] = n0 + 3;
    }
    t->bodies[0].nodes = t->disk_a;
    t->bodies[0].node_count = DISK_NODES;
    t->bodies[1].nodes = t->disk_b;
    t->bodies[1].node_count = DISK_NODES;
    t->bodies[2].nodes = t->ring;
    t->bodies[2].node_count = 2 * DISK_NODES;
    t->bodies[2].loop_nodes = t->ring_loops;
    t->bodies[2].loop_start = t->ring_start;
    t->bodies[2].loop_count = 2;
    t->bodies[3].nodes = t->mesh;
    t->bodies[3].node_count = 9;
    t->bodies[3].triangles = t->mesh_tri;
    t->bodies[3].triangle_count = 8;
    t->def = nts_default_scene_def();
    t->def.bodies = t->bodies;
    t->def.body_count = 4;
    t->def.lx = lx;
    t->def.ly = ly;
}

static nts_options all_outputs(int threads, nts_search search) {
    nts_options o = nts_default_options();
    o.penalty = 100.0;
    o.search_radius = 0.3;
    o.outputs = NTS_OUT_ALL;
    o.threads = threads;
    o.search = search;
    return o;
}

/* A copy of what a result says, to compare a run after failures with the
 * reference run bitwise. */
typedef struct result_copy {
    nts_summary summary;
    int node_count, contact_count, gap_count;
    nts_vec2* forces;
    nts_contact* contacts;
    nts_contact* gaps;
} result_copy;

static void copy_result(result_copy* c, const nts_result* r, int node_count) {
    memset(c, 0, sizeof *c);
    c->summary = r->summary;
    c->node_count = node_count;
    c->contact_count = r->contact_count;
    c->gap_count = r->gap_count;
    c->forces = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)node_count);
    c->contacts = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(r->contact_count + 1));
    c->gaps = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(r->gap_count + 1));
    if (c->forces && r->forces) memcpy(c->forces, r->forces, sizeof(nts_vec2) * (size_t)node_count);
    if (c->contacts && r->contacts) memcpy(c->contacts, r->contacts, sizeof(nts_contact) * (size_t)r->contact_count);
    if (c->gaps && r->gaps) memcpy(c->gaps, r->gaps, sizeof(nts_contact) * (size_t)r->gap_count);
}

static void free_copy(result_copy* c) {
    free(c->forces);
    free(c->contacts);
    free(c->gaps);
}

static int same_result(const result_copy* c, const nts_result* r) {
    return memcmp(&c->summary, &r->summary, sizeof c->summary) == 0 && c->contact_count == r->contact_count &&
           c->gap_count == r->gap_count && r->forces != NULL &&
           memcmp(c->forces, r->forces, sizeof(nts_vec2) * (size_t)c->node_count) == 0 &&
           (c->contact_count == 0 ||
            memcmp(c->contacts, r->contacts, sizeof(nts_contact) * (size_t)c->contact_count) == 0) &&
           (c->gap_count == 0 || memcmp(c->gaps, r->gaps, sizeof(nts_contact) * (size_t)c->gap_count) == 0);
}

/* The reference: one run with the plain allocator. */
static int reference(const test_scene* t, const nts_options* opt, result_copy* out) {
    nts_error err;
    nts_result res;
    nts_scene* s = nts_scene_create(&t->def, &err);
    nts_context* ctx = nts_context_create();
    int rc = -1;
    if (s != NULL && ctx != NULL && nts_evaluate(ctx, s, opt, &res, &err) == NTS_OK) {
        copy_result(out, &res, nts_scene_node_count(s));
        rc = 0;
    }
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    return rc;
}

/* ------------------------------------------------------------ the sweep */

/* Fails allocation N = 1, 2, ... of scene creation + context creation +
 * evaluation until a run goes through untouched. Returns how many N were tried. */
static long sweep(const test_scene* t, const nts_options* opt) {
    result_copy ref;
    long n, limit = 100000;
    int ok_runs = 0;
    CU_ASSERT_FATAL(reference(t, opt, &ref) == 0);
    CU_ASSERT(ref.summary.contacts > 0);
    for (n = 1; n <= limit; ++n) {
        nts_error err;
        nts_result res;
        nts_scene* s;
        nts_context* ctx = NULL;
        int rc = NTS_ENOMEM, failed_here = 0;
        fa_install(n);
        s = nts_scene_create(&t->def, &err);
        if (s == NULL) {
            CU_ASSERT_EQUAL(err.code, NTS_ENOMEM);
            failed_here = 1;
        } else {
            ctx = nts_context_create();
            if (ctx == NULL) {
                failed_here = 1;
            } else {
                rc = nts_evaluate(ctx, s, opt, &res, &err);
                if (rc != NTS_OK) {
                    CU_ASSERT_EQUAL(rc, NTS_ENOMEM);
                    CU_ASSERT_EQUAL(err.code, NTS_ENOMEM);
                    failed_here = 1;
                    /* The same context, the hook still failing nothing more: the
                     * retry must give exactly the reference answer. */
                    g_fa.fail_at = 0;
                    rc = nts_evaluate(ctx, s, opt, &res, &err);
                    CU_ASSERT_EQUAL(rc, NTS_OK);
                    if (rc == NTS_OK) CU_ASSERT(same_result(&ref, &res));
                } else {
                    CU_ASSERT(same_result(&ref, &res));
                }
            }
        }
        /* Every refused allocation must have surfaced as an error. */
        CU_ASSERT_EQUAL(g_fa.failed > 0, failed_here);
        nts_context_destroy(ctx);
        nts_scene_destroy(s);
        CU_ASSERT_EQUAL(g_fa.live, 0);
        if (g_fa.live != 0) break; /* one leak report is enough */
        if (g_fa.failed == 0) {    /* fewer than n allocations: every N tried */
            ++ok_runs;
            break;
        }
    }
    fa_remove();
    free_copy(&ref);
    CU_ASSERT_EQUAL(ok_runs, 1);
    CU_ASSERT(n > 10); /* the sweep did exercise the allocations */
    return n;
}

static void test_oom_open_scene(void) {
    test_scene t;
    nts_options opt = all_outputs(0, NTS_SEARCH_CELLS);
    make_scene(&t, 0.0, 0.0);
    sweep(&t, &opt);
}

static void test_oom_brute_force(void) {
    test_scene t;
    nts_options opt = all_outputs(0, NTS_SEARCH_BRUTE_FORCE);
    make_scene(&t, 0.0, 0.0);
    sweep(&t, &opt);
}

static void test_oom_periodic(void) {
    test_scene t;
    nts_options opt = all_outputs(0, NTS_SEARCH_CELLS);
    make_scene(&t, 8.0, 9.0);
    sweep(&t, &opt);
}

/* Per-worker buffers grow inside the parallel region (when built with OpenMP;
 * serial otherwise): a refusal there must surface too. */
static void test_oom_threads(void) {
    test_scene t;
    nts_options opt = all_outputs(2, NTS_SEARCH_CELLS);
    make_scene(&t, 0.0, 0.0);
    sweep(&t, &opt);
}

/* The reach's growth (issue 22 §1) has buffers of its own: the default
 * radius, disk b pushed 0.5 into disk a (contacts far deeper than the median
 * segment, found by widened searches). */
static void test_oom_deep_contacts(void) {
    test_scene t;
    nts_options opt = all_outputs(0, NTS_SEARCH_CELLS);
    result_copy ref;
    int i;
    make_scene(&t, 0.0, 0.0);
    for (i = 0; i < DISK_NODES; ++i) t.disk_b[i].x -= 0.45;
    opt.search_radius = -1.0;
    CU_ASSERT_FATAL(reference(&t, &opt, &ref) == 0);
    CU_ASSERT(ref.summary.deep_contacts > 4);
    free_copy(&ref);
    sweep(&t, &opt);
}

/* One step of a kept list's loop (nts_evaluate_positions, or nts_evaluate
 * when pos is NULL) under the failing hook: either the answer from scratch
 * `ref`, bit for bit, or NTS_ENOMEM; after a refusal the same step, nothing
 * failing any more, must give `ref`. Returns 1 when a refusal surfaced.
 * nts_evaluate surfaces every refusal; nts_evaluate_positions may absorb
 * one met before it judged the positions (it then takes them and
 * evaluates as two calls, evaluate.c: evaluate_at), with the right answer. */
static int kept_step(nts_context* ctx, nts_scene* s, const nts_vec2* pos, const nts_options* opt,
                     const result_copy* ref) {
    nts_error err;
    nts_result res;
    const long refused = g_fa.failed;
    int rc = pos != NULL ? nts_evaluate_positions(ctx, s, pos, opt, &res, &err) : nts_evaluate(ctx, s, opt, &res, &err);
    if (rc == NTS_OK) {
        CU_ASSERT(same_result(ref, &res));
        if (pos == NULL) CU_ASSERT_EQUAL(g_fa.failed, refused);
        return 0;
    }
    CU_ASSERT(g_fa.failed > refused);
    CU_ASSERT_EQUAL(rc, NTS_ENOMEM);
    CU_ASSERT_EQUAL(err.code, NTS_ENOMEM);
    g_fa.fail_at = 0;
    rc = pos != NULL ? nts_evaluate_positions(ctx, s, pos, opt, &res, &err) : nts_evaluate(ctx, s, opt, &res, &err);
    CU_ASSERT_EQUAL(rc, NTS_OK);
    if (rc == NTS_OK) CU_ASSERT(same_result(ref, &res));
    return 1;
}

/* A kept candidate list (docs/model.md §15) has buffers of its own, grown
 * by its builds (each slave's list, in every chunk) and by its replays: the
 * list built, replayed, then built again after disk b moved past the skin,
 * failing allocation N = 1, 2, ... of the whole loop. A list whose build
 * failed must not be replayed as if it held. */
static void test_oom_kept(void) {
    test_scene t;
    nts_options fresh = all_outputs(0, NTS_SEARCH_CELLS), opt;
    result_copy ref0, ref1;
    nts_vec2* moved;
    nts_error err;
    nts_result res;
    nts_scene* s;
    nts_context* ctx;
    long n;
    int i, node_count, done = 0;
    make_scene(&t, 0.0, 0.0);
    CU_ASSERT_FATAL(reference(&t, &fresh, &ref0) == 0);
    /* the moved positions (disk b, nodes 24..47, 0.1 deeper into disk a: more
     * than half the default skin, 0.3 r = 0.09) and their answer from scratch */
    s = nts_scene_create(&t.def, &err);
    ctx = nts_context_create();
    CU_ASSERT_FATAL(s != NULL && ctx != NULL);
    node_count = nts_scene_node_count(s);
    moved = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)node_count);
    CU_ASSERT_FATAL(moved != NULL);
    memcpy(moved, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)node_count);
    for (i = DISK_NODES; i < 2 * DISK_NODES; ++i) moved[i].x -= 0.1;
    CU_ASSERT_FATAL(nts_scene_update_positions(s, moved, &err) == NTS_OK);
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &fresh, &res, &err) == NTS_OK);
    copy_result(&ref1, &res, node_count);
    CU_ASSERT(memcmp(&ref0.summary, &ref1.summary, sizeof ref0.summary) != 0); /* the move changes the answer */
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    for (n = 1; n <= 100000 && !done; ++n) {
        nts_candidates* kc = NULL;
        int failed_here = 0;
        fa_install(n);
        ctx = NULL;
        s = nts_scene_create(&t.def, &err);
        if (s == NULL) {
            CU_ASSERT_EQUAL(err.code, NTS_ENOMEM);
            failed_here = 1;
        } else if ((kc = nts_candidates_create(-1.0)) == NULL || (ctx = nts_context_create()) == NULL) {
            failed_here = 1;
        } else {
            nts_candidates_info info;
            opt = fresh;
            opt.candidates = kc;
            failed_here |= kept_step(ctx, s, NULL, &opt, &ref0);  /* the build */
            failed_here |= kept_step(ctx, s, NULL, &opt, &ref0);  /* a replay */
            failed_here |= kept_step(ctx, s, moved, &opt, &ref1); /* past the skin: built again */
            failed_here |= kept_step(ctx, s, moved, &opt, &ref1); /* a replay */
            info = nts_candidates_get_info(kc);
            CU_ASSERT(info.evaluations >= 4);
            if (!failed_here) CU_ASSERT(info.builds == 2); /* the lists were used, twice built */
        }
        if (failed_here) CU_ASSERT(g_fa.failed > 0);
        nts_context_destroy(ctx);
        nts_candidates_destroy(kc);
        nts_scene_destroy(s);
        CU_ASSERT_EQUAL(g_fa.live, 0);
        if (g_fa.live != 0) break;
        done = g_fa.failed == 0;
    }
    fa_remove();
    CU_ASSERT(done);
    CU_ASSERT(n > 20);
    free(moved);
    free_copy(&ref0);
    free_copy(&ref1);
}

/* A context that has evaluated a small scene grows for a bigger one: failures
 * during that growth leave the context usable for both. */
static void test_oom_context_regrowth(void) {
    test_scene small, big;
    nts_options opt = all_outputs(0, NTS_SEARCH_CELLS);
    nts_body_def two[2];
    result_copy ref_small, ref_big;
    nts_error err;
    nts_result res;
    nts_scene *s_small, *s_big;
    nts_context* ctx;
    long n;
    make_scene(&big, 0.0, 0.0);
    make_scene(&small, 0.0, 0.0);
    two[0] = small.bodies[0];
    two[1] = small.bodies[1];
    small.def.bodies = two;
    small.def.body_count = 2;
    CU_ASSERT_FATAL(reference(&small, &opt, &ref_small) == 0);
    CU_ASSERT_FATAL(reference(&big, &opt, &ref_big) == 0);
    for (n = 1; n < 10000; ++n) {
        int rc;
        fa_install(0);
        s_small = nts_scene_create(&small.def, &err);
        s_big = nts_scene_create(&big.def, &err);
        ctx = nts_context_create();
        CU_ASSERT_FATAL(s_small != NULL && s_big != NULL && ctx != NULL);
        CU_ASSERT_FATAL(nts_evaluate(ctx, s_small, &opt, &res, &err) == NTS_OK);
        g_fa.calls = 0;
        g_fa.fail_at = n;
        rc = nts_evaluate(ctx, s_big, &opt, &res, &err);
        CU_ASSERT(rc == NTS_OK || rc == NTS_ENOMEM);
        g_fa.fail_at = 0;
        CU_ASSERT_EQUAL(nts_evaluate(ctx, s_small, &opt, &res, &err), NTS_OK);
        CU_ASSERT(same_result(&ref_small, &res));
        CU_ASSERT_EQUAL(nts_evaluate(ctx, s_big, &opt, &res, &err), NTS_OK);
        CU_ASSERT(same_result(&ref_big, &res));
        nts_context_destroy(ctx);
        nts_scene_destroy(s_small);
        nts_scene_destroy(s_big);
        CU_ASSERT_EQUAL(g_fa.live, 0);
        if (g_fa.failed == 0 || g_fa.live != 0) break;
    }
    fa_remove();
    CU_ASSERT(n > 1);
    free_copy(&ref_small);
    free_copy(&ref_big);
}

/* The hook itself: NULL restores malloc, and zero-size requests still get a
 * distinct block (callers tell failure from an empty array by NULL). */
static void test_hook_basics(void) {
    void* p;
    fa_install(0);
    p = nts_alloc(0);
    CU_ASSERT_PTR_NOT_NULL(p);
    CU_ASSERT_EQUAL(g_fa.live, 1);
    nts_free(p);
    nts_free(NULL);
    CU_ASSERT_EQUAL(g_fa.live, 0);
    fa_remove();
    p = nts_alloc(16);
    CU_ASSERT_PTR_NOT_NULL(p);
    nts_free(p);
    CU_ASSERT_EQUAL(g_fa.calls, 1); /* the removed hook saw nothing more */
}

void register_alloc_suite(void) {
    CU_pSuite s = CU_add_suite("alloc", NULL, NULL);
    CU_add_test(s, "hook basics", test_hook_basics);
    CU_add_test(s, "fail every allocation: open scene, cells", test_oom_open_scene);
    CU_add_test(s, "fail every allocation: brute force", test_oom_brute_force);
    CU_add_test(s, "fail every allocation: periodic", test_oom_periodic);
    CU_add_test(s, "fail every allocation: two threads", test_oom_threads);
    CU_add_test(s, "fail every allocation: deep contacts", test_oom_deep_contacts);
    CU_add_test(s, "fail every allocation: context regrowth", test_oom_context_regrowth);
    CU_add_test(s, "fail every allocation: kept candidates", test_oom_kept);
}
