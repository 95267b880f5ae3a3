/* The segment data of every surface entry (docs/model.md §2), and the order
 * statistics of the segment lengths that set the default search radius (the
 * median segment, docs/model.md §9). */
#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "context.h"

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

/* The length of segment i, as the segment pass computes it (the same bits),
 * or -1 outside the supported range (scene.c: nts_scene_set_positions does
 * not check it, and 1/|t|^2 must not overflow). */
static inline double segment_length(const nts_scene* s, int i, nts_vec2 p, nts_vec2* t) {
    double l2;
    *t = nts_scene_diff(s, s->pos[s->surf_node[s->surf_next[i]]], p);
    l2 = nts_length_sq(*t);
    return l2 >= 1e-200 && l2 <= 1e201 ? sqrt(l2) : -1.0;
}

/* The order statistic of the lengths that the segment pass brackets (below). */
typedef struct kth_plan {
    int bracket;   /* 1: keep the lengths in [lo, hi] while the segments are computed */
    double lo, hi;
} kth_plan;

/* The k-th smallest length, exactly, without another pass over the segments
 * when the scene is large: a sample of NTS_SAMPLE lengths (a fixed stride, so
 * the same scene gives the same sample, computed from the positions as the
 * segment pass will) brackets it between two of its order statistics, 256
 * ranks on either side: 8 standard deviations of the sample's rank at the
 * median (sqrt(NTS_SAMPLE) / 2 = 32), so that a scene of random lengths
 * misses it about never (a miss costs a copy and a selection of every
 * length, evaluation after evaluation for the same scene). The segment pass
 * then counts the lengths below the bracket and keeps those inside, and the
 * k-th is selected among the kept. Should the bracket miss (adversarial
 * lengths), every length is copied and selected: the answer is the same, only
 * slower. `sample`: NTS_SAMPLE doubles. */
typedef struct sample_task {
    const nts_scene* s;
    double* sample;
} sample_task;

static void sample_lengths(int begin, int end, int wi, void* p) {
    const sample_task* t = (const sample_task*)p;
    const int n = t->s->surface_count;
    int i;
    (void)wi;
    for (i = begin; i < end; ++i) {
        const int e = (int)((long long)i * n / NTS_SAMPLE);
        nts_vec2 tt;
        t->sample[i] = segment_length(t->s, e, t->s->pos[t->s->surf_node[e]], &tt);
    }
}

static kth_plan kth_prepare(const nts_scene* s, int k, double* sample, const nts_run* run) {
    const int n = s->surface_count;
    kth_plan plan;
    sample_task st;
    int rlo, rhi;
    plan.bracket = k >= 0 && n > 4 * NTS_SAMPLE;
    plan.lo = plan.hi = 0.0;
    if (!plan.bracket) return plan;
    st.s = s;
    st.sample = sample;
    nts_run_each(run, sample_lengths, NTS_SAMPLE, &st);
    /* The sample rank of the k-th, +- 256 (4 sqrt(NTS_SAMPLE)): an eighth of the lengths is kept. */
    rlo = (int)((double)k / (double)(n - 1) * (NTS_SAMPLE - 1)) - 256;
    rhi = rlo + 512;
    if (rlo < 0) rlo = 0;
    if (rhi > NTS_SAMPLE - 1) rhi = NTS_SAMPLE - 1;
    plan.lo = nts_select_kth(sample, NTS_SAMPLE, rlo);
    plan.hi = nts_select_kth(sample, NTS_SAMPLE, rhi);
    return plan;
}

/* The pass runs over SHARES fixed slices of the entries (in parallel, each
 * taken by whichever thread is free), each keeping the lengths in the
 * bracket from its own first entry on in `scratch`; the value selected does
 * not depend on their order anyway. */
enum { SHARES = 64 };

/* The share q's first entry (its kept lengths start there in `scratch`). */
static inline int share_begin(int n, int q) { return (int)((long long)n * q / SHARES); }

/* Where a length of the bracket [lo, hi] falls among BINS equal bins: never
 * decreasing with the length (a difference, a product by a positive number,
 * a floor), so the bins hold the kept lengths in order. */
enum { BINS = 1024, PARTS = 4 };
typedef char nts_histograms_fit_the_sample[PARTS * BINS * sizeof(int) <= NTS_SAMPLE * sizeof(double) ? 1 : -1];
static inline int bin_of(double x, double lo, double inv_w) {
    const double t = (x - lo) * inv_w;
    return t < (double)BINS ? (int)t : BINS - 1;
}

