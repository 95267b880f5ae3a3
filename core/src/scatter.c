/* The scatter (docs/model.md §6, §7): the chunks' records, read in chunk
 * order (slave order), become forces, energy, virial, contacts and the
 * tangent. Every phase runs in parallel and gives the same bits for any
 * number of threads: each chunk sums its own energy and virial and the
 * chunks' sums are added in chunk order; each thread owns a range of nodes
 * and adds, in record order, what every record gives them. */
#include <math.h>

#include "stages.h"

/* make_contact writes every field of a record instead of clearing it first:
 * that gives the same bytes only while nts_contact has no padding. */
typedef char nts_contact_has_no_padding[sizeof(nts_contact) == 8 * sizeof(int) + 15 * sizeof(double) ? 1 : -1];

/* The master nodes of record b, as surface entries, and their weights
 * (docs/model.md §4): the segment's two ends, the corner's three nodes
 * (X2, X3, X4) with the shape functions (3), or the vertex. */
static inline int record_masters(const search_env* env, const candidate* b, int entry[3], double w[3]) {
    const nts_scene* s = env->s;
    const int j = b->entry;
    if (b->kind == NTS_KIND_SEGMENT) {
        entry[0] = j;
        entry[1] = s->surf_next[j];
        w[0] = 1.0 - b->param;
        w[1] = b->param;
        return 2;
    }
    if (b->kind == NTS_KIND_CORNER) {
        const nts_shape3 N = nts_corner_shape(alpha_of_body(s, b->body, env->alpha), b->param);
        entry[0] = s->surf_prev[j];
        entry[1] = j;
        entry[2] = s->surf_next[j];
        w[0] = N.n2;
        w[1] = N.n3;
        w[2] = N.n4;
        return 3;
    }
    entry[0] = j;
    w[0] = 1.0;
    return 1;
}

/* The slave's penalty (docs/model.md §6): per node, or per unit of the node's
 * tributary length at creation (a pressure stiffness). */
static inline double record_penalty(const search_env* env, const candidate* b) {
    return env->per_length ? env->eps * env->s->surf_trib[b->slave] : env->eps;
}

/* The virial of an active record: W_ab = -sum_k f_ka (X_k - Xs)_b over the
 * master nodes, f_k = eps g N_k n (the slave's own term vanishes); equals
 * eps g^2 n_a n_b at the PCA. */
static inline nts_virial record_virial(const search_env* env, const candidate* b, double eg) {
    const nts_scene* s = env->s;
    const nts_vec2 xs = env->seg[b->slave].p;
    int entry[3], q, m;
    double w[3], wxx = 0.0, wyy = 0.0, wxy = 0.0, wyx = 0.0;
    nts_virial v;
    m = record_masters(env, b, entry, w);
    for (q = 0; q < m; ++q) {
        const nts_vec2 rel = nts_scene_diff(s, env->seg[entry[q]].p, xs);
        const nts_vec2 f = nts_scale(eg * w[q], b->normal);
        wxx -= f.x * rel.x;
        wyy -= f.y * rel.y;
        wxy -= f.x * rel.y;
        wyx -= f.y * rel.x;
    }
    v.xx = wxx;
    v.yy = wyy;
    v.xy = 0.5 * (wxy + wyx);
    return v;
}

/* The full record of candidate b: master nodes and their weights, the
 * slave's penalty, force and virial. */
static nts_contact make_contact(const search_env* env, const candidate* b) {
    const nts_scene* s = env->s;
    const int i = b->slave;
    int entry[3], q;
    double w[3];
    nts_contact c;
    c.master_count = record_masters(env, b, entry, w);
    for (q = 0; q < 3; ++q) {
        c.master_nodes[q] = q < c.master_count ? s->surf_local[entry[q]] : -1;
        c.weights[q] = q < c.master_count ? w[q] : 0.0;
    }
    c.master_body = b->body;
    c.kind = (nts_kind)b->kind;
    c.param = b->param;
    c.gap = b->gap;
    c.normal = b->normal;
    c.point = b->point;
    c.slave_body = s->surf_body[i];
    c.slave_node = s->surf_local[i];
    c.penalty = record_penalty(env, b);
    c.force = nts_v2(0.0, 0.0);
    c.virial.xx = c.virial.yy = c.virial.xy = 0.0;
    if (c.gap < 0.0) {
        const double eg = c.penalty * c.gap;
        c.force = nts_scale(-eg, c.normal); /* f_s = -eps g n (docs/model.md §6) */
        if (env->want_virial) c.virial = record_virial(env, b, eg);
    }
    return c;
}

