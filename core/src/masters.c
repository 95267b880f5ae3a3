/* What the local search reads of the masters: their hot records in cell
 * order, and the long masters listed in every cell their reach box overlaps
 * (docs/model.md §9); the order statistics that size the cells. */
#include <math.h>
#include <stdlib.h>

#include "stages.h"

/* The masters' hot records and keys in the order the search reads them. The
 * factor 1 + 1e-9 on the reach covers the round-off of the feature tests it
 * stands for, and `pad` that of the cell frame. With a cell list (`long_len` >
 * 0), a master whose reach length exceeds `long_len` (the cell side minus r)
 * is searched through the long lists instead: its key offers nothing, and
 * ctx->long_m keeps its real reach. A body with role "slave" offers nothing
 * at all. */
int nts_fill_hot(nts_context* ctx, const nts_scene* s, const int* order, double alpha, double r,
                 double long_len, double pad, int threads) {
    const nts_cells* cl = order != NULL ? &ctx->cells : NULL;
    int e, count = 0, rc;
    (void)threads; /* without OpenMP */
    ctx->long_count = 0;
    /* Every record is its own (in parallel); the long ones are then listed in
     * entry order, by one thread (the long lists' order is the result's). */
    NTS_PARALLEL_FOR(threads)
    for (e = 0; e < s->surface_count; ++e) {
        int j = order != NULL ? order[e] : e, b = s->surf_body[j];
        master_hot* m = &ctx->hot[e];
        master_key* k = &ctx->keys[e];
        double a = alpha_of_body(s, b, alpha), len = reach_length(ctx->seg, s, j, a);
        double reach = (r + len) * (1.0 + 1e-9) + pad;
        m->p = s->pos[s->surf_node[j]];
        m->t = ctx->seg[j].t;
        m->inv_len2 = ctx->seg[j].inv_len2;
        m->len = ctx->seg[j].len;
        m->entry = j;
        m->body = b;
        if (cl != NULL) {
            nts_cell_place q = nts_cells_place(cl, s, m->p);
            k->x = q.x;
            k->y = q.y;
            k->cell = q.cell;
        } else {
            k->x = m->p.x;
            k->y = m->p.y;
            k->cell = 0;
        }
        k->reach2 = reach * reach;
        k->body = b;
        /* A "slave" body, or a long master (listed below): nothing from the stencil. */
        if (s->body_role[b] == NTS_ROLE_SLAVE || (long_len > 0.0 && len > long_len)) k->reach2 = -1.0;
    }
    if (!(long_len > 0.0)) return NTS_OK;
    for (e = 0; e < s->surface_count; ++e)
        count += ctx->keys[e].reach2 == -1.0 && s->body_role[ctx->hot[e].body] != NTS_ROLE_SLAVE;
    /* Sized to the long masters, usually a few walls, not to every entry. */
    if (count > 0 && (rc = nts_grow((void**)&ctx->long_m, &ctx->long_m_cap, count, sizeof(long_master))) != NTS_OK)
        return rc;
    for (e = 0; e < s->surface_count; ++e) {
        const master_hot* m = &ctx->hot[e];
        if (ctx->keys[e].reach2 == -1.0 && s->body_role[m->body] != NTS_ROLE_SLAVE) {
            long_master* lm = &ctx->long_m[ctx->long_count++];
            double reach = (r + reach_length(ctx->seg, s, m->entry, alpha_of_body(s, m->body, alpha))) *
                           (1.0 + 1e-9) + pad; /* as above */
            lm->reach2 = reach * reach;
            lm->hot = e;
            lm->pad = 0;
        }
    }
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

/* Cells of one axis that the interval [lo, hi] (in the grid's frame) overlaps:
 * the first one and how many; periodic grids wrap, open ones clip. */
static int cell_span(double lo, double hi, double h, int n, int periodic, int* first) {
    double flo = floor(lo / h), fhi = floor(hi / h);
    if (periodic) {
        if (!(fhi - flo + 1.0 < (double)n)) {
            *first = 0;
            return n;
        }
        *first = (int)(flo - (double)n * floor(flo / (double)n));
        return (int)(fhi - flo) + 1;
    }
    if (flo < 0.0) flo = 0.0;
    if (fhi > (double)(n - 1)) fhi = (double)(n - 1);
    if (fhi < flo) return 0;
    *first = (int)flo;
    return (int)(fhi - flo) + 1;
}

/* The reach box of long master m, as cells: the corner curve lies in the
 * triangle Xa X_j Xb and the flat part on segment j, so every feature lies
 * within r of bbox(X_j, X_j + t_j, X_j - alpha t_{j-1}); `pad` covers the
 * round-off of binning. Returns the number of cells; *cx0, *ncx (*cy0, *ncy). */
static long long long_box(const nts_context* ctx, const nts_scene* s, const long_master* lm, double alpha, double r,
                          double pad, int* cx0, int* ncx, int* cy0, int* ncy) {
    const nts_cells* cl = &ctx->cells;
    const master_hot* m = &ctx->hot[lm->hot];
    const master_key* k = &ctx->keys[lm->hot];
    nts_vec2 tp = ctx->seg[s->surf_prev[m->entry]].t, t = m->t;
    double x = k->x, y = k->y, R = r * (1.0 + 1e-9) + pad; /* the frame nts_cells_build bins in */
    double xlo, xhi, ylo, yhi, a = alpha_of_body(s, m->body, alpha);
    xlo = fmin(fmin(0.0, t.x), -a * tp.x);
    xhi = fmax(fmax(0.0, t.x), -a * tp.x);
    ylo = fmin(fmin(0.0, t.y), -a * tp.y);
    yhi = fmax(fmax(0.0, t.y), -a * tp.y);
    *ncx = cell_span(x + xlo - R, x + xhi + R, cl->hx, cl->nx, cl->periodic, cx0);
    *ncy = cell_span(y + ylo - R, y + yhi + R, cl->hy, cl->ny, cl->periodic, cy0);
    return (long long)*ncx * (long long)*ncy;
}

/* List every long master in every cell its reach box overlaps (CSR by cell,
 * masters in entry order within a cell). Returns NTS_OK, NTS_ENOMEM, or
 * NTS_ELIMIT when the lists would exceed `budget` entries (the caller then
 * coarsens the grid). */
int nts_build_long_lists(nts_context* ctx, const nts_scene* s, double alpha, double r, double pad, long long budget) {
    const nts_cells* cl = &ctx->cells;
    int ncell = cl->nx * cl->ny, i, rc;
    long long total = 0;
    if ((rc = nts_grow((void**)&ctx->long_start, &ctx->long_start_cap, ncell + 1, sizeof(int))) != NTS_OK) return rc;
    memset(ctx->long_start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (i = 0; i < ctx->long_count; ++i) {
        int cx0, ncx, cy0, ncy;
        total += long_box(ctx, s, &ctx->long_m[i], alpha, r, pad, &cx0, &ncx, &cy0, &ncy);
        if (total > budget) return NTS_ELIMIT;
    }
    if ((rc = nts_grow((void**)&ctx->long_items, &ctx->long_items_cap, (int)total, sizeof(int))) != NTS_OK) return rc;
    for (i = 0; i < ctx->long_count; ++i) { /* counts */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(ctx, s, &ctx->long_m[i], alpha, r, pad, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a) ++ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx + 1];
    }
    for (i = 0; i < ncell; ++i) ctx->long_start[i + 1] += ctx->long_start[i];
    for (i = 0; i < ctx->long_count; ++i) { /* fill, in entry order */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(ctx, s, &ctx->long_m[i], alpha, r, pad, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a) ctx->long_items[ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx]++] = i;
    }
    for (i = ncell; i > 0; --i) ctx->long_start[i] = ctx->long_start[i - 1];
    ctx->long_start[0] = 0;
    return NTS_OK;
}

