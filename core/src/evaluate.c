/* nts_evaluate: segment data -> cells and masters -> local search ->
 * scatter -> summary. Each stage is its own file with its own header (segments.h, cells.h, masters.h,
 * search.h, reach.h, scatter.h, context.h; docs/architecture.md); this one sizes
 * the search (radius, cell side) and runs the stages in order, timing each
 * for nts_context_profile. */
#include <assert.h>
#include <float.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "scatter.h"

/* The message of an evaluation stopped by the caller's cancel (the build of
 * a kept list, the search, the deep contacts' growth). */
static const char CANCELLED[] = "the evaluation was cancelled (a deadline passed, or the caller asked)";

/* Wall clock for the phase profile (nts_context_profile): monotonic, with
 * or without OpenMP (clock() would count the CPU time of the process). */
static double wall_time(void) {
    return nts_wall_seconds();
}

/* Sample i's reach (and at alpha 0, `sharp`), or -1 when its master offers
 * nothing (a slave body's, or off the contact surface). */
typedef struct reach_sample_task {
    const nts_context* ctx;
    const nts_scene* s;
    double alpha, ext, r, pad;
    int m;
    double *reach, *sharp; /* sharp NULL: not asked */
} reach_sample_task;

static void reach_samples(int begin, int end, int wi, void* p) {
    const reach_sample_task* t = (const reach_sample_task*)p;
    const nts_scene* s = t->s;
    const int n = s->surface_count;
    int i;
    (void)wi;
    for (i = begin; i < end; ++i) {
        const int e = (int)((long long)i * n / t->m), b = s->surf_body[e];
        const int offers = s->body_role[b] != NTS_ROLE_SLAVE && nts_on_surface(s, e);
        t->reach[i] = offers ? reach_allowed(reach_at_middle(t->ctx->seg, e, alpha_of_body(s, b, t->alpha), t->ext),
                                             t->r, t->pad)
                             : -1.0;
        if (t->sharp != NULL)
            t->sharp[i] =
                offers ? reach_allowed(reach_at_middle(t->ctx->seg, e, alpha_of_body(s, b, 0.0), t->ext), t->r, t->pad)
                       : -1.0;
    }
}

/* The cell side that suits most masters: the 95th percentile of their reach
 * (around the middle of their segment, with the allowances), from a sample
 * of REACH_SAMPLE masters at a fixed stride, for the options' alpha and,
 * when `finest` is asked, for alpha = 0 (the finest grid the options could
 * ask for). It only sets the cell side, never a result, so a sample is as
 * good as all. 0 when no body offers a surface. `scratch`: 2 REACH_SAMPLE
 * doubles. */
enum { REACH_SAMPLE = 1024 };
static void typical_reach(const nts_context* ctx, const nts_scene* s, double alpha, double ext, double r, double pad,
                          double* scratch, double* typical, double* finest, const nts_run* run) {
    const int n = s->surface_count, m = n < REACH_SAMPLE ? n : REACH_SAMPLE;
    double* sharp = scratch + REACH_SAMPLE;
    reach_sample_task t;
    int i, count = 0;
    /* the samples' reaches in parallel (scattered reads: most of the
     * time), then those of masters that offer something, in sample order */
    t.ctx = ctx;
    t.s = s;
    t.alpha = alpha;
    t.ext = ext;
    t.r = r;
    t.pad = pad;
    t.m = m;
    t.reach = scratch;
    t.sharp = finest != NULL ? sharp : NULL;
    nts_run_each(run, reach_samples, m, &t);
    for (i = 0; i < m; ++i) {
        if (scratch[i] < 0.0) continue;
        scratch[count] = scratch[i];
        if (finest != NULL) sharp[count] = sharp[i];
        ++count;
    }
    *typical = 0.0;
    if (finest != NULL) *finest = 0.0;
    if (count == 0) return;
    *typical = nts_select_kth(scratch, count, (int)(0.95 * (double)(count - 1)));
    if (finest != NULL) *finest = nts_select_kth(sharp, count, (int)(0.95 * (double)(count - 1)));
}

/* The largest alpha that shapes a surface: the options' and the bodies' own. */
static double largest_alpha(const nts_scene* s, double alpha) {
    double a = alpha;
    int b;
    for (b = 0; b < s->body_count; ++b)
        if (s->body_alpha[b] > a) a = s->body_alpha[b];
    return a;
}

/* Cells and masters (docs/model.md §9). The cell side is the typical reach;
 * the masters that reach farther are listed in every cell their reach box
 * overlaps. When the longest reach is within half again the typical, it sets
 * the side itself and there are no long lists; when the long lists would be
 * too many, the side doubles, at most up to the longest reach. */
/* The round-off of the grid's frame, relative to the size of the
 * coordinates (not of the cells): it widens every reach. */
static double frame_pad(const nts_scene* s, const seg_summary* ss) {
    return 1e-12 * (ss->coord_max + (ss->xmax - ss->xmin) + (ss->ymax - ss->ymin) + s->lx + s->ly);
}

/* Every reach around the middle is at most (1/2 + ext + alpha) L_max. */
static double longest_reach(const nts_scene* s, const search_env* env, const seg_summary* ss) {
    return reach_allowed((0.5 + env->ext + largest_alpha(s, env->alpha)) * ss->lmax, env->r, frame_pad(s, ss)) *
           (1.0 + 1e-11);
}

