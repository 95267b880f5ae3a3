/* The build's own backend with OpenMP (parallel.h): a task's ranges of
 * min_range items, run before enqueue returns. One range per thread at most
 * (nts_run_each): range q on thread q, as schedule(static) did, so that the
 * loops over the same entries run where the last one left them in cache.
 * More ranges than threads (the search's chunks): the ranges are cut into
 * contiguous blocks, one per thread (at most STACK_BLOCKS; past that,
 * threads share them); each thread takes its block's ranges in order, then
 * steals one at a time from the back of the others', so that a thread the
 * machine slows down takes fewer. Contiguous blocks, not ranges dealt in
 * turn (schedule(dynamic)): neighbouring chunks search neighbouring slaves
 * against the same masters, and a thread that runs both reads them from its
 * own cache (docs/benchmarks.md, "Two threads, paired"). */
#include <stdint.h>

#include <omp.h>
#if defined(__GNUC__) && (defined(__unix__) || defined(__APPLE__))
#include <pthread.h>
#endif

#include "parallel.h"

/* fork(): GNU libgomp's threads do not survive it, and the first parallel
 * region of a child whose parent had started them never returns (Python's
 * multiprocessing forks by default on Linux). Whether the parent started
 * them cannot be told from here (any other OpenMP code in the process
 * starts the same pool), so every child forked from a process that loaded
 * the library runs each loop in the caller's thread: the same bits
 * (parallel.h: no result depends on the workers), one core. Watched from
 * the library's load; read by nts_run_stock. */
static int omp_forked;
#if defined(__GNUC__) && (defined(__unix__) || defined(__APPLE__))
static void fork_child(void) { omp_forked = 1; /* (the child has one thread now) */ }
__attribute__((constructor)) static void fork_watch(void) { (void)pthread_atfork(NULL, NULL, fork_child); }
#endif

/* Range q of a task's min_range items. */
static void run_range(nts_task_fn* task, int q, int count, int min_range, void* tc) {
    const long long b = (long long)q * min_range, e = b + min_range < count ? b + min_range : count;
    task((int)b, (int)e, omp_get_thread_num(), tc);
}

/* A block of ranges [lo, hi), both in one word (lo the low half) so that
 * its owners (from the front) and a thief (from the back) take ranges with
 * one compare-and-swap each; a line of its own. */
typedef struct block {
    uint64_t w;
    char pad[64 - sizeof(uint64_t)];
} block;

/* At most this many blocks (on the stack: enqueue allocates nothing). */
enum { STACK_BLOCKS = 16 };

/* Take one range of b: the first (front) or the last; -1 when it is empty. */
static int block_take(block* b, int front) {
    uint64_t w = nts_atomic_load_u64(&b->w);
    for (;;) { /* retried only when another thread took one of b's ranges */
        const uint32_t lo = (uint32_t)w, hi = (uint32_t)(w >> 32);
        uint64_t next;
        if (lo >= hi) return -1;
        next = front ? (w & ~(uint64_t)0xffffffffu) | (uint64_t)(lo + 1) : (uint64_t)(hi - 1) << 32 | lo;
        if (nts_atomic_cas_u64(&b->w, &w, next)) return front ? (int)lo : (int)(hi - 1);
    }
}

/* Thread t's ranges: its block's (block t mod nb), then the others' from
 * their backs, each until it is empty. */
static void run_blocks(block* blocks, int nb, nts_task_fn* task, int count, int min_range, void* tc) {
    const int t = omp_get_thread_num() % nb;
    int q, v;
    while ((q = block_take(&blocks[t], 1)) >= 0) run_range(task, q, count, min_range, tc);
    for (v = 1; v < nb; ++v)
        while ((q = block_take(&blocks[(t + v) % nb], 0)) >= 0) run_range(task, q, count, min_range, tc);
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
        block blocks[STACK_BLOCKS];
        const int nb = threads < STACK_BLOCKS ? threads : STACK_BLOCKS;
        for (q = 0; q < nb; ++q) {
            const uint64_t lo = (uint64_t)((long long)ranges * q / nb);
            const uint64_t hi = (uint64_t)((long long)ranges * (q + 1) / nb);
            blocks[q].w = hi << 32 | lo;
        }
#pragma omp parallel num_threads(threads)
        run_blocks(blocks, nb, task, count, min_range, tc);
    }
    return NULL; /* done: no finish */
}

static void omp_finish(void* handle, void* user) {
    (void)handle;
    (void)user;
}

nts_run nts_run_stock(int threads) {
    nts_run run;
    run.workers = threads > 1 && !__atomic_load_n(&omp_forked, __ATOMIC_RELAXED) ? threads : 1;
    run.backend.enqueue = omp_enqueue;
    run.backend.finish = omp_finish;
    run.backend.worker_count = run.workers;
    run.backend.user = (void*)(intptr_t)run.workers;
    return run;
}
