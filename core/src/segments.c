/* The segment data of every surface entry (docs/model.md §2), and the order
 * statistics of the segment lengths that set the default search radius (the
 * median segment, docs/model.md §9). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "stages.h"


/* Room for n records, aligned to NTS_SEG_ALIGN whatever the allocator's
 * alignment (nts_set_allocator): the block has one alignment more. The
 * records are recomputed each evaluation, so a larger buffer copies nothing. */
static int seg_reserve(nts_context* ctx, int n) {
    void* block;
    int cap;
    uintptr_t at;
    if (n <= ctx->seg_cap && ctx->seg_block != NULL) return NTS_OK;
    cap = ctx->seg_cap > 16 ? ctx->seg_cap : 16;
    while (cap < n) cap = cap > (1 << 29) ? n : 2 * cap;
    block = nts_alloc((size_t)cap * sizeof(seg_data) + NTS_SEG_ALIGN);
    if (block == NULL) return NTS_ENOMEM;
    nts_free(ctx->seg_block);
    ctx->seg_block = block;
    at = ((uintptr_t)block + (NTS_SEG_ALIGN - 1)) & ~(uintptr_t)(NTS_SEG_ALIGN - 1);
    ctx->seg = (seg_data*)(void*)((char*)block + (at - (uintptr_t)block));
    ctx->seg_cap = cap;
    return NTS_OK;
}

/* Each segment is its own, so the loop runs in parallel; the reductions are
 * a minimum and maxima, exact whatever the threads. A segment of zero length
 * (possible after new positions) is reported, never divided by. */
int nts_segments_compute(nts_context* ctx, const nts_scene* s, int threads, seg_summary* out) {
    const int n = s->surface_count;
    int i, rc, bad = n;
    double lmax = 0.0, amax = 0.0, xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
    (void)threads; /* without OpenMP */
    if ((rc = seg_reserve(ctx, n)) != NTS_OK) return rc;
#if NTS_CONFIG_OPENMP
#pragma omp parallel for num_threads(threads) if (threads > 1) schedule(static) reduction(min : bad, xmin, ymin) \
    reduction(max : lmax, amax, xmax, ymax)
#endif
    for (i = 0; i < n; ++i) {
        seg_data* sd = &ctx->seg[i];
        const int next = s->surf_next[i];
        const nts_vec2 p = s->pos[s->surf_node[i]];
        double l2, a;
        sd->p = p;
        sd->t = nts_scene_diff(s, s->pos[s->surf_node[next]], p);
        sd->prev = s->surf_prev[i];
        sd->next = next;
        sd->node = s->surf_node[i];
        sd->body = s->surf_body[i];
        l2 = nts_length_sq(sd->t);
        /* The supported range (scene.c): nts_scene_set_positions does not
         * check it, and 1/|t|^2 must not overflow. */
        if (!(l2 >= 1e-200) || !(l2 <= 1e201)) {
            sd->len = -1.0;
            sd->inv_len2 = 0.0;
            if (i < bad) bad = i;
            continue;
        }
        sd->len = sqrt(l2);
        sd->inv_len2 = 1.0 / l2;
        if (sd->len > lmax) lmax = sd->len;
        a = fabs(p.x) > fabs(p.y) ? fabs(p.x) : fabs(p.y);
        if (a > amax) amax = a;
        if (p.x < xmin) xmin = p.x;
        if (p.x > xmax) xmax = p.x;
        if (p.y < ymin) ymin = p.y;
        if (p.y > ymax) ymax = p.y;
    }
    out->bad = bad;
    out->lmax = lmax;
    out->coord_max = amax;
    out->xmin = xmin;
    out->xmax = xmax;
    out->ymin = ymin;
    out->ymax = ymax;
    return NTS_OK;
}

/* The k-th smallest of v[0..n) (v is reordered): quickselect with a
 * median-of-three pivot, and a full sort of what is left if it has not
 * converged after 2 log2(n) + 8 partitions, so the time is bounded by
 * O(n log n) whatever the values. Deterministic. */
static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

