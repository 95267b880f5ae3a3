/* The whole scene's frame (distributed.h: nts_frame), found across the
 * ranks: the extremes reduced, the median segment exactly. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"


static uint64_t bits_of(double v) {
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

static double double_of(uint64_t u) {
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* The k-th smallest (0-based) of every rank's values v[0..n), exactly: the
 * values are positive doubles, ordered as their bits, so eight rounds each
 * fix the next byte of the answer's bits, from a histogram of that byte
 * among the values that agree with the bytes found so far, summed across
 * the ranks (v is reordered: those candidates are kept in front). */
static double kth_across(MPI_Comm comm, double* v, int n, long long k) {
    uint64_t prefix = 0;
    long long h[256], sum[256];
    int round, live = n, i, c;
    for (round = 0; round < 8; ++round) {
        const int shift = 56 - 8 * round;
        memset(h, 0, sizeof h);
        for (i = 0; i < live; ++i) h[(bits_of(v[i]) >> shift) & 255u]++;
        MPI_Allreduce(h, sum, 256, MPI_LONG_LONG, MPI_SUM, comm);
        for (c = 0; c < 255 && k >= sum[c]; ++c) k -= sum[c];
        prefix |= (uint64_t)c << shift;
        { /* keep the candidates that share the bytes so far */
            int kept = 0;
            const uint64_t mask = ~(uint64_t)0 << shift;
            for (i = 0; i < live; ++i)
                if ((bits_of(v[i]) & mask) == prefix) v[kept++] = v[i];
            live = kept;
        }
    }
    return double_of(prefix);
}

/* The whole scene's frame: its segments' extremes reduced, and the median
 * (the k-th smallest of every rank's lengths, exactly: the lengths are
 * positive doubles, ordered as their bits, so 8 rounds of counting, a byte
 * each, find it: kth_across). */
int ntsm_frame_find(ntsm_scene* m, const nts_options* opt, nts_frame* f, nts_error* err) {
    const int n = m->own != NULL ? nts_scene_surface_node_count(m->own) : 0;
    double* len = (double*)malloc(sizeof(double) * (size_t)(n + 1));
    double ext[7], red[7];
    int rc = len ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
    nts_frame mine;
    /* This rank's segments' extremes and lengths alone: no median of its
     * own (the whole's is found across the ranks below) and no cell size
     * (the part's evaluation sets it), which a radius given and the brute
     * force search spare (nts_scene_frame). */
    nts_options fo = *opt;
    fo.search_radius = 0.0;
    fo.search = NTS_SEARCH_BRUTE_FORCE;
    memset(&mine, 0, sizeof mine);
    if (rc == NTS_OK && n > 0 && (rc = nts_scene_frame(m->own_ctx, m->own, &fo, &mine, len, err)) != NTS_OK)
        ntsm_global_body(err, m->ids, m->count);
    if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, err)) != NTS_OK) {
        free(len);
        return rc;
    }
    if (n == 0) {
        mine.xmin = mine.ymin = HUGE_VAL;
        mine.xmax = mine.ymax = -HUGE_VAL;
    }
    ext[0] = mine.lmax;
    ext[1] = mine.coord_max;
    ext[2] = -mine.xmin;
    ext[3] = mine.xmax;
    ext[4] = -mine.ymin;
    ext[5] = mine.ymax;
    ext[6] = mine.surface_ends;
    MPI_Allreduce(ext, red, 7, MPI_DOUBLE, MPI_MAX, m->comm);
    memset(f, 0, sizeof *f);
    /* friction's switch on the whole: each body counted by its owner */
    MPI_Allreduce(mine.rubbing, f->rubbing, 4, MPI_LONG_LONG, MPI_SUM, m->comm);
    f->lmax = red[0];
    f->coord_max = red[1];
    f->xmin = -red[2];
    f->xmax = red[3];
    f->ymin = -red[4];
    f->ymax = red[5];
    f->surface_ends = red[6] > 0.0;
    f->cell_size = -1.0;
    f->surface_nodes = (int)m->entry_off[m->bodies];
    if (opt->search_radius < 0.0 && f->surface_nodes > 0)
        f->median = kth_across(m->comm, len, n, (long long)(f->surface_nodes - 1) / 2);
    free(len);
    return NTS_OK;
}
