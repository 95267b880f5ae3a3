/* Cell list (Verlet buckets, docs/model.md §9): the grid, a counting sort of
 * entries by cell, and the 3 x 3 stencil of a cell. Buffers grow only, so
 * re-evaluating the same topology allocates nothing. */
#include <math.h>
#include <string.h>

#include "parallel.h"
#include "context.h"


void nts_cells_free(nts_cells* c) {
    nts_free(c->cell_start);
    memset(c, 0, sizeof *c);
}

/* The grid's dimensions and sides for side h (no allocation). */
static void cells_dims(nts_cells* c, const nts_scene* s, const seg_summary* sum, double h) {
    /* The grid never has more than about 4 cells per surface entry, whatever
     * the spread of the bodies: h only grows, which the search allows. */
    const double cap = 4.0 * (double)s->surface_count + 16.0;
    assert(h > 0.0);
    c->periodic = s->lx > 0.0;
    c->lx = s->lx;
    c->ly = s->ly;
    if (c->periodic) {
        double fx = floor(s->lx / h), fy = floor(s->ly / h);
        int nx = fx < 1.0 ? 1 : (fx > cap ? (int)cap : (int)fx);
        int ny = fy < 1.0 ? 1 : (fy > cap ? (int)cap : (int)fy);
        int guard;
        for (guard = 0; guard < 128 && (double)nx * (double)ny > cap; ++guard) {
            if (nx >= ny) nx = (nx + 1) / 2; else ny = (ny + 1) / 2;
        }
        c->nx = nx;
        c->ny = ny;
        c->x0 = c->y0 = 0.0;
        c->hx = s->lx / nx;
        c->hy = s->ly / ny;
    } else {
        double wx = sum->xmax - sum->xmin, wy = sum->ymax - sum->ymin, hh = h;
        if (hh < sqrt(wx * wy / cap)) hh = sqrt(wx * wy / cap);
        if (hh < wx / cap) hh = wx / cap;
        if (hh < wy / cap) hh = wy / cap;
        c->nx = (int)floor(wx / hh) + 1;
        c->ny = (int)floor(wy / hh) + 1;
        c->x0 = sum->xmin;
        c->y0 = sum->ymin;
        c->hx = c->hy = hh;
    }
}

int nts_cells_count(const nts_scene* s, const seg_summary* sum, double h) {
    nts_cells c;
    cells_dims(&c, s, sum, h);
    return c.nx * c.ny;
}

double nts_cells_side(const nts_scene* s, const seg_summary* sum, double h) {
    nts_cells c;
    cells_dims(&c, s, sum, h);
    return c.hx > c.hy ? c.hx : c.hy;
}

int nts_cells_shape(nts_cells* c, const nts_scene* s, const seg_summary* sum, double h, int min_cells) {
    double extent;
    int e, need;
    cells_dims(c, s, sum, h);
    extent = c->periodic ? (s->lx > s->ly ? s->lx : s->ly) : (c->nx > c->ny ? c->nx : c->ny) * c->hx;
    c->inv_hx = 1.0 / c->hx;
    c->inv_hy = 1.0 / c->hy;
    /* The keys' frame: a power of two, so scaling is exact. */
    (void)frexp(extent, &e);
    c->scale = ldexp(1.0, -e);
    need = c->nx * c->ny > min_cells ? c->nx * c->ny : min_cells;
    return nts_grow((void**)&c->cell_start, &c->cap_cells, need + 1, sizeof(int));
}

/* A counting sort's first half. Each slice of the entries counts its own
 * entries per cell (the slices in parallel); then the slices are laid out
 * cell by cell, in slice order within a cell, so that placing each slice's
 * entries in increasing order puts every cell's entries in increasing order,
 * exactly as one slice would. */
typedef struct offsets_task {
    nts_cells* c;
    const int* cell_of;
    int* hist;
    int* total;
    int n, slices, ncell;
} offsets_task;

/* Slice u's count of its entries in each cell. */
static void offsets_count(int begin, int end, int wi, void* p) {
    const offsets_task* t = (const offsets_task*)p;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u) {
        const int b = nts_slice_begin(t->n, t->slices, u), e = nts_slice_begin(t->n, t->slices, u + 1);
        int* h = t->hist + (size_t)u * (size_t)t->ncell;
        int j;
        memset(h, 0, sizeof(int) * (size_t)t->ncell);
        for (j = b; j < e; ++j)
            if (t->cell_of[j] >= 0) ++h[t->cell_of[j]];
    }
}

/* Block u of cells: its total over every slice. `S`: the slices, a
 * constant at the usual call (two threads: two slices), so that the loop
 * over them unrolls. */
