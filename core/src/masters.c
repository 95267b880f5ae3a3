/* What the local search reads of the masters (docs/model.md §9): the keys
 * of the masters binned by the middle of their segment, in cell order, and
 * the long masters listed in every cell their reach box overlaps. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "context.h"

/* The float keys' own round-off, in the scaled frame (coordinates in [0, 1],
 * a slave shifted by at most one box, so |values| <= 2): converting the
 * slave and the master to float and subtracting costs at most 2^-21 per
 * axis, so at most 2^-20 on the distance; the squares and their sum in float
 * lose at most 3 * 2^-24 relative, which the factor 1 + 2^-20 on the reach
 * squared covers with room to spare. */
#define KEY_SLACK 9.5367431640625e-07 /* 2^-20 */
/* How far ahead the binning asks for the lines of a key it will write. */
enum { KEY_AHEAD = 48 };

static int keys_reserve(master_keys* k, int count) {
    const int need = count + KEY_PAD;
    char* p;
    if (need <= k->cap) return NTS_OK;
    p = (char*)nts_alloc((size_t)need * (3 * sizeof(float) + sizeof(int)));
    if (p == NULL) return NTS_ENOMEM;
    nts_free(k->block);
    k->block = p;
    k->x = (float*)(void*)p;
    k->y = k->x + need;
    k->reach2 = k->y + need;
    k->entry = (int*)(void*)(k->reach2 + need);
    k->cap = need;
    return NTS_OK;
}

/* The reach box of long master j, as cells: the corner curve lies in the
 * triangle Xa X_j Xb and the flat part on segment j, so every feature lies
 * within r of bbox(X_j, X_j + t_j, X_j - alpha t_{j-1}); `R` is r with the
 * round-off allowances. Returns the number of cells; *cx0, *ncx (*cy0, *ncy). */
