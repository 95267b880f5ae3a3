/* The decomposition (docs/distributed.md): cuts along a direction (the
 * longer axis, or one that keeps a quarter more nodes on their owners'
 * ranks) at
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

static int bin_of(const slabs* sl, double c) {
    const double w = sl->hi - sl->lo;
    double q;
    if (!(w > 0.0)) return 0;
    q = (c - sl->lo) / w * BINS;
    return q <= 0.0 ? 0 : (q >= BINS - 1 ? BINS - 1 : (int)q);
}

/* The direction's frame (axis: 0 x, 1 y, 2 -x, 3 -y): the box along it,
 * or the nodes' extent. */
static void axis_frame(slabs* sl, int axis, const nts_frame* f, double lx, double ly) {
    const double lo = (axis & 1) ? f->ymin : f->xmin, hi = (axis & 1) ? f->ymax : f->xmax;
    sl->axis = axis;
    if (lx > 0.0) {
        sl->period = (axis & 1) ? ly : lx;
        sl->lo = 0.0;
        sl->hi = sl->period;
    } else {
        sl->period = 0.0;
        sl->lo = (axis & 2) ? -hi : lo;
        sl->hi = (axis & 2) ? -lo : hi;
    }
}

/* The cuts at the quantiles (equal shares, or the shares) of the summed
 * histogram h along sl's axis, into sl->cut. */
static void cuts_from(const ntsm_scene* m, slabs* sl, const long long* h) {
    const long long total = m->entry_off[m->bodies];
    long long acc = 0;
    int b = 0, r;
    sl->cut[0] = -HUGE_VAL;
    sl->cut[m->size] = HUGE_VAL;
    for (r = 1; r < m->size; ++r) {
        long long target = total * r / m->size;
        if (m->share_on) { /* uneven shares (ntsm_scene_set_weights): the same doubles on every rank */
            double cum = 0.0;
            int i;
            for (i = 0; i < r; ++i) cum += m->share[i];
            target = (long long)((double)total * cum);
        }
        while (b < BINS && acc + h[b] < target) acc += h[b++];
        /* the slab boundary at the end of bin b (the bins' edges, exactly the
         * same on every rank) */
        sl->cut[r] = b >= BINS ? HUGE_VAL : sl->lo + (sl->hi - sl->lo) * (double)(b + 1) / BINS;
        if (sl->cut[r] < sl->cut[r - 1]) sl->cut[r] = sl->cut[r - 1];
    }
}

/* The cuts: at the quantiles of the surface nodes along a direction, slab
 * r for rank r. Along the longer axis, unless another direction leaves a
 * quarter more of the surface nodes in their owner's slab (the same axis
 * the other way, or the other axis when it is at least half as long): a
 * host that owns rows of bodies gets slabs along its rows, in its ranks'
 * order, so that a slave's forces on its own and its masters' nodes mostly
 * stay on its rank (docs/distributed.md, "The slabs follow the host"). The same on every
 * rank. */
enum { DIRS = 4 };
int ntsm_slabs_make(ntsm_scene* m, const nts_frame* f, double lx, double ly, slabs* sl) {
    const nts_vec2* pos = m->own ? nts_scene_positions(m->own) : NULL;
    const double ex = lx > 0.0 ? lx : f->xmax - f->xmin, ey = lx > 0.0 ? ly : f->ymax - f->ymin;
    const int longer = ex >= ey ? 0 : 1;
    const int nd = m->size == 1 ? 1 : (longer == 0 ? ey >= 0.5 * ex : ex >= 0.5 * ey) ? 4 : 2;
    long long* h = (long long*)calloc(2u * DIRS * BINS, sizeof(long long)); /* mine, then summed */
    slabs cand[DIRS];
    long long kept[DIRS], sum[DIRS];
    int b, k, d, best = 0;
    int fine, all;
    memset(cand, 0, sizeof cand);
    memset(kept, 0, sizeof kept);
    for (d = 0, fine = h != NULL; d < nd; ++d) {
        /* the longer axis, the other way, the other axis, the other way */
        axis_frame(&cand[d], (d < 2 ? longer : 1 - longer) | (d & 1) << 1, f, lx, ly);
        if ((cand[d].cut = (double*)malloc(sizeof(double) * (size_t)(m->size + 1))) == NULL) fine = 0;
    }
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm); /* before the histograms' reduction */
    if (!all) {
        free(h);
        for (d = 0; d < nd; ++d) free(cand[d].cut);
        sl->cut = NULL;
        return NTS_ENOMEM;
    }
    for (b = 0; b < m->count; ++b) {
        const int e0 = nts_scene_body_entry_start(m->own, b), e1 = nts_scene_body_entry_start(m->own, b + 1);
        const int n0 = nts_scene_body_node_offset(m->own, b);
        for (k = e0; k < e1; ++k) {
            int body, node;
            nts_scene_entry(m->own, k, &body, &node);
            for (d = 0; d < nd; ++d) h[d * BINS + bin_of(&cand[d], ntsm_axis_of(&cand[d], pos[n0 + node]))]++;
        }
    }
    /* (every rank reduces as many values, whatever its nd: ranks given
     * different frames get a wrong decomposition, never a hang) */
    MPI_Allreduce(h, h + DIRS * BINS, DIRS * BINS, MPI_LONG_LONG, MPI_SUM, m->comm);
    for (d = 0; d < nd; ++d) cuts_from(m, &cand[d], h + (DIRS + d) * BINS);
    /* the surface nodes each direction's slabs leave on their owner's rank */
    for (b = 0; b < m->count && nd > 1; ++b) {
        const int e0 = nts_scene_body_entry_start(m->own, b), e1 = nts_scene_body_entry_start(m->own, b + 1);
        const int n0 = nts_scene_body_node_offset(m->own, b);
        for (k = e0; k < e1; ++k) {
            int body, node;
            nts_scene_entry(m->own, k, &body, &node);
            for (d = 0; d < nd; ++d)
                kept[d] += ntsm_slab_of(&cand[d], m->size, ntsm_axis_of(&cand[d], pos[n0 + node])) == m->rank;
        }
    }
    MPI_Allreduce(kept, sum, DIRS, MPI_LONG_LONG, MPI_SUM, m->comm);
    for (d = 1; d < nd; ++d)
        if (4 * sum[d] > 5 * sum[0] && sum[d] > sum[best]) best = d;
    *sl = cand[best];
    for (d = 0; d < nd; ++d)
        if (d != best) free(cand[d].cut);
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
