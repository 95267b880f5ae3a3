/* The grid (cell_list.c, docs/model.md §9): square-ish cells over the plane,
 * the counting sort of entries by cell, the stencil a slave visits. */
#ifndef NTSCONTACT_CELLS_H
#define NTSCONTACT_CELLS_H

#include "parallel.h"
#include "segments.h"

/* Square-ish cells over the plane (docs/model.md §9). The frame is the grid's
 * own: coordinates relative to (x0, y0), wrapped into the box when periodic.
 * `scale` is a power of two with scale * (frame coordinate) in [0, 1], the
 * frame of the masters' float keys. */
typedef struct nts_cells {
    double x0, y0, hx, hy, inv_hx, inv_hy;
    double lx, ly;   /* the periodic box, 0 when open */
    double scale;
    int nx, ny;
    int periodic;
    int* cell_start; /* nx*ny + 1: the keys of cell c are [cell_start[c], cell_start[c+1]) */
    int cap_cells;
} nts_cells;

/* Where the grid puts a point: its frame coordinates and its cell. One
 * function for the masters' keys and for the slaves, so that both agree to
 * the bit. Points inside the box (the usual case) skip the wrap. */
typedef struct nts_cell_place {
    double x, y;
    int cx, cy, cell; /* column, row, and cy nx + cx */
} nts_cell_place;
static inline int nts_cells_clamp(double v, int n) {
    /* Compare in double before converting: (int) of a huge double is undefined. */
    if (!(v >= 0.0)) return 0;
    if (v >= (double)(n - 1)) return n - 1;
    return (int)v;
}
static inline NTS_ALWAYS_INLINE nts_cell_place nts_cells_place(const nts_cells* c, nts_vec2 p) {
    nts_cell_place q;
    q.x = p.x - c->x0;
    q.y = p.y - c->y0;
    if (c->periodic) {
        if (!(q.x >= 0.0 && q.x < c->lx)) q.x -= c->lx * floor(q.x / c->lx);
        if (!(q.y >= 0.0 && q.y < c->ly)) q.y -= c->ly * floor(q.y / c->ly);
    }
    q.cx = nts_cells_clamp(q.x * c->inv_hx, c->nx);
    q.cy = nts_cells_clamp(q.y * c->inv_hy, c->ny);
    q.cell = q.cy * c->nx + q.cx;
    return q;
}
/* Shape the grid: cells of side >= h over the box (periodic) or over the
 * bounding box of the summary (open); at most about 4 cells per surface entry
 * (h grows if needed, which the search allows). Room for at least
 * `min_cells` cells. NTS_OK or NTS_ENOMEM. */
int nts_cells_shape(nts_cells* c, const nts_scene* s, const seg_summary* sum, double h, int min_cells);
/* The longer side of the cells nts_cells_shape would make for side h. */
double nts_cells_side(const nts_scene* s, const seg_summary* sum, double h);
/* How many cells nts_cells_shape would make for side h. */
int nts_cells_count(const nts_scene* s, const seg_summary* sum, double h);
/* The first slice entry of slice u of `slices` equal slices of [0, n). */
static inline int nts_slice_begin(int n, int slices, int u) { return (int)((long long)n * u / slices); }
/* Sort entries by cell, first half: cell_start gets the cells' bounds and
 * hist (slices * cells ints) the first place of each slice's entries in each
 * cell, for the caller to place the entries e with cell_of[e] >= 0, each
 * slice in increasing e (in parallel): then every cell lists its entries in
 * increasing e, whatever the slices. With one slice hist is not used: the
 * first places are the cells' starts. */
/* At most this many slices: each costs a count per cell (the sort is a
 * small part of the work). */
enum { SORT_SLICES = 4 };
void nts_cells_offsets(nts_cells* c, const int* cell_of, int n, int* hist, int slices, const nts_run* run);
void nts_cells_free(nts_cells* c);

/* The masters a slave in one cell visits: the key ranges of the 3 x 3 cells
 * around it, each with the image shift (in the keys' scaled frame) that brings
 * its masters next to the slave. The three cells of a row are consecutive in
 * cell order, so a row is one range unless it wraps around the box. In a
 * periodic grid of fewer than 3 cells a side the same cell comes back with
 * another shift: a master may then be tried twice, which changes nothing
 * (the better of two equal candidates is the first). */
typedef struct nts_stencil {
    int n;
    int keys; /* in all the ranges */
    int begin[9], end[9];
    double shift_x[9], shift_y[9];
} nts_stencil;
void nts_cells_stencil(const nts_cells* c, int cell, nts_stencil* st);

#endif
