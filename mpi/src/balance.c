/* The slabs' balance by measured time (balance.h). */
#include "balance.h"

#include <math.h>

/* The fraction by which cuts in proportion to this evaluation's speeds
 * would shorten the slowest part: 1 - (all slaves / all speeds) / slowest.
 * A rank that owned nothing has no measured speed: it is counted at the
 * others' mean. 0 when nothing can be said. */
static double gain_of(const double* seconds, const double* owned, int P) {
    double worst = 0.0, slaves = 0.0, speeds = 0.0, measured = 0.0;
    int r, n = 0;
    for (r = 0; r < P; ++r) {
        if (seconds[r] > worst) worst = seconds[r];
        slaves += owned[r];
        if (owned[r] > 0.0 && seconds[r] > 0.0) {
            measured += owned[r] / seconds[r];
            ++n;
        }
    }
    if (n == 0 || worst < NTSM_BALANCE_MIN_SECONDS) return 0.0;
    speeds = measured * (double)P / (double)n;
    return 1.0 - slaves / speeds / worst;
}

int ntsm_balance_step(double* speed, double* lost, const double* seconds, const double* owned, int P,
                      const double* current, double* share, double cost) {
    double sum = 0.0, total = 0.0, moved = 0.0, mean, gain, worst = 0.0;
    int r, n = 0;
    for (r = 0; r < P; ++r) /* smoothed: a rank's speed changes over seconds, not one evaluation */
        if (owned[r] > 0.0 && seconds[r] > 0.0) {
            const double v = owned[r] / seconds[r];
            speed[r] = speed[r] > 0.0 ? 0.5 * speed[r] + 0.5 * v : v;
        }
    gain = P < 2 ? 0.0 : gain_of(seconds, owned, P);
    if (!(gain >= NTSM_BALANCE_GAIN)) {
        *lost *= 0.5; /* an unevenness that comes and goes (noise) predicts little */
        return 0;
    }
    for (r = 0; r < P; ++r)
        if (seconds[r] > worst) worst = seconds[r];
    *lost += gain * worst; /* what cuts at these speeds would have saved */
    if (!(*lost >= cost)) return 0; /* rent: the cut costs more than it has lost yet */
    for (r = 0; r < P; ++r)
        if (speed[r] > 0.0) sum += speed[r], ++n;
    if (n == 0) return 0;
    mean = sum / n; /* (a rank never measured counts at the others' mean) */
    sum += (P - n) * mean;
    for (r = 0; r < P; ++r) { /* within a quarter and four times an equal share (before the norming) */
        double sh = (speed[r] > 0.0 ? speed[r] : mean) / sum;
        if (sh < 0.25 / P) sh = 0.25 / P;
        if (sh > 4.0 / P) sh = 4.0 / P;
        share[r] = sh;
        total += sh;
    }
    for (r = 0; r < P; ++r) {
        share[r] /= total;
        moved = fmax(moved, fabs(share[r] - current[r]));
    }
    /* The same cuts again (the shares at their bounds): no rebuild for them. */
    if (!(moved > 0.02 / P)) return 0;
    *lost = 0.0;
    return 1;
}
