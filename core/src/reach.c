/* The growth of the reach (docs/model.md §4.5): the active contacts deeper
 * than the search radius r, which the search cannot see.
 *
 * A slave node inside a master body belongs to a chain of its loop's nodes
 * inside that body. Where the chain meets the master's surface, the loop
 * crosses it: of the segment that crosses, one end lies within half its
 * length of the surface. So, unless that segment is longer than 2 r, a node
 * at each end of the chain is within r of the master, and the search found
 * its closest point there. From there the chain is followed node by node:
 * the closest point of a neighbour k of a node i lies within
 * |g_i| + |X_k - X_i| of k (the triangle inequality), so a search widened to
 * that radius around k finds it, the closest point over the whole body:
 * exactly what any larger radius would give.
 *
 * The search compares each slave's closest points with those of the slave
 * before it (search.c: reach_neighbours) and asks for a neighbour that has
 * none on a body where the other has one, when it could lie deeper than r
 * there (|X_k - X_i| - g_i > r, reach_may_be_deeper); a neighbour across the
 * end of a chunk (or the end of a loop that crosses one) is compared here
 * (its "edges"). A neighbour beyond all of the body's nodes in the direction
 * of the other's normal, or outside a circle around them, is outside the
 * body and is not searched. A pair found deep is followed on to its
 * neighbours that did not ask for it (those have a closest point within r
 * there, or are deep already); the chain stops at its first node outside. A
 * slave next to a segment longer than 2 r is searched widened from the
 * start, against the bodies whose circle holds it, to min(that length, the
 * depth the body can hold: half the smaller side of its bounding box), since
 * its chain may have no closest point within r at all; against a segment far
 * longer than the cells, the bodies come from a grid of their bounding
 * boxes.
 *
 * Every pair (slave, master body) is settled once, and its answer does not
 * depend on the radius it was searched with (a radius that finds nothing is
 * doubled, up to the scene's size), so the contacts found do not depend on
 * the order of the work, the threads or how space is binned. */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "parallel.h"
#include "context.h"


void nts_reach_free(nts_reach* r) {
    nts_free(r->queue);
    nts_free(r->hits);
    nts_free(r->edges);
    nts_free(r->seen);
    nts_free(r->deep);
    nts_free(r->shares);
    nts_free(r->shape);
    nts_free(r->grid_start);
    nts_free(r->grid_items);
    nts_free(r->unresolved_slaves);
    nts_free(r->beyond_slaves);
    nts_free(r->outside);
    nts_free(r->ask_at);
    memset(r, 0, sizeof *r);
}

size_t nts_reach_memory_bytes(const nts_reach* r) {
    return (size_t)r->queue_cap * sizeof(reach_request) + (size_t)r->hits_cap * sizeof(candidate) +
           (size_t)r->seen_cap * sizeof(reach_seen) +
           (size_t)r->edge_cap * sizeof(reach_item) +
           (size_t)r->deep_cap * sizeof(candidate) + (size_t)r->shares_cap * sizeof(force_shares) +
           (size_t)r->shape_cap * sizeof(double) + (size_t)(r->grid_start_cap + r->grid_items_cap) * sizeof(int) +
           (size_t)r->outside_cap + (size_t)r->ask_at_cap * sizeof(int);
}

/* The largest (X_m - xs) . n and |X_m - xs| by axis over nodes [m, e),
 * without a branch: max[0] the first, max[1] and max[2] the others (each as
 * large as on entry at least), the products and sums those of the
 * node-by-node loop (beyond_body). In a periodic box the differences are
 * the minimum images as nts_min_image_1 gives them within a quarter box
 * (d + 0.0); 0 when some node lies farther (max untouched: the caller takes
 * the block node by node). */
