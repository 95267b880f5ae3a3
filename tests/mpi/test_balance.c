/* The slabs' balance by measured time (mpi/src/balance.c) on made-up part
 * times and cut costs: when it cuts the slabs anew and at which shares. What every rank
 * decides from the same gathered numbers; the cuts themselves are tested
 * under MPI (test_mpi: weights 3:1, the same bits). Exit 0 when all holds. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "balance.h"

static int failures;

#define CHECK(cond, ...)                                  \
    do {                                                  \
        if (!(cond)) {                                    \
            ++failures;                                   \
            fprintf(stderr, "%s:%d: ", __FILE__, __LINE__); \
            fprintf(stderr, __VA_ARGS__);                 \
            fputc('\n', stderr);                          \
        }                                                 \
    } while (0)

enum { MAXP = 4 };

typedef struct run {
    int P;
    double cost, lost;
    double speed[MAXP], current[MAXP], share[MAXP];
} run;

static run start(int P, double cost) {
    run r;
    int k;
    memset(&r, 0, sizeof r);
    r.P = P;
    r.cost = cost;
    for (k = 0; k < P; ++k) r.current[k] = 1.0 / P;
    return r;
}

/* One evaluation: rank k's part of owned[k] slaves at speed v[k] (slaves a
 * second); whether it cuts. The cuts become the current shares. */
static int step(run* r, const double* owned, const double* v) {
    double t[MAXP];
    int k, cut;
    for (k = 0; k < r->P; ++k) t[k] = owned[k] / v[k];
    cut = ntsm_balance_step(r->speed, &r->lost, t, owned, r->P, r->current, r->share, r->cost);
    if (cut)
        for (k = 0; k < r->P; ++k) r->current[k] = r->share[k];
    return cut;
}

/* The slaves each rank owns at the current shares. */
static void owned_at(const run* r, double n, double* owned) {
    int k;
    for (k = 0; k < r->P; ++k) owned[k] = n * r->current[k];
}

/* The seconds an evaluation loses to unevenness: the slowest part's time
 * less the time of parts cut at the speeds. */
static double loss_of(const double* owned, const double* v, int P) {
    double worst = 0.0, n = 0.0, speeds = 0.0;
    int k;
    for (k = 0; k < P; ++k) {
        if (owned[k] / v[k] > worst) worst = owned[k] / v[k];
        n += owned[k];
        speeds += v[k];
    }
    return worst - n / speeds;
}