/* The k-th smallest of the lengths kept in the bracket (share q's cnt_in[q]
 * of them from its first entry on in `v`), with the threads: PARTS partial
 * histograms of BINS equal bins of [lo, hi] (counts: the same whatever the
 * threads) find the bin that holds the k-th, and only that bin's lengths are
 * gathered and selected, one in about BINS of those kept. `hist`: PARTS BINS
 * ints. */
typedef struct bracket_task {
    double* v;
    const int* cnt_in;
    int* cnt_bin;
    int* hist;
    int n, bin;
    double lo, inv_w;
} bracket_task;

/* Part u's histogram of the kept lengths of its shares. */
static void bracket_histogram(int begin, int end, int wi, void* p) {
    const bracket_task* t = (const bracket_task*)p;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u) {
        int* h = t->hist + u * BINS;
        int qq, j;
        memset(h, 0, sizeof(int) * BINS);
        for (qq = u * SHARES / PARTS; qq < (u + 1) * SHARES / PARTS; ++qq) {
            const int b = share_begin(t->n, qq);
            for (j = b; j < b + t->cnt_in[qq]; ++j) ++h[bin_of(t->v[j], t->lo, t->inv_w)];
        }
    }
}

/* The bin's lengths to the front of each share's, without a branch. */
static void bracket_gather(int begin, int end, int wi, void* p) {
    const bracket_task* t = (const bracket_task*)p;
    int q;
    (void)wi;
    for (q = begin; q < end; ++q) {
        const int b = share_begin(t->n, q);
        int j, m = 0;
        for (j = b; j < b + t->cnt_in[q]; ++j) {
            const double x = t->v[j];
            t->v[b + m] = x;
            m += bin_of(x, t->lo, t->inv_w) == t->bin;
        }
        t->cnt_bin[q] = m;
    }
}

static double kth_in_bracket(double* v, int n, const int* cnt_in, int k, double lo, double hi, int* hist,
                             const nts_run* run) {
    int cnt_bin[SHARES];
    int u, q, bin, below = 0;
    long long at = 0;
    bracket_task t;
    if (!(hi > lo)) return lo; /* every kept length is lo */
    t.v = v;
    t.cnt_in = cnt_in;
    t.cnt_bin = cnt_bin;
    t.hist = hist;
    t.n = n;
    t.lo = lo;
    t.inv_w = (double)BINS / (hi - lo);
    nts_run_each(run, bracket_histogram, PARTS, &t);
    for (bin = 0; bin < BINS; ++bin) {
        int c = 0;
        for (u = 0; u < PARTS; ++u) c += hist[u * BINS + bin];
        if (below + c > k) break;
        below += c;
    }
    assert(bin < BINS);
    t.bin = bin;
    nts_run_each(run, bracket_gather, SHARES, &t);
    for (q = 0; q < SHARES; ++q) { /* to the front (each share's start is at or past where its go) */
        const int b = share_begin(n, q);
        if (at != b) memmove(v + at, v + b, sizeof(double) * (size_t)cnt_bin[q]);
        at += cnt_bin[q];
    }
    return nts_select_kth(v, (int)at, k - below);
}

/* Each segment is its own, so the loop runs in parallel; the reductions are
 * a minimum and maxima, exact whatever the threads. A segment of zero length
 * (possible after new positions) is reported, never divided by. */
/* What one share of the pass finds: its counts of the bracket, and its
 * part of the summary (combined by the caller in share order). */
typedef struct share_found {
    int below, in, first_bad;
    double lmax, amax, xmin, xmax, ymin, ymax, moved2;
} share_found;

typedef struct pass_task {
    nts_context* ctx;
    const nts_scene* s;
    double* scratch;
    kth_plan plan;
    share_found* found;
    const nts_vec2* since;
} pass_task;