static int cell_span(double lo, double hi, double inv_h, int n, int periodic, int* first) {
    double flo = floor(lo * inv_h), fhi = floor(hi * inv_h);
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

static long long long_box(const nts_context* ctx, const nts_scene* s, int j, double alpha, double ext, double R,
                          int* cx0, int* ncx, int* cy0, int* ncy) {
    const nts_cells* cl = &ctx->cells;
    const seg_data* m = &ctx->seg[j];
    const nts_vec2 tp = ctx->seg[m->prev].t, t = m->t;
    const nts_cell_place q = nts_cells_place(cl, m->p);
    const double a = alpha_of_body(s, m->body, alpha);
    /* the flat part from X_j - ext t_j to X_j + (1 + ext) t_j (ext 0: from X_j to X_{j+1}) */
    const double x0 = -ext * t.x, x1 = (1.0 + ext) * t.x, y0 = -ext * t.y, y1 = (1.0 + ext) * t.y;
    const double xlo = fmin(fmin(x0, x1), -a * tp.x), xhi = fmax(fmax(x0, x1), -a * tp.x);
    const double ylo = fmin(fmin(y0, y1), -a * tp.y), yhi = fmax(fmax(y0, y1), -a * tp.y);
    *ncx = cell_span(q.x + xlo - R, q.x + xhi + R, cl->inv_hx, cl->nx, cl->periodic, cx0);
    *ncy = cell_span(q.y + ylo - R, q.y + yhi + R, cl->inv_hy, cl->ny, cl->periodic, cy0);
    return (long long)*ncx * (long long)*ncy;
}

/* List every long master in every cell its reach box overlaps (CSR by cell,
 * masters in entry order within a cell). */
static int build_long_lists(nts_context* ctx, const nts_scene* s, double alpha, double ext, double R,
                            long long budget) {
    const nts_cells* cl = &ctx->cells;
    const int ncell = cl->nx * cl->ny;
    long long total = 0;
    int i, rc;
    if ((rc = nts_grow((void**)&ctx->long_start, &ctx->long_start_cap, ncell + 1, sizeof(int))) != NTS_OK)
        return rc;
    memset(ctx->long_start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (i = 0; i < ctx->long_count; ++i) {
        int cx0, ncx, cy0, ncy;
        total += long_box(ctx, s, ctx->long_m[i].entry, alpha, ext, R, &cx0, &ncx, &cy0, &ncy);
        if (total > budget) return NTS_ELIMIT;
    }
    if ((rc = nts_grow((void**)&ctx->long_items, &ctx->long_items_cap, (int)total, sizeof(int))) != NTS_OK) return rc;
    for (i = 0; i < ctx->long_count; ++i) { /* counts */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(ctx, s, ctx->long_m[i].entry, alpha, ext, R, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a) ++ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx + 1];
    }
    for (i = 0; i < ncell; ++i) ctx->long_start[i + 1] += ctx->long_start[i];
    for (i = 0; i < ctx->long_count; ++i) { /* fill, in entry order */
        int cx0, ncx, cy0, ncy, a, b;
        long_box(ctx, s, ctx->long_m[i].entry, alpha, ext, R, &cx0, &ncx, &cy0, &ncy);
        for (b = 0; b < ncy; ++b)
            for (a = 0; a < ncx; ++a)
                ctx->long_items[ctx->long_start[((cy0 + b) % cl->ny) * cl->nx + (cx0 + a) % cl->nx]++] = i;
    }
    for (i = ncell; i > 0; --i) ctx->long_start[i] = ctx->long_start[i - 1];
    ctx->long_start[0] = 0;
    return NTS_OK;
}

typedef struct bin_task {
    nts_context* ctx;
    const nts_scene* s;
    int* cell_of;
    double alpha, ext, r, pad, fits;
    long long nlong;
    int slices, ncell;
} bin_task;

/* Each master's cell: -1 when it offers nothing (its body, or its segment
 * off the contact surface, docs/model.md §13), -2 when its reach
 * does not fit a cell (a long master, counted). */
static void masters_bin(int begin, int end, int wi, void* p) {
    bin_task* t = (bin_task*)p;
    const nts_context* ctx = t->ctx;
    const nts_scene* s = t->s;
    const nts_cells* cl = &ctx->cells;
    const seg_data* seg = ctx->seg;
    int* cell_of = t->cell_of;
    /* the task's fields in locals: the loop keeps them in registers */
    const double alpha = t->alpha, ext = t->ext, r = t->r, pad = t->pad, fits = t->fits;
    int e, nlong = 0;
    (void)wi;
    for (e = begin; e < end; ++e) {
        const seg_data* m = &seg[e];
        const int b = m->body;
        if (s->body_role[b] == NTS_ROLE_SLAVE || !nts_on_surface(s, e)) { /* offers nothing */
            cell_of[e] = -1;
            continue;
        }
        if (fits > 0.0 && !(reach_allowed(reach_at_middle(seg, e, alpha_of_body(s, b, alpha), ext), r, pad) <= fits)) {
            cell_of[e] = -2;
            ++nlong;
            continue;
        }
        cell_of[e] = nts_cells_place(cl, nts_mul_add(m->p, 0.5, m->t)).cell;
    }
    if (nlong > 0) nts_atomic_add_ll(&t->nlong, nlong);
}

/* Slice u places its masters' keys, computed from the entries in entry
 * order (a sequential read, scattered writes). */
static void masters_place(int begin, int end, int wi, void* p) {
    const bin_task* t = (const bin_task*)p;
    nts_context* ctx = t->ctx;
    const nts_scene* s = t->s;
    const nts_cells* cl = &ctx->cells;
    master_keys* k = &ctx->keys;
    const int n = s->surface_count, slices = t->slices;
    const double scale = cl->scale, alpha = t->alpha, ext = t->ext, r = t->r, pad = t->pad;
    const int* cell_of = t->cell_of;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u) {
        int* next = slices > 1 ? ctx->hist + (size_t)u * (size_t)t->ncell : cl->cell_start;
        const int last = nts_slice_begin(n, slices, u + 1);
        int j;
        for (j = nts_slice_begin(n, slices, u); j < last; ++j) {
            const int cell = cell_of[j];
            const seg_data* m = &ctx->seg[j];
            nts_cell_place q;
            double R, Rs;
            int at;
            if (j + KEY_AHEAD < last && cell_of[j + KEY_AHEAD] >= 0) {
                /* Where a later master's key goes: four scattered lines. */
                const int ahead = next[cell_of[j + KEY_AHEAD]];
                NTS_PREFETCH_W(&k->x[ahead]);
                NTS_PREFETCH_W(&k->y[ahead]);
                NTS_PREFETCH_W(&k->reach2[ahead]);
                NTS_PREFETCH_W(&k->entry[ahead]);
            }
            if (cell < 0) continue;
            at = next[cell]++;
            q = nts_cells_place(cl, nts_mul_add(m->p, 0.5, m->t));
            R = reach_allowed(reach_at_middle(ctx->seg, j, alpha_of_body(s, m->body, alpha), ext), r, pad);
            Rs = R * scale + KEY_SLACK;
            k->x[at] = (float)(q.x * scale);
            k->y[at] = (float)(q.y * scale);
            k->reach2[at] = (float)(Rs * Rs * (1.0 + KEY_SLACK));
            k->entry[at] = j;
        }
    }
}

