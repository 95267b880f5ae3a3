/* The scatter (docs/model.md §6, §7): the chunks' records, read in chunk
 * order (slave order), become forces, energy, virial, contacts and the
 * tangent (and the pressure: pressure.c). Every phase runs in parallel and gives the same bits for any
 * number of threads: each chunk sums its own energy and virial and the
 * chunks' sums are added in chunk order; each thread owns a range of nodes
 * and adds, in record order, what every record gives them. */
#include <math.h>
#include <string.h>

#include "parallel.h"
#include "scatter.h"

/* make_contact writes every field of a record instead of clearing it first:
 * that gives the same bytes only while nts_contact has no padding. */
typedef char nts_contact_has_no_padding[sizeof(nts_contact) == 10 * sizeof(int) + 19 * sizeof(double) ? 1 : -1];

/* The full record of candidate b: master nodes and their weights, the
 * slave's penalty, force and virial; with friction (fo, for an active
 * record) the whole force, its tangential part, the slip and the state. */
static nts_contact make_contact(const search_env* env, const candidate* b, const friction_out* fo) {
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
    c.virial.xx = c.virial.yy = c.virial.xy = c.virial.yx = 0.0;
    c.tangential_force = nts_v2(0.0, 0.0);
    c.slip = 0.0;
    c.state = NTS_FRICTIONLESS;
    c.reserved = 0;
    if (c.gap < 0.0 && fo != NULL) {
        c.force = fo->f;
        c.tangential_force = nts_scale(fo->t, fo->tau);
        c.slip = fo->slip;
        c.state = fo->state;
        if (env->want_virial) c.virial = law_virial_force(c.gap, fo->f, c.normal);
    } else if (c.gap < 0.0) {
        const double eg = c.penalty * c.gap;
        c.force = law_slave_force(eg, c.normal);
        if (env->want_virial) c.virial = law_virial(eg, c.gap, c.normal);
    }
    return c;
}

/* ---- friction (friction.h, docs/model.md §14): each active record's
 * friction_out, computed once (chunk by chunk, in record order), then read
 * by the sums, the force shares, the contacts, the anchors and the tangent. */

/* Active record b's force shares with its whole slave force (contact_law.h). */
static force_shares friction_shares(const search_env* env, const candidate* b, const friction_out* fo) {
    force_shares sh = contact_shares(env, b);
    sh.eg = 1.0;
    sh.n = nts_neg(fo->f);
    return sh;
}

static void friction_sum(const search_env* env, const candidate* b, const friction_out* fo, contact_sums* cs) {
    law_sum_friction(cs, record_penalty(env, b), b->gap, b->normal, fo->f, fo->energy_t, fo->dissipation, fo->state,
                     env->want_virial);
}

/* A chunk's active records' friction and its sums. */
static void chunk_friction(nts_context* ctx, const search_env* env, chunk_info* ch) {
    const candidate* rec = chunk_recs(ch);
    friction_out* fo = ctx->fric + ch->share_at;
    int k, hint = 0;
    memset(&ch->sums, 0, sizeof ch->sums);
    for (k = 0; k < chunk_count(ch); ++k)
        if (rec[k].gap < 0.0) {
            nts_friction_eval(env, &rec[k], fo, &hint);
            friction_sum(env, &rec[k], fo, &ch->sums);
            ++fo;
        }
}

/* A chunk's active contacts and their sums. */
static void chunk_sums(const search_env* env, chunk_info* ch) {
    const candidate* rec = chunk_recs(ch);
    int k;
    memset(&ch->sums, 0, sizeof ch->sums);
    for (k = 0; k < chunk_count(ch); ++k)
        if (rec[k].gap < 0.0) contact_sum(env, &rec[k], &ch->sums);
}

/* A chunk's active records' force shares, from its place on (none, and
 * maybe no buffer at all, when it has no active record). */
static void chunk_shares(nts_context* ctx, const search_env* env, chunk_info* ch) {
    const candidate* rec = chunk_recs(ch);
    force_shares* out;
    int k;
    ch->sh = NULL;
    chunk_node_span(ch, NULL, 0);
    if (ch->sums.active == 0) return;
    out = ctx->shares + ch->share_at;
    ch->sh = out;
    if (env->friction) {
        const friction_out* fo = ctx->fric + ch->share_at;
        for (k = 0; k < chunk_count(ch); ++k)
            if (rec[k].gap < 0.0) *out++ = friction_shares(env, &rec[k], fo++);
    } else {
        for (k = 0; k < chunk_count(ch); ++k)
            if (rec[k].gap < 0.0) *out++ = contact_shares(env, &rec[k]);
    }
    chunk_node_span(ch, ch->sh, ch->sums.active);
}