static inline NTS_ALWAYS_INLINE void block_total(const offsets_task* t, int u, const int S) {
    const int c1 = nts_slice_begin(t->ncell, t->slices, u + 1);
    int sum = 0, cc, v;
    for (cc = nts_slice_begin(t->ncell, t->slices, u); cc < c1; ++cc)
        for (v = 0; v < S; ++v) sum += t->hist[(size_t)v * (size_t)t->ncell + cc];
    t->total[u] = sum;
}

static void offsets_total(int begin, int end, int wi, void* p) {
    const offsets_task* t = (const offsets_task*)p;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u) {
        if (t->slices == 2) block_total(t, u, 2);
        else block_total(t, u, t->slices);
    }
}

/* Block u of cells: each (cell, slice)'s first place, from the block's start. */
static inline NTS_ALWAYS_INLINE void block_place(const offsets_task* t, int u, const int S) {
    const int c1 = nts_slice_begin(t->ncell, t->slices, u + 1);
    int place = t->total[u], cc, v;
    for (cc = nts_slice_begin(t->ncell, t->slices, u); cc < c1; ++cc) {
        t->c->cell_start[cc] = place;
        for (v = 0; v < S; ++v) {
            int* h = t->hist + (size_t)v * (size_t)t->ncell + cc;
            const int k = *h;
            *h = place;
            place += k;
        }
    }
}

static void offsets_place(int begin, int end, int wi, void* p) {
    const offsets_task* t = (const offsets_task*)p;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u) {
        if (t->slices == 2) block_place(t, u, 2);
        else block_place(t, u, t->slices);
    }
}

void nts_cells_offsets(nts_cells* c, const int* cell_of, int n, int* hist, int slices, const nts_run* run) {
    const int ncell = c->nx * c->ny;
    int u, cell, at = 0;
    int total[SORT_SLICES];
    offsets_task t;
    if (slices == 1) { /* one slice: its places are the cells' starts, counted in cell_start + 1 */
        int* h = c->cell_start + 1;
        int j;
        memset(c->cell_start, 0, sizeof(int) * (size_t)(ncell + 1));
        for (j = 0; j < n; ++j)
            if (cell_of[j] >= 0) ++h[cell_of[j]];
        for (cell = 0; cell < ncell; ++cell) c->cell_start[cell + 1] += c->cell_start[cell];
        return;
    }
    assert(slices <= SORT_SLICES);
    t.c = c;
    t.cell_of = cell_of;
    t.hist = hist;
    t.total = total;
    t.n = n;
    t.slices = slices;
    t.ncell = ncell;
    nts_run_each(run, offsets_count, slices, &t);
    /* The prefix sum over (cell, slice), in parallel over `slices` blocks of
     * cells: each block's total, their prefix, then each block's places from
     * its start (the places are the same whatever the blocks). */
    nts_run_each(run, offsets_total, slices, &t);
    for (u = 0; u < slices; ++u) {
        const int k = total[u];
        total[u] = at;
        at += k;
    }
    nts_run_each(run, offsets_place, slices, &t);
    c->cell_start[ncell] = at;
}

void nts_cells_stencil(const nts_cells* c, int cell, nts_stencil* st) {
    const int nx = c->nx, ny = c->ny, cx = cell % nx, cy = cell / nx;
    const double sx = c->lx * c->scale, sy = c->ly * c->scale;
    int dy, dx;
    st->n = 0;
    st->keys = 0;
    for (dy = -1; dy <= 1; ++dy) {
        int yy = cy + dy, first = st->n;
        double shy = 0.0;
        if (yy < 0 || yy >= ny) {
            if (!c->periodic) continue;
            shy = yy < 0 ? -sy : sy;
            yy += yy < 0 ? ny : -ny;
        }
        for (dx = -1; dx <= 1; ++dx) {
            int xx = cx + dx, b, e;
            double shx = 0.0;
            if (xx < 0 || xx >= nx) {
                if (!c->periodic) continue;
                shx = xx < 0 ? -sx : sx;
                xx += xx < 0 ? nx : -nx;
            }
            b = c->cell_start[yy * nx + xx];
            e = c->cell_start[yy * nx + xx + 1];
            if (b == e) continue;
            st->keys += e - b;
            /* The next cell of the row with the same shift extends the range. */
            if (st->n > first && st->end[st->n - 1] == b && st->shift_x[st->n - 1] == shx) {
                st->end[st->n - 1] = e;
                continue;
            }
            st->begin[st->n] = b;
            st->end[st->n] = e;
            st->shift_x[st->n] = shx;
            st->shift_y[st->n] = shy;
            ++st->n;
        }
    }
}
