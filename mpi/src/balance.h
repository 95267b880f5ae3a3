/* The slabs' balance by measured time (docs/distributed.md, "Balance"): a
 * decision on numbers every rank has gathered, so the same on every rank.
 * No MPI here: tests/mpi/test_balance.c drives it with made-up times. */
#ifndef NTSM_BALANCE_H
#define NTSM_BALANCE_H

enum {
    NTSM_BALANCE_STREAK = 3 /* uneven evaluations in a row before the slabs are cut anew */
};

/* Part times below this are noise (seconds). */
#define NTSM_BALANCE_MIN_SECONDS 0.005
/* Uneven: cuts by the ranks' speeds would make the slowest part at least
 * this fraction shorter. */
#define NTSM_BALANCE_GAIN 0.05

/* One evaluation: rank r's part took seconds[r] for owned[r] slaves, on P
 * ranks, with the slabs cut at current[r] (fractions summing to 1).
 * speed[P] (each rank's slaves a second, smoothed; 0: not measured yet) and
 * *streak carry over between evaluations. Returns 1 when the slabs should
 * be cut anew at share[P] (written then), 0 else. */
int ntsm_balance_step(double* speed, int* streak, const double* seconds, const double* owned, int P,
                      const double* current, double* share);

#endif