/* The cell side the grid starts from: the typical reach, or the longest
 * when it is at most half again as much; `min_cells` (when asked) the room
 * for alpha = 0. */
static double first_side(nts_context* ctx, const nts_scene* s, const search_env* env, const seg_summary* ss,
                         int* min_cells) {
    const double hmax = longest_reach(s, env, ss);
    double typical, finest;
    assert(env->run != NULL);
    typical_reach(ctx, s, env->alpha, env->ext, env->r, frame_pad(s, ss), (double*)(void*)ctx->scratch, &typical,
                  min_cells != NULL ? &finest : NULL, env->run);
    /* The cells are smaller with a smaller alpha (the corners reach less):
     * room for the grid of alpha = 0, so that a warm context allocates
     * nothing when only the options' alpha changes. */
    if (min_cells != NULL) *min_cells = finest > 0.0 ? nts_cells_count(s, ss, finest) : 0;
    return hmax <= 1.5 * typical || !(typical > 0.0) ? hmax : typical;
}

/* nts_summary.cell_size: the side of the cells a search from scratch
 * starts from (first_side), with or without a kept list, so that every door
 * gives the same summary (the long lists may coarsen the grid after). A
 * kept step computes it too: without the room for alpha = 0, which only a
 * build of the cells needs. */
static double summary_cell_side(nts_context* ctx, const nts_scene* s, const search_env* env, const seg_summary* ss) {
    return nts_cells_side(s, ss, first_side(ctx, s, env, ss, NULL));
}

static int build_cells(nts_context* ctx, const nts_scene* s, const search_env* env, const seg_summary* ss,
                       const nts_run* run, double* first) {
    /* At most this many (long master, cell) pairs: a few per surface node. */
    const long long budget = 4LL * s->surface_count + 4096;
    const double pad = frame_pad(s, ss), hmax = longest_reach(s, env, ss);
    double hc = 0.0;
    int round, rc, min_cells = 0;
    for (round = 0;; ++round) {
        if (round == 0) {
            hc = *first = first_side(ctx, s, env, ss, &min_cells);
        } else {
            hc = 2.0 * hc < hmax ? 2.0 * hc : hmax;
        }
        if ((rc = nts_cells_shape(&ctx->cells, s, ss, hc, min_cells)) != NTS_OK) return rc;
        /* At hmax every master fits (hmax bounds every reach). */
        rc = nts_masters_build(ctx, s, env->alpha, env->ext, env->r, hc < hmax ? hc : 0.0, pad, budget, min_cells, run);
        if (rc != NTS_ELIMIT) return rc;
        /* Every master fits at hmax: no long lists, no NTS_ELIMIT. */
        assert(hc < hmax && round < 64);
    }
}

/* The cells for radius env->r, built in the middle of an evaluation that
 * replays kept lists, for a widened search that reaches past them (reach.c). */
int nts_cells_now(nts_context* ctx, search_env* env) {
    const nts_scene* s = env->s;
    double first;
    int rc;
    if (env->cells != NULL) return NTS_OK;
    if ((rc = build_cells(ctx, s, env, env->ss, env->run, &first)) != NTS_OK) return rc;
    /* nts_summary.cell_size (what summary_cell_side gives), unless already
     * set: a widened search builds the cells after it is (reach.c); evaluate()
     * puts a distributed frame's in its place after this */
    if (env->cell_side < 0.0) env->cell_side = nts_cells_side(s, env->ss, first);
    env->cells = &ctx->cells;
    env->keys = &ctx->keys;
    if (ctx->long_count > 0) {
        env->long_m = ctx->long_m;
        env->long_start = ctx->long_start;
        env->long_items = ctx->long_items;
    }
    if (env->kept != NULL) ++((nts_candidates*)(void*)env->kept)->cell_builds; /* the caller's object: a count */
    return NTS_OK;
}

typedef struct collect_task {
    const search_env* env;
    nts_candidates* kc;
} collect_task;

/* Chunks [begin, end) of the kept lists; a chunk's failure in its count.
 * The caller's cancel is asked before each chunk (KEPT_CHUNK = 1024 slaves,
 * as the search asks it), so that a deadline does not wait for a whole
 * build; a chunk it stops is NTS_ECANCELLED. */
static void collect_chunks(int begin, int end, int t, void* p) {
    const collect_task* ct = (const collect_task*)p;
    const search_env* env = ct->env;
    int c;
    (void)t;
    for (c = begin; c < end; ++c) {
        int rc;
        if (env->cancel != NULL && env->cancel(env->cancel_user)) {
            ct->kc->chunk_used[c] = NTS_ECANCELLED;
            continue;
        }
        rc = nts_kept_collect(env, ct->kc, c);
        if (rc != NTS_OK) ct->kc->chunk_used[c] = rc;
    }
}

/* Kept candidates (docs/model.md §15): the lists replayed when they hold
 * (no cells: *cells 0), or built, from the cells of their outer radius,
 * which then serve this evaluation's widened searches too (cells built for
 * a larger radius hold every master the normal ones would). A build over
 * its budget leaves the lists off for a while: the search from scratch, on
 * those cells. */
