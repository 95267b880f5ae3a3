/* The segment data of every surface entry (docs/model.md §2), and the order
 * statistics of the segment lengths that set the default search radius (the
 * median segment, docs/model.md §9). */
#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "checks.h"
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

/* The length of segment i at positions `pos` (the scene's, or new ones being
 * checked), as the segment pass computes it (the same bits), or -1 outside
 * the supported range (scene.c: nts_scene_set_positions does not check it,
 * and 1/|t|^2 must not overflow). */
static inline double segment_length(const nts_scene* s, double lx, double ly, const nts_vec2* pos, int i, nts_vec2 p,
                                    nts_vec2* t) {
    double l2;
    *t = nts_box_diff(pos[s->surf_node[s->surf_next[i]]], p, lx, ly);
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
    const nts_vec2* pos;
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
        t->sample[i] = segment_length(t->s, t->s->lx, t->s->ly, t->pos, e, t->pos[t->s->surf_node[e]], &tt);
    }
}

static kth_plan kth_prepare(const nts_scene* s, const nts_vec2* pos, int k, double* sample, const nts_run* run) {
    const int n = s->surface_count;
    kth_plan plan;
    sample_task st;
    int rlo, rhi;
    plan.bracket = k >= 0 && n > 4 * NTS_SAMPLE;
    plan.lo = plan.hi = 0.0;
    if (!plan.bracket) return plan;
    st.s = s;
    st.pos = pos;
    st.sample = sample;
    nts_run_each(run, sample_lengths, NTS_SAMPLE, &st);
    /* The sample rank of the k-th, +- 256 (4 sqrt(NTS_SAMPLE)): an eighth of the lengths is kept. */
    rlo = (int)((double)k / (double)(n - 1) * (NTS_SAMPLE - 1)) - 256;
    rhi = rlo + 512;
    if (rlo < 0) rlo = 0;
    if (rhi > NTS_SAMPLE - 1) rhi = NTS_SAMPLE - 1;
    plan.lo = nts_select_kth(sample, NTS_SAMPLE, rlo);
    /* the selection leaves every value past rlo at least plan.lo: the
     * rhi-th of them all is the (rhi - rlo - 1)-th of those */
    assert(rlo < rhi && rhi < NTS_SAMPLE);
    plan.hi = nts_select_kth(sample + rlo + 1, NTS_SAMPLE - rlo - 1, rhi - rlo - 1);
    return plan;
}

/* The pass runs over SHARES fixed slices of the entries (in parallel, as
 * the backend hands them out), each keeping the lengths in the
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
                             const nts_run* run, int* from) {
    int cnt_bin[SHARES];
    int u, q, bin, below = 0;
    long long at = 0;
    bracket_task t;
    *from = 1;
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
    *from = (int)at;
    return nts_select_kth(v, (int)at, k - below);
}

/* Each segment is its own, so the loop runs in parallel; the reductions are
 * a minimum and maxima, exact whatever the threads. A segment of zero length
 * (possible after new positions) is reported, never divided by. */
/* What one share of the pass finds: its counts of the bracket, and its
 * part of the summary (combined by the caller in share order). */
typedef struct share_found {
    int below, in, first_bad, rejected;
    double lmax, amax, xmin, xmax, ymin, ymax, moved2;
    double lmin; /* checking new positions: the shortest segment */
} share_found;

typedef struct pass_task {
    nts_context* ctx;
    const nts_scene* s;
    const nts_vec2* pos; /* the positions the segments are computed at */
    double* scratch;
    kth_plan plan;
    share_found* found;
    const nts_vec2* since;
    double* area_perim; /* checking new positions: each loop's signed area (twice) and perimeter */
} pass_task;

/* One share's accumulators, in registers once inlined. */
typedef struct share_acc {
    double lm, am, x0, x1, y0, y1, m2;
    int cb, ci, first_bad;
} share_acc;

static void acc_init(share_acc* a, int n) {
    a->lm = a->am = a->m2 = 0.0;
    a->x0 = a->y0 = HUGE_VAL;
    a->x1 = a->y1 = -HUGE_VAL;
    a->cb = a->ci = 0;
    a->first_bad = n;
}

