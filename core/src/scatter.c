/* The scatter (docs/model.md §6, §7): the workers' records in slave order
 * (worker t holds the contiguous slave range t), so forces, energy, virial and
 * the tangent are bitwise the same for any number of threads. */
#include <math.h>

#include "stages.h"

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
        for (t = 0; t < nthreads; ++t) total += ctx->workers[t].rec_count;
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
