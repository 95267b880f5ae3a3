/* Evaluation: global search (cells or brute force), local search per slave node
 * (docs/model.md §4), then forces, energy and virial ("Forces,
 * energy, virial"). The local search writes per-slave records into per-worker
 * buffers; a serial pass scatters them in slave order, so the result is bitwise
 * the same for any number of threads. */
#include <stdio.h>
#include <string.h>

#include "baseline.h"

#if defined(NTS_HAVE_OPENMP)
#include <omp.h>
#endif
#include <time.h>

/* Wall clock for the phase timings (nts_context_phase_times). */
static double wall_time(void) {
#if defined(NTS_HAVE_OPENMP)
    return omp_get_wtime();
#else
    return (double)clock() / (double)CLOCKS_PER_SEC;
#endif
}

/* Per-surface-entry segment data, recomputed each evaluation from the positions:
 * the segment that starts at the entry. */
typedef struct seg_data {
    nts_vec2 t;      /* X1 - X0 (minimum image) */
    nts_vec2 n;      /* outward unit normal (t_y, -t_x)/|t| */
    double inv_len2; /* 1/|t|^2, |t| > 0 checked */
    double len;
} seg_data;

/* One worker's scratch: the per-slave best candidate of each master body, and
 * the records (nts_contact) of the slaves it handled, in slave order. */
typedef struct worker {
    int* slot;         /* body -> index into best, -1 if none (all -1 between slaves) */
    nts_contact* best; /* candidates of the current slave */
    int best_count, best_cap;
    nts_contact* recs;
    int rec_count, rec_cap;
    int status;
} worker;

struct nts_context {
    seg_data* seg;
    int seg_cap;
    nts_cells0 cells;
    worker* workers;
    int worker_count, slot_cap;
    nts_vec2* forces;
    int forces_cap;
    nts_contact* contacts;
    int contacts_cap;
    nts_contact* gaps;
    int gaps_cap;
    double phase[4]; /* seconds of the last evaluation: segments, cells, local search, scatter */
};

/* Phase timings of the last evaluation (internal.h; used by bench/). */
void nts_context_phase_times(const nts_context* ctx, double out[4]) {
    int i;
    for (i = 0; i < 4; ++i) out[i] = ctx->phase[i];
}

nts_context* nts_context_create(void) {
    nts_context* ctx = (nts_context*)nts_alloc(sizeof *ctx);
    if (ctx != NULL) memset(ctx, 0, sizeof *ctx);
    return ctx;
}

static void workers_free(nts_context* ctx) {
    int i;
    for (i = 0; i < ctx->worker_count; ++i) {
        nts_free(ctx->workers[i].slot);
        nts_free(ctx->workers[i].best);
        nts_free(ctx->workers[i].recs);
    }
    nts_free(ctx->workers);
    ctx->workers = NULL;
    ctx->worker_count = 0;
    ctx->slot_cap = 0;
}

void nts_context_destroy(nts_context* ctx) {
    if (ctx == NULL) return;
    nts_free(ctx->seg);
    nts_cells0_free(&ctx->cells);
    workers_free(ctx);
    nts_free(ctx->forces);
    nts_free(ctx->contacts);
    nts_free(ctx->gaps);
    nts_free(ctx);
}

/* Workers with a body slot map of at least body_count entries. */
static int workers_prepare(nts_context* ctx, int count, int body_count) {
    int i, j;
    if (ctx->worker_count != count || ctx->slot_cap < body_count) {
        workers_free(ctx);
        ctx->workers = (worker*)nts_alloc(sizeof(worker) * (size_t)count);
        if (ctx->workers == NULL) return NTS_ENOMEM;
        memset(ctx->workers, 0, sizeof(worker) * (size_t)count);
        ctx->worker_count = count;
        for (i = 0; i < count; ++i) {
            ctx->workers[i].slot = (int*)nts_alloc(sizeof(int) * (size_t)body_count);
            if (ctx->workers[i].slot == NULL) return NTS_ENOMEM;
            for (j = 0; j < body_count; ++j) ctx->workers[i].slot[j] = -1;
        }
        ctx->slot_cap = body_count;
    }
    for (i = 0; i < count; ++i) {
        ctx->workers[i].rec_count = 0;
        ctx->workers[i].best_count = 0;
        ctx->workers[i].status = NTS_OK;
    }
    return NTS_OK;
}