int main(void) {
    const double N = 5e5; /* slaves: parts of 0.1 s and more at these speeds */
    double owned[MAXP] = {0.0, 0.0, 0.0, 0.0}, v[MAXP] = {1.0, 1.0, 1.0, 1.0}, loss;
    int k, cuts;

    { /* even ranks: never, even when a cut costs nothing */
        run r = start(2, 0.0);
        v[0] = v[1] = 4e6;
        for (k = 0, cuts = 0; k < 20; ++k) {
            owned_at(&r, N, owned);
            cuts += step(&r, owned, v);
        }
        CHECK(cuts == 0, "even ranks cut %d times", cuts);
    }
    { /* a rank 30% slower: cut when the time lost reaches the cost (the
       * fourth evaluation at 3.5 evaluations' loss), in proportion to the
       * speeds, then never again */
        run r = start(2, 0.0);
        v[0] = 4.5e6;
        v[1] = 4.5e6 / 1.3;
        owned_at(&r, N, owned);
        loss = loss_of(owned, v, 2);
        r.cost = 3.5 * loss;
        CHECK(!step(&r, owned, v) && !step(&r, owned, v) && !step(&r, owned, v), "cut before the loss reached the cost");
        CHECK(fabs(r.lost - 3.0 * loss) < 1e-12 * loss, "lost %.9g, expected three evaluations' %.9g", r.lost, 3.0 * loss);
        CHECK(step(&r, owned, v), "no cut once the loss reached the cost");
        CHECK(r.lost == 0.0, "a cut leaves %.9g lost", r.lost);
        CHECK(fabs(r.share[0] - 1.3 / 2.3) < 1e-12 && fabs(r.share[1] - 1.0 / 2.3) < 1e-12,
              "shares %.15g %.15g, expected 1.3/2.3 and 1/2.3", r.share[0], r.share[1]);
        for (k = 0, cuts = 0; k < 20; ++k) {
            owned_at(&r, N, owned);
            cuts += step(&r, owned, v);
        }
        CHECK(cuts == 0, "balanced ranks cut again %d times", cuts);
        /* the speeds swap (another program on the first core): cut back */
        v[1] = 4.5e6;
        v[0] = 4.5e6 / 1.3;
        for (k = 0, cuts = 0; k < 10 && !cuts; ++k) {
            owned_at(&r, N, owned);
            cuts = step(&r, owned, v);
        }
        CHECK(cuts && r.current[0] < 0.5, "no cut back after the speeds swapped (share %.3f)", r.current[0]);
    }
    { /* the cut waits until the loss reaches the cost: 2.5 and 4.5
       * evaluations' loss, a cut at the third and the fifth */
        run r = start(2, 0.0);
        int first = 0, second = 0;
        v[0] = 4.5e6;
        v[1] = 4.5e6 / 1.5;
        owned_at(&r, N, owned);
        r.cost = 2.5 * loss_of(owned, v, 2);
        for (k = 1; k <= 20 && !first; ++k) first = step(&r, owned, v) ? k : 0;
        r = start(2, 4.5 * loss_of(owned, v, 2));
        for (k = 1; k <= 20 && !second; ++k) second = step(&r, owned, v) ? k : 0;
        CHECK(first == 3 && second == 5, "cuts at evaluations %d and %d, expected 3 and 5", first, second);
    }
    { /* parts made every evaluation (a cut costs nothing): cut at the first uneven evaluation */
        run r = start(2, 0.0);
        v[0] = 4.5e6;
        v[1] = 4.5e6 / 1.3;
        owned_at(&r, N, owned);
        CHECK(step(&r, owned, v), "no cut at the first uneven evaluation when a cut costs nothing");
    }
    { /* 10% slower: cuts would gain under 5%; never, even at no cost */
        run r = start(2, 0.0);
        v[0] = 4e6;
        v[1] = 4e6 / 1.1;
        for (k = 0, cuts = 0; k < 20; ++k) {
            owned_at(&r, N, owned);
            cuts += step(&r, owned, v);
        }
        CHECK(cuts == 0, "a 10%% slower rank cut %d times", cuts);
    }
    { /* noise: each rank 40% slower in turn; the smoothed speeds lag behind
       * it, so cuts at them would have cost as often as saved: no cut, the
       * time lost stays under one evaluation's loss; then a rank slower
       * for good is cut for within five evaluations */
        run r = start(2, 0.0);
        const double slow0[2] = {4e6 / 1.4, 4e6}, slow1[2] = {4e6, 4e6 / 1.4};
        owned_at(&r, N, owned);
        loss = loss_of(owned, slow1, 2);
        r.cost = 3.5 * loss;
        for (k = 0, cuts = 0; k < 20; ++k) cuts += step(&r, owned, slow0) + step(&r, owned, slow1);
        CHECK(cuts == 0 && r.lost < loss, "noise cut %d times, lost %.3g (one evaluation's loss %.3g)", cuts, r.lost,
              loss);
        for (k = 0, cuts = 0; k < 5 && !cuts; ++k) cuts = step(&r, owned, slow1);
        CHECK(cuts, "lasting unevenness after noise: no cut");
    }
    { /* equal speeds, the slaves owned off the shares (the cuts' rounding,
       * the nodes' drift in a kept decomposition): no cut saves that, no
       * time is lost */
        run r = start(2, 0.1);
        v[0] = v[1] = 4e6;
        owned[0] = 0.52 * N;
        owned[1] = 0.48 * N;
        for (k = 0, cuts = 0; k < 100; ++k) cuts += step(&r, owned, v);
        CHECK(cuts == 0 && r.lost == 0.0, "owned 52:48 at equal speeds: %d cuts, lost %.3g", cuts, r.lost);
    }
    { /* a rank 15% slower (cuts 7% better): cut, at the speeds' ratio; the
       * speeds smoothed half and half */
        run r = start(2, 0.0);
        v[0] = 4e6;
        v[1] = 4e6 / 1.15;
        owned_at(&r, N, owned);
        r.cost = 2.5 * loss_of(owned, v, 2);
        for (k = 1, cuts = 0; k <= 3 && !cuts; ++k) cuts = step(&r, owned, v);
        CHECK(cuts && k == 4 && fabs(r.current[0] - 1.15 / 2.15) < 1e-12, "15%% slower: cut %d at %d, share %.6f",
              cuts, k - 1, r.current[0]);
        r = start(2, 1.0);
        owned_at(&r, N, owned);
        v[1] = 4e6;
        step(&r, owned, v);
        v[0] = 2e6;
        step(&r, owned, v);
        CHECK(r.speed[0] == 0.5 * 4e6 + 0.5 * 2e6 && r.speed[1] == 4e6, "smoothed speeds %.9g %.9g", r.speed[0],
              r.speed[1]);
    }
    { /* one evaluation 12% uneven after even ones, at no cost: the smoothed
       * speeds barely moved (cuts at them gain under 5%), no cut */
        run r = start(2, 0.0);
        v[0] = v[1] = 4e6;
        owned_at(&r, N, owned);
        for (k = 0, cuts = 0; k < 10; ++k) cuts += step(&r, owned, v);
        v[1] = 4e6 / 1.12;
        cuts += step(&r, owned, v);
        CHECK(cuts == 0, "one uneven evaluation after even ones cut %d times", cuts);
    }
    { /* parts of a few milliseconds: noise */
        run r = start(2, 0.0);
        v[0] = 4e6;
        v[1] = 1e6;
        for (k = 0, cuts = 0; k < 20; ++k) {
            owned_at(&r, 1e4, owned); /* 1.25 and 5 ms... */
            owned[1] = 4e3;           /* ...and 4 ms */
            cuts += step(&r, owned, v);
        }
        CHECK(cuts == 0, "parts under 5 ms cut %d times", cuts);
    }
    { /* a rank 10 times slower: the bounds, then no rebuild for the same cuts */
        run r = start(2, 0.0);
        v[0] = 4e6;
        v[1] = 4e5;
        owned_at(&r, N, owned);
        r.cost = 2.5 * loss_of(owned, v, 2);
        cuts = step(&r, owned, v) + step(&r, owned, v) + step(&r, owned, v);
        CHECK(cuts == 1 && r.current[1] > 1.0 / 11.0 + 0.02 && r.current[1] < 0.125,
              "shares %.4f %.4f: expected the slow rank raised towards a quarter of an equal share", r.current[0],
              r.current[1]);
        for (k = 0, cuts = 0; k < 20; ++k) {
            owned_at(&r, N, owned);
            cuts += step(&r, owned, v);
        }
        CHECK(cuts == 0, "the same bounded cuts rebuilt %d times", cuts);
    }
    { /* four ranks, one twice as slow; a rank that owns nothing has no speed measured */
        run r = start(4, 0.0);
        for (k = 0; k < 4; ++k) v[k] = 4e6;
        v[2] = 2e6;
        owned_at(&r, N, owned);
        r.cost = 2.5 * loss_of(owned, v, 4);
        cuts = step(&r, owned, v) + step(&r, owned, v) + step(&r, owned, v);
        CHECK(cuts == 1 && fabs(r.current[2] - 1.0 / 7.0) < 1e-12 && fabs(r.current[0] - 2.0 / 7.0) < 1e-12,
              "four ranks: shares %.6f %.6f %.6f %.6f, expected 2/7 2/7 1/7 2/7", r.current[0], r.current[1],
              r.current[2], r.current[3]);
        r = start(4, 0.0);
        owned[0] = owned[1] = owned[2] = N / 3.0;
        owned[3] = 0.0;
        for (k = 0; k < 4; ++k) v[k] = 4e6;
        for (k = 0, cuts = 0; k < 10; ++k) cuts += step(&r, owned, v);
        /* uneven (one rank idle), but the idle rank counts at the others' mean
         * speed: the speeds' cuts are the equal ones in place, no rebuild */
        CHECK(cuts == 0 && r.speed[3] == 0.0, "a rank without slaves: %d cuts, speed %g", cuts, r.speed[3]);
        r.current[0] = r.current[1] = r.current[2] = 0.3;
        r.current[3] = 0.1;
        cuts = step(&r, owned, v);
        CHECK(cuts == 1 && fabs(r.current[3] - 0.25) < 1e-12, "from uneven cuts, an idle rank: %d cuts, share %.6f",
              cuts, r.current[3]);
    }
    if (failures == 0) printf("test_balance: all passed\n");
    return failures == 0 ? 0 : 1;
}