enum { BEYOND_BLOCK = 8 };
static int block_extent(const nts_scene* s, int m, int e, nts_vec2 xs, double nx, double ny, double max[3]) {
#if defined(__SSE2__)
    const nts_vec2* pos = s->pos;
    const int periodic = s->lx > 0.0 || s->ly > 0.0;
    const __m128d x = _mm_setr_pd(xs.x, xs.y), n = _mm_setr_pd(nx, ny), sign = _mm_set1_pd(-0.0);
    /* (adding -0.0 changes no value, adding +0.0 turns -0 into +0) */
    const __m128d zero = periodic ? _mm_setzero_pd() : sign;
    const __m128d quarter = periodic ? _mm_setr_pd(0.25 * s->lx, 0.25 * s->ly) : _mm_set1_pd(HUGE_VAL);
    __m128d h = _mm_set1_pd(max[0]), a = _mm_setr_pd(max[1], max[2]), far = _mm_setzero_pd();
    for (; m + 1 < e; m += 2) {
        const __m128d d0 = _mm_sub_pd(_mm_loadu_pd(&pos[m].x), x), d1 = _mm_sub_pd(_mm_loadu_pd(&pos[m + 1].x), x);
        const __m128d a0 = _mm_andnot_pd(sign, d0), a1 = _mm_andnot_pd(sign, d1);
        const __m128d p0 = _mm_mul_pd(_mm_add_pd(d0, zero), n), p1 = _mm_mul_pd(_mm_add_pd(d1, zero), n);
        far = _mm_or_pd(far, _mm_or_pd(_mm_cmpnlt_pd(a0, quarter), _mm_cmpnlt_pd(a1, quarter)));
        /* (dx nx + dy ny of the two nodes: their lows plus their highs) */
        h = _mm_max_pd(_mm_add_pd(_mm_unpacklo_pd(p0, p1), _mm_unpackhi_pd(p0, p1)), h);
        a = _mm_max_pd(a0, a);
        a = _mm_max_pd(a1, a);
    }
    if (m < e) {
        const __m128d d0 = _mm_sub_pd(_mm_loadu_pd(&pos[m].x), x), a0 = _mm_andnot_pd(sign, d0);
        const __m128d p0 = _mm_mul_pd(_mm_add_pd(d0, zero), n);
        const __m128d h0 = _mm_add_sd(p0, _mm_unpackhi_pd(p0, p0)); /* (in its low lane) */
        far = _mm_or_pd(far, _mm_cmpnlt_pd(a0, quarter));
        h = _mm_max_pd(_mm_unpacklo_pd(h0, h0), h);
        a = _mm_max_pd(a0, a);
    }
    if (_mm_movemask_pd(far) != 0) return 0;
    h = _mm_max_pd(h, _mm_unpackhi_pd(h, h));
    max[0] = _mm_cvtsd_f64(h);
    max[1] = _mm_cvtsd_f64(a);
    max[2] = _mm_cvtsd_f64(_mm_unpackhi_pd(a, a));
    return 1;
#else
    (void)s, (void)m, (void)e, (void)xs, (void)nx, (void)ny, (void)max;
    return 0;
#endif
}

/* Whether X_k lies beyond body b's every node in direction n: then it is
 * outside the body, whose smoothed surface lies in its nodes' convex hull
 * (a corner curve is a convex combination of three nodes, eq. (2)-(3); the
 * nodes inside a mesh lie in it too). n may be single precision: the
 * allowance. The nodes are read from the scene's positions (16 bytes each,
 * in body order: a quarter of the memory of their segment data), each as
 * its minimum image from X_k. A neighbour that a slave asks for along its
 * chain is usually outside so (the chain's end): a pass over the body's
 * nodes spares a widened search. */
static int beyond_body(const search_env* env, int k, int b, double nx, double ny) {
    const nts_scene* s = env->s;
    const nts_vec2 xs = env->seg[k].p;
    const int all = nts_body_all_on_loops(s, b);
    /* A node at or above -ext L_max along n decides: not beyond, whatever
     * the extent (the bound below is at most that). */
    const double fail = -env->ext * env->wide_lmax;
    double top = -HUGE_VAL, mx[3];
    int m, q;
    mx[1] = mx[2] = 0.0;
    /* A block at a time (block_extent), the block's verdict after it: the
     * same verdict as node by node. */
    /* The body's loops' nodes: its nodes in blocks when all are on its
     * loops, else its entries' nodes one by one (a node on no loop, a
     * mesh's interior, is not read: contact reads the loops alone). */
    int m1, m0 = all ? s->body_node_start[b] : nts_body_entries(s, b, &m1);
    if (all) m1 = s->body_node_start[b + 1];
    for (m = m0; m < m1; m += BEYOND_BLOCK) {
        const int e = m1 - m > BEYOND_BLOCK ? m + BEYOND_BLOCK : m1;
        mx[0] = -HUGE_VAL;
        if (!all || !block_extent(s, m, e, xs, nx, ny, mx))
            for (q = m; q < e; ++q) {
                const nts_vec2 d = nts_scene_diff(s, s->pos[all ? q : s->surf_node[q]], xs);
                const double h = d.x * nx + d.y * ny;
                mx[0] = h > mx[0] ? h : mx[0];
                mx[1] = fabs(d.x) > mx[1] ? fabs(d.x) : mx[1];
                mx[2] = fabs(d.y) > mx[2] ? fabs(d.y) : mx[2];
            }
        if (mx[0] >= fail) return 0;
        top = mx[0] > top ? mx[0] : top;
    }
    /* In a periodic box, nodes a quarter of a side or more away may not be
     * the body's nearest images: nothing is ruled out. */
    if (s->lx > 0.0 && !(mx[1] < 0.25 * s->lx && mx[2] < 0.25 * s->ly)) return 0;
    /* A contact surface's end reaches up to ext L_max past the hull (docs/model.md §13). */
    return top < -1e-6 * (mx[1] + mx[2]) + fail;
}

/* Whether slave k lies outside body b, asked along normal n, by a rule of
 * (k, b, n) alone, whatever the search met before (the kept lists' or the
 * cells'; the evaluation's path must not change the queue): a body of at
 * most WIDE_HULL nodes by one pass over its nodes along n (beyond_body,
 * docs/model.md (20)); a larger one by the circle around its nodes
 * (nts_body_shape, found once an evaluation: the caller's thread only).
 * HULL_UNKNOWN: not found yet (a larger body asked from a worker,
 * ask_verdicts, or no verdict at all), for outside_hull to find. */
