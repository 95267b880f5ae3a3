/* The "before" core for the benchmarks: evaluate.c and cell_list.c exactly as
 * they were at commit 6027dec (the first core), with the cell list renamed
 * nts_cells0 so it cannot clash with the current internal.h, and the same
 * phase-timing hook as the current core. nts_bench_before links these instead
 * of core/src/evaluate.c and core/src/cell_list.c; everything else (scene,
 * geometry, solvers) is the current core, so the comparison isolates the
 * search and evaluation changes. */
#ifndef NTS_BENCH_BASELINE_H
#define NTS_BENCH_BASELINE_H

#include "../../core/src/internal.h"

typedef struct nts_cells0 {
    double x0, y0, hx, hy;
    int nx, ny;
    int periodic;
    int* cell_start; /* nx*ny + 1 */
    int* items;      /* surface entries sorted by cell */
    int* entry_cell; /* surface entry -> cell */
    int cap_cells, cap_items;
} nts_cells0;
int nts_cells0_build(nts_cells0* c, const nts_scene* s, double h);
void nts_cells0_free(nts_cells0* c);
int nts_cells0_stencil(const nts_cells0* c, int cell, int out[9]);

void nts_context_phase_times(const nts_context* ctx, double out[4]);

#endif