int nts_masters_build(nts_context* ctx, const nts_scene* s, double alpha, double ext, double r, double hcell,
                      double pad, long long budget, int min_cells, const nts_run* run) {
    nts_cells* cl = &ctx->cells;
    const int n = s->surface_count, ncell = cl->nx * cl->ny;
    int e, nlong, count, rc, slices;
    master_keys* k = &ctx->keys;
    bin_task t;
    t.ctx = ctx;
    t.s = s;
    t.cell_of = ctx->scratch;
    t.alpha = alpha;
    t.ext = ext;
    t.r = r;
    t.pad = pad;
    /* A master is binned when its reach fits a cell with room for the
     * round-off of binning (a cell's side is at least hcell); hcell = 0: all
     * fit, the caller knows. */
    t.fits = hcell * (1.0 - 1e-12);
    t.nlong = 0;
    t.ncell = ncell;
    nts_run_each(run, masters_bin, n, &t);
    nlong = (int)t.nlong;
    /* Sorted by cell. Slices of the counting sort: one per worker, at most
     * SORT_SLICES (each costs a count per cell; the sort is a small part of
     * the work). */
    slices = run->workers < SORT_SLICES ? run->workers : SORT_SLICES;
    t.slices = slices;
    if (slices > 1 && (rc = nts_grow((void**)&ctx->hist, &ctx->hist_cap,
                                     slices * (ncell > min_cells ? ncell : min_cells), sizeof(int))) != NTS_OK)
        return rc;
    nts_cells_offsets(cl, t.cell_of, n, ctx->hist, slices, run);
    count = cl->cell_start[ncell];
    if ((rc = keys_reserve(k, count)) != NTS_OK) return rc;
    k->count = count;
    nts_run_each(run, masters_place, slices, &t);
    if (slices == 1) { /* the starts were moved to the ends: back one cell */
        for (e = ncell; e > 0; --e) cl->cell_start[e] = cl->cell_start[e - 1];
        cl->cell_start[0] = 0;
    }
    for (e = count; e < count + KEY_PAD; ++e) { /* read 4 at a time, never kept */
        k->x[e] = k->y[e] = 0.0f;
        k->reach2[e] = -1.0f;
        k->entry[e] = -1;
    }
    ctx->long_count = 0;
    if (nlong == 0) return NTS_OK;
    if ((rc = nts_grow((void**)&ctx->long_m, &ctx->long_m_cap, nlong, sizeof(long_master))) != NTS_OK) return rc;
    for (e = 0; e < n; ++e) {
        if (t.cell_of[e] == -2) {
            long_master* lm = &ctx->long_m[ctx->long_count++];
            const double R =
                reach_allowed(reach_at_node(ctx->seg, e, alpha_of_body(s, ctx->seg[e].body, alpha), ext), r, pad);
            lm->reach2 = R * R;
            lm->entry = e;
            lm->pad = 0;
        }
    }
    return build_long_lists(ctx, s, alpha, ext, reach_allowed(0.0, r, pad), budget);
}
