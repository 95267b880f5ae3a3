/* One scene across the ranks of a communicator (ntscontact/mpi.h,
 * docs/distributed.md). An evaluation:
 *   1. the frame: what the whole scene's segments set (the median segment,
 *      exactly, by eight rounds of byte histograms; the longest; the extent), reduced
 *      across the ranks (distributed.h);
 *   2. the slabs: cuts along a direction (the longer axis, or the one that
 *      follows the host's bodies: slabs.c) at the quantiles of the surface
 *      nodes (a histogram summed across the ranks): each slab owns the slave
 *      entries whose node lies in it;
 *   3. the halo: each body goes whole to every slab its bounding box, grown
 *      by the reach, overlaps (a contact's slave lies within the reach of
 *      its master, or inside it; the corners and the deep contacts' chains
 *      need the whole loop);
 *   4. each rank evaluates its part with the whole's frame and keeps the
 *      parts (distributed.h) of the slaves it owns;
 *   5. the sums in one process's order: each contribution to a node's force
 *      goes to the node's owner with its key (deep, global slave entry,
 *      master body, place) and is added in key order; each chunk of
 *      NTS_PART_CHUNK slave entries is summed by one rank in contact order,
 *      the chunks' sums are added in chunk order, then the deep contacts'.
 * Steps 2 and 3 are kept between evaluations while no node has moved far
 * enough to leave its halo (the skin: ntsm_scene_set_skin); then only the
 * positions travel. Every step that can fail ends in ntsm_agree: the same
 * error on every rank. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "balance.h"
#include "internal.h"

static double now(void) { return MPI_Wtime(); }

/* The committed anchors whose bodies the part holds, as its indices, in
 * the part's history: its slaves' contacts are all among them. */
static int part_history(ntsm_scene* m, nts_error* err) {
    const int nb = m->part != NULL ? nts_scene_body_count(m->part) : 0;
    int k, n = 0;
    if (m->part == NULL) return NTS_OK;
    if ((m->part_history == NULL && (m->part_history = nts_history_create()) == NULL) ||
        !ntsm_grow(&m->part_anchors, &m->part_anchors_cap, m->hist_count + 1, sizeof(nts_anchor)) ||
        (m->part_of == NULL && (m->part_of = (int*)malloc(sizeof(int) * (size_t)(m->bodies + 1))) == NULL))
        return ntsm_fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < m->bodies; ++k) m->part_of[k] = -1;
    for (k = 0; k < nb; ++k) m->part_of[m->part_ids[k]] = k;
    for (k = 0; k < m->hist_count; ++k) {
        nts_anchor a = m->hist[k];
        if (a.slave_body < 0 || a.slave_body >= m->bodies || a.master_body < 0 || a.master_body >= m->bodies) {
            ntsm_fail(err, NTS_EINVALID_HISTORY, "a friction history entry names a body the scene does not have");
            err->item = k;
            snprintf(err->option, sizeof err->option, "history");
            return NTS_EINVALID_HISTORY;
        }
        a.slave_body = m->part_of[a.slave_body];
        a.master_body = m->part_of[a.master_body];
        if (a.slave_body >= 0 && a.master_body >= 0) m->part_anchors[n++] = a;
    }
    if (nts_history_set(m->part_history, m->part, m->part_anchors, n, err) != NTS_OK) {
        ntsm_global_body(err, m->part_ids, nb);
        return err->code != 0 ? err->code : NTS_EINVALID_HISTORY;
    }
    return NTS_OK;
}

/* Whether every rank was given the same options and skin (what decides the
 * evaluation's path; the threads may differ: the answer does not). */
static int same_everywhere(ntsm_scene* m, const nts_options* opt) {
    const double v[13] = {opt->alpha, opt->penalty, opt->search_radius, (double)opt->solver, (double)opt->outputs,
                          (double)opt->search, (double)opt->penalty_scaling, (double)opt->max_candidates,
                          opt->surface_extension, opt->friction, opt->tangential_penalty, m->skin,
                          (double)(m->weights != NULL)};
    double lo[13], hi[13];
    int k;
    MPI_Allreduce(v, lo, 13, MPI_DOUBLE, MPI_MIN, m->comm);
    MPI_Allreduce(v, hi, 13, MPI_DOUBLE, MPI_MAX, m->comm);
    for (k = 0; k < 13; ++k)
        if (lo[k] != hi[k]) return 0;
    return 1;
}

