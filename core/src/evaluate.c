/* Evaluation: global search (cells or brute force), local search per slave node
 * (docs/model.md §4), then forces, energy and virial ("Forces,
 * energy, virial"). The local search writes per-slave records into per-worker
 * buffers; a serial pass scatters them in slave order, so the result is bitwise
 * the same for any number of threads. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages.h"

#if NTS_CONFIG_OPENMP
#include <omp.h>
#endif
#include <time.h>

/* Wall clock for the phase profile (nts_context_profile). */
static double wall_time(void) {
#if NTS_CONFIG_OPENMP
    return omp_get_wtime();
#else
    return (double)clock() / (double)CLOCKS_PER_SEC;
#endif
}

int nts_evaluate(nts_context* ctx, const nts_scene* s, const nts_options* opt, nts_result* out, nts_error* err) {
    search_env env;
    double lmax = 0.0, h;
    int i, rc, nthreads = 1;
    double t0 = wall_time(), t1;

    if (err != NULL) *err = nts_error_none();
    if (ctx == NULL || s == NULL || opt == NULL || out == NULL)
        return eval_fail(err, NTS_EINVALID_ARGUMENT, -1, -1, "null argument");
    if ((rc = nts_options_validate(opt, err)) != NTS_OK) return rc;
    memset(out, 0, sizeof *out);
#if NTS_CONFIG_OPENMP
    if (opt->threads > 1) nthreads = opt->threads;
    if (nthreads > s->surface_count) nthreads = s->surface_count > 0 ? s->surface_count : 1;
#endif

    /* Segment data; a zero-length segment (possible after new positions) is an
     * error, never a division by zero. */
    if ((rc = nts_grow((void**)&ctx->seg, &ctx->seg_cap, s->surface_count, sizeof(seg_data))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    {
        /* Each segment is its own (in parallel); the first bad one in entry
         * order is the error, whatever the threads. */
        int bad = s->surface_count;
        NTS_PARALLEL_FOR(nthreads)
        for (i = 0; i < s->surface_count; ++i) {
            seg_data* sd = &ctx->seg[i];
            double l2;
            sd->t = nts_scene_diff(s, s->pos[s->surf_node[s->surf_next[i]]], s->pos[s->surf_node[i]]);
            l2 = nts_length_sq(sd->t);
            /* The supported range (scene.c): nts_scene_set_positions does not check
             * it, and 1/|t|^2 must not overflow. */
            if (!(l2 >= 1e-200) || !(l2 <= 1e201)) {
                sd->len = -1.0;
                continue;
            }
            sd->len = sqrt(l2);
            sd->inv_len2 = 1.0 / l2;
        }
        for (i = 0; i < s->surface_count; ++i) { /* serial: the first bad one, and the longest */
            if (!(ctx->seg[i].len > 0.0)) {
                bad = i;
                break;
            }
            if (ctx->seg[i].len > lmax) lmax = ctx->seg[i].len;
        }
        if (bad < s->surface_count) {
            char msg[160];
            double l2 = nts_length_sq(ctx->seg[bad].t);
            snprintf(msg, sizeof msg, "body %d: segment from node %d has length %.3g, outside [1e-100, 3e100]",
                     s->surf_body[bad], s->surf_local[bad], sqrt(l2));
            return eval_fail(err, NTS_EDEGENERATE_SEGMENT, s->surf_body[bad], s->surf_local[bad], msg);
        }
    }

    t1 = wall_time();
    ctx->phase[0] = t1 - t0;
    t0 = t1;
    env.s = s;
    env.seg = ctx->seg;
    env.alpha = opt->alpha;
    env.eps = opt->penalty;
    env.per_length = opt->penalty_scaling == NTS_PENALTY_PER_LENGTH;
    env.max_records = opt->max_candidates > 0 ? opt->max_candidates : 64LL * s->surface_count + 1000000;
    if (env.max_records > INT_MAX) env.max_records = INT_MAX; /* the count is nts_summary.gaps, an int */
    env.cancel = opt->cancel;
    env.cancel_user = opt->cancel_user;
    env.long_m = NULL;
    env.long_start = NULL;
    env.long_items = NULL;
    /* A typical segment, not the longest, sets the default search radius and
     * the cell side, so that one long wall neither widens the search nor
     * coarsens the grid (docs/model.md, "Global search"): the median segment,
     * and the 95th percentile of the masters' reach lengths. */
    if ((rc = nts_grow((void**)&ctx->scratch, &ctx->scratch_cap, s->surface_count, sizeof(double))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    NTS_PARALLEL_FOR(nthreads)
    for (i = 0; i < s->surface_count; ++i) ctx->scratch[i] = ctx->seg[i].len;
    env.r = opt->search_radius < 0.0 ? nts_select_kth(ctx->scratch, s->surface_count, (s->surface_count - 1) / 2)
                                     : opt->search_radius;
    env.solver = opt->solver;
    env.want_virial = (opt->outputs & NTS_OUT_VIRIAL) != 0u;
    env.keep_all = (opt->outputs & (NTS_OUT_CONTACTS | NTS_OUT_GAPS | NTS_OUT_STIFFNESS)) != 0u;
    h = lmax + env.r; /* every feature lies within L_max + r of its master node */
    if (s->lx > 0.0 && !(2.0 * h < s->lx && 2.0 * h < s->ly)) {
        char msg[160];
        snprintf(msg, sizeof msg, "periodic box %.6g x %.6g must exceed twice the search reach %.6g", s->lx, s->ly, h);
        rc = eval_fail(err, NTS_EBOX_TOO_SMALL, -1, -1, msg);
        if (err != NULL) snprintf(err->option, sizeof err->option, "periodic");
        return rc;
    }
    env.lx = s->lx;
    env.ly = s->ly;
    env.qx = 0.25 * s->lx;
    env.qy = 0.25 * s->ly;
    env.cell_shift = 0;
    env.cells = NULL;
    if ((rc = nts_grow((void**)&ctx->keys, &ctx->keys_cap, s->surface_count, sizeof(master_key))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    env.keys = ctx->keys;
    if ((rc = nts_grow((void**)&ctx->hot, &ctx->hot_cap, s->surface_count, sizeof(master_hot))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    env.hot = ctx->hot;
    if (opt->search == NTS_SEARCH_CELLS) {
        const nts_cells* cl = &ctx->cells;
        /* At most this many (long master, cell) pairs: a few per surface node. */
        const long long budget = 4LL * s->surface_count + 4096;
        double scale, pad, hc;
        int round;
        NTS_PARALLEL_FOR(nthreads)
        for (i = 0; i < s->surface_count; ++i)
            ctx->scratch[i] = reach_length(ctx->seg, s, i, alpha_of_body(s, s->surf_body[i], env.alpha));
        hc = nts_select_kth(ctx->scratch, s->surface_count, (int)(0.95 * (double)(s->surface_count - 1))) + env.r;
        /* Long lists pay for a few masters that reach far beyond the rest
         * (walls); when the longest reach is within half again the typical,
         * it sets the side itself (a polydisperse packing: no long lists). */
        if (hc > h || h <= 1.5 * hc) hc = h;
        /* The cell side hc >= (typical reach) + r: masters that reach farther
         * are listed in every cell their reach box overlaps. Too many such
         * pairs: coarsen, at most until hc = L_max + r, where none is left. */
        for (round = 0;; ++round) {
            if ((rc = nts_cells_build(&ctx->cells, s, hc, nthreads)) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            /* The round-off of binning and of the cell frame, relative to the
             * size of the coordinates (not of the cells). */
            scale = fabs(cl->x0) + fabs(cl->y0) + cl->nx * cl->hx + cl->ny * cl->hy + s->lx + s->ly;
            pad = 1e-12 * scale;
            if ((rc = nts_fill_hot(ctx, s, cl->items, env.alpha, env.r, hc < h ? hc - env.r : 0.0, pad, nthreads)) !=
                NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            if (ctx->long_count == 0) break;
            rc = nts_build_long_lists(ctx, s, env.alpha, env.r, pad, budget);
            if (rc == NTS_OK) break;
            if (rc != NTS_ELIMIT) return eval_fail(err, rc, -1, -1, "out of memory");
            assert(round < 64);
            hc = 2.0 * hc < h ? 2.0 * hc : h;
        }
        env.cells = cl;
        if (ctx->long_count > 0) {
            env.long_m = ctx->long_m;
            env.long_start = ctx->long_start;
            env.long_items = ctx->long_items;
        }
        /* One image shift per stencil range: when every stencil offset is a
         * distinct image (then each master within reach is the nearest image). */
        env.cell_shift = !cl->periodic || (cl->nx >= 4 && cl->ny >= 4);
    } else {
        nts_fill_hot(ctx, s, NULL, env.alpha, env.r, 0.0, 0.0, nthreads); /* no long lists: cannot fail */
    }

    t1 = wall_time();
    ctx->phase[1] = t1 - t0;
    t0 = t1;
    if ((rc = nts_workers_prepare(ctx, nthreads, s->body_count)) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");

    /* Local search. Worker t handles the contiguous slave range t; the ranges are
     * concatenated in order below, which is the serial order. */
#if NTS_CONFIG_OPENMP
    if (nthreads > 1) {
        int t;
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
        for (t = 0; t < nthreads; ++t) {
            long long n = s->surface_count;
            nts_search_range(&env, &ctx->workers[t], (int)(n * t / nthreads), (int)(n * (t + 1) / nthreads));
        }
    } else
#endif
    {
        nts_search_range(&env, &ctx->workers[0], 0, s->surface_count);
    }
    {
        long long records = 0;
        int limited = 0, status = NTS_OK;
        for (i = 0; i < nthreads; ++i) {
            records += ctx->workers[i].gaps;
            if (ctx->workers[i].status == NTS_ELIMIT) limited = 1;
            else if (ctx->workers[i].status != NTS_OK && status == NTS_OK) status = ctx->workers[i].status;
        }
        if (status == NTS_ECANCELLED || (status == NTS_OK && env.cancel != NULL && env.cancel(env.cancel_user)))
            return eval_fail(err, NTS_ECANCELLED, -1, -1, "the evaluation was cancelled (a deadline passed, or the "
                                                          "caller asked)");
        if (limited || records > env.max_records) {
            char msg[192];
            snprintf(msg, sizeof msg, "more than max_candidates = %lld closest points within the search radius: "
                     "the bodies overlap far more than contact does (or raise the limit)", env.max_records);
            rc = eval_fail(err, NTS_ELIMIT, -1, -1, msg);
            if (err != NULL) snprintf(err->option, sizeof err->option, "max_candidates");
            return rc;
        }
        if (status != NTS_OK) return eval_fail(err, status, -1, -1, "out of memory");
    }

    t1 = wall_time();
    ctx->phase[2] = t1 - t0;
    t0 = t1;
    /* Scatter in slave order (scatter.c). */
    if ((rc = nts_scatter(ctx, s, opt, &env, nthreads, out, err)) != NTS_OK) return rc;
    ctx->phase[3] = wall_time() - t0;
    return NTS_OK;
}
