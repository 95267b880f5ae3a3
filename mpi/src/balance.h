/* The slabs' balance by measured time (docs/distributed.md, "Balance"): a
 * decision on numbers every rank has gathered, so the same on every rank.
 * No MPI here: tests/mpi/test_balance.c drives it with made-up times. */
#ifndef NTSM_BALANCE_H
#define NTSM_BALANCE_H

/* Part times below this are noise (seconds). */
#define NTSM_BALANCE_MIN_SECONDS 0.005
/* Uneven: cuts by the ranks' (smoothed) speeds would make the slowest part
 * at least this fraction shorter. */
#define NTSM_BALANCE_GAIN 0.05

/* One evaluation: rank r's part took seconds[r] for owned[r] slaves, on P
 * ranks, with the slabs cut at current[r] (fractions summing to 1); a cut
 * costs `cost` seconds (the parts made anew, their candidate lists built:
 * 0 when every evaluation makes them anyway). speed[P] (each rank's slaves
 * a second, smoothed; 0: not measured yet) and *lost carry over between
 * evaluations: the seconds that cuts at the smoothed speeds would have
 * saved against the cuts in place since the last cut (each evaluation's
 * at its own speeds; never below 0). share[P] is scratch. Returns 1 when
 * the slabs should be cut anew at share[P], 0 else: when such cuts differ
 * from the ones in place,
 * would make the slowest part at least NTSM_BALANCE_GAIN shorter at the
 * smoothed speeds, and the time lost has reached the cost (a rent-or-buy
 * rule: never more than twice the time of the best schedule of cuts, for
 * an unevenness that lasts). */
int ntsm_balance_step(double* speed, double* lost, const double* seconds, const double* owned, int P,
                      const double* current, double* share, double cost);

#endif
