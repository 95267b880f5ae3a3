/* The decomposition (docs/distributed.md): cuts along the longer axis at
 * the quantiles of the surface nodes (equal shares, or the shares of
 * ntsm_scene_set_weights or of the measured speeds), the same on every
 * rank. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"


enum { BINS = 4096 };

double ntsm_axis_of(const slabs* sl, nts_vec2 p) {
    double c = sl->axis == 0 ? p.x : p.y;
    if (sl->period > 0.0) {
        c -= sl->period * floor(c / sl->period);
        if (!(c < sl->period)) c = 0.0; /* a round-off at the top */
    }
    return c;
}

int ntsm_slab_of(const slabs* sl, int size, double c) {
    int lo = 0, hi = size - 1; /* the last r with cut[r] <= c */
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (sl->cut[mid] <= c) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

static int bin_of(const slabs* sl, double c) {
    const double w = sl->hi - sl->lo;
    double q;
    if (!(w > 0.0)) return 0;
    q = (c - sl->lo) / w * BINS;
    return q <= 0.0 ? 0 : (q >= BINS - 1 ? BINS - 1 : (int)q);
}

/* The cuts: at the quantiles of the surface nodes along the longer axis. */
int ntsm_slabs_make(ntsm_scene* m, const nts_frame* f, double lx, double ly, slabs* sl) {
    long long* h = (long long*)calloc(2 * BINS, sizeof(long long));
    const nts_vec2* pos = m->own ? nts_scene_positions(m->own) : NULL;
    const long long total = m->entry_off[m->bodies];
    long long acc = 0;
    int b, k, r;
    int fine, all;
    sl->cut = h != NULL ? (double*)malloc(sizeof(double) * (size_t)(m->size + 1)) : NULL;
    fine = h != NULL && sl->cut != NULL;
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm); /* before the histogram's reduction */
    if (!all) {
        free(h);
        free(sl->cut);
        sl->cut = NULL;
        return NTS_ENOMEM;
    }
    if (lx > 0.0) {
        sl->axis = lx >= ly ? 0 : 1;
        sl->period = sl->axis == 0 ? lx : ly;
        sl->lo = 0.0;
        sl->hi = sl->period;
    } else {
        sl->axis = f->xmax - f->xmin >= f->ymax - f->ymin ? 0 : 1;
        sl->period = 0.0;
        sl->lo = sl->axis == 0 ? f->xmin : f->ymin;
        sl->hi = sl->axis == 0 ? f->xmax : f->ymax;
    }
    for (b = 0; b < m->count; ++b) {
        const int e0 = nts_scene_body_entry_start(m->own, b), e1 = nts_scene_body_entry_start(m->own, b + 1);
        const int n0 = nts_scene_body_node_offset(m->own, b);
        for (k = e0; k < e1; ++k) {
            int body, node;
            nts_scene_entry(m->own, k, &body, &node);
            h[bin_of(sl, ntsm_axis_of(sl, pos[n0 + node]))]++;
        }
    }
    MPI_Allreduce(h, h + BINS, BINS, MPI_LONG_LONG, MPI_SUM, m->comm);
    sl->cut[0] = -HUGE_VAL;
    sl->cut[m->size] = HUGE_VAL;
    for (r = 1, b = 0; r < m->size; ++r) {
        long long target = total * r / m->size;
        if (m->share_on) { /* uneven shares (ntsm_scene_set_weights): the same doubles on every rank */
            double cum = 0.0;
            int i;
            for (i = 0; i < r; ++i) cum += m->share[i];
            target = (long long)((double)total * cum);
        }
        while (b < BINS && acc + h[BINS + b] < target) acc += h[BINS + b++];
        /* the slab boundary at the end of bin b (the bins' edges, exactly the
         * same on every rank) */
        sl->cut[r] = b >= BINS ? HUGE_VAL : sl->lo + (sl->hi - sl->lo) * (double)(b + 1) / BINS;
        if (sl->cut[r] < sl->cut[r - 1]) sl->cut[r] = sl->cut[r - 1];
    }
    free(h);
    return NTS_OK;
}

/* Whether [a, b] (along the axis, maybe past the box) meets slab r. */
int ntsm_meets(const slabs* sl, int r, double a, double b) {
    int k;
    if (sl->period <= 0.0) return b >= sl->cut[r] && a < sl->cut[r + 1];
    if (b - a >= sl->period) return 1;
    {
        const double s0 = sl->cut[r] < 0.0 ? 0.0 : sl->cut[r];
        const double s1 = sl->cut[r + 1] > sl->period ? sl->period : sl->cut[r + 1];
        const double shift = sl->period * floor(a / sl->period);
        for (k = -1; k <= 2; ++k) {
            const double o = shift + k * sl->period;
            if (b >= s0 + o && a < s1 + o) return 1;
        }
    }
    return 0;
}