/* Add the forces of shares sh[0..n) on nodes [n0, n1), in order; 1 when a
 * sum it wrote is not finite (law_add_share says why that is enough). */
enum { SHARES_AHEAD = 8 };
static int shares_range(nts_vec2* F, const force_shares* sh, int n, int n0, int n1) {
    int k, q, bad = 0;
    for (k = 0; k < n; ++k) {
        /* the nodes a later share adds to are scattered over the range:
         * asked for SHARES_AHEAD shares ahead (as the direct path delays its
         * adds, search.h) */
        if (k + SHARES_AHEAD < n)
            for (q = 0; q < 4 && sh[k + SHARES_AHEAD].node[q] >= 0; ++q)
                if (sh[k + SHARES_AHEAD].node[q] >= n0 && sh[k + SHARES_AHEAD].node[q] < n1)
                    NTS_PREFETCH_W(&F[sh[k + SHARES_AHEAD].node[q]]);
        for (q = 0; q < 4 && sh[k].node[q] >= 0; ++q)
            if (sh[k].node[q] >= n0 && sh[k].node[q] < n1) bad |= law_add_share(F, &sh[k], q);
    }
    return bad;
}

/* shares_range for shares whose every node is in the range (most chunks'
 * with one part of the nodes per thread): no test of each node. */
static int shares_all(nts_vec2* F, const force_shares* sh, int n) {
    int k, q, bad = 0;
    for (k = 0; k < n; ++k) {
        if (k + SHARES_AHEAD < n)
            for (q = 0; q < 4 && sh[k + SHARES_AHEAD].node[q] >= 0; ++q) NTS_PREFETCH_W(&F[sh[k + SHARES_AHEAD].node[q]]);
        bad |= law_add_shares(F, &sh[k]);
    }
    return bad;
}

/* The forces on nodes [n0, n1) from the chunks' force shares, in chunk
 * order and in record order within a chunk, then the deep contacts' (in
 * their order): each thread reads the shares of every chunk whose nodes
 * reach its range (most chunks touch the nodes of a few neighbouring
 * bodies, so about its share of them) but computes none. Returns 1 when one
 * of them overflowed. */
static int forces_range(nts_context* ctx, int n0, int n1) {
    nts_vec2* F = ctx->forces;
    int c, bad = 0;
    memset(F + n0, 0, sizeof(nts_vec2) * (size_t)(n1 - n0));
    for (c = 0; c < ctx->chunk_count; ++c) {
        const chunk_info* ch = &ctx->chunks[c];
        if (ch->node_lo >= n0 && ch->node_hi < n1) bad |= shares_all(F, ch->sh, ch->sums.active);
        else if (ch->node_hi >= n0 && ch->node_lo < n1) bad |= shares_range(F, ch->sh, ch->sums.active, n0, n1);
    }
    return bad | shares_range(F, ctx->reach.shares, ctx->reach.deep_count, n0, n1);
}

typedef struct scatter_task {
    nts_context* ctx;
    const search_env* env;
    int want_contacts, want_gaps, parts, bad;
} scatter_task;

/* Each chunk's active records, counted (friction: where each chunk's friction goes). */
static void count_task(int begin, int end, int wi, void* p) {
    const scatter_task* t = (const scatter_task*)p;
    int c, k;
    (void)wi;
    for (c = begin; c < end; ++c) {
        chunk_info* ch = &t->ctx->chunks[c];
        const candidate* rec = chunk_recs(ch);
        int n = 0;
        for (k = 0; k < chunk_count(ch); ++k) n += rec[k].gap < 0.0;
        ch->sums.active = n;
    }
}

static void friction_task(int begin, int end, int wi, void* p) {
    const scatter_task* t = (const scatter_task*)p;
    int c;
    (void)wi;
    for (c = begin; c < end; ++c) chunk_friction(t->ctx, t->env, &t->ctx->chunks[c]);
}

/* The friction_out of the merged iterator's last record, when active: a
 * chunk record's (k_rec counts the chunk's active records so far) or a deep
 * contact's. */