static void acc_store(const share_acc* a, share_found* f) {
    f->below = a->cb;
    f->in = a->ci;
    f->first_bad = a->first_bad;
    f->lmax = a->lm;
    f->amax = a->am;
    f->xmin = a->x0;
    f->xmax = a->x1;
    f->ymin = a->y0;
    f->ymax = a->y1;
    f->moved2 = a->m2;
    f->lmin = HUGE_VAL; /* the checking pass's, after */
}

/* A valid segment's part of the share's extremes: its length, its node's
 * coordinates (the largest magnitude, the bounding box). */
static inline NTS_ALWAYS_INLINE void acc_extremes(share_acc* a, nts_vec2 pp, double len) {
    const double m = fabs(pp.x) > fabs(pp.y) ? fabs(pp.x) : fabs(pp.y);
    a->lm = len > a->lm ? len : a->lm;
    a->am = m > a->am ? m : a->am;
    a->x0 = pp.x < a->x0 ? pp.x : a->x0;
    a->x1 = pp.x > a->x1 ? pp.x : a->x1;
    a->y0 = pp.y < a->y0 ? pp.y : a->y0;
    a->y1 = pp.y > a->y1 ? pp.y : a->y1;
}

/* Entry i's record, its node at pp and its segment tt of length len (-1:
 * outside the supported range), and its part of the share's summary; b is
 * the share's first entry (its kept lengths start there in `scratch`). */
static inline NTS_ALWAYS_INLINE void put_entry(const pass_task* t, double lx, double ly, int i, int b, nts_vec2 pp,
                                               nts_vec2 tt, double len, share_acc* a) {
    const nts_scene* s = t->s;
    seg_data* sd = &t->ctx->seg[i];
    sd->p = pp;
    sd->t = tt;
    if (t->since != NULL) {
        const double d2 = nts_length_sq(nts_box_diff(pp, t->since[i], lx, ly));
        a->m2 = d2 > a->m2 ? d2 : a->m2;
    }
    sd->prev = s->surf_prev[i];
    sd->next = s->surf_next[i];
    sd->node = s->surf_node[i];
    sd->body = s->surf_body[i];
    if (len < 0.0) {
        sd->len = -1.0;
        sd->inv_len2 = 0.0;
        if (i < a->first_bad) a->first_bad = i;
        return;
    }
    sd->len = len;
    sd->inv_len2 = 1.0 / nts_length_sq(tt);
    if (t->plan.bracket) { /* without a branch: 1 in 8 is kept, at random */
        t->scratch[b + a->ci] = len;
        a->cb += len < t->plan.lo;
        a->ci += (len >= t->plan.lo) & (len <= t->plan.hi);
    }
    acc_extremes(a, pp, len);
}

static void segments_pass(int begin, int end, int wi, void* p) {
    const pass_task* t = (const pass_task*)p;
    const nts_scene* s = t->s;
    const double lx = s->lx, ly = s->ly; /* (in registers across the records' stores) */
    const int n = s->surface_count;
    int q;
    (void)wi;
    for (q = begin; q < end; ++q) {
        const int b = share_begin(n, q), e = share_begin(n, q + 1);
        share_acc a;
        int i;
        acc_init(&a, n);
        for (i = b; i < e; ++i) {
            const nts_vec2 pp = t->pos[s->surf_node[i]];
            nts_vec2 tt;
            const double len = segment_length(s, lx, ly, t->pos, i, pp, &tt);
            put_entry(t, lx, ly, i, b, pp, tt, len, &a);
        }
        acc_store(&a, &t->found[q]);
        t->found[q].rejected = 0;
    }
}

/* The share holding entry i. */
static int share_of(int n, int i) {
    int q = (int)((long long)i * SHARES / n);
    while (q + 1 < SHARES && share_begin(n, q + 1) <= i) ++q;
    while (q > 0 && share_begin(n, q) > i) --q;
    return q;
}

