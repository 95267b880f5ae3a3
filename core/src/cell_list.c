/* Cell list (Verlet buckets) over the surface nodes (docs/model.md
 * §9): cells of side >= h, built in O(N) with a counting sort; buffers grow
 * only, so re-evaluating the same topology allocates nothing. */
#include <string.h>

#include "internal.h"

void nts_cells_free(nts_cells* c) {
    nts_free(c->cell_start);
    nts_free(c->items);
    nts_free(c->rank);
    memset(c, 0, sizeof *c);
}

int nts_cells_build(nts_cells* c, const nts_scene* s, double h, int threads) {
    const int n = s->surface_count;
    /* The grid never has more than about 4 cells per surface node, whatever the
     * spread of the bodies: h only grows, which the search allows (h >= L_max + r). */
    const double cap = 4.0 * (double)n + 16.0;
    int i, ncell, rc;
    (void)threads; /* without OpenMP */
    assert(h > 0.0);
    c->periodic = s->lx > 0.0;
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
        double xmin, xmax, ymin, ymax, wx, wy, hh = h;
        nts_vec2 p = s->pos[s->surf_node[0]];
        xmin = xmax = p.x;
        ymin = ymax = p.y;
        for (i = 1; i < n; ++i) {
            p = s->pos[s->surf_node[i]];
            if (p.x < xmin) xmin = p.x;
            if (p.x > xmax) xmax = p.x;
            if (p.y < ymin) ymin = p.y;
            if (p.y > ymax) ymax = p.y;
        }
        wx = xmax - xmin;
        wy = ymax - ymin;
        if (hh < sqrt(wx * wy / cap)) hh = sqrt(wx * wy / cap);
        if (hh < wx / cap) hh = wx / cap;
        if (hh < wy / cap) hh = wy / cap;
        c->nx = (int)floor(wx / hh) + 1;
        c->ny = (int)floor(wy / hh) + 1;
        c->x0 = xmin;
        c->y0 = ymin;
        c->hx = c->hy = hh;
    }
    ncell = c->nx * c->ny;
    if ((rc = nts_grow((void**)&c->cell_start, &c->cap_cells, ncell + 1, sizeof(int))) != NTS_OK) return rc;
    if (n > c->cap_items) {
        int cap_items = c->cap_items;
        if ((rc = nts_grow((void**)&c->items, &cap_items, n, sizeof(int))) != NTS_OK) return rc;
        cap_items = c->cap_items;
        if ((rc = nts_grow((void**)&c->rank, &cap_items, n, sizeof(int))) != NTS_OK) return rc;
        c->cap_items = cap_items;
    }
    memset(c->cell_start, 0, sizeof(int) * (size_t)(ncell + 1));
    /* The cell of each entry (in parallel: each is its own), then the counts. */
    NTS_PARALLEL_FOR(threads)
    for (i = 0; i < n; ++i) c->rank[i] = nts_cells_place(c, s, s->pos[s->surf_node[i]]).cell;
    for (i = 0; i < n; ++i) ++c->cell_start[c->rank[i] + 1];
    /* Counting sort: prefix sums, then place entries in increasing order, so each
     * cell lists its entries in ascending order (determinism); each entry's
     * cell is replaced by its place. */
    for (i = 0; i < ncell; ++i) c->cell_start[i + 1] += c->cell_start[i];
    for (i = 0; i < n; ++i) {
        const int at = c->cell_start[c->rank[i]]++;
        c->items[at] = i;
        c->rank[i] = at;
    }
    for (i = ncell; i > 0; --i) c->cell_start[i] = c->cell_start[i - 1];
    c->cell_start[0] = 0;
    return NTS_OK;
}

void nts_cells_stencil(const nts_cells* c, int cell, nts_stencil* st) {
    int cx = cell % c->nx, cy = cell / c->nx, dx, dy;
    st->n = 0;
    if (!c->periodic || (c->nx >= 3 && c->ny >= 3)) {
        /* No repeats: wrap (periodic) or clip (open) each neighbour once. */
        for (dy = -1; dy <= 1; ++dy) {
            int y = cy + dy;
            if (y < 0 || y >= c->ny) {
                if (!c->periodic) continue;
                y += y < 0 ? c->ny : -c->ny;
            }
            for (dx = -1; dx <= 1; ++dx) {
                int x = cx + dx;
                if (x < 0 || x >= c->nx) {
                    if (!c->periodic) continue;
                    x += x < 0 ? c->nx : -c->nx;
                }
                st->cell[st->n] = y * c->nx + x;
                st->ox[st->n] = dx;
                st->oy[st->n] = dy;
                ++st->n;
            }
        }
        return;
    }
    for (dy = -1; dy <= 1; ++dy) {
        int y = cy + dy, dup, k;
        if (c->periodic) y = ((y % c->ny) + c->ny) % c->ny;
        if (y < 0 || y >= c->ny) continue;
        for (dup = 0, k = -1; k < dy; ++k) {
            int yk = cy + k;
            if (c->periodic) yk = ((yk % c->ny) + c->ny) % c->ny;
            dup |= (yk == y);
        }
        if (dup) continue;
        for (dx = -1; dx <= 1; ++dx) {
            int x = cx + dx, dupx = 0, q;
            if (c->periodic) x = ((x % c->nx) + c->nx) % c->nx;
            if (x < 0 || x >= c->nx) continue;
            for (q = -1; q < dx; ++q) {
                int xq = cx + q;
                if (c->periodic) xq = ((xq % c->nx) + c->nx) % c->nx;
                dupx |= (xq == x);
            }
            if (dupx) continue;
            st->cell[st->n] = y * c->nx + x;
            st->ox[st->n] = dx;
            st->oy[st->n] = dy;
            ++st->n;
        }
    }
}