/* Everything the local search reads, copied once (hot loop locals). */
typedef struct search_env {
    const nts_scene* s;
    const seg_data* seg;
    const nts_cells0* cells; /* NULL: brute force */
    double alpha, r, eps;
    nts_solver solver;
    int want_virial;
} search_env;

/* The master node a feature belongs to: segment (j, j+1), corner or vertex at j. */
static inline int feature_node(const nts_contact* c) {
    return c->kind == NTS_KIND_CORNER ? c->master_nodes[1] : c->master_nodes[0];
}

/* Tie-break (docs/model.md §5): smaller |g|, then the smaller master
 * node index, then segment before corner/vertex at the same node. */
static inline int better(const nts_contact* c, const nts_contact* b) {
    double gc = fabs(c->gap), gb = fabs(b->gap);
    if (gc != gb) return gc < gb;
    if (feature_node(c) != feature_node(b)) return feature_node(c) < feature_node(b);
    return c->kind < b->kind;
}

static inline void offer(worker* w, const nts_contact* c) {
    int k = w->slot[c->master_body];
    if (k < 0) {
        if (w->best_count == w->best_cap &&
            nts_grow((void**)&w->best, &w->best_cap, w->best_count + 1, sizeof(nts_contact)) != NTS_OK) {
            w->status = NTS_ENOMEM;
            return;
        }
        k = w->best_count++;
        w->slot[c->master_body] = k;
        w->best[k] = *c;
    } else if (better(c, &w->best[k])) {
        w->best[k] = *c;
    }
}

/* Try the features that master surface entry j offers to slave entry i: the flat
 * part of segment (j, j+1), and the corner (alpha > 0) or vertex (alpha = 0) at j. */
static void try_master(const search_env* env, worker* w, int i, nts_vec2 xs, int j) {
    const nts_scene* s = env->s;
    const seg_data* sj = &env->seg[j];
    const int jp = s->surf_prev[j], jn = s->surf_next[j];
    const nts_vec2 pj = s->pos[s->surf_node[j]];
    const double alpha = env->alpha, r = env->r;
    nts_vec2 d = nts_scene_diff(s, xs, pj); /* Xs - X0 (or Xs - X3): subtract first */
    double sj_param = nts_dot(d, sj->t) * sj->inv_len2; /* docs/model.md §12, correction 2 */
    double lo = alpha, hi = 1.0 - alpha;
    nts_contact c;
    (void)i;

    /* Flat candidate of segment j (alpha <= s <= 1 - alpha). */
    if (sj_param >= lo && sj_param <= hi) {
        double g = nts_dot(d, sj->n);
        if (fabs(g) <= r) {
            memset(&c, 0, sizeof c);
            c.master_body = s->surf_body[j];
            c.kind = NTS_KIND_SEGMENT;
            c.master_count = 2;
            c.master_nodes[0] = s->surf_local[j];
            c.master_nodes[1] = s->surf_local[jn];
            c.master_nodes[2] = -1;
            c.weights[0] = 1.0 - sj_param;
            c.weights[1] = sj_param;
            c.param = sj_param;
            c.gap = g;
            c.normal = sj->n;
            c.point = nts_mul_add(pj, sj_param, sj->t);
            offer(w, &c);
        }
    }
    if (sj_param > (alpha > 0.0 ? alpha : 0.0)) return; /* needs s_j <= alpha */
    {
        const seg_data* sp = &env->seg[jp];
        nts_vec2 pp = s->pos[s->surf_node[jp]];
        nts_vec2 dp = nts_scene_diff(s, xs, pp);
        double sp_param = nts_dot(dp, sp->t) * sp->inv_len2;
        if (alpha > 0.0) {
            /* Corner candidate: s_{j-1} >= 1 - alpha and s_j <= alpha (docs/model.md §12, correction 3). */
            nts_vec2 a, cc;
            double reach;
            nts_corner k;
            nts_corner_solution sol;
            nts_shape3 N;
            if (sp_param < 1.0 - alpha) return;
            a = nts_neg(sp->t); /* X2 - X3 */
            cc = sj->t;         /* X4 - X3 */
            /* Cheap reject: the curve lies in the triangle Xa X3 Xb, within
             * alpha max(|a|, |c|) of X3, so |g| >= |d| - that reach. */
            reach = alpha * (sp->len > sj->len ? sp->len : sj->len);
            if (nts_length(d) > (r + reach) * (1.0 + 1e-12)) return;
            k = nts_corner_make(a, cc, alpha);
            sol = nts_corner_solve(k, d, env->solver);
            if (!sol.ok || !(fabs(sol.gap) <= r)) return;
            N = nts_corner_shape(alpha, sol.xi);
            memset(&c, 0, sizeof c);
            c.master_body = s->surf_body[j];
            c.kind = NTS_KIND_CORNER;
            c.master_count = 3;
            c.master_nodes[0] = s->surf_local[jp];
            c.master_nodes[1] = s->surf_local[j];
            c.master_nodes[2] = s->surf_local[jn];
            c.weights[0] = N.n2;
            c.weights[1] = N.n3;
            c.weights[2] = N.n4;
            c.param = sol.xi;
            c.gap = sol.gap;
            c.normal = sol.normal;
            c.point = nts_add(pj, sol.point);
            offer(w, &c);
        } else {
            /* Vertex candidate (alpha = 0): s_{j-1} >= 1 and s_j <= 0; the sign
             * comes from the pseudo-normal n_{j-1} + n_j. */
            double dist, side;
            nts_vec2 pseudo;
            if (sp_param < 1.0) return;
            dist = nts_length(d);
            if (!(dist <= r)) return;
            pseudo = nts_add(sp->n, sj->n);
            side = nts_dot(d, pseudo) >= 0.0 ? 1.0 : -1.0;
            memset(&c, 0, sizeof c);
            c.master_body = s->surf_body[j];
            c.kind = NTS_KIND_VERTEX;
            c.master_count = 1;
            c.master_nodes[0] = s->surf_local[j];
            c.master_nodes[1] = c.master_nodes[2] = -1;
            c.weights[0] = 1.0;
            c.param = 0.0;
            if (dist > 0.0) {
                c.normal = nts_scale(side / dist, d);
                c.gap = side * dist;
            } else {
                /* On the node itself: the pseudo-normal direction, zero gap. */
                c.normal = nts_normalize_or_zero(pseudo);
                c.gap = 0.0;
            }
            c.point = pj;
            offer(w, &c);
        }
    }
}

