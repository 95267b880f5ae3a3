/* The corner's closest point when F may have several roots in [-1, 1]
 * (docs/model.md §4.3): every root by the chosen solver, and the one nearest
 * to the slave. corner.h runs the usual case (one root) inline and calls this
 * for the rest. Everything is scaled by the corner's size (corner_problem),
 * so tolerances are relative to the geometry. */
#include <float.h>
#include <gsl/gsl_poly.h>

#include "corner.h"

static inline double problem_dist_sq(const corner_problem* p, double xi) {
    return nts_length_sq(nts_sub(p->e, nts_scale(xi, nts_mul_add(p->B, xi, p->A))));
}

static inline double clamp_unit(double x) { return x < -1.0 ? -1.0 : (x > 1.0 ? 1.0 : x); }

enum { NTS_POLISH_MAX_ITER = 8 };

/* Newton safeguarded by bisection (Numerical Recipes' rtsafe) on [lo, hi] with a
 * sign change of F. The bracket shrinks every step, so it ends within
 * NTS_ROOT_MAX_ITER steps even when Newton misbehaves. */
static double bracketed_root(const corner_problem* p, double lo, double hi, double flo, double x, int* iters) {
    const double tol = 2.0 * DBL_EPSILON;
    int it;
    for (it = 0; it < NTS_ROOT_MAX_ITER; ++it) {
        double df, f = problem_f(p, x, &df), xn;
        if (f == 0.0) break;
        if ((f > 0.0) == (flo > 0.0)) lo = x; else hi = x;
        xn = (df != 0.0) ? x - f / df : 0.5 * (lo + hi);
        /* A converged Newton step is accepted before the bracket test: at the
         * root x sits on the bracket's edge and a sub-ulp step lands on it too,
         * which must not send the iteration bisecting away. */
        if (df != 0.0 && fabs(xn - x) <= tol) {
            x = xn < lo ? lo : (xn > hi ? hi : xn);
            ++it;
            break;
        }
        if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi); /* Newton left the bracket: bisect */
        if (hi - lo <= tol) { x = xn; ++it; break; }
        x = xn;
    }
    *iters += it;
    return x;
}

/* Up to 3 roots of F in [-1, 1]: split [-1, 1] at the critical points of F (roots
 * of F', a quadratic) into monotone pieces and bracket every sign change. */
static int roots_newton(const corner_problem* p, double* roots, int* iters) {
    double cuts[4];
    int ncut = 0, n = 0, i;
    /* F' = 3 c3 xi^2 + 2 c2 xi + c1 with c3 = -2 A.A, c2 = -3 A.B, c1 = 2 e.A - B.B. */
    double qa = -6.0 * nts_dot(p->A, p->A), qb = -6.0 * nts_dot(p->A, p->B);
    double qc = 2.0 * nts_dot(p->e, p->A) - nts_dot(p->B, p->B);
    double r0 = 0.0, r1 = 0.0;
    int nr = gsl_poly_solve_quadratic(qa, qb, qc, &r0, &r1);
    cuts[ncut++] = -1.0;
    if (nr >= 1 && r0 > -1.0 && r0 < 1.0) cuts[ncut++] = r0;
    if (nr >= 2 && r1 > -1.0 && r1 < 1.0 && r1 != r0) cuts[ncut++] = r1;
    cuts[ncut++] = 1.0;
    if (ncut == 4 && cuts[1] > cuts[2]) { double t = cuts[1]; cuts[1] = cuts[2]; cuts[2] = t; }
    for (i = 0; i + 1 < ncut; ++i) {
        double u = cuts[i], v = cuts[i + 1];
        double fu = problem_f(p, u, NULL), fv = problem_f(p, v, NULL);
        if (fu == 0.0) {
            if (n == 0 || roots[n - 1] != u) roots[n++] = u;
        } else if (fv == 0.0) {
            roots[n++] = v;
        } else if ((fu > 0.0) != (fv > 0.0)) {
            roots[n++] = bracketed_root(p, u, v, fu, 0.5 * (u + v), iters);
        }
        if (n >= 3) break;
    }
    return n;
}

