/* Backend suite (issue 24 §1): the evaluation's parallel loops go through
 * the host's backend (nts_context_set_parallel) when it has one, and give
 * bitwise the serial result whatever it does within its contract: ranges in
 * reverse or random order, deferred until finish, worker indices handed out
 * in any pattern, or real threads of its own (no OpenMP). Every output is
 * compared, for the three paths of the scatter (records, shares, direct),
 * on scenes that run every loop (the segment bracket of a large scene, the
 * sorted masters, the reach's growth of deep contacts, periodic boxes). And
 * one scene evaluated at once by host threads, each on its own context. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

/* What a test backend does with a task: its ranges of min_range items. */
enum { ORDER_REVERSE = 0, ORDER_RANDOM = 1, ORDER_DEFERRED = 2, ORDER_THREADS = 3 };

typedef struct test_backend {
    int order;
    int workers;
    test_rng rng;
    long long tasks, ranges; /* how many the core handed over (the seam is used) */
    int bad_range;           /* a range the core asked for broke the contract */
    /* ORDER_DEFERRED: the task waiting for finish */
    nts_task_fn* task;
    void* tc;
    int count, min_range;
} test_backend;

static int range_count(int count, int min_range) { return (count + min_range - 1) / min_range; }

/* Ranges q in the order `perm`, range q on worker q % workers (sequential:
 * no two run at once). */
static void run_ranges(test_backend* b, nts_task_fn* task, int count, int min_range, void* tc) {
    const int n = range_count(count, min_range);
    int* perm = (int*)malloc(sizeof(int) * (size_t)n);
    int q;
    for (q = 0; q < n; ++q) perm[q] = b->order == ORDER_REVERSE ? n - 1 - q : q;
    if (b->order != ORDER_REVERSE)
        for (q = n - 1; q > 0; --q) { /* Fisher-Yates */
            const int k = (int)(rng_uniform(&b->rng) * (q + 1)), t = perm[q];
            perm[q] = perm[k];
            perm[k] = t;
        }
    for (q = 0; q < n; ++q) {
        const int begin = perm[q] * min_range, end = begin + min_range < count ? begin + min_range : count;
        /* the worker index: scattered, never the range's own */
        task(begin, end, (perm[q] * 7 + 3) % b->workers, tc);
        ++b->ranges;
    }
    free(perm);
}

/* ORDER_THREADS: `workers` pthreads, each taking the next range from the
 * end (a mutex), with its own index. */
typedef struct thread_job {
    test_backend* b;
    nts_task_fn* task;
    void* tc;
    int count, min_range, next;
    pthread_mutex_t lock;
} thread_job;
typedef struct thread_arg {
    thread_job* job;
    int index;
} thread_arg;

static void* thread_main(void* p) {
    thread_arg* a = (thread_arg*)p;
    thread_job* j = a->job;
    for (;;) {
        int q, begin, end;
        pthread_mutex_lock(&j->lock);
        q = --j->next;
        if (q >= 0) ++j->b->ranges;
        pthread_mutex_unlock(&j->lock);
        if (q < 0) return NULL;
        begin = q * j->min_range;
        end = begin + j->min_range < j->count ? begin + j->min_range : j->count;
        j->task(begin, end, a->index, j->tc);
    }
}

static void* test_enqueue(nts_task_fn* task, int count, int min_range, void* tc, void* user) {
    test_backend* b = (test_backend*)user;
    ++b->tasks;
    if (count < 1 || min_range < 1) b->bad_range = 1;
    if (b->order == ORDER_DEFERRED) { /* run nothing now: finish will */
        b->task = task;
        b->tc = tc;
        b->count = count;
        b->min_range = min_range;
        return b;
    }
    if (b->order == ORDER_THREADS) {
        thread_job j;
        pthread_t th[8];
        thread_arg args[8];
        int k;
        j.b = b;
        j.task = task;
        j.tc = tc;
        j.count = count;
        j.min_range = min_range;
        j.next = range_count(count, min_range);
        pthread_mutex_init(&j.lock, NULL);
        for (k = 0; k < b->workers; ++k) {
            args[k].job = &j;
            args[k].index = k;
            pthread_create(&th[k], NULL, thread_main, &args[k]);
        }
        for (k = 0; k < b->workers; ++k) pthread_join(th[k], NULL);
        pthread_mutex_destroy(&j.lock);
        return NULL;
    }
    run_ranges(b, task, count, min_range, tc);
    return NULL;
}