/* Move the current slave's best candidates to the worker's records, filling the
 * slave fields, forces and virial; reset the slot map. Candidates are emitted in
 * increasing master body order (determinism independent of visiting order). */
static void flush_slave(const search_env* env, worker* w, int i) {
    const nts_scene* s = env->s;
    int k, m, need = w->rec_count + w->best_count;
    nts_vec2 xs = s->pos[s->surf_node[i]];
    if (w->best_count == 0) return;
    if (need > w->rec_cap && nts_grow((void**)&w->recs, &w->rec_cap, need, sizeof(nts_contact)) != NTS_OK) {
        w->status = NTS_ENOMEM;
    }
    /* Insertion sort by master body (a handful of entries). */
    for (k = 1; k < w->best_count; ++k) {
        nts_contact t = w->best[k];
        m = k - 1;
        while (m >= 0 && w->best[m].master_body > t.master_body) { w->best[m + 1] = w->best[m]; --m; }
        w->best[m + 1] = t;
    }
    for (k = 0; k < w->best_count; ++k) {
        nts_contact* c = &w->best[k];
        w->slot[c->master_body] = -1;
        if (w->status != NTS_OK) continue;
        c->slave_body = s->surf_body[i];
        c->slave_node = s->surf_local[i];
        if (c->gap < 0.0) {
            /* f_s = -eps g n (docs/model.md §6). */
            double eg = env->eps * c->gap;
            c->force = nts_scale(-eg, c->normal);
            if (env->want_virial) {
                /* W_ab = -sum_k f_ka (X_k - Xs)_b over the master nodes, f_k = eps g N_k n
                 * (the slave's own term vanishes); equals eps g^2 n_a n_b at the PCA. */
                int base = s->body_node_start[c->master_body], q;
                double wxx = 0.0, wyy = 0.0, wxy = 0.0, wyx = 0.0;
                for (q = 0; q < c->master_count; ++q) {
                    nts_vec2 rel = nts_scene_diff(s, s->pos[base + c->master_nodes[q]], xs);
                    nts_vec2 f = nts_scale(eg * c->weights[q], c->normal);
                    wxx -= f.x * rel.x;
                    wyy -= f.y * rel.y;
                    wxy -= f.x * rel.y;
                    wyx -= f.y * rel.x;
                }
                c->virial.xx = wxx;
                c->virial.yy = wyy;
                c->virial.xy = 0.5 * (wxy + wyx);
            }
        }
        w->recs[w->rec_count++] = *c;
    }
    w->best_count = 0;
}