/* Newton polish of an approximate root, kept inside [-1, 1]. */
static double polish(const corner_problem* p, double x, int* iters) {
    int it;
    x = clamp_unit(x);
    for (it = 0; it < NTS_POLISH_MAX_ITER; ++it) {
        double df, f = problem_f(p, x, &df), xn;
        if (f == 0.0 || df == 0.0) break;
        xn = clamp_unit(x - f / df);
        ++*iters;
        if (fabs(xn - x) <= 2.0 * DBL_EPSILON) { x = xn; break; }
        x = xn;
    }
    return x;
}

/* Below this ratio A.A / B.B the cubic term is dropped for the first guess: the
 * corner is nearly straight (A = 0 exactly when the neighbours are collinear) and
 * the monic cubic's huge coefficients would cost accuracy (docs/model.md,
 * "the cubic degenerates toward the linear equation"). The neglected term is at
 * most 2 A.A <= 2e-6 B.B inside [-1, 1]; Newton polishing removes it. */
#define NTS_DEGENERATE_RATIO 1e-6

static int roots_closed_form(const corner_problem* p, double* roots, int* iters) {
    double x[3];
    int nx, i, n = 0;
    double aa = nts_dot(p->A, p->A), bb = nts_dot(p->B, p->B);
    double c3 = -2.0 * aa, c2 = -3.0 * nts_dot(p->A, p->B);
    double c1 = 2.0 * nts_dot(p->e, p->A) - bb, c0 = nts_dot(p->e, p->B);
    if (aa > NTS_DEGENERATE_RATIO * bb) {
        nx = gsl_poly_solve_cubic(c2 / c3, c1 / c3, c0 / c3, &x[0], &x[1], &x[2]);
    } else {
        nx = gsl_poly_solve_quadratic(c2, c1, c0, &x[0], &x[1]);
    }
    for (i = 0; i < nx; ++i) {
        /* A root just outside [-1, 1] by round-off is the endpoint root. */
        const double slack = 1e-6;
        double r;
        int j, dup = 0;
        if (!(x[i] >= -1.0 - slack && x[i] <= 1.0 + slack)) continue;
        r = polish(p, x[i], iters);
        for (j = 0; j < n; ++j) dup |= (roots[j] == r);
        if (!dup) roots[n++] = r;
    }
    return n;
}

double nts_corner_root_general(const corner_problem* p, nts_solver solver, int* nroots, int* iters) {
    double roots[3], best_d2 = 0.0;
    int n, i, best = -1;
    n = solver == NTS_SOLVER_NEWTON ? roots_newton(p, roots, iters) : roots_closed_form(p, roots, iters);
    if (n == 0) {
        /* Rounding can hide a root the bracket guarantees (F(-1) >= 0 >= F(1)):
         * fall back to the bracketed solver, then to the better endpoint. */
        n = roots_newton(p, roots, iters);
        if (n == 0) {
            double fl = fabs(problem_f(p, -1.0, NULL)), fr = fabs(problem_f(p, 1.0, NULL));
            roots[0] = (fl <= fr) ? -1.0 : 1.0;
            n = 1;
        }
    }
    /* The root nearest to the slave. Two roots equally near (a slave on the
     * symmetry axis of a corner, beyond its evolute) are a tie up to round-off,
     * which differs between solvers and platforms: distances within a few ulps
     * of each other tie, and a tie goes to the smaller xi (docs/model.md,
     * "Selection"), so every solver picks the same root. */
    for (i = 0; i < n; ++i) {
        double d2 = problem_dist_sq(p, roots[i]);
        if (best < 0 || d2 < best_d2) {
            best = i;
            best_d2 = d2;
        }
    }
    {
        const double tie = best_d2 * (1.0 + 64.0 * DBL_EPSILON);
        for (i = 0; i < n; ++i)
            if (roots[i] < roots[best] && problem_dist_sq(p, roots[i]) <= tie) best = i;
    }
    *nroots = n;
    return roots[best];
}