static void test_finish(void* handle, void* user) {
    test_backend* b = (test_backend*)user;
    if (handle != b) b->bad_range = 1;
    b->order = ORDER_RANDOM; /* runs the deferred task's ranges in random order */
    run_ranges(b, b->task, b->count, b->min_range, b->tc);
    b->order = ORDER_DEFERRED;
}

/* A scene's serial result against every backend, worker count 1 to 4, and
 * OpenMP's 1 to 4 threads, for all the outputs (records) and the default
 * ones (direct with one worker, shares with several). */
static void check_backends(const nts_scene* s, double alpha, double radius, int want_deep) {
    const unsigned outs[2] = {NTS_OUT_ALL, 0u};
    int o_i, order, workers;
    for (o_i = 0; o_i < 2; ++o_i) {
        nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r0, r1;
        nts_error err;
        CU_ASSERT_FATAL(c0 != NULL && c1 != NULL);
        o.alpha = alpha;
        o.search_radius = radius;
        if (o_i == 0) o.outputs = outs[0];
        CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
        CU_ASSERT(r0.summary.contacts > 20);
        if (want_deep) CU_ASSERT(r0.summary.deep_contacts > 0);
        for (order = ORDER_REVERSE; order <= ORDER_THREADS; ++order)
            for (workers = 1; workers <= 4; ++workers) {
                test_backend tb;
                nts_parallel p;
                int same;
                memset(&tb, 0, sizeof tb);
                tb.order = order;
                tb.workers = workers;
                tb.rng.s = 0x9e3779b97f4a7c15ull + (unsigned long long)(order * 8 + workers);
                p.enqueue = test_enqueue;
                p.finish = test_finish;
                p.worker_count = workers;
                p.user = &tb;
                CU_ASSERT_FATAL(nts_context_set_parallel(c1, &p) == NTS_OK);
                CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
                same = same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE);
                if (!same)
                    fprintf(stderr, "\n  backend order %d, %d workers, outputs %u differ from serial\n", order,
                            workers, o.outputs);
                CU_ASSERT(same);
                CU_ASSERT(tb.bad_range == 0);
                /* with several workers the loops went through the host */
                if (workers > 1) CU_ASSERT(tb.tasks > 0 && tb.ranges >= tb.tasks);
                if (workers == 1) CU_ASSERT(tb.tasks == 0);
            }
        /* Back to the build's own backend: OpenMP's threads (or serial). */
        CU_ASSERT(nts_context_set_parallel(c1, NULL) == NTS_OK);
        for (workers = 1; workers <= 4; ++workers) {
            o.threads = workers;
            CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
            CU_ASSERT(same_answer(s, &r0, &r1, NTST_SUMMARY_WHOLE));
        }
        nts_context_destroy(c0);
        nts_context_destroy(c1);
    }
}

static void test_backends_open_and_periodic(void) {
    int periodic;
    for (periodic = 0; periodic <= 1; ++periodic) {
        test_packing p = make_packing(36, 40, 1.0, 1.93, periodic, 700 + (unsigned)periodic);
        nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
        CU_ASSERT_FATAL(s != NULL);
        check_backends(s, 0.2, -1.0, 0);
        check_backends(s, 0.0, 0.05, 0);
        nts_scene_destroy(s);
        free_packing(&p);
    }
}

/* Deep overlaps (spacing 1.7 for radius 1): contacts deeper than the default
 * radius, found by the reach's growth in rounds run on the workers. */