static const friction_out* merged_friction(const nts_context* ctx, const chunk_info* ch, const merged* it,
                                           const candidate* rec, int* k_rec) {
    if (!(rec->gap < 0.0)) return NULL;
    if (it->deep != NULL && it->j > 0 && rec == &it->deep[it->j - 1]) return &ctx->fric_deep[ch->deep_at + it->j - 1];
    return &ctx->fric[ch->share_at + (*k_rec)++];
}

static void sums_task(int begin, int end, int wi, void* p) {
    const scatter_task* t = (const scatter_task*)p;
    int c;
    (void)wi;
    for (c = begin; c < end; ++c) chunk_sums(t->env, &t->ctx->chunks[c]);
}

static void shares_task(int begin, int end, int wi, void* p) {
    const scatter_task* t = (const scatter_task*)p;
    int c;
    (void)wi;
    for (c = begin; c < end; ++c) chunk_shares(t->ctx, t->env, &t->ctx->chunks[c]);
}

/* Part u of the nodes gets its forces. */
static void forces_task(int begin, int end, int wi, void* p) {
    scatter_task* t = (scatter_task*)p;
    const long long n = t->env->s->node_count;
    int u;
    (void)wi;
    for (u = begin; u < end; ++u)
        if (forces_range(t->ctx, (int)(n * u / t->parts), (int)(n * (u + 1) / t->parts))) nts_atomic_or(&t->bad, 1);
}

/* Each chunk's records with its deep contacts at their places in the arrays
 * (slave order), as asked: the gaps, the contacts, and with friction each
 * active contact's anchor after this step (what a commit keeps; contact
 * order too, whatever the outputs). */
static void records_task(int begin, int end, int wi, void* p) {
    const scatter_task* t = (const scatter_task*)p;
    nts_context* ctx = t->ctx;
    int c;
    (void)wi;
    for (c = begin; c < end; ++c) {
        const chunk_info* ch = &ctx->chunks[c];
        merged it = merged_begin(ctx, ch);
        const candidate* rec;
        int g = ch->gap_at, a = ch->contact_at, k_anchor = ch->contact_at, k_rec = 0;
        while ((rec = merged_next(&it)) != NULL) {
            const friction_out* fo = t->env->friction ? merged_friction(ctx, ch, &it, rec, &k_rec) : NULL;
            nts_contact cc;
            if (fo != NULL) ctx->anchors[k_anchor++] = fo->anchor;
            if (!t->want_gaps && !(t->want_contacts && rec->gap < 0.0)) continue;
            cc = make_contact(t->env, rec, fo);
            if (t->want_gaps) ctx->gaps[g++] = cc;
            if (t->want_contacts && cc.gap < 0.0) ctx->contacts[a++] = cc;
        }
    }
}

/* A distributed host's parts (ntscontact/distributed.h): every record's
 * slave entry (when every record is kept), and each active one's sums and forces, in contact order, by
 * the law's functions as the paths above compute them (the same bits). */
static int parts_make(nts_context* ctx, const search_env* env, int ncontact, int total) {
    int c, q, rc, live, p = 0, g = 0;
    if ((rc = nts_grow((void**)&ctx->parts, &ctx->parts_cap, ncontact, sizeof(nts_part))) != NTS_OK ||
        (env->keep_all && (rc = nts_grow((void**)&ctx->gap_entries, &ctx->gap_entries_cap, total, sizeof(int))) != NTS_OK))
        return rc;
    for (c = 0; c < ctx->chunk_count; ++c) {
        const chunk_info* ch = &ctx->chunks[c];
        merged it = merged_begin(ctx, ch);
        const candidate* rec;
        int k_rec = 0;
        while ((rec = merged_next(&it)) != NULL) {
            const friction_out* fo = env->friction ? merged_friction(ctx, ch, &it, rec, &k_rec) : NULL;
            const int deep = it.deep != NULL && it.j > 0 && rec == &it.deep[it.j - 1];
            nts_part* pt;
            contact_sums cs;
            force_shares sh;
            if (env->keep_all) {
                assert(g < total);
                ctx->gap_entries[g++] = rec->slave;
            }
            if (!(rec->gap < 0.0)) continue;
            assert(p < ncontact);
            pt = &ctx->parts[p++];
            memset(&cs, 0, sizeof cs);
            if (fo != NULL) {
                friction_sum(env, rec, fo, &cs);
                sh = friction_shares(env, rec, fo);
            } else {
                contact_sum(env, rec, &cs);
                sh = contact_shares(env, rec);
            }
            pt->entry = rec->slave;
            pt->master_body = rec->body;
            pt->deep = deep;
            pt->state = fo != NULL ? fo->state : NTS_FRICTIONLESS;
            for (q = 0, live = 1; q < 4; ++q) { /* as law_add_shares reads them */
                live = live && sh.node[q] >= 0;
                pt->nodes[q] = live ? sh.node[q] : -1;
                pt->force[q] = live ? share_force(&sh, q) : nts_v2(0.0, 0.0);
            }
            pt->energy = cs.energy;
            pt->dissipation = cs.dissipation;
            pt->virial.xx = cs.vxx;
            pt->virial.yy = cs.vyy;
            pt->virial.xy = cs.vxy;
            pt->virial.yx = cs.vyx;
            pt->penetration = cs.maxpen;
            pt->stiff_at = pt->stiff_count = 0;
        }
    }
    ctx->part_count = p;
    ctx->gap_entry_count = g;
    return p == ncontact && (!env->keep_all || g == total) ? NTS_OK : NTS_EINTERNAL;
}