/* Whether the checking pass sums loop l's area and perimeter as it goes: a
 * loop inside one share and stored in the caller's order, so that its sums
 * run in the order of the scene's check (check_loop). The others are summed
 * after the pass, from the records. */
static int loop_summed_inline(const nts_scene* s, int l) {
    const int n = s->surface_count, ls = s->loop_start[l], le = s->loop_start[l + 1];
    return !s->loop_reversed[l] && share_of(n, ls) == share_of(n, le - 1);
}

/* The pass checking new positions as it computes the segments: each share
 * loop piece by loop piece (a loop's entries inside the share), every entry
 * computed as the plain pass computes it and given, at once, the checks of
 * nts_scene_update_positions's loops (scene.c, check_loop): the spike
 * verdict at its first node, from the segment before it, which the piece's
 * previous entry has just computed, and the loop's shoelace and perimeter,
 * summed in check_loop's order. A loop inside the share has its first
 * node's verdict at its end, from its last segment and its first record;
 * a piece across the share's edge has the segment before it computed from
 * the positions (the same bits). The verdicts are or-ed: their order
 * decides nothing. The verdict only: a share that finds a fault says so,
 * and the caller leaves the error to the scene's own check. */
static void segments_pass_checked(int begin, int end, int wi, void* p) {
    const pass_task* t = (const pass_task*)p;
    const nts_scene* s = t->s;
    const double lx = s->lx, ly = s->ly; /* (in registers across the records' stores) */
    const nts_vec2* pos = t->pos;
    const int n = s->surface_count;
    int q;
    (void)wi;
    for (q = begin; q < end; ++q) {
        const int b = share_begin(n, q), e = share_begin(n, q + 1);
        int lo = 0, hi = s->loop_total - 1, l, i, bad = 0;
        double lmin = HUGE_VAL;
        share_acc a;
        acc_init(&a, n);
        if (b < e) {
            while (lo < hi) { /* the loop holding b: the last that starts at or before it */
                const int mid = lo + (hi - lo + 1) / 2;
                if (s->loop_start[mid] <= b) lo = mid;
                else hi = mid - 1;
            }
        }
        for (l = lo, i = b; i < e; ++l) {
            const int ls = s->loop_start[l], le = s->loop_start[l + 1], stop = le < e ? le : e;
            const int whole = ls >= b && le <= e; /* the loop inside the share */
            nts_vec2 cur = nts_v2(0.0, 0.0), tp = nts_v2(0.0, 0.0);
            double a2 = 0.0, perim = 0.0, lp = 0.0; /* (a zero segment before: no spike, nts_is_spike) */
            if (!whole) {
                const int ip = i > ls ? i - 1 : le - 1; /* (surf_prev: scene.c) */
                assert(s->surf_prev[i] == ip);
                lp = segment_length(s, lx, ly, pos, ip, pos[s->surf_node[ip]], &tp);
            }
            for (; i < stop; ++i) {
                const nts_vec2 pp = pos[s->surf_node[i]];
                nts_vec2 tt;
                const double len = segment_length(s, lx, ly, pos, i, pp, &tt);
                put_entry(t, lx, ly, i, b, pp, tt, len, &a);
                /* check_loop's spike verdict at the segment's first node; its
                 * degenerate verdicts follow from the lengths' extremes
                 * (nts_segments_compute) */
                bad |= nts_is_spike(tp, tt, lp, len);
                lmin = len < lmin ? len : lmin;
                /* check_loop's shoelace and perimeter, in its order (kept
                 * when the loop is inline: begun at its first entry) */
                nts_shoelace_step(&cur, &a2, tt);
                perim += len;
                tp = tt;
                lp = len;
            }
            if (whole) {
                /* its first node: from its last segment (tp) to its first */
                const seg_data* first = &t->ctx->seg[ls];
                assert(s->surf_prev[ls] == le - 1);
                bad |= nts_is_spike(tp, first->t, lp, first->len);
                /* (loop_summed_inline: the loop begins and ends in this share) */
                assert((s->loop_reversed[l] == 0) == (loop_summed_inline(s, l) != 0));
                if (!s->loop_reversed[l]) {
                    t->area_perim[2 * l] = a2;
                    t->area_perim[2 * l + 1] = perim;
                }
            } else {
                assert(!(ls >= b && loop_summed_inline(s, l)));
            }
        }
        acc_store(&a, &t->found[q]);
        t->found[q].rejected = bad;
        t->found[q].lmin = lmin;
    }
}

