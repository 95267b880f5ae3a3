/* The slabs' balance by measured time (balance.h). */
#include "balance.h"

#include <math.h>

/* Rank r's speed (slaves a second): the smoothed one (smooth != 0), else
 * what this evaluation measured; either, when the rank has none, the
 * other's, then `mean`. */
static double speed_of(const double* speed, const double* seconds, const double* owned, int r, int smooth,
                       double mean) {
    const double now = owned[r] > 0.0 && seconds[r] > 0.0 ? owned[r] / seconds[r] : 0.0;
    const double v = smooth ? (speed[r] > 0.0 ? speed[r] : now) : (now > 0.0 ? now : speed[r]);
    return v > 0.0 ? v : mean;
}

/* The cuts in proportion to the speeds (speed_of, smooth or not), each
 * share within a quarter and four times an equal one, into share[P]. */
static void cuts_at(const double* speed, const double* seconds, const double* owned, int P, int smooth,
                    double mean, double* share) {
    double sum = 0.0, total = 0.0;
    int r;
    for (r = 0; r < P; ++r) sum += speed_of(speed, seconds, owned, r, smooth, mean);
    for (r = 0; r < P; ++r) {
        double sh = speed_of(speed, seconds, owned, r, smooth, mean) / sum;
        if (sh < 0.25 / P) sh = 0.25 / P;
        if (sh > 4.0 / P) sh = 4.0 / P;
        share[r] = sh;
        total += sh;
    }
    for (r = 0; r < P; ++r) share[r] /= total;
}

/* The smoothed speeds take this evaluation's: a rank's speed changes over
 * seconds, not one evaluation. */
static void smooth_speeds(double* speed, const double* seconds, const double* owned, int P) {
    int r;
    for (r = 0; r < P; ++r)
        if (owned[r] > 0.0 && seconds[r] > 0.0)
            speed[r] = speed[r] > 0.0 ? 0.5 * speed[r] + 0.5 * owned[r] / seconds[r] : owned[r] / seconds[r];
}

/* The slowest part's time, rank r's share of `slaves` at its speed. */
static double slowest_at(const double* share, double slaves, const double* speed, const double* seconds,
                         const double* owned, int P, int smooth, double mean) {
    double t = 0.0;
    int r;
    for (r = 0; r < P; ++r) t = fmax(t, share[r] * slaves / speed_of(speed, seconds, owned, r, smooth, mean));
    return t;
}

int ntsm_balance_step(double* speed, double* lost, const double* seconds, const double* owned, int P,
                      const double* current, double* share, double cost) {
    double worst = 0.0, slaves = 0.0, mean = 0.0, moved = 0.0;
    int r, n = 0;
    for (r = 0; r < P; ++r) {
        worst = fmax(worst, seconds[r]);
        slaves += owned[r];
        if (owned[r] > 0.0 && seconds[r] > 0.0) mean += owned[r] / seconds[r], ++n;
    }
    if (P < 2 || n == 0 || !(worst >= NTSM_BALANCE_MIN_SECONDS)) { /* noise, or nothing to say */
        smooth_speeds(speed, seconds, owned, P); /* (the speeds still follow) */
        return 0;
    }
    mean /= n; /* (a rank that owned nothing counts at the others' mean) */
    /* What cuts at the speeds known before this evaluation (smoothed) would
     * have saved in it against the cuts in place, both at the speeds it
     * measured (both of the same model: what the slaves owned now differ
     * from the shares by, the cuts' rounding and the nodes' drift, no cut
     * saves): an unevenness that lasts adds up; noise, which the smoothed
     * speeds lag behind, saves as often as it costs. (A rank not measured
     * before: at its speed now.) */
    cuts_at(speed, seconds, owned, P, 1, mean, share);
    *lost = fmax(0.0, *lost + slowest_at(current, slaves, speed, seconds, owned, P, 0, mean) -
                          slowest_at(share, slaves, speed, seconds, owned, P, 0, mean));
    smooth_speeds(speed, seconds, owned, P);
    /* A cut at the speeds known now: new cuts (not the ones in place, as
     * the shares at their bounds can be), worth it at those speeds, and the
     * time lost since the last cut has reached its cost (rent, then buy). */
    cuts_at(speed, seconds, owned, P, 1, mean, share);
    for (r = 0; r < P; ++r) moved = fmax(moved, fabs(share[r] - current[r]));
    if (!(moved > 0.02 / P)) return 0;
    if (!(1.0 - slowest_at(share, slaves, speed, seconds, owned, P, 1, mean) /
                    slowest_at(current, slaves, speed, seconds, owned, P, 1, mean) >=
          NTSM_BALANCE_GAIN))
        return 0;
    if (!(*lost >= cost)) return 0;
    *lost = 0.0;
    return 1;
}
