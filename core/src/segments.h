/* The segment pass (segments.c, docs/model.md §2): the data of every surface
 * entry, recomputed each evaluation, and the order statistic of the segment
 * lengths that sets the default search radius (§9). */
#ifndef NTSCONTACT_SEGMENTS_H
#define NTSCONTACT_SEGMENTS_H

#include "internal.h"
#include "parallel.h"

/* Segment data of surface entry j, recomputed each evaluation from the
 * positions (entry order): its node X_j and the segment j that starts there
 * (its normal is seg_normal), with the scene's topology of the entry. One
 * record is one 64-byte cache line (the buffer is aligned): everything the
 * local search and the forces read of a master is in its line or in the line
 * of the entry before it, so a master costs one prefetch, not one per array. */
typedef struct seg_data {
    nts_vec2 p;      /* X_j */
    nts_vec2 t;      /* X_{j+1} - X_j (minimum image) */
    double inv_len2; /* 1/|t|^2, |t| > 0 checked */
    double len;      /* |t| */
    int prev, next;  /* the entries before and after j in its loop */
    int node, body;  /* the node of X_j and its body */
} seg_data;

/* The buffer's alignment: a record never straddles two cache lines. */
enum { NTS_SEG_ALIGN = 64 };
typedef char nts_seg_data_is_one_line[sizeof(seg_data) == NTS_SEG_ALIGN ? 1 : -1];

/* What the segment pass finds besides the data: the first bad segment in
 * entry order (or surface_count), the longest segment, the largest
 * coordinate (for round-off allowances), the bounding box of the nodes, and
 * the k-th smallest length when asked for (and no segment is bad). */
typedef struct seg_summary {
    int bad;
    int rejected; /* checking new positions: some check of a loop failed (the scene's check says which) */
    double lmax;
    double coord_max;
    double xmin, xmax, ymin, ymax;
    double kth;
    int kth_from; /* the lengths the k-th was selected among at last: all n when the bracket missed it or
                   * there are too few to sample, the one bin of the bracket's that holds it else; 0: none */
    double moved; /* the largest displacement of a node since `since` (nts_segments_compute), or 0 */
} seg_summary;

/* The outward unit normal of a segment (t_y, -t_x)/|t|, computed where it is
 * needed (the same bits every time). */
static inline nts_vec2 seg_normal(nts_vec2 t, double len) { return nts_v2(t.y / len, -t.x / len); }

/* The order statistic's sample: this many entries at a fixed stride. */
enum { NTS_SAMPLE = 4096 };
/* The segment data, the summary, and the k-th smallest segment length
 * (0-based, exactly; k < 0: none) found in the same pass, at positions `pos`
 * (NULL: the scene's). `scratch` holds surface_count + NTS_SAMPLE doubles.
 * `since` (or NULL): positions of the surface entries, from which the pass
 * finds the largest displacement (the minimum image in a periodic box: a kept
 * candidate list's test, eq. (29)). `area_perim` (or NULL): new positions
 * are checked as the scene checks each loop (nts_scene_update_positions), the
 * verdict in out->rejected, each loop's twice signed area and perimeter (in
 * the caller's order, the scene's check's bits) in area_perim[2 l], [2 l + 1]
 * (2 loop_total doubles) for the scene's verdicts on them
 * (nts_scene_keeps_shape); the coordinates of nodes on no loop must have
 * passed nts_scene_interior_in_range. */
int nts_segments_compute(nts_context* ctx, const nts_scene* s, const nts_vec2* pos, int k, double* scratch,
                         const nts_vec2* since, double* area_perim, const nts_run* run, seg_summary* out);
/* The summary's lengths and extremes alone (bad, lmax, coord_max, the
 * bounding box; the same as nts_segments_compute's), each length into
 * lengths[i] when not NULL (-1: outside the supported range; written
 * whatever `bad` says): no segment data written, nothing allocated. */
void nts_segments_lengths(const nts_scene* s, double* lengths, const nts_run* run, seg_summary* out);
/* The k-th smallest of v[0..n) (v is reordered: every value before k is at
 * most it, every value after at least it): quickselect, O(n log n) at worst. */
double nts_select_kth(double* v, int n, int k);

#endif