double nts_select_kth(double* v, int n, int k) {
    int lo = 0, hi = n - 1, rounds = 8, m;
    assert(n > 0 && k >= 0 && k < n);
    for (m = n; m > 1; m >>= 1) rounds += 2;
    while (hi > lo) {
        double a, b, c, pivot;
        int i = lo, j = hi;
        if (rounds-- == 0) {
            qsort(v + lo, (size_t)(hi - lo + 1), sizeof(double), cmp_double);
            break;
        }
        a = v[lo];
        b = v[lo + (hi - lo) / 2];
        c = v[hi];
        pivot = a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
        while (i <= j) { /* Hoare partition: every step moves i or j, so it ends */
            while (v[i] < pivot) ++i;
            while (v[j] > pivot) --j;
            if (i <= j) {
                double t = v[i];
                v[i] = v[j];
                v[j] = t;
                ++i;
                --j;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break; /* v[k] == pivot */
    }
    return v[k];
}

/* Exact, in one pass over the lengths plus a small selection: a sample of
 * NTS_SAMPLE lengths (a fixed stride, so the same scene gives the same sample)
 * brackets the k-th length between two of its order statistics, about
 * 4 standard deviations of the sample's rank on either side; one pass counts
 * the lengths below the bracket and inside it, a second keeps those inside,
 * and the k-th is selected among the kept. Should the bracket miss
 * (adversarial lengths), every length is copied and selected: the answer is
 * the same, only slower. Both passes run over SHARES fixed slices of the
 * entries (in parallel), each keeping its lengths at its own offset; the
 * value selected does not depend on their order anyway. */
enum { SHARES = 64 };
double nts_kth_length(const nts_context* ctx, const nts_scene* s, int k, double* scratch, int threads) {
    const int n = s->surface_count;
    const seg_data* seg = ctx->seg;
    double* sample = scratch + n; /* past the kept lengths */
    double lo, hi;
    long long below = 0, inside = 0;
    int cnt_below[SHARES], cnt_in[SHARES], at[SHARES + 1];
    int i, rlo, rhi;
    (void)threads;
    assert(n > 0 && k >= 0 && k < n);
    if (n <= 4 * NTS_SAMPLE) {
        for (i = 0; i < n; ++i) scratch[i] = seg[i].len;
        return nts_select_kth(scratch, n, k);
    }
    for (i = 0; i < NTS_SAMPLE; ++i) sample[i] = seg[(int)((long long)i * n / NTS_SAMPLE)].len;
    /* The sample rank of the k-th, +- 256 (4 sqrt(NTS_SAMPLE)). */
    rlo = (int)((double)k / (double)(n - 1) * (NTS_SAMPLE - 1)) - 256;
    rhi = rlo + 512;
    if (rlo < 0) rlo = 0;
    if (rhi > NTS_SAMPLE - 1) rhi = NTS_SAMPLE - 1;
    lo = nts_select_kth(sample, NTS_SAMPLE, rlo);
    hi = nts_select_kth(sample, NTS_SAMPLE, rhi);
    NTS_PARALLEL_FOR(threads)
    for (i = 0; i < SHARES; ++i) {
        const int b = (int)((long long)n * i / SHARES), e = (int)((long long)n * (i + 1) / SHARES);
        int j, cb = 0, ci = 0;
        for (j = b; j < e; ++j) {
            const double v = seg[j].len;
            cb += v < lo;
            ci += v >= lo && v <= hi;
        }
        cnt_below[i] = cb;
        cnt_in[i] = ci;
    }
    at[0] = 0;
    for (i = 0; i < SHARES; ++i) {
        below += cnt_below[i];
        inside += cnt_in[i];
        at[i + 1] = at[i] + cnt_in[i];
    }
    if (below <= k && k < below + inside) {
        if (lo == hi) return lo; /* every length in the bracket is the k-th */
        NTS_PARALLEL_FOR(threads)
        for (i = 0; i < SHARES; ++i) {
            const int b = (int)((long long)n * i / SHARES), e = (int)((long long)n * (i + 1) / SHARES);
            int j, o = at[i];
            for (j = b; j < e; ++j) {
                const double v = seg[j].len;
                if (v >= lo && v <= hi) scratch[o++] = v;
            }
        }
        return nts_select_kth(scratch, (int)inside, k - (int)below);
    }
    for (i = 0; i < n; ++i) scratch[i] = seg[i].len;
    return nts_select_kth(scratch, n, k);
}