/* Whether some segment is degenerate by check_loop's verdict (checks.h), its
 * neighbours' lengths and its ends' coordinates read from the records. */
static int some_degenerate(const nts_context* ctx, int n) {
    const seg_data* seg = ctx->seg;
    int i;
    for (i = 0; i < n; ++i) {
        const seg_data* c = &seg[i];
        if (nts_segment_degenerate(c->len, seg[c->prev].len, seg[c->next].len, c->p, seg[c->next].p)) return 1;
    }
    return 0;
}

/* The area and perimeter of the loops the pass did not sum, in the caller's
 * order from the records: a reversed loop's input step k is the negated
 * segment of stored entry m - 1 - k (a difference and the minimum image are
 * odd), and negating every step negates every partial sum, which leaves each
 * cross product as it is; so the stored segments read backwards give the bits
 * check_loop sums. */
static void loops_summed_after(const nts_context* ctx, const nts_scene* s, double* area_perim) {
    int l;
    for (l = 0; l < s->loop_total; ++l) {
        const int ls = s->loop_start[l], m = s->loop_start[l + 1] - ls, rev = s->loop_reversed[l];
        nts_vec2 cur = nts_v2(0.0, 0.0);
        double a2 = 0.0, perim = 0.0;
        int k;
        if (loop_summed_inline(s, l)) continue;
        for (k = 0; k < m; ++k) {
            const seg_data* sd = &ctx->seg[ls + (rev ? m - 1 - k : k)];
            nts_shoelace_step(&cur, &a2, sd->t);
            perim += sd->len;
        }
        area_perim[2 * l] = a2;
        area_perim[2 * l + 1] = perim;
    }
}

/* The lengths and the extremes alone (nts_segments_lengths): each share's
 * entries as the pass computes them, no record written. */
typedef struct lengths_task {
    const nts_scene* s;
    double* lengths;
    share_found* found;
} lengths_task;

static void lengths_pass(int begin, int end, int wi, void* p) {
    const lengths_task* t = (const lengths_task*)p;
    const nts_scene* s = t->s;
    const double lx = s->lx, ly = s->ly;
    const int n = s->surface_count;
    int q;
    (void)wi;
    for (q = begin; q < end; ++q) {
        const int b = share_begin(n, q), e = share_begin(n, q + 1);
        share_acc a;
        int i;
        acc_init(&a, n);
        for (i = b; i < e; ++i) {
            const nts_vec2 pp = s->pos[s->surf_node[i]];
            nts_vec2 tt;
            const double len = segment_length(s, lx, ly, s->pos, i, pp, &tt);
            if (t->lengths != NULL) t->lengths[i] = len;
            if (len < 0.0) {
                if (i < a.first_bad) a.first_bad = i;
            } else {
                acc_extremes(&a, pp, len);
            }
        }
        acc_store(&a, &t->found[q]);
        t->found[q].rejected = 0;
    }
}

void nts_segments_lengths(const nts_scene* s, double* lengths, const nts_run* run, seg_summary* out) {
    share_found found[SHARES];
    lengths_task t;
    int q;
    t.s = s;
    t.lengths = lengths;
    t.found = found;
    nts_run_tasks(run, lengths_pass, SHARES, 1, &t);
    memset(out, 0, sizeof *out);
    out->bad = s->surface_count;
    out->xmin = out->ymin = HUGE_VAL;
    out->xmax = out->ymax = -HUGE_VAL;
    for (q = 0; q < SHARES; ++q) { /* as nts_segments_compute combines them */
        const share_found* f = &found[q];
        if (f->first_bad < out->bad) out->bad = f->first_bad;
        if (f->lmax > out->lmax) out->lmax = f->lmax;
        if (f->amax > out->coord_max) out->coord_max = f->amax;
        if (f->xmin < out->xmin) out->xmin = f->xmin;
        if (f->xmax > out->xmax) out->xmax = f->xmax;
        if (f->ymin < out->ymin) out->ymin = f->ymin;
        if (f->ymax > out->ymax) out->ymax = f->ymax;
    }
}