static void search_range(const search_env* env, worker* w, int begin, int end) {
    const nts_scene* s = env->s;
    int i;
    for (i = begin; i < end && w->status == NTS_OK; ++i) {
        const int bi = s->surf_body[i];
        const nts_vec2 xs = s->pos[s->surf_node[i]];
        if (env->cells != NULL) {
            const nts_cells0* cl = env->cells;
            int st[9], ns = nts_cells0_stencil(cl, cl->entry_cell[i], st), q;
            for (q = 0; q < ns; ++q) {
                int e, e0 = cl->cell_start[st[q]], e1 = cl->cell_start[st[q] + 1];
                for (e = e0; e < e1; ++e) {
                    int j = cl->items[e];
                    if (s->surf_body[j] != bi) try_master(env, w, i, xs, j);
                }
            }
        } else {
            int j;
            for (j = 0; j < s->surface_count; ++j)
                if (s->surf_body[j] != bi) try_master(env, w, i, xs, j);
        }
        flush_slave(env, w, i);
    }
}

static int eval_fail(nts_error* err, int code, int body, int node, const char* msg) {
    if (err != NULL) {
        *err = nts_error_none();
        err->code = code;
        err->body = body;
        err->node = node;
        strncpy(err->message, msg, sizeof err->message - 1);
    }
    return code;
}