static inline const candidate* chunk_recs(const nts_context* ctx, const chunk_info* ch) {
    return ctx->workers[ch->worker].recs + ch->first;
}

/* A chunk's active contacts and their sums. */
static void chunk_sums(const nts_context* ctx, const search_env* env, chunk_info* ch) {
    const candidate* rec = chunk_recs(ctx, ch);
    double energy = 0.0, maxpen = 0.0, vxx = 0.0, vyy = 0.0, vxy = 0.0;
    int k, active = 0, overflow = 0;
    for (k = 0; k < ch->count; ++k) {
        const candidate* b = &rec[k];
        double pen;
        if (!(b->gap < 0.0)) continue;
        ++active;
        pen = record_penalty(env, b);
        energy += 0.5 * pen * b->gap * b->gap; /* (9) */
        if (-b->gap > maxpen) maxpen = -b->gap;
        overflow |= !isfinite(pen * b->gap);
        if (env->want_virial) {
            const nts_virial v = record_virial(env, b, pen * b->gap);
            overflow |= !isfinite(v.xx + v.yy + v.xy);
            vxx += v.xx;
            vyy += v.yy;
            vxy += v.xy;
        }
    }
    ch->active = active;
    ch->energy = energy;
    ch->maxpen = maxpen;
    ch->vxx = vxx;
    ch->vyy = vyy;
    ch->vxy = vxy;
    ch->overflow = overflow;
}

/* The forces on nodes [n0, n1): every active record's share of them, in
 * record order (docs/model.md §6: f_s = -eps g n, f_k = eps g N_k n).
 * Returns 1 when one of them overflowed. */
static int forces_range(nts_context* ctx, const search_env* env, int n0, int n1) {
    const nts_scene* s = env->s;
    nts_vec2* F = ctx->forces;
    int c, k, i;
    memset(F + n0, 0, sizeof(nts_vec2) * (size_t)(n1 - n0));
    for (c = 0; c < ctx->chunk_count; ++c) {
        const chunk_info* ch = &ctx->chunks[c];
        const candidate* rec = chunk_recs(ctx, ch);
        for (k = 0; k < ch->count; ++k) {
            const candidate* b = &rec[k];
            int entry[3], q, m, ns;
            double w[3], eg;
            if (!(b->gap < 0.0)) continue;
            eg = record_penalty(env, b) * b->gap;
            ns = s->surf_node[b->slave];
            if (ns >= n0 && ns < n1) F[ns] = nts_add(F[ns], nts_scale(-eg, b->normal));
            m = record_masters(env, b, entry, w);
            for (q = 0; q < m; ++q) {
                const int nm = s->surf_node[entry[q]];
                if (nm >= n0 && nm < n1) F[nm] = nts_mul_add(F[nm], eg * w[q], b->normal);
            }
        }
    }
    for (i = n0; i < n1; ++i)
        if (!nts_is_valid_vec2(F[i])) return 1;
    return 0;
}

static int overflow_error(nts_error* err, const char* msg) {
    const int rc = eval_fail(err, NTS_ENONFINITE, -1, -1, msg);
    if (err != NULL) snprintf(err->option, sizeof err->option, "penalty");
    return rc;
}

