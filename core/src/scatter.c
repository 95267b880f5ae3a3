/* The scatter (docs/model.md §6, §7): the workers' records in slave order
 * (worker t holds the contiguous slave range t), so forces, energy, virial and
 * the tangent are bitwise the same for any number of threads. */
#include <math.h>

#include "stages.h"

/* make_contact writes every field of a record instead of clearing it first:
 * that gives the same bytes only while nts_contact has no padding. */
typedef char nts_contact_has_no_padding[sizeof(nts_contact) == 8 * sizeof(int) + 15 * sizeof(double) ? 1 : -1];

/* The full record of candidate b (a record of the search): master nodes and
 * their weights, the slave's penalty, force and virial. */
static nts_contact make_contact(const search_env* env, const candidate* b) {
    const nts_scene* s = env->s;
    const int i = b->slave, j = b->entry;
    const nts_vec2 xs = s->pos[s->surf_node[i]];
    /* The slave's penalty (docs/model.md §6): per node, or per unit of
     * the node's tributary length at creation (a pressure stiffness). */
    const double eps = env->per_length ? env->eps * s->surf_trib[i] : env->eps;
    nts_contact c;
    c.weights[1] = c.weights[2] = 0.0;
    c.force = nts_v2(0.0, 0.0);
    c.virial.xx = c.virial.yy = c.virial.xy = 0.0;
    c.master_body = b->body;
    c.kind = (nts_kind)b->kind;
    if (b->kind == NTS_KIND_SEGMENT) {
        c.master_count = 2;
        c.master_nodes[0] = s->surf_local[j];
        c.master_nodes[1] = s->surf_local[s->surf_next[j]];
        c.master_nodes[2] = -1;
        c.weights[0] = 1.0 - b->param;
        c.weights[1] = b->param;
    } else if (b->kind == NTS_KIND_CORNER) {
        nts_shape3 N = nts_corner_shape(alpha_of_body(s, b->body, env->alpha), b->param);
        c.master_count = 3;
        c.master_nodes[0] = s->surf_local[s->surf_prev[j]];
        c.master_nodes[1] = s->surf_local[j];
        c.master_nodes[2] = s->surf_local[s->surf_next[j]];
        c.weights[0] = N.n2;
        c.weights[1] = N.n3;
        c.weights[2] = N.n4;
    } else {
        c.master_count = 1;
        c.master_nodes[0] = s->surf_local[j];
        c.master_nodes[1] = c.master_nodes[2] = -1;
        c.weights[0] = 1.0;
    }
    c.param = b->param;
    c.gap = b->gap;
    c.normal = b->normal;
    c.point = b->point;
    c.slave_body = s->surf_body[i];
    c.slave_node = s->surf_local[i];
    c.penalty = eps;
    if (c.gap < 0.0) {
        /* f_s = -eps g n (docs/model.md §6). */
        double eg = eps * c.gap;
        c.force = nts_scale(-eg, c.normal);
        if (env->want_virial) {
            /* W_ab = -sum_k f_ka (X_k - Xs)_b over the master nodes, f_k = eps g N_k n
             * (the slave's own term vanishes); equals eps g^2 n_a n_b at the PCA. */
            int base = s->body_node_start[c.master_body], q;
            double wxx = 0.0, wyy = 0.0, wxy = 0.0, wyx = 0.0;
            for (q = 0; q < c.master_count; ++q) {
                nts_vec2 rel = nts_scene_diff(s, s->pos[base + c.master_nodes[q]], xs);
                nts_vec2 f = nts_scale(eg * c.weights[q], c.normal);
                wxx -= f.x * rel.x;
                wyy -= f.y * rel.y;
                wxy -= f.x * rel.y;
                wyx -= f.y * rel.x;
            }
            c.virial.xx = wxx;
            c.virial.yy = wyy;
            c.virial.xy = 0.5 * (wxy + wyx);
        }
    }
    return c;
}

