/* The build's own backend with OpenMP (parallel.h): a task's ranges of
 * min_range items, taken by whichever of the threads is free (a thread that
 * the machine slows down takes fewer), run before enqueue returns. */
#include <stdint.h>

#include <omp.h>

#include "parallel.h"

static void* omp_enqueue(nts_task_fn* task, int count, int min_range, void* tc, void* user) {
    /* The stock backend carries its thread count in `user` (nts_run_stock). */
    const int threads = (int)(intptr_t)user;
    const int ranges = (int)(((long long)count + min_range - 1) / min_range);
    int q;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
    for (q = 0; q < ranges; ++q) {
        const long long b = (long long)q * min_range, e = b + min_range < count ? b + min_range : count;
        task((int)b, (int)e, omp_get_thread_num(), tc);
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