/* The shares' buffer, on every rank or on none (agreed). Collective. */
static int share_buffer(ntsm_scene* m) {
    int fine, all;
    if (m->share == NULL) m->share = (double*)malloc(sizeof(double) * (size_t)m->size);
    fine = m->share != NULL;
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm);
    return all;
}

/* The host's weights (ntsm_scene_set_weights): positive, finite and the
 * same on every rank; the shares they give (equal ones when all are equal:
 * the equal cuts). Collective: the same verdict on every rank. */
static int weights_shares(ntsm_scene* m) {
    double* lo = (double*)malloc(sizeof(double) * 2u * (size_t)m->size);
    double sum = 0.0;
    int r, fine = lo != NULL, all, equal = 1;
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm);
    if (!all || !share_buffer(m)) {
        free(lo);
        return NTS_ENOMEM;
    }
    for (r = 0; fine && r < m->size; ++r) fine = m->weights[r] > 0.0 && isfinite(m->weights[r]);
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm);
    if (!all) {
        free(lo);
        return NTS_EINVALID_OPTION;
    }
    MPI_Allreduce(m->weights, lo, m->size, MPI_DOUBLE, MPI_MIN, m->comm);
    MPI_Allreduce(m->weights, lo + m->size, m->size, MPI_DOUBLE, MPI_MAX, m->comm);
    for (r = 0; r < m->size; ++r) {
        if (lo[r] != lo[m->size + r]) fine = 0;
        if (m->weights[r] != m->weights[0]) equal = 0;
        sum += m->weights[r];
    }
    free(lo);
    if (!fine) return NTS_EINVALID_OPTION; /* (the same verdict everywhere: the same reductions) */
    for (r = 0; r < m->size; ++r) m->share[r] = m->weights[r] / sum;
    m->share_on = !equal;
    return NTS_OK;
}

/* Balanced by measured time (no host weights): each rank's part took
 * `seconds` for `owned` slaves, and `elapsed` since the evaluation began.
 * When cuts by the ranks' speeds would make the slowest part at least 5%
 * shorter and the time such cuts would have saved since the last cut has
 * reached what a cut costs, the next evaluation cuts the slabs at them
 * (balance.c). A cut costs about an evaluation that makes the parts: the
 * last one's time (the slowest rank's) stands for it, the making itself
 * and the next evaluation's candidate lists; not the scene's first (cold:
 * its allocations and first touches of memory, twice a warm one here), and
 * until another is measured, twice the slowest part's time (a made
 * evaluation costs 1.5 to 1.8 kept ones here); nothing when the parts are
 * made every evaluation (a skin of 0). The same gathered numbers on every
 * rank: the same decision and shares. Collective. */
static void balance(ntsm_scene* m, double seconds, long long owned, double elapsed) {
    const int P = m->size;
    double mine[3], *all, *times, *counts, *current, *next, slowest = 0.0, worst = 0.0, cost;
    int r, fine, every;
    mine[0] = seconds;
    mine[1] = (double)owned;
    mine[2] = elapsed;
    all = (double*)malloc(sizeof(double) * 7u * (size_t)P);
    if (m->speed == NULL) m->speed = (double*)calloc((size_t)P, sizeof(double));
    if (m->share == NULL) m->share = (double*)malloc(sizeof(double) * (size_t)P);
    fine = all != NULL && m->speed != NULL && m->share != NULL;
    MPI_Allreduce(&fine, &every, 1, MPI_INT, MPI_MIN, m->comm);
    if (!every) { /* (no memory on some rank: no balancing this time, anywhere) */
        free(all);
        return;
    }
    MPI_Allgather(mine, 3, MPI_DOUBLE, all, 3, MPI_DOUBLE, m->comm);
    times = all + 3 * P;
    counts = times + P;
    current = counts + P;
    next = current + P;
    for (r = 0; r < P; ++r) {
        times[r] = all[3 * r];
        counts[r] = all[3 * r + 1];
        slowest = fmax(slowest, all[3 * r + 2]);
        worst = fmax(worst, times[r]);
        current[r] = m->share_on ? m->share[r] : 1.0 / P;
    }
    if (m->stats.rebuilt && m->rebuilds > 1) m->recut_cost = slowest; /* (the scene's first is cold: allocations) */
    cost = m->skin == 0.0 ? 0.0 : m->recut_cost > 0.0 ? m->recut_cost : 2.0 * worst;
    if (ntsm_balance_step(m->speed, &m->lost, times, counts, P, current, next, cost)) {
        for (r = 0; r < P; ++r) m->share[r] = next[r];
        m->share_on = 1;
        m->rebuild_next = 1;
    }
    free(all);
}