enum { WIDE_HULL = 512, HULL_UNKNOWN = 2 };
static int hull_small(const search_env* env, int k, int b, double nx, double ny) {
    const nts_scene* s = env->s;
    int end;
    const int first = nts_body_entries(s, b, &end);
    if (end - first > WIDE_HULL) return HULL_UNKNOWN; /* (its loops' nodes) */
    return beyond_body(env, k, b, nx, ny);
}

static int outside_hull(const search_env* env, nts_reach* r, int k, int b, double nx, double ny) {
    const int v = hull_small(env, k, b, nx, ny);
    return v != HULL_UNKNOWN ? v : nts_outside_bounds(env, r->shape, b, env->seg[k].p);
}

/* ----------------------------------------------------------- the pairs */

/* The set of pairs queued or settled: open addressing on slave * bodies +
 * body, at most half full. Returns the pair's slot; *fresh is 1 when it was
 * not there (its `at` is then the caller's to set). NULL: out of memory. */
static unsigned long long pair_hash(long long key, int cap) {
    return ((unsigned long long)key * 0x9E3779B97F4A7C15ull) >> 11 & (unsigned long long)(cap - 1);
}

static reach_seen* seen_find(nts_reach* r, long long key, int* fresh) {
    unsigned long long h;
    if (2 * (r->seen_count + 1) > r->seen_cap) {
        const int cap = r->seen_cap > 0 ? 2 * r->seen_cap : 1024;
        reach_seen* old = r->seen;
        const int old_cap = r->seen_cap;
        int i;
        if (cap <= 0 || (r->seen = (reach_seen*)nts_alloc(sizeof(reach_seen) * (size_t)cap)) == NULL) {
            r->seen = old;
            return NULL;
        }
        r->seen_cap = cap;
        for (i = 0; i < cap; ++i) r->seen[i].key = -1;
        for (i = 0; i < old_cap; ++i) {
            if (old[i].key < 0) continue;
            for (h = pair_hash(old[i].key, cap); r->seen[h].key >= 0; h = (h + 1) & (unsigned long long)(cap - 1))
                continue;
            r->seen[h] = old[i];
        }
        nts_free(old);
    }
    for (h = pair_hash(key, r->seen_cap); r->seen[h].key >= 0; h = (h + 1) & (unsigned long long)(r->seen_cap - 1))
        if (r->seen[h].key == key) {
            *fresh = 0;
            return &r->seen[h];
        }
    r->seen[h].key = key;
    r->seen[h].at = -1;
    ++r->seen_count;
    *fresh = 1;
    return &r->seen[h];
}

/* Queue (k, body) with radius rho, asked by k's neighbour on side `from`
 * whose closest point on the body has normal n, unless k lies outside the
 * body (outside_hull; `verdict`: hull_small's answer, found already, or
 * HULL_UNKNOWN). A pair
 * queued already records the second neighbour that asks; a pair settled
 * already is left alone. */
static int enqueue_with(nts_context* ctx, const search_env* env, int k, int body, double rho, int from, double nx,
                        double ny, int verdict) {
    nts_reach* r = &ctx->reach;
    const nts_scene* s = env->s;
    reach_seen* p;
    int fresh, rc;
    if (!nts_node_on_surface(s, k)) return NTS_OK; /* no slave: off the contact surface (docs/model.md §13) */
    if ((p = seen_find(r, (long long)k * s->body_count + body, &fresh)) == NULL) return NTS_ENOMEM;
    if (!fresh) {
        if (p->at >= 0) r->queue[p->at].from |= from;
        return NTS_OK;
    }
    if (verdict == HULL_UNKNOWN) verdict = outside_hull(env, r, k, body, nx, ny);
    if (verdict) return NTS_OK; /* settled: outside */
    if ((rc = nts_grow((void**)&r->queue, &r->queue_cap, r->queue_count + 1, sizeof(reach_request))) != NTS_OK)
        return rc;
    p->at = r->queue_count;
    r->queue[r->queue_count].slave = k;
    r->queue[r->queue_count].body = body;
    r->queue[r->queue_count].rho = rho;
    r->queue[r->queue_count++].from = from;
    return NTS_OK;
}

static int enqueue(nts_context* ctx, const search_env* env, int k, int body, double rho, int from, double nx,
                   double ny) {
    return enqueue_with(ctx, env, k, body, rho, from, nx, ny, HULL_UNKNOWN);
}

/* The hull test of every ask the search left (REACH_ASK items), before they
 * are queued one by one: each its own answer (hull_small reads only; a
 * larger body's circle is left to the queue), so they run in parallel, a
 * chunk's items a task, into r->outside at the chunk's r->ask_at. The queue
 * then takes the verdict of a pair's first ask as enqueue() would find it;
 * the asks of pairs seen already (a second neighbour) were tested for
 * nothing (those off the surface are not). */
typedef struct verdict_task {
    nts_context* ctx;
    const search_env* env;
} verdict_task;