static int kept_prepare(nts_context* ctx, search_env* env, nts_candidates* kc, int* cells) {
    const nts_scene* s = env->s;
    search_env wide;
    collect_task ct;
    double h;
    int rc, c, nchunk;
    *cells = 1;
    ++kc->evaluations;
    if (nts_kept_valid(kc, s, env->ss->moved, env->alpha, env->ext, env->r, env->wide_pad)) {
        env->kept = kc;
        env->kept_shift = nts_kept_shift(kc, env->wide_pad);
        *cells = 0;
        return NTS_OK;
    }
    if (kc->backoff > 0) {
        --kc->backoff;
        return NTS_OK;
    }
    rc = nts_kept_begin(kc, s, ctx->seg, env->alpha, largest_alpha(s, env->alpha), env->ext, env->r, env->wide_pad);
    if (rc != NTS_OK) return rc;
    /* In a periodic box the lists' reach must stay below half the box (the
     * minimum image), as the search's does. */
    h = (1.0 + env->ext) * env->ss->lmax + kc->outer;
    if (s->lx > 0.0 && !(2.0 * h < s->lx && 2.0 * h < s->ly)) return NTS_OK;
    wide = *env;
    wide.r = kc->outer;
    if ((rc = nts_cells_now(ctx, &wide)) != NTS_OK) return rc;
    env->cells = wide.cells;
    env->keys = wide.keys;
    env->long_m = wide.long_m;
    env->long_start = wide.long_start;
    env->long_items = wide.long_items;
    if ((rc = nts_kept_key_bases(kc, ctx->keys.reach2, ctx->keys.count, ctx->cells.scale,
                                  env->ss->coord_max + s->lx + s->ly)) != NTS_OK)
        return rc;
    nchunk = (s->surface_count + KEPT_CHUNK - 1) / KEPT_CHUNK;
    ct.env = &wide;
    ct.kc = kc;
    for (c = 0; c < nchunk; ++c) kc->chunk_used[c] = 0;
    nts_run_tasks(env->run, collect_chunks, nchunk, 1, &ct);
    for (c = 0; c < nchunk; ++c) {
        if (kc->chunk_used[c] == NTS_ENOMEM) return NTS_ENOMEM;
        if (kc->chunk_used[c] == NTS_ECANCELLED) return NTS_ECANCELLED; /* (not built: the next one builds) */
        if (kc->chunk_used[c] < 0) {
            /* over budget: from scratch for the next 16 evaluations, and
             * what the build grew given back */
            nts_kept_drop(kc);
            kc->backoff = 16;
            return NTS_OK;
        }
    }
    nts_kept_end(kc, s, ctx->seg);
    env->kept = kc;
    env->kept_prune = kc;
    env->kept_shift = nts_kept_shift(kc, env->wide_pad);
    return NTS_OK;
}

typedef struct search_task {
    nts_context* ctx;
    const search_env* env;
} search_task;

/* Chunks [begin, end) of slaves, on `worker`'s scratch; each chunk's records
 * and items kept in the pools, whoever ran it. */
static void search_chunks(int begin, int end, int t, void* p) {
    const search_task* st = (const search_task*)p;
    nts_context* ctx = st->ctx;
    const search_env* env = st->env;
    const int n = env->s->surface_count;
    worker* w = &ctx->workers[t];
    int i;
    for (i = begin; i < end; ++i) {
        chunk_info* ch = &ctx->chunks[i];
        const int first = i * CHUNK_SLAVES, last = first + CHUNK_SLAVES < n ? first + CHUNK_SLAVES : n;
        chunk_part* recs = &ch->part[STREAM_RECORDS];
        chunk_part* items = &ch->part[STREAM_REACH];
        ch->worker = t;
        /* the chunk's own records and items, then kept in the pools */
        w->rec_count = w->share_count = w->item_count = 0;
        w->last_slave = w->first_slave = -1;
        w->sums = &ch->sums;
        if (w->status == NTS_OK) nts_search_range(env, w, first, last);
        recs->count = env->shares ? w->share_count : w->rec_count;
        if (env->shares) chunk_node_span(ch, w->shares, w->share_count); /* (just written: in cache) */
        items->count = w->item_count;
        if (w->status == NTS_OK && recs->count > 0)
            nts_chunk_keep(ctx, w, ch, STREAM_RECORDS, env->shares ? (const void*)w->shares : (const void*)w->recs,
                           (size_t)recs->count * (env->shares ? sizeof(force_shares) : sizeof(candidate)));
        if (w->status == NTS_OK && items->count > 0)
            nts_chunk_keep(ctx, w, ch, STREAM_REACH, w->items, (size_t)items->count * sizeof(reach_item));
    }
}

/* Self-contact (docs/model.md §16): the entries of each self-contact body
 * unwrapped along its loops, from its outer loop's first node (each hole's
 * first node by the minimum image from there), so that the body's coverage
 * is taken in one frame, and a master's image is told from the slave's own
 * (search.c, self_same_image and self_settle). */
