/* The build's own backend with OpenMP (parallel.h): a task's ranges of
 * min_range items, run before enqueue returns. More ranges than threads (the
 * search's chunks): each taken by whichever thread is free, so a thread that
 * the machine slows down takes fewer. One range per thread at most
 * (nts_run_each): range q on thread q, as schedule(static) did, so that the
 * loops over the same entries run where the last one left them in cache. */
#include <stdint.h>

#include <omp.h>

#include "parallel.h"

/* Range q of a task's min_range items. */
static void run_range(nts_task_fn* task, int q, int count, int min_range, void* tc) {
    const long long b = (long long)q * min_range, e = b + min_range < count ? b + min_range : count;
    task((int)b, (int)e, omp_get_thread_num(), tc);
}

static void* omp_enqueue(nts_task_fn* task, int count, int min_range, void* tc, void* user) {
    /* The stock backend carries its thread count in `user` (nts_run_stock). */
    const int threads = (int)(intptr_t)user;
    const int ranges = (int)(((long long)count + min_range - 1) / min_range);
    int q;
    if (ranges <= threads) {
#pragma omp parallel for num_threads(ranges) schedule(static, 1)
        for (q = 0; q < ranges; ++q) run_range(task, q, count, min_range, tc);
    } else {
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
        for (q = 0; q < ranges; ++q) run_range(task, q, count, min_range, tc);
    }
    return NULL; /* done: no finish */
}

static void omp_finish(void* handle, void* user) {
    (void)handle;
    (void)user;
}

nts_run nts_run_stock(int threads) {
    nts_run run;
    run.workers = threads > 1 ? threads : 1;
    run.backend.enqueue = omp_enqueue;
    run.backend.finish = omp_finish;
    run.backend.worker_count = run.workers;
    run.backend.user = (void*)(intptr_t)run.workers;
    return run;
}