static void ask_verdicts(int begin, int end, int wi, void* p) {
    const verdict_task* t = (const verdict_task*)p;
    nts_reach* r = &t->ctx->reach;
    const nts_scene* s = t->env->s;
    int c, k;
    (void)wi;
    for (c = begin; c < end; ++c) {
        const chunk_part* part = &t->ctx->chunks[c].part[STREAM_REACH];
        const reach_item* it = (const reach_item*)part->data;
        unsigned char* out;
        if (part->count == 0) continue;
        out = r->outside + r->ask_at[c];
        for (k = 0; k < part->count; ++k) {
            if (k + 4 < part->count && it[k + 4].kind == REACH_ASK) { /* the body's nodes, scattered: 4 items ahead */
                const int ab = it[k + 4].body, m0 = s->body_node_start[ab], m1 = s->body_node_start[ab + 1];
                int m;
                NTS_PREFETCH(&t->env->seg[it[k + 4].slave]);
                for (m = m0; nts_body_all_on_loops(s, ab) && m1 - m0 <= WIDE_HULL && m < m1 && m < m0 + 64; m += 4)
                    NTS_PREFETCH(&s->pos[m]); /* (hull_small reads them) */
            }
            out[k] = (unsigned char)(it[k].kind == REACH_ASK && nts_node_on_surface(s, it[k].slave)
                                         ? hull_small(t->env, it[k].slave, it[k].body, it[k].nx, it[k].ny)
                                         : 0);
        }
    }
}

/* Slave k, settled deep inside c->body (gap g < -r, normal n): its
 * neighbours along the loop that did not ask for it (those have a closest
 * point within r there, or are settled) may be deeper still. */
static int follow(nts_context* ctx, const search_env* env, int k, const candidate* c, int asked) {
    const seg_data* seg = env->seg;
    const int prev = seg[k].prev, next = seg[k].next;
    const double lp = seg[prev].len, ln = seg[k].len;
    const double g = c->gap;
    int rc = NTS_OK;
    if (!(asked & SIDE_PREV) && reach_may_be_deeper(lp, g, env->r))
        rc = enqueue(ctx, env, prev, c->body, fabs(g) + lp, SIDE_NEXT, c->normal.x, c->normal.y);
    if (rc == NTS_OK && !(asked & SIDE_NEXT) && reach_may_be_deeper(ln, g, env->r))
        rc = enqueue(ctx, env, next, c->body, fabs(g) + ln, SIDE_PREV, c->normal.x, c->normal.y);
    return rc;
}

/* Slave q.slave, inside q.body in a periodic box with no closest
 * point there within the largest radius (counted: r->unresolved): its chain
 * goes on past it, and the nodes beyond may lie within reach again. Its
 * neighbours that did not ask are searched out to that radius (no normal:
 * the pass over a small body's nodes rules nothing out; a larger body's
 * circle may). */
static int follow_beyond(nts_context* ctx, const search_env* env, reach_request q) {
    const seg_data* seg = env->seg;
    int rc = NTS_OK;
    /* (q is a copy: enqueue may move the queue it came from) */
    if (!(q.from & SIDE_PREV)) rc = enqueue(ctx, env, seg[q.slave].prev, q.body, env->reach_max, SIDE_NEXT, 0.0, 0.0);
    if (rc == NTS_OK && !(q.from & SIDE_NEXT))
        rc = enqueue(ctx, env, seg[q.slave].next, q.body, env->reach_max, SIDE_PREV, 0.0, 0.0);
    return rc;
}

/* The closest point c of slave k on c->body, found by a widened search, the
 * search having found none within r: an active contact deeper than r is
 * kept, and its chain followed past the neighbours that did not ask. */
static int settle(nts_context* ctx, const search_env* env, int k, const candidate* c, int asked) {
    nts_reach* r = &ctx->reach;
    int rc;
    if (!(c->gap < 0.0 && -c->gap > env->r)) return NTS_OK; /* outside, or found by the search: the chain ends */
    if ((rc = nts_grow((void**)&r->deep, &r->deep_cap, r->deep_count + 1, sizeof(candidate))) != NTS_OK) return rc;
    r->deep[r->deep_count] = *c;
    r->deep[r->deep_count++].slave = k;
    return follow(ctx, env, k, c, asked);
}

/* The columns (or rows) of the cells that [lo, hi] (frame coordinates)
 * overlaps: [*first, *first + count), wrapped in a periodic grid, each once. */
static int grid_span(double lo, double hi, double inv_h, int n, int periodic, int* first) {
    const double a = floor(lo * inv_h), z = floor(hi * inv_h);
    if (periodic) {
        if (!(z - a + 1.0 < (double)n)) {
            *first = 0;
            return n;
        }
        *first = (int)(a - (double)n * floor(a / (double)n));
        return (int)(z - a) + 1;
    }
    *first = a < 0.0 ? 0 : (a > (double)(n - 1) ? n - 1 : (int)a);
    return (z > (double)(n - 1) ? n - 1 : (z < 0.0 ? 0 : (int)z)) - *first + 1;
}