static void test_backends_deep_contacts(void) {
    test_packing p = make_packing(25, 48, 1.0, 1.7, 0, 811);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    CU_ASSERT_FATAL(s != NULL);
    check_backends(s, 0.2, -1.0, 1);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* More than 4 NTS_SAMPLE surface nodes: the segment pass brackets the median
 * with a sample, in parallel shares and histogram parts. */
static void test_backends_large_scene(void) {
    test_packing p = make_packing(400, 48, 1.0, 1.93, 1, 4242);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT(nts_scene_surface_node_count(s) > 4 * 4096);
    check_backends(s, 0.2, -1.0, 0);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* The scatter's three paths (search.h) agree bitwise on everything they
 * share: records (contacts asked: every closest point kept, scattered after
 * the search), direct (one worker, default outputs) and shares (several
 * workers, default outputs): forces, energy, virial and the whole summary. */
static void check_paths(const nts_scene* s, double alpha) {
    nts_context *cr = nts_context_create(), *cp = nts_context_create();
    nts_options o = nts_default_options();
    nts_result rec, other;
    nts_error err;
    int workers, order;
    o.alpha = alpha;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(nts_evaluate(cr, s, &o, &rec, &err) == 0);
    CU_ASSERT(rec.contact_count > 20);
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    for (order = ORDER_REVERSE; order <= ORDER_THREADS; order += ORDER_THREADS - ORDER_REVERSE)
        for (workers = 1; workers <= 3; ++workers) {
            test_backend tb;
            nts_parallel p;
            memset(&tb, 0, sizeof tb);
            tb.order = order;
            tb.workers = workers;
            tb.rng.s = 77;
            p.enqueue = test_enqueue;
            p.finish = test_finish;
            p.worker_count = workers;
            p.user = &tb;
            CU_ASSERT_FATAL(nts_context_set_parallel(cp, &p) == NTS_OK);
            CU_ASSERT_FATAL(nts_evaluate(cp, s, &o, &other, &err) == 0);
            if (memcmp(&rec.summary, &other.summary, sizeof rec.summary) != 0 ||
                memcmp(rec.forces, other.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s)) != 0) {
                fprintf(stderr, "\n  the %s path differs from the records path (%d workers)\n",
                        workers == 1 ? "direct" : "shares", workers);
                CU_FAIL("paths differ");
            }
        }
    nts_context_destroy(cr);
    nts_context_destroy(cp);
}

static void test_scatter_paths_agree(void) {
    test_packing p = make_packing(25, 48, 1.0, 1.7, 0, 811);   /* deep contacts too */
    test_packing q = make_packing(36, 40, 1.0, 1.93, 1, 701);  /* periodic */
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_scene* t = make_scene(q.bodies, q.count, q.lx, q.ly);
    CU_ASSERT_FATAL(s != NULL && t != NULL);
    check_paths(s, 0.2);
    check_paths(s, 0.0);
    check_paths(t, 0.2);
    nts_scene_destroy(s);
    nts_scene_destroy(t);
    free_packing(&p);
    free_packing(&q);
}

/* One scene, evaluated at once by host threads, each on its own context (the
 * contract of nts_context: one evaluation at a time on a context, any number
 * on a scene that nobody changes): every answer bitwise the serial one, with
 * one worker and with two (OpenMP's team inside each host thread, when
 * built with it), from scratch and with a kept list of each thread's own.
 * (threads_bench times such pairs to measure what the machine gives two
 * threads, and relies on this.) */
typedef struct shared_scene_job {
    const nts_scene* s;
    const nts_result* ref;
    double alpha;
    int index, rounds, evaluated, differ, failed;
} shared_scene_job;

static void* shared_scene_main(void* p) {
    shared_scene_job* j = (shared_scene_job*)p;
    nts_context* c = nts_context_create();
    nts_candidates* kc = nts_candidates_create(-1.0);
    int k;
    if (c == NULL || kc == NULL) {
        j->failed = 1;
    } else {
        for (k = 0; k < j->rounds; ++k) {
            nts_options o = nts_default_options();
            nts_result r;
            nts_error err;
            o.alpha = j->alpha;
            o.outputs = NTS_OUT_ALL;
            o.threads = 1 + (k + j->index) % 2;
            o.candidates = (k + j->index) % 3 == 0 ? NULL : kc;
            if (nts_evaluate(c, j->s, &o, &r, &err) != NTS_OK) {
                j->failed = 1;
                break;
            }
            ++j->evaluated;
            if (!same_answer(j->s, j->ref, &r, NTST_SUMMARY_WHOLE)) ++j->differ;
        }
    }
    nts_candidates_destroy(kc);
    nts_context_destroy(c);
    return NULL;
}

static void check_shared_scene(const nts_scene* s, double alpha) {
    enum { THREADS = 3, ROUNDS = 6 };
    nts_context* c0 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0;
    nts_error err;
    pthread_t th[THREADS];
    shared_scene_job job[THREADS];
    int k;
    CU_ASSERT_FATAL(c0 != NULL);
    o.alpha = alpha;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == NTS_OK);
    CU_ASSERT(r0.summary.contacts > 20);
    for (k = 0; k < THREADS; ++k) {
        memset(&job[k], 0, sizeof job[k]);
        job[k].s = s;
        job[k].ref = &r0;
        job[k].alpha = alpha;
        job[k].index = k;
        job[k].rounds = ROUNDS;
        CU_ASSERT_FATAL(pthread_create(&th[k], NULL, shared_scene_main, &job[k]) == 0);
    }
    for (k = 0; k < THREADS; ++k) {
        CU_ASSERT(pthread_join(th[k], NULL) == 0);
        CU_ASSERT(job[k].failed == 0);
        CU_ASSERT(job[k].evaluated == ROUNDS);
        if (job[k].differ != 0) fprintf(stderr, "\n  thread %d: %d of %d answers differ from serial\n", k, job[k].differ, ROUNDS);
        CU_ASSERT(job[k].differ == 0);
    }
    nts_context_destroy(c0);
}

