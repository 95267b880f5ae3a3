/* The backend seam: every parallel loop of an evaluation goes through
 * nts_run_tasks, which hands it to the host's backend (nts_context_set_parallel)
 * or to the build's own: parallel_omp.c (OpenMP) or parallel_serial.c, one of
 * which the build compiles (as libuv picks one uv__io_poll per platform).
 * The core never starts a thread itself.
 *
 * A loop's result never depends on which worker runs which range, nor on
 * their order: a range writes only its own items, and what ranges add up
 * together is exact (integer counts: nts_atomic_add) or kept per item and
 * combined in item order by the caller. */
#ifndef NTSCONTACT_PARALLEL_H
#define NTSCONTACT_PARALLEL_H

#include <stdint.h>

#include "internal.h"

/* The workers of one evaluation and the backend that runs them. */
typedef struct nts_run {
    nts_parallel backend;
    int workers; /* >= 1; 1: every loop runs in the caller's thread */
} nts_run;

/* The build's own backend for `threads` workers (parallel_omp.c or
 * parallel_serial.c); `threads` is capped at 1 without OpenMP. */
nts_run nts_run_stock(int threads);

/* Run task over [0, count) in ranges of at least min_range items, and return
 * when all are done. With one worker, or one range, the caller's thread runs
 * it all (worker 0). */
static inline void nts_run_tasks(const nts_run* run, nts_task_fn* task, int count, int min_range, void* tc) {
    void* handle;
    if (count <= 0) return;
    if (min_range < 1) min_range = 1;
    if (run->workers <= 1 || count <= min_range) {
        task(0, count, 0, tc);
        return;
    }
    handle = run->backend.enqueue(task, count, min_range, tc, run->backend.user);
    if (handle != NULL) run->backend.finish(handle, run->backend.user);
}

/* A loop whose items cost about the same: one range per worker (OpenMP's
 * schedule(static)). */
static inline void nts_run_each(const nts_run* run, nts_task_fn* task, int count, void* tc) {
    nts_run_tasks(run, task, count, (count + run->workers - 1) / run->workers, tc);
}

/* Atomic integer addition for counts that ranges add up (any order gives the
 * same sum); returns the value before. The host's threads may not be
 * OpenMP's, so not an omp atomic. */
static inline long long nts_atomic_add_ll(long long* p, long long v) {
#if defined(__GNUC__)
    return __atomic_fetch_add(p, v, __ATOMIC_RELAXED);
#else
#error "ntscontact needs an atomic fetch-and-add for this compiler (parallel.h)"
#endif
}
static inline size_t nts_atomic_add_size(size_t* p, size_t v) {
#if defined(__GNUC__)
    return __atomic_fetch_add(p, v, __ATOMIC_RELAXED);
#else
#error "ntscontact needs an atomic fetch-and-add for this compiler (parallel.h)"
#endif
}
/* A 64-bit word read and swapped atomically (parallel_omp.c's blocks):
 * relaxed, as the parallel region's start and end order the rest. */
static inline uint64_t nts_atomic_load_u64(uint64_t* p) {
#if defined(__GNUC__)
    return __atomic_load_n(p, __ATOMIC_RELAXED);
#else
#error "ntscontact needs an atomic load for this compiler (parallel.h)"
#endif
}
/* *p = desired if *p == *expected (1); else *expected = *p (0). */
static inline int nts_atomic_cas_u64(uint64_t* p, uint64_t* expected, uint64_t desired) {
#if defined(__GNUC__)
    return __atomic_compare_exchange_n(p, expected, desired, 0, __ATOMIC_RELAXED, __ATOMIC_RELAXED);
#else
#error "ntscontact needs an atomic compare-and-swap for this compiler (parallel.h)"
#endif
}
static inline void nts_atomic_or(int* p, int v) {
#if defined(__GNUC__)
    (void)__atomic_fetch_or(p, v, __ATOMIC_RELAXED);
#else
#error "ntscontact needs an atomic fetch-or for this compiler (parallel.h)"
#endif
}

#endif
