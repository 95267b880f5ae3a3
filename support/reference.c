/* The long-double reference of a corner's closest point (docs/model.md §4),
 * shared by the hard-case tests and the benchmarks' error tables. */
#include <math.h>

#include "nts_support.h"

static ntsx_lvec lv(ntsx_ld x, ntsx_ld y) {
    ntsx_lvec v;
    v.x = x;
    v.y = y;
    return v;
}

ntsx_corner ntsx_corner_make(nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d) {
    ntsx_corner k;
    k.A = lv(0.25L * alpha * ((ntsx_ld)a.x + c.x), 0.25L * alpha * ((ntsx_ld)a.y + c.y));
    k.B = lv(0.5L * alpha * ((ntsx_ld)c.x - a.x), 0.5L * alpha * ((ntsx_ld)c.y - a.y));
    k.e = lv((ntsx_ld)d.x - k.A.x, (ntsx_ld)d.y - k.A.y);
    return k;
}

ntsx_ld ntsx_corner_F(const ntsx_corner* k, ntsx_ld xi) {
    ntsx_ld rx = k->e.x - xi * (k->B.x + xi * k->A.x), ry = k->e.y - xi * (k->B.y + xi * k->A.y);
    ntsx_ld tx = k->B.x + 2 * xi * k->A.x, ty = k->B.y + 2 * xi * k->A.y;
    return rx * tx + ry * ty;
}

int ntsx_corner_roots(const ntsx_corner* k, ntsx_ld roots[3]) {
    ntsx_ld cuts[4];
    /* F' = -6 A.A xi^2 - 6 A.B xi + 2 e.A - B.B */
    ntsx_ld qa = -6 * (k->A.x * k->A.x + k->A.y * k->A.y), qb = -6 * (k->A.x * k->B.x + k->A.y * k->B.y);
    ntsx_ld qc = 2 * (k->e.x * k->A.x + k->e.y * k->A.y) - (k->B.x * k->B.x + k->B.y * k->B.y);
    int nc = 0, nr = 0, i;
    cuts[nc++] = -1;
    if (qa != 0) {
        ntsx_ld disc = qb * qb - 4 * qa * qc;
        if (disc > 0) {
            ntsx_ld r1 = (-qb - sqrtl(disc)) / (2 * qa), r2 = (-qb + sqrtl(disc)) / (2 * qa);
            if (r1 > r2) {
                ntsx_ld t = r1;
                r1 = r2;
                r2 = t;
            }
            if (r1 > -1 && r1 < 1) cuts[nc++] = r1;
            if (r2 > -1 && r2 < 1) cuts[nc++] = r2;
        }
    }
    cuts[nc++] = 1;
    for (i = 0; i + 1 < nc; ++i) {
        ntsx_ld lo = cuts[i], hi = cuts[i + 1], flo = ntsx_corner_F(k, lo), fhi = ntsx_corner_F(k, hi);
        int it;
        if (flo == 0) {
            roots[nr++] = lo;
            continue;
        }
        if (fhi == 0) {
            if (i + 2 == nc) roots[nr++] = hi;
            continue;
        }
        if ((flo > 0) == (fhi > 0)) continue;
        for (it = 0; it < 200; ++it) { /* bounded: 64 halvings reach the last bit of a long double */
            ntsx_ld mid = 0.5L * (lo + hi), fm;
            if (!(mid > lo && mid < hi)) break;
            fm = ntsx_corner_F(k, mid);
            if ((fm > 0) == (flo > 0)) {
                lo = mid;
                flo = fm;
            } else {
                hi = mid;
            }
        }
        roots[nr++] = 0.5L * (lo + hi);
    }
    if (nr == 0) roots[nr++] = fabsl(ntsx_corner_F(k, -1)) <= fabsl(ntsx_corner_F(k, 1)) ? -1 : 1;
    return nr;
}

ntsx_ld ntsx_corner_nearest(const ntsx_corner* k, const ntsx_ld* roots, int count) {
    ntsx_ld best = roots[0], bestd = -1;
    int i;
    for (i = 0; i < count; ++i) {
        ntsx_ld xi = roots[i];
        ntsx_ld rx = k->e.x - xi * (k->B.x + xi * k->A.x), ry = k->e.y - xi * (k->B.y + xi * k->A.y);
        ntsx_ld d2 = rx * rx + ry * ry;
        if (bestd < 0 || d2 < bestd) {
            bestd = d2;
            best = xi;
        }
    }
    return best;
}

ntsx_ld ntsx_corner_xi(nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d, int* roots) {
    ntsx_corner k = ntsx_corner_make(a, c, alpha, d);
    ntsx_ld r[3];
    int n = ntsx_corner_roots(&k, r);
    if (roots != NULL) *roots = n;
    return ntsx_corner_nearest(&k, r, n);
}