int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, int nthreads,
                nts_result* out, nts_error* err) {
    nts_summary* sum;
    int i, rc;
    /* Scatter in slave order (docs/model.md §6). */
    {
        const int want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
        const int want_contacts = (opt->outputs & NTS_OUT_CONTACTS) != 0u;
        const int want_gaps = (opt->outputs & NTS_OUT_GAPS) != 0u;
        const int want_stiffness = (opt->outputs & NTS_OUT_STIFFNESS) != 0u;
        int total = 0, ncontact = 0, ngap = 0, t;
        double energy = 0.0, maxpen = 0.0;
        int overflow = 0;
        nts_virial vir = {0.0, 0.0, 0.0};
        for (t = 0; t < nthreads; ++t) total += (int)ctx->workers[t].gaps;
        if (want_forces) {
            if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            memset(ctx->forces, 0, sizeof(nts_vec2) * (size_t)s->node_count);
        }
        if (want_gaps &&
            (rc = nts_grow((void**)&ctx->gaps, &ctx->gaps_cap, total, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        ctx->stiffness.count = 0;
        for (t = 0; t < nthreads; ++t) {
            const worker* w = &ctx->workers[t];
            int k;
            for (k = 0; k < w->rec_count; ++k) {
                const nts_contact cc = make_contact(env, &w->recs[k]), *c = &cc;
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
                overflow |= !isfinite(c->penalty * c->gap) || !isfinite(c->virial.xx + c->virial.yy + c->virial.xy);
                energy += 0.5 * c->penalty * c->gap * c->gap;
                if (-c->gap > maxpen) maxpen = -c->gap;
                vir.xx += c->virial.xx;
                vir.yy += c->virial.yy;
                vir.xy += c->virial.xy;
                if (want_stiffness &&
                    (rc = nts_stiffness_add(&ctx->stiffness, s, c, alpha_of_body(s, c->master_body, env->alpha))) !=
                        NTS_OK)
                    return eval_fail(err, rc, -1, -1, "out of memory");
                if (want_forces) {
                    int sb = s->body_node_start[c->slave_body], mb = s->body_node_start[c->master_body], q;
                    double eg = c->penalty * c->gap;
                    ctx->forces[sb + c->slave_node] = nts_add(ctx->forces[sb + c->slave_node], c->force);
                    for (q = 0; q < c->master_count; ++q) {
                        /* f_k = eps g N_k n */
                        nts_vec2* f = &ctx->forces[mb + c->master_nodes[q]];
                        *f = nts_mul_add(*f, eg * c->weights[q], c->normal);
                    }
                }
            }
        }
        /* Finite input can still overflow (a huge penalty or huge coordinates):
         * NaN and infinity never leave the library, the caller gets an error. */
        overflow |= !isfinite(energy) || !isfinite(vir.xx) || !isfinite(vir.yy) || !isfinite(vir.xy);
        if (want_forces && !overflow)
            for (i = 0; i < s->node_count && !overflow; ++i) overflow = !nts_is_valid_vec2(ctx->forces[i]);
        if (overflow) {
            rc = eval_fail(err, NTS_ENONFINITE, -1, -1,
                           "the result overflows a double (penalty or coordinates too large)");
            if (err != NULL) snprintf(err->option, sizeof err->option, "penalty");
            return rc;
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
        sum->search_radius = env->r;
        sum->cell_size = env->cells != NULL ? (ctx->cells.hx > ctx->cells.hy ? ctx->cells.hx : ctx->cells.hy) : 0.0;
        out->forces = want_forces ? ctx->forces : NULL;
        out->contacts = want_contacts ? ctx->contacts : NULL;
        out->contact_count = want_contacts ? ncontact : 0;
        out->gaps = want_gaps ? ctx->gaps : NULL;
        out->gap_count = want_gaps ? ngap : 0;
        if (want_stiffness) {
            for (i = 0; i < ctx->stiffness.count && !overflow; ++i) overflow = !isfinite(ctx->stiffness.values[i]);
            if (overflow) {
                rc = eval_fail(err, NTS_ENONFINITE, -1, -1, "the tangent overflows a double (penalty too large)");
                if (err != NULL) snprintf(err->option, sizeof err->option, "penalty");
                return rc;
            }
            out->stiffness.rows = ctx->stiffness.rows;
            out->stiffness.cols = ctx->stiffness.cols;
            out->stiffness.values = ctx->stiffness.values;
            out->stiffness.count = ctx->stiffness.count;
            out->stiffness.size = 2 * s->node_count;
        }
    }
    return NTS_OK;
}
