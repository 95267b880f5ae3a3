/* The corner polynomial and its closest point, public (geometry.h): each a
 * door onto corner.h's inline code, which the search runs itself. */
#include <ntscontact/geometry.h>

#include "corner.h"

nts_shape3 nts_corner_shape(double alpha, double xi) { return corner_shape(alpha, xi); }

nts_corner nts_corner_make(nts_vec2 a, nts_vec2 c, double alpha) { return corner_make(a, c, alpha); }

nts_vec2 nts_corner_point(nts_corner k, double xi) {
    /* C + xi (B + A xi): Horner form. */
    return nts_mul_add(k.C, xi, nts_mul_add(k.B, xi, k.A));
}

nts_vec2 nts_corner_tangent(nts_corner k, double xi) { return nts_mul_add(k.B, 2.0 * xi, k.A); }

nts_cubic nts_corner_cubic(nts_corner k, nts_vec2 d) {
    /* F(xi) = -2(A.A) xi^3 - 3(A.B) xi^2 + (2 e.A - B.B) xi + e.B, e = d - C. */
    nts_cubic f;
    nts_vec2 e = nts_sub(d, k.C);
    f.c3 = -2.0 * nts_dot(k.A, k.A);
    f.c2 = -3.0 * nts_dot(k.A, k.B);
    f.c1 = 2.0 * nts_dot(e, k.A) - nts_dot(k.B, k.B);
    f.c0 = nts_dot(e, k.B);
    return f;
}

nts_corner_solution nts_corner_solve(nts_corner k, nts_vec2 d, nts_solver solver) { return corner_solve(&k, d, solver); }
