/* The scatter (scatter.c, docs/model.md §6, §7): what the active contacts
 * give (forces, energy, virial, contacts, the tangent), by one of three
 * paths, side by side here, chosen by nts_evaluate for what is asked. Each
 * calls the contact law (contact_law.h) for each active contact in the same
 * order, slave order then master body, and adds the same terms in the same
 * order, so the three give the same bits (test_backend.c: the paths).
 *
 *   direct   one worker, no records asked: the search sums each slave's
 *            active contacts into its chunk's sums and adds their forces as
 *            it goes (scatter_direct, scatter_direct_drain);
 *   shares   several workers, no records asked: each chunk sums its active
 *            contacts and keeps their force shares (scatter_share), added
 *            node range by node range after the search (scatter.c);
 *   records  an output that keeps records asked (contacts, gaps, the
 *            tangent, the pressure: NTS_OUT_RECORDS_): every closest point
 *            is kept (scatter_record), and scatter.c sums, shares and makes
 *            the contacts of the chunks' records after the search
 *            (pressure.c the pressure). */
#ifndef NTSCONTACT_SCATTER_H
#define NTSCONTACT_SCATTER_H

#include "context.h"

/* The slave's penalty (docs/model.md §10) for record b. */
static inline double record_penalty(const search_env* env, const candidate* b) {
    return law_penalty(env->eps, env->per_length, env->s->surf_trib[b->slave]);
}

/* Add active record b to the sums. */
static inline void contact_sum(const search_env* env, const candidate* b, contact_sums* cs) {
    law_sum(cs, record_penalty(env, b), b->gap, b->normal, env->want_virial);
}

/* Active record b's forces, node by node (10). */
static inline force_shares contact_shares(const search_env* env, const candidate* b) {
    force_shares sh;
    int entry[3], q, m;
    sh.eg = record_penalty(env, b) * b->gap;
    sh.n = b->normal;
    sh.node[0] = env->seg[b->slave].node;
    m = record_masters(env, b, entry, sh.w);
    for (q = 0; q < 3; ++q) {
        sh.node[q + 1] = q < m ? env->seg[entry[q]].node : -1;
        if (q >= m) sh.w[q] = 0.0;
    }
    return sh;
}

/* ---- path 1: direct ---- */

/* The direct path adds a contact's forces FORCE_DELAY contacts after it was
 * found, in the order found (first in, first out: the same sums, the same
 * bits), and asks for the nodes' forces when it is found: they are scattered
 * over the whole node array, and the additions would otherwise wait on
 * memory one after another. */
static inline void scatter_direct(const search_env* env, worker* w, const candidate* b) {
    force_shares sh;
    int q;
    contact_sum(env, b, w->sums);
    if (env->forces == NULL) return;
    sh = contact_shares(env, b);
    for (q = 0; q < 4 && sh.node[q] >= 0; ++q) NTS_PREFETCH_W(&env->forces[sh.node[q]]);
    if (w->fifo_count == FORCE_DELAY) {
        law_add_shares(env->forces, &w->fifo[w->fifo_head]);
        w->fifo[w->fifo_head] = sh;
        w->fifo_head = (w->fifo_head + 1) % FORCE_DELAY;
    } else {
        w->fifo[(w->fifo_head + w->fifo_count++) % FORCE_DELAY] = sh;
    }
}

/* The forces still delayed, at the end of the worker's range. */
static inline void scatter_direct_drain(const search_env* env, worker* w) {
    for (; w->fifo_count > 0; --w->fifo_count) {
        law_add_shares(env->forces, &w->fifo[w->fifo_head]);
        w->fifo_head = (w->fifo_head + 1) % FORCE_DELAY;
    }
    w->fifo_head = 0;
}

/* ---- path 2: shares (the room is the caller's: flush_slave) ---- */
static inline void scatter_share(const search_env* env, worker* w, const candidate* b) {
    contact_sum(env, b, w->sums);
    if (env->want_forces) w->shares[w->share_count++] = contact_shares(env, b);
}

/* ---- path 3: records (every closest point: summed, shared and made into
 * contacts by scatter.c, after the search, in the same order) ---- */
static inline void scatter_record(worker* w, const candidate* b) { w->recs[w->rec_count++] = *b; }

/* ---- the records after the search (scatter.c, pressure.c) ---- */

/* A chunk's records (none, and maybe no buffer, when it found nothing). */
static inline const candidate* chunk_recs(const chunk_info* ch) {
    return (const candidate*)ch->part[STREAM_RECORDS].data;
}
static inline int chunk_count(const chunk_info* ch) { return ch->part[STREAM_RECORDS].count; }

/* The records of chunk ch and its deep contacts (reach.c), merged by slave
 * then master body (each pair is in one of them only): the order of the
 * contacts and gaps, and of the tangent's blocks and the pressure, the order a radius large
 * enough for every contact would give. */
typedef struct merged {
    const candidate *rec, *deep;
    int i, n, j, m;
} merged;

static inline merged merged_begin(const nts_context* ctx, const chunk_info* ch) {
    merged it;
    it.rec = chunk_recs(ch);
    it.n = chunk_count(ch);
    it.deep = ch->deep_count > 0 ? ctx->reach.deep + ch->deep_at : NULL; /* (no deep contact: maybe no buffer) */
    it.m = ch->deep_count;
    it.i = it.j = 0;
    return it;
}

/* The next record in the merged order, NULL after the last. */
static inline const candidate* merged_next(merged* it) {
    if (it->i < it->n && (it->j == it->m || it->rec[it->i].slave < it->deep[it->j].slave ||
                          (it->rec[it->i].slave == it->deep[it->j].slave && it->rec[it->i].body < it->deep[it->j].body)))
        return &it->rec[it->i++];
    return it->j < it->m ? &it->deep[it->j++] : NULL;
}

/* The chunks' records, in slave order, into *out. */
int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, const nts_run* run,
                nts_result* out, nts_error* err);

/* pressure.c: the pressure (docs/model.md (21)) of every node into
 * ctx->pressure from the chunks' records and deep contacts (the records
 * path: NTS_OUT_PRESSURE keeps them). NTS_OK, NTS_ENOMEM, or NTS_ENONFINITE
 * when a node's pressure overflows a double. */
int nts_pressure(nts_context* ctx, const search_env* env, const nts_run* run);

#endif