static int self_unwrap(nts_context* ctx, const nts_scene* s) {
    int b, l, e;
    if (nts_grow((void**)&ctx->self_u, &ctx->self_u_cap, s->surface_count, sizeof(nts_vec2)) != NTS_OK)
        return NTS_ENOMEM;
    for (b = 0; b < s->body_count; ++b) {
        const int l0 = s->body_loop_start[b], l1 = s->body_loop_start[b + 1];
        nts_vec2 p0;
        if (!s->body_self[b] || l0 == l1) continue;
        p0 = ctx->seg[s->loop_start[l0]].p;
        for (l = l0; l < l1; ++l) {
            const int first = s->loop_start[l], last = s->loop_start[l + 1] - 1;
            const nts_vec2 q = ctx->seg[first].p;
            ctx->self_u[first] = nts_add(p0, nts_scene_diff(s, q, p0));
            for (e = first; e < last; ++e) ctx->self_u[e + 1] = nts_add(ctx->self_u[e], ctx->seg[e].t);
        }
    }
    return NTS_OK;
}

/* The coverage's slabs (search.h): for each self-contact body, its loop
 * edges (each entry to the next along its loop, unwrapped) listed by the
 * horizontal slabs their heights span; about the square root of its entries
 * of slabs, so that a count of crossings reads one slab's edges. */
static int self_slabs_build(nts_context* ctx, const nts_scene* s) {
    int b, e, k, slabs = 0, items = 0, rc;
    if ((rc = nts_grow((void**)&ctx->self_y, &ctx->self_y_cap, 2 * s->body_count, sizeof(double))) != NTS_OK ||
        (rc = nts_grow((void**)&ctx->self_first, &ctx->self_first_cap, s->body_count + 1, sizeof(int))) != NTS_OK)
        return rc;
    for (b = 0; b < s->body_count; ++b) { /* each body's slabs, its heights */
        const int e0 = s->loop_start[s->body_loop_start[b]], e1 = s->loop_start[s->body_loop_start[b + 1]];
        double lo = 0.0, hi = 0.0;
        int n = 0;
        ctx->self_first[b] = slabs;
        ctx->self_y[2 * b] = 0.0;
        ctx->self_y[2 * b + 1] = 0.0;
        /* a small body is read whole (self_first: no slab), as cheaply as a
         * slab is found; only a large one pays for building them */
        if (!s->body_self[b] || e1 - e0 < NTS_SELF_SLAB_MIN) continue;
        lo = hi = ctx->self_u[e0].y;
        for (e = e0; e < e1; ++e) {
            lo = ctx->self_u[e].y < lo ? ctx->self_u[e].y : lo;
            hi = ctx->self_u[e].y > hi ? ctx->self_u[e].y : hi;
        }
        while ((long long)n * n < e1 - e0) ++n; /* ceil(sqrt(entries)) */
        ctx->self_y[2 * b] = lo;
        ctx->self_y[2 * b + 1] = hi > lo ? n / (hi - lo) : 0.0; /* flat: one slab */
        slabs += hi > lo ? n : 1;
    }
    ctx->self_first[s->body_count] = slabs;
    if ((rc = nts_grow((void**)&ctx->self_start, &ctx->self_start_cap, slabs + 1, sizeof(int))) != NTS_OK) return rc;
    memset(ctx->self_start, 0, sizeof(int) * (size_t)(slabs + 1));
    for (k = 0; k < 2; ++k) { /* count, then fill */
        for (b = 0; b < s->body_count; ++b) {
            const int e0 = s->loop_start[s->body_loop_start[b]], e1 = s->loop_start[s->body_loop_start[b + 1]];
            const int f = ctx->self_first[b], count = ctx->self_first[b + 1] - f;
            if (count == 0) continue;
            for (e = e0; e < e1; ++e) {
                const double ya = ctx->self_u[e].y, yb = ctx->self_u[ctx->seg[e].next].y;
                int q0 = nts_self_slab(ctx->self_y + 2 * b, count, ya < yb ? ya : yb);
                const int q1 = nts_self_slab(ctx->self_y + 2 * b, count, ya < yb ? yb : ya);
                for (; q0 <= q1; ++q0) {
                    if (k == 0) ++ctx->self_start[f + q0 + 1];
                    else ctx->self_items[ctx->self_start[f + q0]++] = e;
                }
            }
        }
        if (k == 0) {
            for (b = 0; b < slabs; ++b) ctx->self_start[b + 1] += ctx->self_start[b];
            items = ctx->self_start[slabs];
            if ((rc = nts_grow((void**)&ctx->self_items, &ctx->self_items_cap, items > 0 ? items : 1, sizeof(int))) != NTS_OK)
                return rc;
        }
    }
    for (b = slabs; b > 0; --b) ctx->self_start[b] = ctx->self_start[b - 1]; /* the fill moved each start to its end */
    ctx->self_start[0] = 0;
    return NTS_OK;
}

/* nts_evaluate, at the scene's positions (fresh NULL), or at new positions
 * `fresh` checked in the segment pass and taken when they pass
 * (nts_evaluate_positions: the scene is then not const). *taken: 1 once
 * they are, 0 when they are rejected (the error is then
 * nts_scene_update_positions's to give), left as it was when the
 * evaluation stops before they are judged. `loops_only`: only the nodes on
 * the loops are read from fresh and taken (nts_evaluate_surface_positions:
 * the segment pass reads no other; the others keep their stored positions,
 * checked when they were taken). */
