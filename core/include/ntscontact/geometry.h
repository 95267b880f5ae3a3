/** @file
 * ntscontact: stateless contact geometry (docs/model.md §2 and
 * "Closest point"). Every function works in coordinates relative to a master
 * node, so callers subtract first and multiply after. Results come back as small
 * structs by value (as Box2D's b2SegmentDistanceResult). */
#ifndef NTSCONTACT_GEOMETRY_H
#define NTSCONTACT_GEOMETRY_H

#include "base.h"
#include "math_functions.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Which corner solver (docs/model.md §4.3). Both take the one root of a
 * monotone F by bracketed Halley steps; they differ where F may have several
 * roots in [-1, 1]. */
typedef enum nts_solver {
    NTS_SOLVER_CLOSED_FORM = 0, /**< GSL cubic + Newton polish, degenerate branch for near-collinear corners */
    NTS_SOLVER_NEWTON = 1       /**< Newton safeguarded by bisection on monotone brackets of [-1, 1] */
} nts_solver;

/** Feature kinds of the master surface; the order is the tie-break order at one node. */
typedef enum nts_kind {
    NTS_KIND_SEGMENT = 0,
    NTS_KIND_CORNER = 1,
    NTS_KIND_VERTEX = 2
} nts_kind;

/** Shape functions of the corner polynomial (docs/model.md §3, eq. (3)):
 * N2 = a(1-xi)^2/4, N3 = 1 - a(1+xi^2)/2, N4 = a(1+xi)^2/4. They sum to one. */
typedef struct nts_shape3 {
    /** N2, N3 and N4 at one xi. @{ */
    double n2, n3, n4;
    /** @} */
} nts_shape3;
/** The shape functions N2, N3, N4 of a corner of smoothing fraction `alpha` at `xi`. */
NTS_API nts_shape3 nts_corner_shape(double alpha, double xi);

/** Local coefficients of the corner polynomial at X3 with a = X2 - X3,
 * c = X4 - X3: X(xi) - X3 = A xi^2 + B xi + C, A = C = alpha (a + c)/4,
 * B = alpha (c - a)/2. */
typedef struct nts_corner {
    /** The coefficients A, B and C. @{ */
    nts_vec2 A, B, C;
    /** @} */
} nts_corner;
/** The corner polynomial of a = X2 - X3, c = X4 - X3 and smoothing fraction `alpha`. */
NTS_API nts_corner nts_corner_make(nts_vec2 a, nts_vec2 c, double alpha);
/** @name Points of a corner
 * X(xi) - X3 and the tangent dX/dxi = 2 A xi + B.
 * @{ */
/** X(xi) - X3 */
NTS_API nts_vec2 nts_corner_point(nts_corner k, double xi);
/** The tangent dX/dxi = 2 A xi + B (not normalised). */
NTS_API nts_vec2 nts_corner_tangent(nts_corner k, double xi);
/** @} */

/** Normalised segment parameter s = (Xs - X0).(X1 - X0)/|X1 - X0|^2 (docs/model.md §12, correction 2),
 * given d = Xs - X0 and t = X1 - X0 with |t| > 0. */
static inline double nts_segment_param(nts_vec2 d, nts_vec2 t) { return nts_dot(d, t) / nts_dot(t, t); }

/** The closest point of a slave on a corner polynomial: the root of
 * F(xi) = (Xs - X(xi)).tau(xi) in [-1, 1] nearest to the slave. `d` = Xs - X3.
 * The caller guarantees F(-1) >= 0 >= F(1) (docs/model.md §12, correction 3); the solver still never
 * loops without bound and never returns NaN for finite input. */
typedef struct nts_corner_solution {
    double xi;       /**< the PCA parameter, in [-1, 1] */
    nts_vec2 point;  /**< X(xi) - X3 */
    nts_vec2 normal; /**< outward unit normal (tau_y, -tau_x)/|tau| */
    double gap;      /**< (Xs - X(xi)).normal */
    int roots;       /**< how many roots of F were found in [-1, 1] (1 to 3) */
    int iterations;  /**< Newton/bisection steps taken (diagnostics) */
    int ok;          /**< 0 when the tangent vanished (a zero-angle spike): no candidate */
} nts_corner_solution;
/** Solves for the closest point of the slave `d` = Xs - X3 on the corner `k` with `solver`
 * (nts_corner_solution says what it found; `ok` 0: no candidate). */
NTS_API nts_corner_solution nts_corner_solve(nts_corner k, nts_vec2 d, nts_solver solver);

/** Coefficients of F(xi) = c3 xi^3 + c2 xi^2 + c1 xi + c0 (docs/model.md §4.3, eq. (7)). */
typedef struct nts_cubic {
    /** The coefficients, highest power first. @{ */
    double c3, c2, c1, c0;
    /** @} */
} nts_cubic;
/** The cubic F(xi) of the slave `d` = Xs - X3 on the corner `k`. */
NTS_API nts_cubic nts_corner_cubic(nts_corner k, nts_vec2 d);

#ifdef __cplusplus
}
#endif
#endif