int nts_evaluate(nts_context* ctx, const nts_scene* s, const nts_options* opt, nts_result* out, nts_error* err) {
    search_env env;
    double lmax = 0.0, h;
    int i, rc, nthreads = 1;
    nts_summary* sum;
    double t0 = wall_time(), t1;

    if (err != NULL) *err = nts_error_none();
    if (ctx == NULL || s == NULL || opt == NULL || out == NULL)
        return eval_fail(err, NTS_EINVALID_ARGUMENT, -1, -1, "null argument");
    if ((rc = nts_options_validate(opt, err)) != NTS_OK) return rc;
    memset(out, 0, sizeof *out);

    /* Segment data; a zero-length segment (possible after new positions) is an
     * error, never a division by zero. */
    if ((rc = nts_grow((void**)&ctx->seg, &ctx->seg_cap, s->surface_count, sizeof(seg_data))) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");
    for (i = 0; i < s->surface_count; ++i) {
        seg_data* sd = &ctx->seg[i];
        double l2;
        sd->t = nts_scene_diff(s, s->pos[s->surf_node[s->surf_next[i]]], s->pos[s->surf_node[i]]);
        l2 = nts_length_sq(sd->t);
        if (!(l2 > 0.0) || !isfinite(l2)) {
            char msg[128];
            snprintf(msg, sizeof msg, "body %d: segment from node %d has zero (or non-finite) length",
                     s->surf_body[i], s->surf_local[i]);
            return eval_fail(err, NTS_EDEGENERATE_SEGMENT, s->surf_body[i], s->surf_local[i], msg);
        }
        sd->len = sqrt(l2);
        sd->inv_len2 = 1.0 / l2;
        sd->n = nts_v2(sd->t.y / sd->len, -sd->t.x / sd->len);
        if (sd->len > lmax) lmax = sd->len;
    }

    t1 = wall_time();
    ctx->phase[0] = t1 - t0;
    t0 = t1;
    env.s = s;
    env.seg = ctx->seg;
    env.alpha = opt->alpha;
    env.r = opt->search_radius < 0.0 ? lmax : opt->search_radius;
    env.eps = opt->penalty;
    env.solver = opt->solver;
    env.want_virial = (opt->outputs & NTS_OUT_VIRIAL) != 0u;
    h = lmax + env.r; /* docs/model.md §9: h >= L_max + r */
    if (s->lx > 0.0 && !(2.0 * h < s->lx && 2.0 * h < s->ly)) {
        char msg[160];
        snprintf(msg, sizeof msg, "periodic box %.6g x %.6g must exceed twice the search reach %.6g", s->lx, s->ly, h);
        rc = eval_fail(err, NTS_EBOX_TOO_SMALL, -1, -1, msg);
        if (err != NULL) snprintf(err->option, sizeof err->option, "periodic");
        return rc;
    }
    env.cells = NULL;
    if (opt->search == NTS_SEARCH_CELLS) {
        if ((rc = nts_cells0_build(&ctx->cells, s, h)) != NTS_OK) return eval_fail(err, rc, -1, -1, "out of memory");
        env.cells = &ctx->cells;
    }

    t1 = wall_time();
    ctx->phase[1] = t1 - t0;
    t0 = t1;
#if defined(NTS_HAVE_OPENMP)
    if (opt->threads > 1) nthreads = opt->threads;
    if (nthreads > s->surface_count) nthreads = s->surface_count > 0 ? s->surface_count : 1;
#endif
    if ((rc = workers_prepare(ctx, nthreads, s->body_count)) != NTS_OK)
        return eval_fail(err, rc, -1, -1, "out of memory");

    /* Local search. Worker t handles the contiguous slave range t; the ranges are
     * concatenated in order below, which is the serial order. */
#if defined(NTS_HAVE_OPENMP)
    if (nthreads > 1) {
        int t;
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
        for (t = 0; t < nthreads; ++t) {
            long long n = s->surface_count;
            search_range(&env, &ctx->workers[t], (int)(n * t / nthreads), (int)(n * (t + 1) / nthreads));
        }
    } else
#endif
    {
        search_range(&env, &ctx->workers[0], 0, s->surface_count);
    }
    for (i = 0; i < nthreads; ++i)
        if (ctx->workers[i].status != NTS_OK) return eval_fail(err, ctx->workers[i].status, -1, -1, "out of memory");

    t1 = wall_time();
    ctx->phase[2] = t1 - t0;
    t0 = t1;
    /* Scatter in slave order (docs/model.md §6). */
    {
        const int want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
        const int want_contacts = (opt->outputs & NTS_OUT_CONTACTS) != 0u;
        const int want_gaps = (opt->outputs & NTS_OUT_GAPS) != 0u;
        int total = 0, ncontact = 0, ngap = 0, t;
        double energy = 0.0, maxpen = 0.0;
        nts_virial vir = {0.0, 0.0, 0.0};
        for (t = 0; t < nthreads; ++t) total += ctx->workers[t].rec_count;
        if (want_forces) {
            if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            memset(ctx->forces, 0, sizeof(nts_vec2) * (size_t)s->node_count);
        }
        if (want_gaps &&
            (rc = nts_grow((void**)&ctx->gaps, &ctx->gaps_cap, total, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        for (t = 0; t < nthreads; ++t) {
            const worker* w = &ctx->workers[t];
            int k;
            for (k = 0; k < w->rec_count; ++k) {
                const nts_contact* c = &w->recs[k];
                if (want_gaps) ctx->gaps[ngap++] = *c;
                if (!(c->gap < 0.0)) continue;
                if (want_contacts) {
                    if (ncontact == ctx->contacts_cap &&
                        (rc = nts_grow((void**)&ctx->contacts, &ctx->contacts_cap, ncontact + 1,
                                       sizeof(nts_contact))) != NTS_OK)
                        return eval_fail(err, rc, -1, -1, "out of memory");
                    ctx->contacts[ncontact] = *c;
                }
                ++ncontact;
                energy += 0.5 * env.eps * c->gap * c->gap;
                if (-c->gap > maxpen) maxpen = -c->gap;
                vir.xx += c->virial.xx;
                vir.yy += c->virial.yy;
                vir.xy += c->virial.xy;
                if (want_forces) {
                    int sb = s->body_node_start[c->slave_body], mb = s->body_node_start[c->master_body], q;
                    double eg = env.eps * c->gap;
                    ctx->forces[sb + c->slave_node] = nts_add(ctx->forces[sb + c->slave_node], c->force);
                    for (q = 0; q < c->master_count; ++q) {
                        /* f_k = eps g N_k n */
                        nts_vec2* f = &ctx->forces[mb + c->master_nodes[q]];
                        *f = nts_mul_add(*f, eg * c->weights[q], c->normal);
                    }
                }
            }
        }
        sum = &out->summary;
        sum->bodies = s->body_count;
        sum->surface_nodes = s->surface_count;
        sum->contacts = ncontact;
        sum->gaps = total;
        sum->energy = energy;
        sum->virial = vir;
        sum->max_penetration = maxpen;
        sum->loops_reversed = s->loops_reversed;
        sum->search_radius = env.r;
        sum->cell_size = env.cells != NULL ? (ctx->cells.hx > ctx->cells.hy ? ctx->cells.hx : ctx->cells.hy) : 0.0;
        out->forces = want_forces ? ctx->forces : NULL;
        out->contacts = want_contacts ? ctx->contacts : NULL;
        out->contact_count = want_contacts ? ncontact : 0;
        out->gaps = want_gaps ? ctx->gaps : NULL;
        out->gap_count = want_gaps ? ngap : 0;
    }
    ctx->phase[3] = wall_time() - t0;
    return NTS_OK;
}