int nts_segments_compute(nts_context* ctx, const nts_scene* s, const nts_vec2* pos, int k, double* scratch,
                         const nts_vec2* since, double* area_perim, const nts_run* run, seg_summary* out) {
    const int n = s->surface_count;
    share_found found[SHARES];
    pass_task t;
    int cnt_below[SHARES], cnt_in[SHARES];
    int q, rc, bad = n, rejected = 0;
    long long below = 0, inside = 0;
    double lmax = 0.0, amax = 0.0, xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL, m2 = 0.0;
    assert(k < n);
    if ((rc = seg_reserve(ctx, n)) != NTS_OK) return rc;
    t.ctx = ctx;
    t.s = s;
    t.pos = pos != NULL ? pos : s->pos;
    t.scratch = scratch;
    t.plan = kth_prepare(s, t.pos, k, scratch + n, run);
    t.found = found;
    t.since = since;
    t.area_perim = area_perim;
    /* Whichever worker takes a share, the minima and maxima are exact,
     * whatever the order they are taken in. */
    nts_run_tasks(run, area_perim != NULL && n > 0 ? segments_pass_checked : segments_pass, SHARES, 1, &t);
    for (q = 0; q < SHARES; ++q) {
        const share_found* f = &found[q];
        cnt_below[q] = f->below;
        cnt_in[q] = f->in;
        rejected |= f->rejected;
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
    out->rejected = rejected;
    out->lmax = lmax;
    out->coord_max = amax;
    out->xmin = xmin;
    out->xmax = xmax;
    out->ymin = ymin;
    out->ymax = ymax;
    out->kth = 0.0;
    out->kth_from = 0;
    out->moved = sqrt(m2);
    if (area_perim != NULL && bad < n) rejected = out->rejected = 1; /* a length outside the range: degenerate */
    if (area_perim != NULL && !rejected) {
        /* The coordinates' range and the degenerate verdicts (check_point's
         * and check_loop's) from the extremes: every coordinate of a surface
         * node is in the maximum (a NaN or an infinity makes its segments
         * bad), and each segment's tolerance is at most the largest of 16
         * eps amax, 1e-12 (lmax + lmax) and 1e-100 (each a rounding of a
         * larger or equal operand), so a shortest segment above that bound
         * leaves none degenerate; below it, each is checked. */
        double lmin = HUGE_VAL, bound;
        for (q = 0; q < SHARES; ++q) lmin = found[q].lmin < lmin ? found[q].lmin : lmin;
        bound = nts_segment_tolerance(lmax, lmax, nts_v2(amax, amax), nts_v2(amax, amax));
        if (!(amax <= NTS_COORD_MAX) || (!(lmin > bound) && some_degenerate(ctx, n))) rejected = 1;
        out->rejected = rejected;
        if (!rejected) loops_summed_after(ctx, s, area_perim);
    }
    if (bad < n || rejected || k < 0) return NTS_OK;
    if (t.plan.bracket) {
        for (q = 0; q < SHARES; ++q) {
            below += cnt_below[q];
            inside += cnt_in[q];
        }
        if (below <= k && k < below + inside) {
            /* the sample's room holds the histograms now */
            out->kth = kth_in_bracket(scratch, n, cnt_in, k - (int)below, t.plan.lo, t.plan.hi,
                                      (int*)(void*)(scratch + n), run, &out->kth_from);
            return NTS_OK;
        }
    }
    for (q = 0; q < n; ++q) scratch[q] = ctx->seg[q].len;
    out->kth = nts_select_kth(scratch, n, k);
    out->kth_from = n;
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