static int overflow_error(nts_error* err, const char* msg) {
    return eval_fail_option(err, NTS_ENONFINITE, "penalty", msg);
}

/* The warnings of the result (nts_result.warnings), in code order. */
static void set_warnings(nts_context* ctx, nts_result* out) {
    const long long count[NTS_WARN_COUNT_] = {ctx->reach.beyond, ctx->reach.unresolved};
    int k, n = 0;
    for (k = 0; k < NTS_WARN_COUNT_; ++k) {
        if (count[k] == 0) continue;
        ctx->warnings[n].code = k + 1;
        ctx->warnings[n++].count = count[k];
    }
    out->warnings = n > 0 ? ctx->warnings : NULL;
    out->warning_count = n;
}

int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, const nts_run* run,
                nts_result* out, nts_error* err) {
    const int want_forces = (opt->outputs & NTS_OUT_FORCES) != 0u;
    const int want_contacts = (opt->outputs & NTS_OUT_CONTACTS) != 0u;
    const int want_gaps = (opt->outputs & NTS_OUT_GAPS) != 0u;
    const int want_stiffness = (opt->outputs & NTS_OUT_STIFFNESS) != 0u;
    const int want_pressure = (opt->outputs & NTS_OUT_PRESSURE) != 0u;
    const int nchunk = ctx->chunk_count;
    const nts_reach* reach = &ctx->reach;
    nts_summary* sum = &out->summary;
    long long total = 0;
    int ncontact = 0, c, k, rc, overflow = 0, sticking = 0, slipping = 0;
    double energy = 0.0, maxpen = 0.0, dissipation = 0.0;
    nts_virial vir = {0.0, 0.0, 0.0, 0.0};
    contact_sums deep;
    scatter_task task;

    memset(&task, 0, sizeof task);
    task.ctx = ctx;
    task.env = env;
    task.want_contacts = want_contacts;
    task.want_gaps = want_gaps;
    if (env->friction) {
        /* Each chunk's active records' friction at its place (share_at), and
         * the chunk's sums from it. */
        int at = 0;
        nts_run_each(run, count_task, nchunk, &task);
        for (c = 0; c < nchunk; ++c) {
            ctx->chunks[c].share_at = at;
            at += ctx->chunks[c].sums.active;
        }
        if ((rc = nts_grow((void**)&ctx->fric, &ctx->fric_cap, at, sizeof(friction_out))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        nts_run_each(run, friction_task, nchunk, &task);
    } else if (!env->direct && !env->shares) { /* else the search summed them */
        nts_run_each(run, sums_task, nchunk, &task);
    }
    /* The deep contacts (reach.c) of each chunk's slaves, and their sums. */
    memset(&deep, 0, sizeof deep);
    for (c = 0, k = 0; c < nchunk; ++c) {
        chunk_info* ch = &ctx->chunks[c];
        ch->deep_at = k;
        while (k < reach->deep_count && reach->deep[k].slave < (c + 1) * CHUNK_SLAVES) ++k;
        ch->deep_count = k - ch->deep_at;
    }
    if (env->friction) {
        if ((rc = nts_grow((void**)&ctx->fric_deep, &ctx->fric_deep_cap, reach->deep_count, sizeof(friction_out))) !=
            NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        for (k = 0; k < reach->deep_count; ++k) {
            nts_friction_eval(env, &reach->deep[k], &ctx->fric_deep[k], NULL);
            friction_sum(env, &reach->deep[k], &ctx->fric_deep[k], &deep);
        }
    } else {
        for (k = 0; k < reach->deep_count; ++k) contact_sum(env, &reach->deep[k], &deep);
    }
    /* In chunk order, then the deep contacts: the same order in every path. */
    for (c = 0; c <= nchunk; ++c) {
        const contact_sums* cs = c < nchunk ? &ctx->chunks[c].sums : &deep;
        ncontact += cs->active;
        energy += cs->energy;
        vir.xx += cs->vxx;
        vir.yy += cs->vyy;
        vir.xy += cs->vxy;
        vir.yx += cs->vyx;
        dissipation += cs->dissipation;
        sticking += cs->sticking;
        slipping += cs->slipping;
        if (cs->maxpen > maxpen) maxpen = cs->maxpen;
        overflow |= cs->overflow;
    }
    for (c = 0; c < run->workers; ++c) total += ctx->workers[c].gaps;
    total += reach->deep_count;

    if (want_forces) {
        /* The deep contacts' force shares, added after the chunks'. */
        if ((rc = nts_grow((void**)&ctx->reach.shares, &ctx->reach.shares_cap, reach->deep_count,
                           sizeof(force_shares))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        for (k = 0; k < reach->deep_count; ++k)
            ctx->reach.shares[k] = env->friction ? friction_shares(env, &reach->deep[k], &ctx->fric_deep[k])
                                                 : contact_shares(env, &reach->deep[k]);
    }
    if (want_forces && env->direct) {
        /* (each add says whether it overflowed: no pass over every node) */
        for (k = 0; k < reach->deep_count; ++k) overflow |= law_add_shares(ctx->forces, &reach->shares[k]);
        for (c = 0; c < run->workers; ++c) overflow |= ctx->workers[c].forces_bad;
    } else if (want_forces) {
        /* Each thread adds the forces on its range of nodes, so every node's
         * sum runs in record order whatever the threads; the shares are
         * computed once, in parallel by chunk, not by every thread. */
        int at = 0;
        ctx->forces_serial = 0; /* until every range is zeroed (forces_range) */
        if ((rc = nts_grow((void**)&ctx->forces, &ctx->forces_cap, s->node_count, sizeof(nts_vec2))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if (env->shares) { /* the search kept them, chunk by chunk */
            for (c = 0; c < nchunk; ++c) {
                chunk_info* ch = &ctx->chunks[c];
                assert(chunk_count(ch) == ch->sums.active);
                ch->sh = (const force_shares*)ch->part[STREAM_RECORDS].data;
            }
        } else {
            for (c = 0; c < nchunk; ++c) {
                ctx->chunks[c].share_at = at;
                at += ctx->chunks[c].sums.active;
            }
            if ((rc = nts_grow((void**)&ctx->shares, &ctx->shares_cap, at, sizeof(force_shares))) != NTS_OK)
                return eval_fail(err, rc, -1, -1, "out of memory");
            nts_run_each(run, shares_task, nchunk, &task);
        }
        /* One part of the nodes per worker (any parts give the same bits). */
        task.parts = run->workers;
        nts_run_each(run, forces_task, task.parts, &task);
        ctx->forces_serial = s->serial;
        overflow |= task.bad;
    }
    /* Finite input can still overflow (a huge penalty or huge coordinates):
     * NaN and infinity never leave the library, the caller gets an error. */
    /* (vir.yx is vir.xy without friction: one test covers it) */
    overflow |= !isfinite(energy) || !isfinite(vir.xx) || !isfinite(vir.yy) || !isfinite(vir.xy) ||
                !isfinite(vir.yx) || !isfinite(dissipation);
    if (overflow) return overflow_error(err, "the result overflows a double (penalty or coordinates too large)");

    if (want_contacts || want_gaps || env->friction) {
        /* Each chunk's records with its deep contacts at their places in the
         * arrays (slave order). */
        int gap_at = 0, contact_at = 0;
        for (c = 0; c < nchunk; ++c) {
            chunk_info* ch = &ctx->chunks[c];
            ch->contact_at = contact_at;
            ch->gap_at = gap_at;
            gap_at += chunk_count(ch) + ch->deep_count;
            contact_at += ch->sums.active + ch->deep_count;
        }
    }
    if (want_contacts || want_gaps || env->friction) {
        if (want_gaps && (rc = nts_grow((void**)&ctx->gaps, &ctx->gaps_cap, (int)total, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if (want_contacts &&
            (rc = nts_grow((void**)&ctx->contacts, &ctx->contacts_cap, ncontact, sizeof(nts_contact))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        if (env->friction &&
            (rc = nts_grow((void**)&ctx->anchors, &ctx->anchors_cap, ncontact, sizeof(nts_anchor))) != NTS_OK)
            return eval_fail(err, rc, -1, -1, "out of memory");
        nts_run_each(run, records_task, nchunk, &task);
    }
    if (ctx->parts_on && (rc = parts_make(ctx, env, ncontact, (int)total)) != NTS_OK)
        return eval_fail(err, rc, -1, -1, rc == NTS_ENOMEM ? "out of memory" : "the parts do not match the contacts");
    if (want_stiffness) {
        /* The triplets in contact order, one block per active contact. */
        int i, part = 0;
        ctx->stiffness.count = 0;
        for (c = 0; c < nchunk; ++c) {
            const chunk_info* ch = &ctx->chunks[c];
            merged it = merged_begin(ctx, ch);
            const candidate* rec;
            int k_rec = 0;
            while ((rec = merged_next(&it)) != NULL) {
                const friction_out* fo = env->friction ? merged_friction(ctx, ch, &it, rec, &k_rec) : NULL;
                nts_contact cc;
                int at = ctx->stiffness.count;
                if (!(rec->gap < 0.0)) continue;
                cc = make_contact(env, rec, fo);
                if ((rc = nts_stiffness_add(&ctx->stiffness, s, &cc, alpha_of_body(s, cc.master_body, env->alpha))) !=
                    NTS_OK)
                    return eval_fail(err, rc, -1, -1, "out of memory");
                /* friction's part, not symmetric (docs/model.md §14) */
                if (fo != NULL && (rc = nts_friction_tangent_add(&ctx->stiffness, env, rec, fo)) != NTS_OK)
                    return eval_fail(err, rc, -1, -1, "out of memory");
                if (ctx->parts_on) {
                    ctx->parts[part].stiff_at = at;
                    ctx->parts[part++].stiff_count = ctx->stiffness.count - at;
                }
            }
        }
        for (i = 0; i < ctx->stiffness.count; ++i)
            if (!isfinite(ctx->stiffness.values[i]))
                return overflow_error(err, "the tangent overflows a double (penalty too large)");
        /* (an empty array is NULL, whatever the context held before) */
        out->stiffness.rows = ctx->stiffness.count > 0 ? ctx->stiffness.rows : NULL;
        out->stiffness.cols = ctx->stiffness.count > 0 ? ctx->stiffness.cols : NULL;
        out->stiffness.values = ctx->stiffness.count > 0 ? ctx->stiffness.values : NULL;
        out->stiffness.count = ctx->stiffness.count;
        out->stiffness.size = 2 * s->node_count;
    }

    if (want_pressure) {
        rc = nts_pressure(ctx, env, run);
        if (rc == NTS_ENONFINITE) return overflow_error(err, "the pressure overflows a double (penalty too large)");
        if (rc != NTS_OK) return eval_fail(err, rc, -1, -1, "out of memory");
    }

    sum->bodies = s->body_count;
    sum->surface_nodes = s->surface_count;
    sum->contacts = ncontact;
    sum->gaps = (int)total;
    sum->deep_contacts = reach->deep_count;
    sum->energy = energy;
    sum->virial = vir;
    sum->max_penetration = maxpen;
    sum->loops_reversed = s->loops_reversed;
    sum->search_radius = env->r;
    sum->cell_size = env->cell_side;
    sum->dissipation = dissipation;
    sum->sticking = sticking;
    sum->slipping = slipping;
    /* An empty array is NULL, on a fresh context or on one whose buffers
     * held the last evaluation's: the result does not depend on what the
     * context evaluated before. */
    out->anchors = env->friction && ncontact > 0 ? ctx->anchors : NULL;
    out->anchor_count = env->friction ? ncontact : 0;
    out->forces = want_forces ? ctx->forces : NULL;
    out->pressure = want_pressure ? ctx->pressure : NULL;
    out->contacts = want_contacts && ncontact > 0 ? ctx->contacts : NULL;
    out->contact_count = want_contacts ? ncontact : 0;
    out->gaps = want_gaps && total > 0 ? ctx->gaps : NULL;
    out->gap_count = want_gaps ? (int)total : 0;
    set_warnings(ctx, out);
    return NTS_OK;
}