/* The cells that body b's bounding box overlaps (allowing for round-off). */
static void body_cells(const search_env* env, double* shape, int b, int* cx0, int* ncx, int* cy0, int* ncy) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    const double* c = nts_body_shape(env, shape, b);
    const nts_cell_place q = nts_cells_place(cl, s->pos[nts_body_origin(s, b)]);
    /* More than nts_outside_bounds allows (a contact surface's ends reach
     * ext L_max past the nodes, and the round-off): the cells listed hold
     * every point that test lets in, and it decides. */
    const double pad = 4.0 * env->wide_pad + env->ext * env->wide_lmax +
                       1e-8 * (fabs(c[4]) + fabs(c[5]) + fabs(c[6]) + fabs(c[7]));
    *ncx = grid_span(q.x + c[4] - pad, q.x + c[5] + pad, cl->inv_hx, cl->nx, cl->periodic, cx0);
    *ncy = grid_span(q.y + c[6] - pad, q.y + c[7] + pad, cl->inv_hy, cl->ny, cl->periodic, cy0);
}

/* Every body that offers a surface, listed in every cell its bounding box
 * overlaps (CSR by cell, bodies in order), for the slaves next to long
 * segments: the bodies that can hold a point are those listed in its cell.
 * Built once per evaluation when one asks; NTS_ELIMIT when the lists would
 * exceed `budget` entries (bodies piled on one another: the caller searches
 * by cells instead). */