static int evaluate(nts_context* ctx, const nts_scene* s, const nts_vec2* fresh, const nts_options* opt,
                    nts_result* out, nts_error* err, int* taken, int loops_only) {
    search_env env;
    seg_summary ss;
    double h;
    search_task st;
    nts_run run;
    int i, rc, nthreads, nchunk;
    double t0 = wall_time(), t1, search_s;

    if (err != NULL) *err = nts_error_none();
    if (ctx == NULL || s == NULL || opt == NULL || out == NULL)
        return eval_fail(err, NTS_EINVALID_ARGUMENT, -1, -1, "null argument");
    if ((rc = nts_options_validate(opt, err)) != NTS_OK) return rc;
    memset(out, 0, sizeof *out);
    if (fresh != NULL && !loops_only && !nts_scene_interior_in_range(s, fresh)) {
        *taken = 0;
        return NTS_OK; /* the caller's check names the coordinate */
    }
    /* The workers: the host's (nts_context_set_parallel: the indices it
     * gives are below its count), or the build's own on opt->threads, no
     * more than there are slaves. */
    if (ctx->host_set) {
        run.backend = ctx->host;
        run.workers = ctx->host.worker_count;
    } else {
        run = nts_run_stock(opt->threads < s->surface_count ? opt->threads : s->surface_count);
    }
    nthreads = run.workers;

    /* 1. Segments, and the median segment: a typical segment, not the
     * longest, sets the default search radius, so that one long wall does
     * not widen the search (docs/model.md §9). */
    if ((rc = nts_grow((void**)&ctx->scratch, &ctx->scratch_cap, 2 * (s->surface_count + NTS_SAMPLE), sizeof(int))) !=
        NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    /* (a part of a distributed scene takes the whole's median from its frame) */
    if (fresh != NULL &&
        (rc = nts_grow((void**)&ctx->area_perim, &ctx->area_perim_cap, 2 * s->loop_total, sizeof(double))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    rc = nts_segments_compute(ctx, s, fresh,
                              opt->search_radius < 0.0 && s->surface_count > 0 && !ctx->frame_set
                                  ? (s->surface_count - 1) / 2
                                  : -1,
                              (double*)(void*)ctx->scratch, nts_kept_since(opt->candidates, s),
                              fresh != NULL ? ctx->area_perim : NULL, &run, &ss);
    if (rc != NTS_OK) return eval_fail(err, rc, -1, -1, "out of memory");
    if (fresh != NULL) {
        /* New positions are taken only when every check of the scene's
         * passes (its loops' in the pass above, their areas' here), before
         * anything reads the scene's positions. */
        if (ss.rejected || !nts_scene_keeps_shape((nts_scene*)s, ctx->area_perim)) {
            *taken = 0;
            return NTS_OK;
        }
        if (loops_only) {
            nts_vec2* pos = ((nts_scene*)s)->pos;
            for (i = 0; i < s->surface_count; ++i) pos[s->surf_node[i]] = fresh[s->surf_node[i]];
        } else {
            memmove(s->pos, fresh, sizeof(nts_vec2) * (size_t)s->node_count); /* (fresh may be the scene's own) */
        }
        *taken = 1;
    }
    if (ss.bad < s->surface_count) {
        const int bad = ss.bad;
        char msg[160];
        const double l2 = nts_length_sq(ctx->seg[bad].t);
        snprintf(msg, sizeof msg, "body %d: segment from node %d has length %.3g, outside [1e-100, 3e100]",
                 s->surf_body[bad], s->surf_local[bad], sqrt(l2));
        return eval_fail(err, NTS_EDEGENERATE_SEGMENT, s->surf_body[bad], s->surf_local[bad], msg);
    }
    if (ctx->frame_set) {
        /* A part of a distributed scene (ntscontact/distributed.h): what the
         * whole's segments set, so that every slave's answer is the one the
         * whole scene gives it (docs/distributed.md). */
        ss.kth = ctx->frame.median;
        ss.lmax = ctx->frame.lmax;
        ss.coord_max = ctx->frame.coord_max;
        ss.xmin = ctx->frame.xmin;
        ss.xmax = ctx->frame.xmax;
        ss.ymin = ctx->frame.ymin;
        ss.ymax = ctx->frame.ymax;
    }
    t1 = wall_time();
    ctx->phase[0] = t1 - t0;
    ctx->median_from = ss.kth_from;
    t0 = t1;

    /* 2. The search radius, the cells and the masters. */
    memset(&env, 0, sizeof env);
    env.s = s;
    env.seg = ctx->seg;
    env.alpha = opt->alpha;
    for (i = 0; i < s->body_count && !env.body_alphas; ++i) env.body_alphas = s->body_alpha[i] >= 0.0;
    env.surf_flag = s->surf_flag;
    if (s->self_bodies > 0) { /* nothing of it runs otherwise */
        if ((rc = self_unwrap(ctx, s)) != NTS_OK || (rc = self_slabs_build(ctx, s)) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        env.self = s->body_self;
        env.self_u = ctx->self_u;
        env.self_y = ctx->self_y;
        env.self_first = ctx->self_first;
        env.self_start = ctx->self_start;
        env.self_items = ctx->self_items;
    }
    /* no surface's end (in the whole scene, for a part): nothing to extend */
    env.ext = (ctx->frame_set ? ctx->frame.surface_ends : s->surf_ends > 0) ? opt->surface_extension : 0.0;
    env.eps = opt->penalty;
    env.per_length = opt->penalty_scaling == NTS_PENALTY_PER_LENGTH;
    env.max_records = nts_candidate_budget(opt, ctx->frame_set ? ctx->frame.surface_nodes : s->surface_count);
    env.cancel = opt->cancel;
    env.cancel_user = opt->cancel_user;
    if (opt->search_radius >= 0.0) env.r = opt->search_radius;
    else if (s->surface_count > 0) env.r = ss.kth; /* the median segment, exactly */
    env.solver = opt->solver;
    env.want_virial = (opt->outputs & NTS_OUT_VIRIAL) != 0u;
    /* tables.h's records column */
    env.keep_all = (opt->outputs & (unsigned)NTS_OUT_RECORDS_) != 0u;
    env.owned = ctx->parts_on ? ctx->owned : NULL;
    /* Friction (docs/model.md §14): on when some pair can rub; then the
     * records path (each active record's friction is computed once, after
     * the search, and read by the sums, the forces, the contacts and the
     * tangent). Off, nothing of it runs: today's bits. */
    env.friction = ctx->frame_set ? nts_friction_rubs(ctx->frame.rubbing) : nts_friction_on(s, opt);
    if (env.friction && opt->history != NULL && opt->history->count > 0) {
        /* anchors of this scene only (one committed from another scene's
         * evaluation would be read out of range): checked where used */
        if ((rc = nts_grow((void**)&ctx->entry_of, &ctx->entry_of_cap, s->node_count > 0 ? s->node_count : 1,
                           sizeof(int))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if ((rc = nts_history_check(opt->history, s, ctx->entry_of, err)) != NTS_OK) return rc;
    }
    if (env.friction) {
        env.mu = opt->friction;
        env.eps_t = opt->tangential_penalty > 0.0 ? opt->tangential_penalty : opt->penalty;
        env.history = opt->history;
        env.keep_all = 1;
    }
    h = (1.0 + env.ext) * ss.lmax + env.r; /* every feature lies within (1 + ext) L_max + r of its master node */
    if (s->lx > 0.0 && !(2.0 * h < s->lx && 2.0 * h < s->ly)) {
        char msg[160];
        snprintf(msg, sizeof msg, "periodic box %.6g x %.6g must exceed twice the search reach %.6g", s->lx, s->ly, h);
        rc = eval_fail_option(err, NTS_EBOX_TOO_SMALL, "periodic", msg);
        return rc;
    }
    env.lx = s->lx;
    env.ly = s->ly;
    env.qx = 0.25 * s->lx;
    env.qy = 0.25 * s->ly;
    env.ss = &ss;
    env.run = &run;
    /* The reach's growth (reach.c): the round-off of its tests (that of the
     * grid's frame, the larger), and its largest radius: the scene's
     * diagonal, within which every feature lies; in a periodic box, the
     * radius beyond which an image could be nearer than the minimum one. */
    env.grow = opt->search_radius < 0.0;
    env.coarse = 2.0 * env.r;
    env.wide_lmax = (1.0 + env.ext) * ss.lmax;
    env.wide_pad = 1e-12 * (ss.coord_max + (ss.xmax - ss.xmin) + (ss.ymax - ss.ymin) + s->lx + s->ly);
    if (s->lx > 0.0)
        env.reach_max = 0.5 * (s->lx < s->ly ? s->lx : s->ly) - env.wide_lmax * (1.0 + 1e-9) - env.wide_pad;
    else
        env.reach_max = sqrt((ss.xmax - ss.xmin) * (ss.xmax - ss.xmin) + (ss.ymax - ss.ymin) * (ss.ymax - ss.ymin)) *
                            (1.0 + 1e-9) + env.wide_pad;
    if (env.reach_max < env.r) env.reach_max = env.r;
    if (opt->search == NTS_SEARCH_CELLS && s->surface_count > 0) {
        int cells = 1;
        env.cell_side = -1.0; /* set by nts_cells_now when it builds the cells */
        if (opt->candidates != NULL && (rc = kept_prepare(ctx, &env, opt->candidates, &cells)) != NTS_OK)
            return eval_fail(err, rc, -1, -1, rc == NTS_ECANCELLED ? CANCELLED : "out of memory");
        if (env.kept != NULL) env.kept_ahead = nts_kept_ahead(opt->candidates, s->surface_count);
        if (cells && (rc = nts_cells_now(ctx, &env)) != NTS_OK) return eval_fail(err, rc, -1, -1, "out of memory");
        if (ctx->frame_set && ctx->frame.cell_size >= 0.0)
            env.cell_side = ctx->frame.cell_size;
        else if (env.cell_side < 0.0)
            env.cell_side = summary_cell_side(ctx, s, &env, &ss);
    } else {
        /* The minimum image's round-off, for brute force's reach test. */
        env.brute_pad = 1e-12 * (ss.coord_max + s->lx + s->ly);
    }
    t1 = wall_time();
    ctx->phase[1] = t1 - t0;
    t0 = t1;

    /* 3. Local search, chunk by chunk, the chunks handed out by the backend
     * (parallel_omp.c: a contiguous block per thread, then stolen by
     * whichever thread is free) and their records kept in one pool for all
     * the chunks (the scatter reads them in chunk order, whoever ran them). */
    nchunk = (s->surface_count + CHUNK_SLAVES - 1) / CHUNK_SLAVES;
    if ((rc = nts_workers_prepare(ctx, nthreads, s->body_count, nchunk)) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    /* One thread and no records asked for: no records at all, the search
     * sums and scatters each slave's contacts itself (search_env.direct). */
    env.direct = nthreads == 1 && !env.keep_all && !ctx->parts_on; /* parts read records */
    /* Several threads and no records asked for: each chunk its sums and
     * force shares, no records (search_env.shares). */
    env.shares = nthreads > 1 && !env.keep_all && !ctx->parts_on;
    env.want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
    if (env.direct && env.want_forces) {
        /* A mesh's interior nodes (most of its nodes) get no force: when this
         * scene wrote forces[] last, they still hold zero, and only the
         * surface nodes' forces are cleared (the adds reach no other). */
        const int clean = ctx->forces_serial == s->serial && 2 * (long long)s->surface_count <= s->node_count;
        ctx->forces_serial = 0;
        if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if (clean) {
            for (i = 0; i < s->surface_count; ++i) ctx->forces[s->surf_node[i]] = nts_v2(0.0, 0.0);
        } else {
            memset(ctx->forces, 0, sizeof(nts_vec2) * (size_t)s->node_count);
        }
        ctx->forces_serial = s->serial;
        env.forces = ctx->forces;
    }
    /* (a worker that the machine slows down takes fewer chunks) */
    st.ctx = ctx;
    st.env = &env;
    search_s = wall_time();
    nts_run_tasks(&run, search_chunks, nchunk, 1, &st);
    search_s = wall_time() - search_s;
    {
        long long records = 0, owned_gaps = 0;
        int limited = 0, status = NTS_OK;
        for (i = 0; i < nthreads; ++i) {
            records += ctx->workers[i].gaps;
            owned_gaps += ctx->workers[i].owned_gaps;
            if (env.kept_prune != NULL) env.kept_prune->pruned += ctx->workers[i].pruned; /* (0 at its build) */
            if (ctx->workers[i].status == NTS_ELIMIT) limited = 1;
            else if (ctx->workers[i].status != NTS_OK && status == NTS_OK) status = ctx->workers[i].status;
        }
        if (status == NTS_ECANCELLED || (status == NTS_OK && env.cancel != NULL && env.cancel(env.cancel_user)))
            return eval_fail(err, NTS_ECANCELLED, -1, -1, CANCELLED);
        if (limited || records > env.max_records) {
            char msg[192];
            nts_candidate_budget_message(msg, sizeof msg, env.max_records, 0);
            rc = eval_fail_option(err, NTS_ELIMIT, "max_candidates", msg);
            return rc;
        }
        if (status != NTS_OK) return eval_fail(err, status, -1, -1, "out of memory");
        /* a replay's search that completed: its time, for its choice of asking ahead (nts_kept_ahead) */
        if (env.kept != NULL) nts_kept_ahead_timed(opt->candidates, env.kept_ahead, search_s);
        ctx->owned_gaps = owned_gaps;
        if ((rc = nts_chunks_settle(ctx, nthreads, env.shares)) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        /* The active contacts deeper than r, found (default radius) or
         * counted (an explicit one). */
        rc = nts_reach_grow(ctx, &env, records, &run);
        if (rc == NTS_ECANCELLED)
            return eval_fail(err, rc, -1, -1, CANCELLED);
        if (rc == NTS_ELIMIT) {
            char msg[192];
            nts_candidate_budget_message(msg, sizeof msg, env.max_records, 1);
            rc = eval_fail_option(err, NTS_ELIMIT, "max_candidates", msg);
            return rc;
        }
        if (rc != NTS_OK) return eval_fail(err, rc, -1, -1, "out of memory");
    }
    t1 = wall_time();
    ctx->phase[2] = t1 - t0;
    t0 = t1;

    /* 4. Scatter and summary (scatter.c). */
    if ((rc = nts_scatter(ctx, s, opt, &env, &run, out, err)) != NTS_OK) return rc;
    ctx->phase[3] = wall_time() - t0;
    return NTS_OK;
}

int nts_evaluate(nts_context* ctx, const nts_scene* s, const nts_options* opt, nts_result* out, nts_error* err) {
    return evaluate(ctx, s, NULL, opt, out, err, NULL, 0);
}

/* nts_evaluate_positions and nts_evaluate_surface_positions: `positions`
 * are every node's, or (loops_only) read at the loops' nodes alone and
 * completed, on the slow paths, with the stored positions of the others. */
static int evaluate_at(nts_context* ctx, nts_scene* s, const nts_vec2* positions, const nts_options* opt,
                       nts_result* out, nts_error* err, int loops_only) {
    nts_result kept;
    nts_vec2* whole = NULL;
    int taken = -1, rc, i;
    if (out != NULL && s != NULL && positions != NULL) {
        kept = *out;
        rc = evaluate(ctx, s, positions, opt, out, err, &taken, loops_only);
        if (taken == 1) return rc;
        *out = kept;
    }
    if (loops_only && s != NULL && positions != NULL) {
        /* Every node's positions for the update's check: the stored ones
         * with the loops' nodes given. */
        whole = (nts_vec2*)nts_alloc(sizeof(nts_vec2) * (size_t)(s->node_count > 0 ? s->node_count : 1));
        if (whole == NULL) return eval_fail(err, NTS_ENOMEM, -1, -1, "out of memory");
        memcpy(whole, s->pos, sizeof(nts_vec2) * (size_t)s->node_count);
        for (i = 0; i < s->surface_count; ++i) whole[s->surf_node[i]] = positions[s->surf_node[i]];
        positions = whole;
    }
    if (taken != 0) {
        /* Stopped before the positions were judged (a null argument, an
         * option out of range, no memory), or no result asked for: the two
         * calls, in their order. */
        rc = nts_scene_update_positions(s, positions, err);
        nts_free(whole);
        return rc != NTS_OK ? rc : nts_evaluate(ctx, s, opt, out, err);
    }
    /* Rejected: the scene's own check finds the first fault in its order and
     * names it (nts_scene_update_positions), and leaves the scene (and *out)
     * as they were. */
    rc = nts_scene_update_positions(s, positions, err);
    nts_free(whole);
    if (rc != NTS_OK) return rc;
    /* The two checks decide by the same bits (checks.h): a disagreement is a
     * fault of this library, said as one rather than hidden behind a slower
     * right answer. The positions are taken; nts_evaluate gives the answer. */
    return eval_fail(err, NTS_EINTERNAL, -1, -1, "the checks of the positions in the segment pass refused what the "
                                                 "scene's own check takes");
}

int nts_evaluate_positions(nts_context* ctx, nts_scene* s, const nts_vec2* positions, const nts_options* opt,
                           nts_result* out, nts_error* err) {
    return evaluate_at(ctx, s, positions, opt, out, err, 0);
}

int nts_evaluate_surface_positions(nts_context* ctx, nts_scene* s, const nts_vec2* positions,
                                   const nts_options* opt, nts_result* out, nts_error* err) {
    return evaluate_at(ctx, s, positions, opt, out, err, 1);
}

/* The frame of a scene (ntscontact/distributed.h): what nts_evaluate's first
 * two phases take from the segments, computed as they compute it. */
int nts_scene_frame(nts_context* ctx, const nts_scene* s, const nts_options* opt, nts_frame* out, double* lengths,
                    nts_error* err) {
    seg_summary ss;
    search_env env;
    nts_run run;
    int rc, i, light;
    if (err != NULL) *err = nts_error_none();
    if (ctx == NULL || s == NULL || opt == NULL || out == NULL)
        return eval_fail(err, NTS_EINVALID_ARGUMENT, -1, -1, "null argument");
    if ((rc = nts_options_validate(opt, err)) != NTS_OK) return rc;
    light = opt->search_radius >= 0.0 && opt->search != NTS_SEARCH_CELLS;
    memset(out, 0, sizeof *out);
    out->cell_size = 0.0;
    out->surface_nodes = s->surface_count;
    out->surface_ends = s->surf_ends > 0;
    nts_friction_counts(s, opt, out->rubbing);
    run = nts_run_stock(0);
    if (light) {
        /* neither the median nor the cells asked: the lengths and extremes
         * alone, no segment data (a distributed host's own bodies) */
        nts_segments_lengths(s, lengths, &run, &ss);
    } else {
        if ((rc = nts_grow((void**)&ctx->scratch, &ctx->scratch_cap, 2 * (s->surface_count + NTS_SAMPLE),
                           sizeof(int))) != NTS_OK ||
            (rc = nts_segments_compute(ctx, s, NULL,
                                       opt->search_radius < 0.0 && s->surface_count > 0 ? (s->surface_count - 1) / 2
                                                                                         : -1,
                                       (double*)(void*)ctx->scratch, NULL, NULL, &run, &ss)) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
    }
    if (ss.bad < s->surface_count)
        return eval_fail(err, NTS_EDEGENERATE_SEGMENT, s->surf_body[ss.bad], s->surf_local[ss.bad],
                         "a segment's length is outside [1e-100, 3e100]");
    out->lmax = ss.lmax;
    out->coord_max = ss.coord_max;
    out->xmin = ss.xmin;
    out->xmax = ss.xmax;
    out->ymin = ss.ymin;
    out->ymax = ss.ymax;
    if (light) return NTS_OK;
    out->median = ss.kth;
    if (lengths != NULL)
        for (i = 0; i < s->surface_count; ++i) lengths[i] = ctx->seg[i].len;
    if (opt->search == NTS_SEARCH_CELLS && s->surface_count > 0) {
        memset(&env, 0, sizeof env);
        env.s = s;
        env.seg = ctx->seg;
        env.alpha = opt->alpha;
        env.ext = s->surf_ends > 0 ? opt->surface_extension : 0.0;
        env.r = opt->search_radius >= 0.0 ? opt->search_radius : ss.kth;
        env.run = &run;
        out->cell_size = summary_cell_side(ctx, s, &env, &ss);
    }
    return NTS_OK;
}