/* nts_evaluate's words for its candidate budget: "... within the search
 * radius" when the closest points within r alone exceed it, "... within the
 * search radius and deeper" when only those deeper take it over. A part
 * over it only at its deeper ones may be within it at those within r while
 * the whole is not: the agreed error (that part's) then takes one process's
 * words, from the whole's count within r (every part's owned ones, summed;
 * or a part over it there already). `mine`: this rank's part over the
 * budget within r (1), only deeper (2), done (0), or failed otherwise (3:
 * its count unknown). Every rank calls it, with the same agreed error: a
 * collective. */
static const char AND_DEEPER[] = " and deeper";

static void budget_words(ntsm_scene* m, const nts_options* opt, int mine, nts_error* e) {
    long long my[2], all[2];
    char* at;
    my[0] = mine == 1;
    /* (a part that completed its search within r has counted its owned ones) */
    my[1] = m->part != NULL && (mine == 2 || mine == 0) ? nts_context_owned_gaps(m->ctx) : 0;
    MPI_Allreduce(my, all, 2, MPI_LONG_LONG, MPI_SUM, m->comm);
    if ((all[0] > 0 || all[1] > ntsm_candidate_budget(m, opt)) && (at = strstr(e->message, AND_DEEPER)) != NULL)
        memmove(at, at + sizeof AND_DEEPER - 1, strlen(at + sizeof AND_DEEPER - 1) + 1);
}