static int body_grid(nts_reach* r, const search_env* env, long long budget) {
    const nts_scene* s = env->s;
    const nts_cells* cl = env->cells;
    const int ncell = cl->nx * cl->ny;
    long long total = 0;
    int b, rc, pass;
    if ((rc = nts_grow((void**)&r->grid_start, &r->grid_start_cap, ncell + 1, sizeof(int))) != NTS_OK) return rc;
    memset(r->grid_start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (pass = 0; pass < 2; ++pass) {
        for (b = 0; b < s->body_count; ++b) {
            int cx0, ncx, cy0, ncy, x, y;
            if (s->body_role[b] == NTS_ROLE_SLAVE) continue;
            body_cells(env, r->shape, b, &cx0, &ncx, &cy0, &ncy);
            if (pass == 0) {
                total += (long long)ncx * ncy;
                if (total > budget) return NTS_ELIMIT;
            }
            for (y = 0; y < ncy; ++y)
                for (x = 0; x < ncx; ++x) {
                    const int cell = ((cy0 + y) % cl->ny) * cl->nx + (cx0 + x) % cl->nx;
                    if (pass == 0) ++r->grid_start[cell + 1];
                    else r->grid_items[r->grid_start[cell]++] = b;
                }
        }
        if (pass == 0) {
            for (b = 0; b < ncell; ++b) r->grid_start[b + 1] += r->grid_start[b];
            if ((rc = nts_grow((void**)&r->grid_items, &r->grid_items_cap, (int)total, sizeof(int))) != NTS_OK)
                return rc;
        }
    }
    for (b = ncell; b > 0; --b) r->grid_start[b] = r->grid_start[b - 1];
    r->grid_start[0] = 0;
    r->grid_built = 1;
    return NTS_OK;
}

/* Kept candidates (docs/model.md §15): a widened search around slave k on
 * `body` (every body: -1) within rho that its kept list does not cover
 * tries the body's entries when they are few (wide() without cells), else
 * needs the cells, built now (once an evaluation). */
enum { KEPT_BODY_ENTRIES = 1024 };
static int cells_for(nts_context* ctx, search_env* env, int k, int body, double rho) {
    const nts_scene* s = env->s;
    if (env->cells != NULL || env->kept == NULL || kept_covers(env, k, rho)) return NTS_OK;
    if (body >= 0 && s->loop_start[s->body_loop_start[body + 1]] - s->loop_start[s->body_loop_start[body]] <=
                         KEPT_BODY_ENTRIES)
        return NTS_OK;
    return nts_cells_now(ctx, env);
}

/* A candidate of a long segment's end: deep, and not settled yet, it is. */
static int coarse_hit(nts_context* ctx, const search_env* env, int i, const candidate* b) {
    reach_seen* p;
    int fresh;
    if (!(b->gap < 0.0 && -b->gap > env->r)) return NTS_OK;
    if ((p = seen_find(&ctx->reach, (long long)i * env->s->body_count + b->body, &fresh)) == NULL) return NTS_ENOMEM;
    return fresh ? settle(ctx, env, i, b, 0) : NTS_OK;
}

/* A slave next to a segment of length l > 2 r: its closest point on every
 * other body within min(l, the body's depth), where the end of its chain
 * inside that body lies, for the bodies whose circle holds it (no other can
 * give it an active contact). What lies within r the search has already.
 * Against a segment far longer than the cells (a long wall's corners), the
 * bodies are those listed in its cell of the bodies' grid, each searched on
 * its own, rather than every cell within l. */
static int coarse(nts_context* ctx, search_env* env, worker* w, int i, double l) {
    nts_reach* r = &ctx->reach;
    const nts_cells* cl;
    const double rho = (l < env->reach_max ? l : env->reach_max) * (1.0 + 1e-9) + env->wide_pad;
    int k, rc = NTS_OK;
    if (!nts_node_on_surface(env->s, i)) return NTS_OK; /* no slave (docs/model.md §13) */
    if ((rc = cells_for(ctx, env, i, -1, rho)) != NTS_OK) return rc;
    cl = env->cells;
    if (cl != NULL && rho > 2.0 * (cl->hx > cl->hy ? cl->hx : cl->hy) && r->grid_built >= 0) {
        if (!r->grid_built && (rc = body_grid(r, env, 8LL * env->s->surface_count + 4096)) != NTS_OK) {
            if (rc != NTS_ELIMIT) return rc;
            r->grid_built = -1; /* too many: by cells */
            rc = NTS_OK;
        }
        if (r->grid_built > 0) {
            const int cell = nts_cells_place(cl, env->seg[i].p).cell, own = env->seg[i].body;
            for (k = r->grid_start[cell]; k < r->grid_start[cell + 1] && rc == NTS_OK; ++k) {
                const int b = r->grid_items[k];
                double rb;
                if ((b == own && !self_body(env, own)) || nts_outside_bounds(env, r->shape, b, env->seg[i].p)) continue;
                rb = nts_body_shape(env, r->shape, b)[3];
                rb = (rb < rho ? rb : rho) * (1.0 + 1e-9) + env->wide_pad;
                nts_search_wide(env, w, i, b, rb, NULL);
                if (w->status == NTS_OK && w->best_count > 0) rc = coarse_hit(ctx, env, i, &w->best[0]);
                nts_search_wide_done(w); /* its slots cleared, out of memory too: the context is used again */
                if (w->status != NTS_OK) return w->status;
            }
            return rc;
        }
    }
    nts_search_wide(env, w, i, -1, rho, r->shape);
    if (w->status != NTS_OK) { /* its slots cleared all the same: the context is used again */
        nts_search_wide_done(w);
        return w->status;
    }
    /* Each body's best in body order (found in the order of the cells). */
    for (k = 1; k < w->best_count; ++k) {
        candidate c = w->best[k];
        int m = k - 1;
        while (m >= 0 && w->best[m].body > c.body) {
            w->best[m + 1] = w->best[m];
            --m;
        }
        w->best[m + 1] = c;
    }
    for (k = 0; k < w->best_count && rc == NTS_OK; ++k) rc = coarse_hit(ctx, env, i, &w->best[k]);
    nts_search_wide_done(w);
    return rc;
}

/* Edge items by slave, then side, then body (binary search). */
static int edge_before(const reach_item* a, int slave, int from, int body) {
    if (a->slave != slave) return a->slave < slave;
    if (a->from != from) return a->from < from;
    return a->body < body;
}

static int has_edge(const nts_reach* r, int slave, int from, int body) {
    int lo = 0, hi = r->edge_count;
    while (lo < hi) {
        const int mid = lo + (hi - lo) / 2;
        if (edge_before(&r->edges[mid], slave, from, body)) lo = mid + 1;
        else hi = mid;
    }
    return lo < r->edge_count && r->edges[lo].slave == slave && r->edges[lo].from == from && r->edges[lo].body == body;
}

/* An edge: slave i's closest point on a body, its neighbour on side e->from
 * across the end of a chunk or a loop. That neighbour asks nothing when it
 * has a closest point on the body too (an edge facing back). */
static int edge(nts_context* ctx, const search_env* env, const reach_item* e) {
    const seg_data* seg = env->seg;
    const int i = e->slave, k = e->from == SIDE_PREV ? seg[i].prev : seg[i].next;
    const int back = e->from == SIDE_PREV ? SIDE_NEXT : SIDE_PREV;
    const double l = e->from == SIDE_PREV ? seg[k].len : seg[i].len;
    if (has_edge(&ctx->reach, k, back, e->body) || !reach_may_be_deeper(l, e->value, env->r)) return NTS_OK;
    return enqueue(ctx, env, k, e->body, fabs(e->value) + l, back, e->nx, e->ny);
}

/* Whether X_k lies inside body b's polygon (its loops by their segments,
 * from the image of the body's first node nearest to X_k; a ray along +x
 * crosses them an odd number of times). A body may span more than half the
 * box: that image need not be the one around X_k, and the polygon walked
 * from it lies within the body's extent (less than the box) of it, so X_k is
 * tried with its images one box away as well. For a slave that a search out
 * to half a periodic box finds nothing for: only then may a contact be
 * lost. */
static int inside_at(const search_env* env, nts_vec2 base, int b) {
    const nts_scene* s = env->s;
    const nts_vec2 p0 = env->seg[s->loop_start[s->body_loop_start[b]]].p;
    int l, inside = 0;
    for (l = s->body_loop_start[b]; l < s->body_loop_start[b + 1]; ++l) {
        /* the loop's first node relative to the point tested (base: the body's first node) */
        nts_vec2 cur = nts_add(base, nts_scene_diff(s, env->seg[s->loop_start[l]].p, p0));
        int e;
        for (e = s->loop_start[l]; e < s->loop_start[l + 1]; ++e) {
            const nts_vec2 next = nts_add(cur, env->seg[e].t);
            if ((cur.y > 0.0) != (next.y > 0.0) && cur.x + (next.x - cur.x) * (-cur.y / (next.y - cur.y)) > 0.0)
                inside ^= 1;
            cur = next;
        }
    }
    return inside;
}

static int inside_body(const search_env* env, int k, int b) {
    const nts_scene* s = env->s;
    /* the body's first node relative to X_k, its nearest image, then to X_k's images one box away */
    const nts_vec2 d = nts_scene_diff(s, env->seg[s->loop_start[s->body_loop_start[b]]].p, env->seg[k].p);
    int i, j;
    if (inside_at(env, d, b)) return 1;
    for (i = -1; i <= 1; ++i)
        for (j = -1; j <= 1; ++j)
            if ((i != 0 || j != 0) && inside_at(env, nts_v2(d.x - i * env->lx, d.y - j * env->ly), b)) return 1;
    return 0;
}

/* A pair's search, widened from its radius, doubled while it finds nothing
 * (the closest point may not be where the triangle inequality puts the
 * nearest point of the surface: a slave beside a corner's region), up to
 * the largest radius the scene allows: its closest point on the body in
 * *hit, or hit->kind = -1 when there is none within that. */
/* The first radius search_pair tries. */
static double search_pair_rho(const search_env* env, const reach_request* q) {
    const double rho = q->rho * (1.0 + 1e-9) + env->wide_pad;
    return rho < env->reach_max ? rho : env->reach_max;
}

static void search_pair(const search_env* env, worker* w, const reach_request* q, candidate* hit) {
    double rho = search_pair_rho(env, q);
    hit->kind = -1;
    for (;;) {
        if (rho > env->reach_max) rho = env->reach_max;
        nts_search_wide(env, w, q->slave, q->body, rho, NULL);
        if (w->status != NTS_OK) break; /* out of memory: its slots cleared all the same */
        if (w->best_count > 0 || rho >= env->reach_max) break;
        rho *= 2.0;
    }
    if (w->status == NTS_OK && w->best_count > 0) *hit = w->best[0];
    nts_search_wide_done(w);
}

/* Deep contacts by slave, then master body (each pair is there once). */
static int deep_order(const void* pa, const void* pb) {
    const candidate* a = (const candidate*)pa;
    const candidate* b = (const candidate*)pb;
    if (a->slave != b->slave) return a->slave < b->slave ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

typedef struct pairs_task {
    nts_context* ctx;
    const search_env* env;
    int q0;
} pairs_task;

/* Queued pairs [q0 + begin, q0 + end), each answer its own. */
static void search_pairs(int begin, int end, int wi, void* p) {
    const pairs_task* t = (const pairs_task*)p;
    nts_reach* r = &t->ctx->reach;
    worker* wt = &t->ctx->workers[wi];
    int q;
    for (q = t->q0 + begin; q < t->q0 + end; ++q)
        if (wt->status == NTS_OK) search_pair(t->env, wt, &r->queue[q], &r->hits[q]);
}

int nts_reach_grow(nts_context* ctx, search_env* env, long long found, const nts_run* run) {
    const nts_scene* s = env->s;
    nts_reach* r = &ctx->reach;
    worker* w = &ctx->workers[0];
    int c, i, k, q, q0, q1, rc;
    pairs_task pt;
    pt.ctx = ctx;
    pt.env = env;
    r->queue_count = r->deep_count = r->seen_count = r->edge_count = 0;
    r->beyond = r->unresolved = 0;
    for (i = 0; i < r->seen_cap; ++i) r->seen[i].key = -1;
    if ((rc = nts_grow((void**)&r->shape, &r->shape_cap, SHAPE * s->body_count, sizeof(double))) != NTS_OK) return rc;
    for (i = 0; i < s->body_count; ++i) r->shape[SHAPE * i + 3] = -1.0;
    r->grid_built = 0;

    /* 1. What the search asked for, chunk by chunk (the hull tests first, in
     * parallel); its edges, gathered in slave order, then compared across. */
    if ((rc = nts_grow((void**)&r->ask_at, &r->ask_at_cap, ctx->chunk_count + 1, sizeof(int))) != NTS_OK) return rc;
    r->ask_at[0] = 0;
    for (c = 0; c < ctx->chunk_count; ++c) {
        const long long next = (long long)r->ask_at[c] + ctx->chunks[c].part[STREAM_REACH].count;
        if (next > INT_MAX) return NTS_ENOMEM; /* (more asks than an int counts: no room for their verdicts) */
        r->ask_at[c + 1] = (int)next;
    }
    if ((rc = nts_grow((void**)&r->outside, &r->outside_cap, r->ask_at[ctx->chunk_count], 1)) != NTS_OK) return rc;
    {
        verdict_task vt;
        vt.ctx = ctx;
        vt.env = env;
        nts_run_tasks(run, ask_verdicts, ctx->chunk_count, 1, &vt);
    }
    for (c = 0; c < ctx->chunk_count && rc == NTS_OK; ++c) {
        const chunk_part* part = &ctx->chunks[c].part[STREAM_REACH];
        const reach_item* it = (const reach_item*)part->data;
        const unsigned char* out = part->count > 0 ? r->outside + r->ask_at[c] : NULL;
        for (k = 0; k < part->count && rc == NTS_OK; ++k) {
            if (k + 8 < part->count && it[k + 8].body >= 0 && r->seen_cap > 0) /* asked for 8 items ahead */
                NTS_PREFETCH(&r->seen[pair_hash((long long)it[k + 8].slave * s->body_count + it[k + 8].body,
                                                r->seen_cap)]);
            if (it[k].kind == REACH_ASK) {
                rc = enqueue_with(ctx, env, it[k].slave, it[k].body, it[k].value, it[k].from, it[k].nx, it[k].ny,
                                  out[k]);
            } else if (it[k].kind == REACH_EDGE) {
                if ((rc = nts_grow((void**)&r->edges, &r->edge_cap, r->edge_count + 1, sizeof(reach_item))) == NTS_OK)
                    r->edges[r->edge_count++] = it[k];
            }
        }
    }
    /* (in slave order already: the chunks in order, each slave's edges on
     * its previous side and then its next, by body) */
    for (k = 0; k < r->edge_count && rc == NTS_OK; ++k) rc = edge(ctx, env, &r->edges[k]);
    /* 2. The slaves next to long segments. */
    for (c = 0; c < ctx->chunk_count && rc == NTS_OK; ++c) {
        const chunk_part* part = &ctx->chunks[c].part[STREAM_REACH];
        const reach_item* it = (const reach_item*)part->data;
        for (k = 0; k < part->count && rc == NTS_OK; ++k)
            if (it[k].kind == REACH_COARSE) {
                const seg_data* seg = env->seg;
                const int i2 = it[k].slave;
                const double lp = seg[seg[i2].prev].len, ln = seg[i2].len;
                rc = coarse(ctx, env, w, i2, lp > ln ? lp : ln);
            }
    }
    /* 3. The chains, in rounds: the pairs queued are searched (in parallel,
     * each answer its own), then settled in queue order, which queues the
     * next round: the queue, and so the answer, do not depend on the threads. */
    for (q0 = 0; q0 < r->queue_count && rc == NTS_OK; q0 = q1) {
        q1 = r->queue_count;
        if (found + r->deep_count > env->max_records) return NTS_ELIMIT;
        if (env->cancel != NULL && env->cancel(env->cancel_user)) return NTS_ECANCELLED;
        if ((rc = nts_grow((void**)&r->hits, &r->hits_cap, q1, sizeof(candidate))) != NTS_OK) return rc;
        /* A round of a few pairs runs in the caller's thread (not worth the
         * workers); else ranges of 16, handed out by the backend. */
        /* (a pair that finds nothing at its rho tries twice it, maybe past
         * what the kept lists cover: wide() then tries the body's entries) */
        for (q = q0; q < q1 && rc == NTS_OK; ++q)
            rc = cells_for(ctx, env, r->queue[q].slave, r->queue[q].body, search_pair_rho(env, &r->queue[q]));
        if (rc != NTS_OK) return rc;
        pt.q0 = q0;
        nts_run_tasks(run, search_pairs, q1 - q0, q1 - q0 > 64 ? 16 : q1 - q0, &pt);
        for (i = 0; i < run->workers; ++i)
            if (ctx->workers[i].status != NTS_OK) return ctx->workers[i].status;
        for (q = q0; q < q1 && rc == NTS_OK; ++q) {
            if (r->hits[q].kind >= 0) rc = settle(ctx, env, r->queue[q].slave, &r->hits[q], r->queue[q].from);
            else if (env->lx > 0.0 && inside_body(env, r->queue[q].slave, r->queue[q].body)) {
                /* inside, deeper than the box's half: beyond it no image is the nearest */
                if ((rc = nts_grow((void**)&r->unresolved_slaves, &r->unresolved_cap, (int)r->unresolved + 1,
                                   sizeof(int))) != NTS_OK)
                    return rc;
                r->unresolved_slaves[r->unresolved++] = r->queue[q].slave;
                rc = follow_beyond(ctx, env, r->queue[q]);
            }
        }
    }
    if (rc != NTS_OK) return rc;
    if (found + r->deep_count > env->max_records) return NTS_ELIMIT;
    if (r->deep_count > 1) qsort(r->deep, (size_t)r->deep_count, sizeof(candidate), deep_order);
    if (!env->grow) { /* an explicit radius: counted, left out */
        if ((rc = nts_grow((void**)&r->beyond_slaves, &r->beyond_cap, r->deep_count, sizeof(int))) != NTS_OK)
            return rc;
        for (k = 0; k < r->deep_count; ++k) r->beyond_slaves[k] = r->deep[k].slave;
        r->beyond = r->deep_count;
        r->deep_count = 0;
    }
    return NTS_OK;
}
