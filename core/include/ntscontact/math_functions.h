/** @file
 * ntscontact: inline 2D vector math (small structs by value, as Box2D's
 * math_functions.h). Nothing here divides by a length that can be zero without
 * saying so in the name. */
#ifndef NTSCONTACT_MATH_FUNCTIONS_H
#define NTSCONTACT_MATH_FUNCTIONS_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A point or vector of the plane, passed by value. */
typedef struct nts_vec2 {
    /** The components. @{ */
    double x, y;
    /** @} */
} nts_vec2;

/** The virial (Kirkwood) terms xx, yy, xy and yx: symmetric (yx = xy)
 * without friction; with friction the tangential forces make it not
 * (docs/model.md §14). */
typedef struct nts_virial {
    /** The tensor's components. @{ */
    double xx, yy, xy, yx;
    /** @} */
} nts_virial;

/** The vector (x, y). */
static inline nts_vec2 nts_v2(double x, double y) { nts_vec2 v = {x, y}; return v; }
/** a + b */
static inline nts_vec2 nts_add(nts_vec2 a, nts_vec2 b) { return nts_v2(a.x + b.x, a.y + b.y); }
/** a - b */
static inline nts_vec2 nts_sub(nts_vec2 a, nts_vec2 b) { return nts_v2(a.x - b.x, a.y - b.y); }
/** -a */
static inline nts_vec2 nts_neg(nts_vec2 a) { return nts_v2(-a.x, -a.y); }
/** s a */
static inline nts_vec2 nts_scale(double s, nts_vec2 a) { return nts_v2(s * a.x, s * a.y); }
/** a + s b */
static inline nts_vec2 nts_mul_add(nts_vec2 a, double s, nts_vec2 b) { return nts_v2(a.x + s * b.x, a.y + s * b.y); }
/** The dot product a.b */
static inline double nts_dot(nts_vec2 a, nts_vec2 b) { return a.x * b.x + a.y * b.y; }
/** The 2D cross product a_x b_y - a_y b_x (twice the signed area of the triangle 0, a, b). */
static inline double nts_cross(nts_vec2 a, nts_vec2 b) { return a.x * b.y - a.y * b.x; }
/** |a|^2 */
static inline double nts_length_sq(nts_vec2 a) { return a.x * a.x + a.y * a.y; }
/** |a| */
static inline double nts_length(nts_vec2 a) { return sqrt(a.x * a.x + a.y * a.y); }
/** Outward normal direction of a tangent for a counter-clockwise loop: (t_y, -t_x). */
static inline nts_vec2 nts_right_perp(nts_vec2 t) { return nts_v2(t.y, -t.x); }
/** Unit vector, or the zero vector when the length is zero or not finite. */
static inline nts_vec2 nts_normalize_or_zero(nts_vec2 a) {
    double l = nts_length(a);
    if (!(l > 0.0) || !isfinite(l)) return nts_v2(0.0, 0.0);
    return nts_v2(a.x / l, a.y / l);
}
/** 1 when `a` is finite (not NaN, not infinite), else 0. */
static inline int nts_is_valid_double(double a) { return isfinite(a) != 0; }
/** 1 when both components of `a` are finite, else 0. */
static inline int nts_is_valid_vec2(nts_vec2 a) { return isfinite(a.x) && isfinite(a.y); }

/** Minimum-image difference in a periodic box of sides lx, ly (0 means not periodic
 * along that axis). Used for every difference vector in a periodic scene.
 * This one: a single axis of side `l`. */
static inline double nts_min_image_1(double d, double l) {
    /* Within a quarter box the image is 0: nearbyint gives a signed zero and
     * d - l * (+-0) is d + 0.0 (which also turns -0 into +0), so near pairs skip
     * the division and the library call, with the same bits. */
    if (!(l > 0.0)) return d;
    if (fabs(d) < 0.25 * l) return d + 0.0;
    return d - l * nearbyint(d / l);
}
/** The minimum-image difference of `d` in the box lx x ly (nts_min_image_1 on each axis). */
static inline nts_vec2 nts_min_image(nts_vec2 d, double lx, double ly) {
    d.x = nts_min_image_1(d.x, lx);
    d.y = nts_min_image_1(d.y, ly);
    return d;
}

#ifdef __cplusplus
}
#endif
#endif
