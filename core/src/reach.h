/* The growth of the reach (reach.c, shape.c; docs/model.md §4.5). */
#ifndef NTSCONTACT_REACH_H
#define NTSCONTACT_REACH_H

#include "search.h"

/* The growth of the reach (reach.c, docs/model.md §4.5): the closest points
 * deeper than r that the search could not see, found by widening the search
 * around the slaves next to those it found. */
typedef struct reach_request {
    int slave, body; /* a slave entry and a master body it may be inside of */
    double rho;      /* a radius within which its closest point on the body lies */
    int from;        /* SIDE_* bits: the neighbours that asked (they have a closest point there) */
    int pad;
} reach_request;

/* A pair queued or settled: slave * bodies + body, and its place in the queue
 * (-1: settled outside it). */
typedef struct reach_seen {
    long long key;
    int at, pad;
} reach_seen;

enum { SHAPE = 8 }; /* doubles per body in nts_reach.shape */

typedef struct nts_reach {
    reach_request* queue;   /* the pairs to search, each once */
    int queue_count, queue_cap;
    candidate* hits;        /* each queued pair's closest point (kind -1: none) */
    int hits_cap;
    reach_seen* seen;       /* open addressing, key -1: empty */
    int seen_cap, seen_count;
    reach_item* edges;      /* the chunks' REACH_EDGE items, by slave */
    int edge_count, edge_cap;
    candidate* deep;        /* the active contacts deeper than r, by slave then body */
    int deep_count, deep_cap;
    force_shares* shares;   /* their forces */
    int shares_cap;
    double* shape;          /* per body, SHAPE: a circle around its nodes, the deepest a point inside can
                               be, its bounding box (nts_body_shape) */
    int shape_cap;
    int* grid_start;        /* the bodies' grid (reach.c: body_grid), cells + 1 */
    int* grid_items;
    int grid_start_cap, grid_items_cap, grid_built; /* built: 1, not yet: 0, too many: -1 */
    long long beyond;       /* with an explicit radius: the active contacts deeper than r, left out */
    long long unresolved;   /* slaves inside a body deeper than the periodic box's limit */
    /* Which slaves those two counted (a distributed host's seam:
     * nts_context_warning_entries), one per count. */
    int* unresolved_slaves;
    int unresolved_cap;
    int* beyond_slaves;
    int beyond_cap;
    /* The search's asks, chunk after chunk: whether each slave lies outside
     * the body it asks about (reach.c: ask_verdicts), and each chunk's first. */
    unsigned char* outside;
    int outside_cap;
    int* ask_at;
    int ask_at_cap;
} nts_reach;

/* After the search, the pairs (slave, master body) next to those
 * it found whose closest point lies deeper than r; kept in ctx->reach.deep
 * when env->grow, else counted in ctx->reach.beyond. The widened searches
 * run on `threads` workers. NTS_OK, NTS_ENOMEM, NTS_ELIMIT (more than
 * env->max_records closest points with `found`) or NTS_ECANCELLED. */
int nts_reach_grow(nts_context* ctx, search_env* env, long long found, const nts_run* run);
size_t nts_reach_memory_bytes(const nts_reach* r);
/* shape.c: body b's shape, once per evaluation (shape[SHAPE b + 3] < 0
 * until then): a circle around its nodes, centre relative to its first node
 * and radius squared, the deepest a point inside can lie below its surface,
 * and its bounding box. A point outside the circle or the box is outside
 * the body (nts_outside_bounds). */
const double* nts_body_shape(const search_env* env, double* shape, int b);
int nts_outside_bounds(const search_env* env, double* shape, int b, nts_vec2 x);
void nts_reach_free(nts_reach* r);

#endif
