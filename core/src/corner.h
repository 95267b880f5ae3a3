/* The closest point on a corner (docs/model.md §4.3), the part the local
 * search runs for every corner candidate, inline (private to the core). The
 * problem is scaled by the corner's size, so its tolerances are relative to
 * the geometry and the same code works at 1e-9 and 1e9 scale. When F may
 * have several roots in [-1, 1] the chosen solver takes over (corner.c). */
#ifndef NTSCONTACT_CORNER_H
#define NTSCONTACT_CORNER_H

#include <float.h>

#include "internal.h"

/* The scaled problem: A, B, e divided by the corner size L, so F is O(1). */
typedef struct corner_problem {
    nts_vec2 A, B, e;
} corner_problem;

/* F and F' in product form: r = e - xi (B + A xi) is Xs - X(xi), tau = B + 2 A xi;
 * F = r.tau, F' = 2 r.A - tau.tau. The product form has no cancellation in
 * forming coefficients, so residuals near a root are accurate. */
static inline double problem_f(const corner_problem* p, double xi, double* df) {
    nts_vec2 r = nts_sub(p->e, nts_scale(xi, nts_mul_add(p->B, xi, p->A)));
    nts_vec2 tau = nts_mul_add(p->B, 2.0 * xi, p->A);
    if (df != NULL) *df = 2.0 * nts_dot(r, p->A) - nts_dot(tau, tau);
    return nts_dot(r, tau);
}

enum { NTS_ROOT_MAX_ITER = 100 };

/* The usual case, for both solvers: F strictly decreasing on [-1, 1], so one
 * root. F' = qa xi^2 + qb xi + qc is a parabola opening downwards (qa =
 * -6 A.A <= 0); its largest value on [-1, 1] is at its vertex
 * xi = -ab / (2 aa) when that lies inside, where it is qc + 1.5 ab^2 / aa,
 * else at an end. When that largest value is below minus its round-off, F
 * has one root in [-1, 1] (F(-1) >= 0 >= F(1), docs/model.md §12,
 * correction 3). Halley's method from the secant's root finds it, kept in
 * the bracket (a step that leaves it bisects instead): the second derivative
 * F2 = -6 A.tau and the third F3 = -12 A.A are at hand, and the error after
 * a step is about K |step|^3 with K = (F2 / 2F')^2 + |F3 / 6F'|, so the
 * iteration stops as soon as that is below half an ulp of 1 (xi is in
 * [-1, 1]; the bracketed Newton of the general case stops at the same
 * absolute accuracy), without a step to confirm it. Every test is written without a division (the problem
 * is scaled to O(1), so the products stay in range): a solve is a chain of
 * dependent operations, and divisions are the slow links. Returns 0 when F
 * may have several roots: the caller's solver then cuts [-1, 1] into
 * monotone pieces or solves the cubic. */
static inline int root_monotone(const corner_problem* p, double* root, int* iters) {
    const double aa = nts_dot(p->A, p->A), ab = nts_dot(p->A, p->B);
    const double qa = -6.0 * aa, qb = -6.0 * ab, qc = 2.0 * nts_dot(p->e, p->A) - nts_dot(p->B, p->B);
    const double tol = 64.0 * DBL_EPSILON * (fabs(qa) + fabs(qb) + fabs(qc));
    double flo, fhi, lo = -1.0, hi = 1.0, x;
    int it;
    if (!(qa - qb + qc < -tol && qa + qb + qc < -tol)) return 0;
    /* The vertex inside (|ab| < 2 aa, so aa > 0): qc + 1.5 ab^2 / aa < -tol. */
    if (fabs(ab) < 2.0 * aa && !((qc + tol) * aa + 1.5 * ab * ab < 0.0)) return 0;
    flo = problem_f(p, -1.0, NULL);
    fhi = problem_f(p, 1.0, NULL);
    /* An end that is a root, or, when round-off breaks the bracket, the end
     * where |F| is smaller (F decreases, so it is the nearer one). */
    if (!(flo > 0.0)) {
        *root = -1.0;
        return 1;
    }
    if (!(fhi < 0.0)) {
        *root = 1.0;
        return 1;
    }
    /* The first guess: the root of F's linear part, c1 xi + c0 (F'(0) = c1 =
     * qc < 0 here), refined once by the fixed point xi = -(c0 + c2 xi^2 +
     * c3 xi^3) / c1; its error is of order (A/B)^2 on a gentle corner, where
     * the secant's is of order A/B, so two Halley steps do. A guess outside
     * the bracket (a sharp corner) gives way to the secant's root. */
    {
        const double c0 = nts_dot(p->e, p->B), c2 = -3.0 * ab, c3 = -2.0 * aa, inv_c1 = 1.0 / qc;
        const double x0 = -c0 * inv_c1;
        x = x0 - x0 * x0 * (c2 + c3 * x0) * inv_c1;
        if (!(x > -1.0 && x < 1.0)) x = -1.0 + 2.0 * flo / (flo - fhi);
    }
    for (it = 0; it < NTS_ROOT_MAX_ITER; ++it) {
        const nts_vec2 tau = nts_mul_add(p->B, 2.0 * x, p->A);
        const nts_vec2 r = nts_sub(p->e, nts_scale(x, nts_mul_add(p->B, x, p->A)));
        const double f = nts_dot(r, tau), df = 2.0 * nts_dot(r, p->A) - nts_dot(tau, tau);
        const double d2f = -6.0 * nts_dot(p->A, tau);
        const double step = 2.0 * f * df / (2.0 * df * df - f * d2f), as = fabs(step);
        const double xn = x - step;
        if (f == 0.0) break;
        if (f > 0.0) lo = x; else hi = x;
        /* Converged (K |step|^3 <= eps^2 / 2, times F'^2): the step is taken,
         * onto the bracket's edge at most (a step below the last bit may land
         * on it; it must not count as leaving the bracket, or the iteration
         * would bisect away). */
        if ((0.25 * d2f * d2f + 2.0 * aa * fabs(df)) * as * as * as <= 0.5 * DBL_EPSILON * df * df) {
            x = xn < lo ? lo : (xn > hi ? hi : xn);
            break;
        }
        if (!(xn > lo && xn < hi)) { /* left the bracket (or not finite): bisect */
            x = 0.5 * (lo + hi);
            if (hi - lo <= 2.0 * DBL_EPSILON) break;
            continue;
        }
        x = xn;
    }
    *iters += it + 1;
    *root = x;
    return 1;
}