static void test_one_scene_many_threads(void) {
    /* deep contacts too; periodic and large enough (19,200 surface nodes)
     * that the threads' evaluations overlap on a machine with free cores */
    test_packing p = make_packing(25, 48, 1.0, 1.7, 0, 811);
    test_packing q = make_packing(400, 48, 1.0, 1.93, 1, 702);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_scene* t = make_scene(q.bodies, q.count, q.lx, q.ly);
    CU_ASSERT_FATAL(s != NULL && t != NULL);
    check_shared_scene(s, 0.2);
    check_shared_scene(t, 0.0);
    check_shared_scene(t, 0.2);
    nts_scene_destroy(s);
    nts_scene_destroy(t);
    free_packing(&p);
    free_packing(&q);
}

static void* never(nts_task_fn* task, int count, int min_range, void* tc, void* user) {
    (void)task, (void)count, (void)min_range, (void)tc, (void)user;
    return NULL;
}
static void never_finish(void* h, void* user) { (void)h, (void)user; }

static void test_backend_rejected(void) {
    nts_context* c = nts_context_create();
    nts_parallel p;
    p.enqueue = never;
    p.finish = never_finish;
    p.worker_count = 0;
    p.user = NULL;
    CU_ASSERT(nts_context_set_parallel(c, &p) == NTS_EINVALID_ARGUMENT);
    p.worker_count = 2;
    p.enqueue = NULL;
    CU_ASSERT(nts_context_set_parallel(c, &p) == NTS_EINVALID_ARGUMENT);
    p.enqueue = never;
    p.finish = NULL;
    CU_ASSERT(nts_context_set_parallel(c, &p) == NTS_EINVALID_ARGUMENT);
    CU_ASSERT(nts_context_set_parallel(NULL, NULL) == NTS_EINVALID_ARGUMENT);
    CU_ASSERT(nts_context_set_parallel(c, NULL) == NTS_OK);
    nts_context_destroy(c);
}

void register_backend_suite(void) {
    CU_pSuite s = CU_add_suite("backend", NULL, NULL);
    ADD_TEST(s, test_backends_open_and_periodic);
    ADD_TEST(s, test_backends_deep_contacts);
    ADD_TEST(s, test_backends_large_scene);
    ADD_TEST(s, test_backend_rejected);
    ADD_TEST(s, test_scatter_paths_agree);
    ADD_TEST(s, test_one_scene_many_threads);
}
