/* The masters (masters.c, docs/model.md §9): their keys in cell order for
 * the search's first pass, the long masters' lists, and the reach of a
 * master, which sizes both. */
#ifndef NTSCONTACT_MASTERS_H
#define NTSCONTACT_MASTERS_H

#include "cells.h"

/* The masters that the stencil offers, in cell order, as the first pass of
 * the search reads them: float positions in the scaled frame and the reach
 * squared, widened to cover every round-off on the way (masters.c), so that
 * the float test never drops a master that the exact test could keep. Struct
 * of arrays, KEY_PAD elements past the end that no range reaches, so that
 * the last range of the arrays can be read 8 at a time. 16 bytes a master. */
enum { KEY_PAD = 8 };
typedef struct master_keys {
    float* x;
    float* y;
    float* reach2;
    int* entry; /* a body's entries are consecutive: its range tells own from other */
    int count, cap;
    void* block;
} master_keys;

/* A master that reaches farther than the cell side allows (a long wall),
 * searched through the long lists of the cells its reach box overlaps: the
 * exact test is in double, around X_j. */
typedef struct long_master {
    double reach2;
    int entry;
    int pad;
} long_master;

/* The alpha that shapes body b's surface: its own, or the options' (docs/model.md §10). */
static inline double alpha_of_body(const nts_scene* s, int b, double alpha) {
    return s->body_alpha[b] >= 0.0 ? s->body_alpha[b] : alpha;
}

/* A reach length plus the search radius, with the allowances of every test
 * that stands for the exact ones: the factor 1 + 1e-9 covers the round-off of
 * the feature tests, `pad` that of the frame the distance is taken in. */
static inline double reach_allowed(double reach, double r, double pad) { return (reach + r) * (1.0 + 1e-9) + pad; }

/* The reach of master j around X_j: its features lie within r + max(|t_j|,
 * alpha |t_{j-1}|) of X_j (the flat part of segment j within |t_j| + r, the
 * corner within r + alpha max(|t_{j-1}|, |t_j|), the vertex within r), with
 * alpha the master body's; `ext` the contact surfaces' end extension (the
 * flat part of an end segment reaches ext |t_j| past its ends,
 * docs/model.md §13; 0 without surfaces, and then the same bits). */
static inline double reach_at_node(const seg_data* seg, int j, double alpha, double ext) {
    double lp = alpha * seg[seg[j].prev].len, lj = (1.0 + ext) * seg[j].len;
    return lj > lp ? lj : lp;
}

/* The reach of master j around the middle M_j = X_j + t_j / 2 of its segment,
 * which the cells bin: the flat part lies within (1/2 + ext) |t_j| of M_j,
 * and the corner in the triangle X_j, X_j + alpha t_j, X_j - alpha t_{j-1},
 * within |t_j| / 2 + alpha |t_{j-1}|; so every feature within r of a slave
 * puts the slave within r + this of M_j. Smaller than the reach around X_j,
 * so the cells are smaller and fewer masters pass the first test. */
static inline double reach_at_middle(const seg_data* seg, int j, double alpha, double ext) {
    return (0.5 + ext) * seg[j].len + alpha * seg[seg[j].prev].len;
}

/* Bin the masters that reach at most `hcell` (with their round-off
 * allowance `pad`; every master when hcell = 0) and fill their keys in cell order; list the others in the
 * long lists of the cells they reach (`ext`: the surfaces' end extension,
 * reach_at_node). `min_cells`: the room to keep for the
 * cells' buffers. NTS_OK, NTS_ENOMEM, or NTS_ELIMIT when
 * the long lists would exceed `budget` entries (the caller coarsens). */
int nts_masters_build(nts_context* ctx, const nts_scene* s, double alpha, double ext, double r, double hcell,
                      double pad, long long budget, int min_cells, const nts_run* run);

#endif
