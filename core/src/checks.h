/* The geometry checks of a loop (docs/model.md §2), one place for each: the
 * scene's checks (scene.c: nts_scene_create, nts_scene_update_positions) and
 * the segment pass that checks new positions as it computes the segments
 * (segments.c, nts_evaluate_positions) decide by the same bits. Each verdict
 * is symmetric in the loop's direction (a sum of two lengths, a maximum, the
 * product of two lengths by a power of two, |cross|), so it is the same for a
 * loop stored reversed; only the area and the perimeter are sums in order.
 * The equalities hold in IEEE double arithmetic without contraction: the
 * build passes -ffp-contract=off (CMakeLists.txt), and x86-64 has no x87
 * doubles. */
#ifndef NTSCONTACT_CHECKS_H
#define NTSCONTACT_CHECKS_H

#include <float.h>
#include <math.h>

#include <ntscontact/math_functions.h>

/* The supported range (docs/model.md, "Geometry"): squares of lengths and
 * products of coordinates must stay well inside a double (1e-200 .. 1e200),
 * so that no test of the search, no 1/|t|^2 and no area overflows or
 * underflows into a silent wrong answer. */
#define NTS_COORD_MAX 1e100
/* Below this a length is zero for the checks (and 1/length^2 overflows). */
#define NTS_LENGTH_MIN 1e-100

static inline double nts_max4(double a, double b, double c, double d) {
    double m = a > b ? a : b, n = c > d ? c : d;
    return m > n ? m : n;
}

/* A segment is degenerate when it is shorter than 1e-12 of its two neighbours
 * together (a doubled node), or than what its own coordinates can resolve (a
 * few ulps of the largest), or than NTS_LENGTH_MIN: the tolerance of the
 * segment from p to q, l_prev and l_next its neighbours' lengths. Only the
 * segment's own neighbourhood counts: no body elsewhere changes the verdict. */
static inline double nts_segment_tolerance(double l_prev, double l_next, nts_vec2 p, nts_vec2 q) {
    const double res = 16.0 * DBL_EPSILON * nts_max4(fabs(p.x), fabs(p.y), fabs(q.x), fabs(q.y));
    const double nb = 1e-12 * (l_prev + l_next);
    const double tol = res > nb ? res : nb;
    return tol > NTS_LENGTH_MIN ? tol : NTS_LENGTH_MIN;
}
static inline int nts_segment_degenerate(double len, double l_prev, double l_next, nts_vec2 p, nts_vec2 q) {
    return !(len > nts_segment_tolerance(l_prev, l_next, p, q));
}

/* Zero-angle spike at a node: both neighbours leave it in the same direction
 * (d_in: the step into the node, d_out: the step out of it), so the corner
 * tangent vanishes (docs/model.md §3). */
static inline int nts_is_spike(nts_vec2 d_in, nts_vec2 d_out, double l_in, double l_out) {
    const nts_vec2 a = nts_neg(d_in);
    return nts_dot(a, d_out) > 0.0 && fabs(nts_cross(a, d_out)) <= 64.0 * DBL_EPSILON * l_in * l_out;
}

/* One step of the shoelace (twice the signed area) along a loop, from the
 * running sum of the steps so far (`cur`, relative to the loop's first node:
 * subtracting first keeps precision when coordinates are large, and works
 * across a periodic boundary) and the next minimum-image step d. The scene's
 * check and the segment pass sum with it, step by step in the caller's
 * order, for the same bits. */
static inline void nts_shoelace_step(nts_vec2* cur, double* a2, nts_vec2 d) {
    const nts_vec2 next = nts_add(*cur, d);
    *a2 += nts_cross(*cur, next);
    *cur = next;
}

/* A loop of twice the signed area a2 and perimeter perim encloses zero area.
 * perim^2 <= (n 2e100)^2: finite for any loop the limits allow. */
static inline int nts_zero_area(double a2, double perim) { return !(fabs(a2) > 64.0 * DBL_EPSILON * perim * perim); }

#endif