int ntsm_evaluate(ntsm_scene* m, const nts_options* opt, ntsm_result* out, nts_error* err) {
    nts_error e = nts_error_none();
    nts_frame f;
    slabs sl;
    nts_options po;
    double t0 = now(), t1, t_part, halo, r;
    const double t_begin = t0;
    const nts_vec2* part_pos = NULL; /* a kept part's new positions (ntsm_part_move), for its evaluation */
    int rc = NTS_OK, deeper;
    memset(&sl, 0, sizeof sl);
    memset(out, 0, sizeof *out);
    memset(&m->stats, 0, sizeof m->stats);
    memset(&m->part_result, 0, sizeof m->part_result);
    memset(&m->summary, 0, sizeof m->summary);
    if (opt == NULL) rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT, "null options");
    else if (opt->history != NULL || opt->candidates != NULL || opt->cancel != NULL)
        rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT,
                  "a distributed evaluation takes no kept candidate list or cancel callback yet, and friction's "
                  "history through ntsm_scene_set_history");
    else rc = nts_options_validate(opt, &e);
    if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    if (!same_everywhere(m, opt)) { /* else the ranks would take different paths and wait for each other */
        rc = ntsm_fail(&e, NTS_EINVALID_OPTION,
                       "the ranks' options (or skins, or weights) differ: give every rank the same");
        goto out;
    }
    if (m->weights != NULL && (rc = weights_shares(m)) != NTS_OK) {
        rc = rc == NTS_ENOMEM ? ntsm_fail(&e, NTS_ENOMEM, "out of memory")
                              : ntsm_fail(&e, NTS_EINVALID_OPTION,
                                          "the ranks' weights (ntsm_scene_set_weights) must be positive, finite and "
                                          "the same on every rank");
        goto out;
    }
    m->outputs = opt->outputs;

    /* 1. The frame; 2. the slabs; 3. the halo: a slave's contacts are on
     * masters within the reach (r, and each feature within (1 + ext) L_max
     * of its master node) or around it (deep): twice that, and the bodies
     * that contain it (their boxes hold it). */
    if (m->frame_given) f = m->frame;
    else if ((rc = ntsm_frame_find(m, opt, &f, &e)) != NTS_OK) goto out;
    r = opt->search_radius >= 0.0 ? opt->search_radius : f.median;
    halo = 2.0 * (r + (1.0 + opt->surface_extension) * f.lmax) * (1.0 + 1e-9) +
           1e-9 * (f.coord_max + m->lx + m->ly);
    t1 = now();
    m->stats.seconds[0] = t1 - t0;
    t0 = t1;
    /* The kept decomposition holds while a slave's contacts stay within the
     * halo it was built with: each of their bodies was within `halo` of the
     * slave's slab then, and both have moved at most `moved` since. */
    if (m->built && !m->rebuild_next) {
        double moved2 = 0.0, moved, all;
        int k2, i2, at2 = 0;
        for (k2 = 0; k2 < m->count; ++k2)
            for (i2 = 0; i2 < m->own_defs[k2].node_count; ++i2, ++at2) {
                const double dx = m->own_defs[k2].nodes[i2].x - m->build_pos[at2].x;
                const double dy = m->own_defs[k2].nodes[i2].y - m->build_pos[at2].y;
                if (dx * dx + dy * dy > moved2) moved2 = dx * dx + dy * dy;
            }
        moved = sqrt(moved2);
        MPI_Allreduce(&moved, &all, 1, MPI_DOUBLE, MPI_MAX, m->comm);
        if (!(halo + 2.0 * all <= m->halo_b) || opt->surface_extension != m->ext_b) m->built = 0;
    }
    { /* kept only where every rank keeps it */
        int keep = m->built && !m->rebuild_next, all_keep;
        MPI_Allreduce(&keep, &all_keep, 1, MPI_INT, MPI_MIN, m->comm);
        if (!all_keep) m->built = 0;
    }
    if (m->built && !m->rebuild_next) {
        sl.axis = m->axis_b;
        sl.period = m->period_b;
        sl.lo = m->lo_b;
        sl.hi = m->hi_b;
        sl.cut = m->cut_b;
        rc = ntsm_part_move(m, &part_pos, &e);
        sl.cut = NULL;
        if (rc != NTS_OK) goto out;
    } else {
        m->built = 0;
    }
    m->rebuild_next = 0;
    if (!m->built) {
        part_pos = NULL; /* the part built here holds the positions itself */
        const double skin = m->skin >= 0.0 ? m->skin : 0.3 * r;
        rc = ntsm_slabs_make(m, &f, m->lx, m->ly, &sl) == NTS_OK ? NTS_OK : ntsm_fail(&e, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
        m->halo_b = halo + 2.0 * skin;
        m->ext_b = opt->surface_extension;
        if ((rc = ntsm_part_build(m, &sl, m->halo_b, m->lx, m->ly, &e)) != NTS_OK) goto out;
        free(m->build_pos);
        m->build_pos = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)(m->own_nodes + 1));
        rc = m->build_pos != NULL ? NTS_OK : ntsm_fail(&e, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
        {
            int k2, at2 = 0;
            for (k2 = 0; k2 < m->count; ++k2) {
                memcpy(m->build_pos + at2, m->own_defs[k2].nodes, sizeof(nts_vec2) * (size_t)m->own_defs[k2].node_count);
                at2 += m->own_defs[k2].node_count;
            }
        }
        free(m->cut_b);
        m->cut_b = sl.cut;
        m->axis_b = sl.axis;
        m->period_b = sl.period;
        m->lo_b = sl.lo;
        m->hi_b = sl.hi;
        sl.cut = NULL;
        m->built = 1;
        m->rebuilds++;
        m->stats.rebuilt = 1;
    }
    sl.axis = m->axis_b;
    sl.period = m->period_b;
    sl.lo = m->lo_b;
    sl.hi = m->hi_b;
    sl.cut = m->cut_b;
    if (m->stats.rebuilt) m->maps_whole = 0; /* a new part: its nodes' and entries' maps too */
    rc = ntsm_part_maps(m, &sl, !m->maps_whole, part_pos) == NTS_OK ? NTS_OK
                                                                    : ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK) m->maps_whole = 1;
    sl.cut = NULL;
    if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    {
        /* an uneven load (some slab owning a quarter more than its share):
         * the next evaluation cuts the slabs anew */
        const double share = m->share_on ? m->share[m->rank] : 1.0 / m->size;
        int over = (double)m->stats.owned_slaves > 1.25 * share * (double)m->entry_off[m->bodies] + NTS_PART_CHUNK, any;
        MPI_Allreduce(&over, &any, 1, MPI_INT, MPI_MAX, m->comm);
        if (any) m->rebuild_next = 1;
    }
    t1 = now();
    m->stats.seconds[1] = t1 - t0;
    t0 = t1;

    /* 4. The part, with the whole's frame; its parts. */
    po = *opt;
    po.outputs &= ~(unsigned)NTS_OUT_FORCES; /* the parts carry them */
    /* A solver's loop: the part keeps its candidates between evaluations
     * while it is kept (the same bits as searching anew), built by the
     * first evaluation of a part kept (not by the one that makes a part:
     * parts made every evaluation would pay for lists never replayed). */
    po.candidates = m->skin != 0.0 && !m->stats.rebuilt ? m->part_kc : NULL;
    if (m->hist_count > 0) { /* friction's anchors of the part's bodies (§14) */
        rc = part_history(m, &e);
        if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
        po.history = m->part != NULL ? m->part_history : NULL;
    }
    nts_context_set_frame(m->ctx, &f);
    nts_context_set_parts(m->ctx, 1);
    nts_context_set_owned(m->ctx, m->owned_mask);
    t_part = now();
    /* A kept part takes its moved positions here, checked in the segment
     * pass. Every body's verdicts are its own (its loops, its coordinates)
     * and its owner took these very positions: the part cannot refuse
     * them, nor renormalise (were it to, that is a bug, said so). */
    if (m->part != NULL) {
        const nts_candidates_info before = nts_candidates_get_info(po.candidates);
        nts_candidates_info after;
        rc = part_pos != NULL ? nts_evaluate_positions(m->ctx, m->part, part_pos, &po, &m->part_result, &e)
                              : nts_evaluate(m->ctx, m->part, &po, &m->part_result, &e);
        after = nts_candidates_get_info(po.candidates);
        m->stats.candidates_replayed = rc == NTS_OK && after.evaluations > before.evaluations &&
                                       after.builds == before.builds; /* the list held: replayed, not built */
        if (rc != NTS_OK) ntsm_global_body(&e, m->part_ids, nts_scene_body_count(m->part));
        if (rc == NTS_ERESHAPED) { /* the body's owner took these very positions: a bug, said so */
            const int body = e.body, node = e.node;
            rc = ntsm_fail(&e, NTS_EINTERNAL, "internal: a part would renormalise a body at positions its owner took");
            e.body = body; /* (the global body, ntsm_global_body) */
            e.node = node;
        }
    }
    t_part = now() - t_part; /* this rank's own time, before waiting for the others */
    deeper = rc == NTS_OK                                                   ? 0
             : rc == NTS_ELIMIT && strcmp(e.option, "max_candidates") == 0 ? 1 + (strstr(e.message, AND_DEEPER) != NULL)
                                                                           : 3;
    if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) {
        if (rc == NTS_ELIMIT && strcmp(e.option, "max_candidates") == 0 && strstr(e.message, AND_DEEPER) != NULL)
            budget_words(m, opt, deeper, &e); /* (every rank has this error: a collective) */
        /* every rank has the error: on an internal one, every rank builds
         * the parts anew next time (the collectives before then differ
         * between a kept decomposition and a new one) */
        if (rc == NTS_EINTERNAL) m->built = 0;
        goto out;
    }
    if (m->weights == NULL) balance(m, t_part, m->stats.owned_slaves, now() - t_begin);
    t1 = now();
    m->stats.seconds[2] = t1 - t0;
    t0 = t1;

    /* 5. The sums. */
    rc = ntsm_sums(m, opt, &e);
    if ((rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    m->summary.search_radius = r;
    if (opt->search != NTS_SEARCH_CELLS) {
        m->summary.cell_size = 0.0;
    } else if (f.cell_size >= 0.0) {
        m->summary.cell_size = f.cell_size; /* the whole's (ntscontact-mpi's rank 0 computed it) */
    } else {
        /* no rank holds the whole: the largest part's grid, the same on every
         * rank (a diagnostic; one process's may differ, docs/distributed.md) */
        double mine = m->part != NULL ? m->part_result.summary.cell_size : 0.0;
        MPI_Allreduce(&mine, &m->summary.cell_size, 1, MPI_DOUBLE, MPI_MAX, m->comm);
    }
    m->stats.seconds[3] = now() - t0;
    out->summary = m->summary;
    memcpy(out->warnings, m->warnings, sizeof out->warnings);
    out->warning_count = m->warning_count;
    out->forces = (opt->outputs & NTS_OUT_FORCES) ? m->forces : NULL;
    out->pressure = NULL;
    out->node_count = m->own_nodes;
    out->stats = m->stats;
out:
    free(sl.cut);
    if (err != NULL) *err = rc == NTS_OK ? nts_error_none() : e;
    return rc;
}
