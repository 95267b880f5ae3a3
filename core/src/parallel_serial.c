/* The build's own backend without OpenMP (parallel.h): one worker, the
 * caller's thread, every range in order. */
#include "parallel.h"

static void* serial_enqueue(nts_task_fn* task, int count, int min_range, void* tc, void* user) {
    (void)min_range;
    (void)user;
    task(0, count, 0, tc);
    return NULL;
}

static void serial_finish(void* handle, void* user) {
    (void)handle;
    (void)user;
}

nts_run nts_run_stock(int threads) {
    nts_run run;
    (void)threads; /* no threads to run them on */
    run.workers = 1;
    run.backend.enqueue = serial_enqueue;
    run.backend.finish = serial_finish;
    run.backend.worker_count = 1;
    run.backend.user = NULL;
    return run;
}