/* corner.c: every root of F in [-1, 1] by the chosen solver (at least
 * one: a root hidden by rounding falls back to the bracketed solver, then to
 * the better end), and the one nearest to the slave. *roots: how many. */
double nts_corner_root_general(const corner_problem* p, nts_solver solver, int* roots, int* iters);

/* X(xi) - X3 = A xi^2 + B xi + C with A = C = alpha (a + c)/4, B = alpha (c - a)/2
 * (docs/model.md §3), a = X2 - X3, c = X4 - X3. */
static inline nts_corner corner_make(nts_vec2 a, nts_vec2 c, double alpha) {
    nts_corner k;
    k.A = nts_scale(0.25 * alpha, nts_add(a, c));
    k.B = nts_scale(0.5 * alpha, nts_sub(c, a));
    k.C = k.A;
    return k;
}

/* The shape functions (docs/model.md §3, eq. (3), with §12 correction 1):
 * N3 = 1 - alpha (1 + xi^2) / 2, so that they sum to one. */
static inline nts_shape3 corner_shape(double alpha, double xi) {
    nts_shape3 s;
    const double m = 1.0 - xi, q = 1.0 + xi;
    s.n2 = 0.25 * alpha * m * m;
    s.n3 = 1.0 - 0.5 * alpha * (1.0 + xi * xi);
    s.n4 = 0.25 * alpha * q * q;
    return s;
}

/* The closest point of a slave at d = Xs - X3 on corner k (nts_corner_solve). */
static inline nts_corner_solution corner_solve(const nts_corner* k, nts_vec2 d, nts_solver solver) {
    nts_corner_solution s;
    corner_problem p;
    /* The corner's size, |A|_1 + |B|_1: zero only if a = c = 0 (impossible
     * after validation); never divide by it unless it is positive. */
    const double L = fabs(k->A.x) + fabs(k->A.y) + fabs(k->B.x) + fabs(k->B.y);
    double inv, tl;
    nts_vec2 tau;
    s.xi = 0.0;
    s.point = s.normal = nts_v2(0.0, 0.0);
    s.gap = 0.0;
    s.roots = 0;
    s.iterations = 0;
    s.ok = 0;
    if (!(L > 0.0) || !(L < HUGE_VAL)) return s;
    inv = 1.0 / L;
    p.A = nts_scale(inv, k->A);
    p.B = nts_scale(inv, k->B);
    p.e = nts_scale(inv, nts_sub(d, k->C));
    if (root_monotone(&p, &s.xi, &s.iterations)) s.roots = 1;
    else s.xi = nts_corner_root_general(&p, solver, &s.roots, &s.iterations);
    tau = nts_mul_add(k->B, 2.0 * s.xi, k->A);
    tl = nts_length(tau);
    if (!(tl > 0.0) || !(tl < HUGE_VAL)) return s; /* tangent vanished: zero-angle spike */
    s.point = nts_mul_add(k->C, s.xi, nts_mul_add(k->B, s.xi, k->A)); /* C + xi (B + A xi) */
    s.normal = nts_v2(tau.y / tl, -tau.x / tl);
    s.gap = nts_dot(nts_sub(d, s.point), s.normal);
    s.ok = 1;
    return s;
}

#endif