int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, int nthreads,
                nts_result* out, nts_error* err) {
    const int want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
    const int want_contacts = (opt->outputs & NTS_OUT_CONTACTS) != 0u;
    const int want_gaps = (opt->outputs & NTS_OUT_GAPS) != 0u;
    const int want_stiffness = (opt->outputs & NTS_OUT_STIFFNESS) != 0u;
    const int nchunk = ctx->chunk_count;
    nts_summary* sum = &out->summary;
    long long total = 0;
    int ncontact = 0, c, rc, overflow = 0;
    double energy = 0.0, maxpen = 0.0;
    nts_virial vir = {0.0, 0.0, 0.0};

    NTS_PARALLEL_FOR(nthreads)
    for (c = 0; c < nchunk; ++c) chunk_sums(ctx, env, &ctx->chunks[c]);
    for (c = 0; c < nchunk; ++c) { /* in chunk order */
        const chunk_info* ch = &ctx->chunks[c];
        ncontact += ch->active;
        energy += ch->energy;
        vir.xx += ch->vxx;
        vir.yy += ch->vyy;
        vir.xy += ch->vxy;
        if (ch->maxpen > maxpen) maxpen = ch->maxpen;
        overflow |= ch->overflow;
    }
    for (c = 0; c < nthreads; ++c) total += ctx->workers[c].gaps;

    if (want_forces) {
        int part, bad = 0;
        if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        NTS_PARALLEL_FOR_REDUCE(nthreads, reduction(| : bad))
        for (part = 0; part < nthreads; ++part) {
            const long long n = s->node_count;
            bad |= forces_range(ctx, env, (int)(n * part / nthreads), (int)(n * (part + 1) / nthreads));
        }
        overflow |= bad;
    }
    /* Finite input can still overflow (a huge penalty or huge coordinates):
     * NaN and infinity never leave the library, the caller gets an error. */
    overflow |= !isfinite(energy) || !isfinite(vir.xx) || !isfinite(vir.yy) || !isfinite(vir.xy);
    if (overflow) return overflow_error(err, "the result overflows a double (penalty or coordinates too large)");

    if (want_contacts || want_gaps) {
        /* Each chunk's records at their places in the arrays (slave order). */
        int gap_at = 0, contact_at = 0;
        if (want_gaps && (rc = nts_grow((void**)&ctx->gaps, &ctx->gaps_cap, (int)total, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if (want_contacts &&
            (rc = nts_grow((void**)&ctx->contacts, &ctx->contacts_cap, ncontact, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        for (c = 0; c < nchunk; ++c) {
            chunk_info* ch = &ctx->chunks[c];
            ch->contact_at = contact_at;
            ch->gap_at = gap_at;
            gap_at += ch->count;
            contact_at += ch->active;
        }
        NTS_PARALLEL_FOR(nthreads)
        for (c = 0; c < nchunk; ++c) {
            const chunk_info* ch = &ctx->chunks[c];
            const candidate* rec = chunk_recs(ctx, ch);
            int k, g = ch->gap_at, a = ch->contact_at;
            for (k = 0; k < ch->count; ++k) {
                const nts_contact cc = make_contact(env, &rec[k]);
                if (want_gaps) ctx->gaps[g++] = cc;
                if (want_contacts && cc.gap < 0.0) ctx->contacts[a++] = cc;
            }
        }
    }
    if (want_stiffness) {
        /* The triplets in contact order, one block per active contact. */
        int i;
        ctx->stiffness.count = 0;
        for (c = 0; c < nchunk; ++c) {
            const chunk_info* ch = &ctx->chunks[c];
            const candidate* rec = chunk_recs(ctx, ch);
            int k;
            for (k = 0; k < ch->count; ++k) {
                nts_contact cc;
                if (!(rec[k].gap < 0.0)) continue;
                cc = make_contact(env, &rec[k]);
                if ((rc = nts_stiffness_add(&ctx->stiffness, s, &cc, alpha_of_body(s, cc.master_body, env->alpha))) !=
                    NTS_OK)
                    return eval_fail(err, rc, -1, -1, "out of memory");
            }
        }
        for (i = 0; i < ctx->stiffness.count; ++i)
            if (!isfinite(ctx->stiffness.values[i]))
                return overflow_error(err, "the tangent overflows a double (penalty too large)");
        out->stiffness.rows = ctx->stiffness.rows;
        out->stiffness.cols = ctx->stiffness.cols;
        out->stiffness.values = ctx->stiffness.values;
        out->stiffness.count = ctx->stiffness.count;
        out->stiffness.size = 2 * s->node_count;
    }

    sum->bodies = s->body_count;
    sum->surface_nodes = s->surface_count;
    sum->contacts = ncontact;
    sum->gaps = (int)total;
    sum->energy = energy;
    sum->virial = vir;
    sum->max_penetration = maxpen;
    sum->loops_reversed = s->loops_reversed;
    sum->search_radius = env->r;
    sum->cell_size = env->cells != NULL ? (ctx->cells.hx > ctx->cells.hy ? ctx->cells.hx : ctx->cells.hy) : 0.0;
    out->forces = want_forces ? ctx->forces : NULL;
    out->contacts = want_contacts ? ctx->contacts : NULL;
    out->contact_count = want_contacts ? ncontact : 0;
    out->gaps = want_gaps ? ctx->gaps : NULL;
    out->gap_count = want_gaps ? (int)total : 0;
    return NTS_OK;
}