static void segments_pass(int begin, int end, int wi, void* p) {
    const pass_task* t = (const pass_task*)p;
    const nts_scene* s = t->s;
    const int n = s->surface_count;
    int q;
    (void)wi;
    for (q = begin; q < end; ++q) {
        /* The share's own accumulators, in registers. */
        const int b = share_begin(n, q), e = share_begin(n, q + 1);
        const int keep = t->plan.bracket;
        const double lo = t->plan.lo, hi = t->plan.hi;
        double* scratch = t->scratch;
        double lm = 0.0, am = 0.0, x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL, m2 = 0.0;
        int i, cb = 0, ci = 0, first_bad = n;
        share_found* f = &t->found[q];
        for (i = b; i < e; ++i) {
            seg_data* sd = &t->ctx->seg[i];
            const nts_vec2 pp = s->pos[s->surf_node[i]];
            double len, a;
            sd->p = pp;
            if (t->since != NULL) {
                double dx = pp.x - t->since[i].x, dy = pp.y - t->since[i].y, d2;
                if (s->lx > 0.0) {
                    dx = nts_min_image_1(dx, s->lx);
                    dy = nts_min_image_1(dy, s->ly);
                }
                d2 = dx * dx + dy * dy;
                m2 = d2 > m2 ? d2 : m2;
            }
            len = segment_length(s, i, pp, &sd->t);
            sd->prev = s->surf_prev[i];
            sd->next = s->surf_next[i];
            sd->node = s->surf_node[i];
            sd->body = s->surf_body[i];
            if (len < 0.0) {
                sd->len = -1.0;
                sd->inv_len2 = 0.0;
                if (i < first_bad) first_bad = i;
                continue;
            }
            sd->len = len;
            sd->inv_len2 = 1.0 / nts_length_sq(sd->t);
            if (keep) { /* without a branch: 1 in 8 is kept, at random */
                scratch[b + ci] = len;
                cb += len < lo;
                ci += (len >= lo) & (len <= hi);
            }
            lm = len > lm ? len : lm;
            a = fabs(pp.x) > fabs(pp.y) ? fabs(pp.x) : fabs(pp.y);
            am = a > am ? a : am;
            x0 = pp.x < x0 ? pp.x : x0;
            x1 = pp.x > x1 ? pp.x : x1;
            y0 = pp.y < y0 ? pp.y : y0;
            y1 = pp.y > y1 ? pp.y : y1;
        }
        f->below = cb;
        f->in = ci;
        f->first_bad = first_bad;
        f->lmax = lm;
        f->amax = am;
        f->xmin = x0;
        f->xmax = x1;
        f->ymin = y0;
        f->ymax = y1;
        f->moved2 = m2;
    }
}

int nts_segments_compute(nts_context* ctx, const nts_scene* s, int k, double* scratch, const nts_vec2* since,
                         const nts_run* run, seg_summary* out) {
    const int n = s->surface_count;
    share_found found[SHARES];
    pass_task t;
    int cnt_below[SHARES], cnt_in[SHARES];
    int q, rc, bad = n;
    long long below = 0, inside = 0;
    double lmax = 0.0, amax = 0.0, xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL, m2 = 0.0;
    assert(k < n);
    if ((rc = seg_reserve(ctx, n)) != NTS_OK) return rc;
    t.ctx = ctx;
    t.s = s;
    t.scratch = scratch;
    t.plan = kth_prepare(s, k, scratch + n, run);
    t.found = found;
    t.since = since;
    /* Each share taken by whichever worker is free; the minima and maxima
     * are exact, whatever the order they are taken in. */
    nts_run_tasks(run, segments_pass, SHARES, 1, &t);
    for (q = 0; q < SHARES; ++q) {
        const share_found* f = &found[q];
        cnt_below[q] = f->below;
        cnt_in[q] = f->in;
        if (f->first_bad < bad) bad = f->first_bad;
        if (f->lmax > lmax) lmax = f->lmax;
        if (f->amax > amax) amax = f->amax;
        if (f->xmin < xmin) xmin = f->xmin;
        if (f->xmax > xmax) xmax = f->xmax;
        if (f->ymin < ymin) ymin = f->ymin;
        if (f->ymax > ymax) ymax = f->ymax;
        if (f->moved2 > m2) m2 = f->moved2;
    }
    out->bad = bad;
    out->lmax = lmax;
    out->coord_max = amax;
    out->xmin = xmin;
    out->xmax = xmax;
    out->ymin = ymin;
    out->ymax = ymax;
    out->kth = 0.0;
    out->moved = sqrt(m2);
    if (bad < n || k < 0) return NTS_OK;
    if (t.plan.bracket) {
        for (q = 0; q < SHARES; ++q) {
            below += cnt_below[q];
            inside += cnt_in[q];
        }
        if (below <= k && k < below + inside) {
            /* the sample's room holds the histograms now */
            out->kth = kth_in_bracket(scratch, n, cnt_in, k - (int)below, t.plan.lo, t.plan.hi,
                                      (int*)(void*)(scratch + n), run);
            return NTS_OK;
        }
    }
    for (q = 0; q < n; ++q) scratch[q] = ctx->seg[q].len;
    out->kth = nts_select_kth(scratch, n, k);
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
