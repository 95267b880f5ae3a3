/* The sums in one process's order (docs/distributed.md): each node's
 * forces at its owner, each chunk's energy and virial at its home, then the
 * chunks and the deep contacts in order (core/src/scatter.c's order). */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"


/* One process's order of a node's contributions: the chunks' (by slave
 * entry, master body, place), then the deep contacts' (scatter.c). */
static int cmp_share(const share_msg* a, const share_msg* b) {
    if ((a->dq >> 2) != (b->dq >> 2)) return (a->dq >> 2) - (b->dq >> 2);
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    if (a->body != b->body) return a->body < b->body ? -1 : 1;
    return (a->dq & 3) - (b->dq & 3);
}

static int cmp_sum(const void* pa, const void* pb) {
    const sum_msg* a = (const sum_msg*)pa;
    const sum_msg* b = (const sum_msg*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

/* v[0..n) in (entry, body) order: a counting sort by entry (the entries a
 * chunk home receives span its chunks), then each entry's few by body. */
static int sort_sums(ntsm_scene* m, sum_msg* v, int n) {
    int lo = v[0].entry, hi = v[0].entry, k, j, e;
    int* start;
    sum_msg* out;
    for (k = 1; k < n; ++k) {
        if (v[k].entry < lo) lo = v[k].entry;
        if (v[k].entry > hi) hi = v[k].entry;
    }
    start = (int*)ntsm_scratch(&m->sc[SC_SUMS_START], sizeof(int) * ((size_t)(hi - lo) + 2));
    out = (sum_msg*)ntsm_scratch(&m->sc[SC_SUMS_TMP], sizeof(sum_msg) * (size_t)n);
    if (start == NULL || out == NULL) return NTS_ENOMEM;
    memset(start, 0, sizeof(int) * ((size_t)(hi - lo) + 2));
    for (k = 0; k < n; ++k) start[v[k].entry - lo + 1]++;
    for (e = 0; e <= hi - lo; ++e) start[e + 1] += start[e];
    for (k = 0; k < n; ++k) out[start[v[k].entry - lo]++] = v[k];
    for (k = 1; k < n; ++k) /* insertion sort: only a slave's few contacts are out of order */
        for (j = k; j > 0 && cmp_sum(&out[j - 1], &out[j]) > 0; --j) {
            const sum_msg t = out[j];
            out[j] = out[j - 1];
            out[j - 1] = t;
        }
    memcpy(v, out, sizeof(sum_msg) * (size_t)n);
    return NTS_OK;
}

static int cmp_chunk(const void* pa, const void* pb) {
    const chunk_msg* a = (const chunk_msg*)pa;
    const chunk_msg* b = (const chunk_msg*)pb;
    return (a->chunk > b->chunk) - (a->chunk < b->chunk);
}

/* All-to-all of records of `size` bytes, send[] grouped by destination with
 * counts[r]; the received records (in `into`) and their count. NULL on
 * every rank when one of them cannot: more than 2 GiB to send or to receive
 * (*limit set), or no memory. */
static void* exchange(ntsm_scene* m, const void* send, const int* counts, size_t size, int* got, scratch* into,
                      int* limit) {
    int* sc = (int*)ntsm_scratch(&m->sc[SC_EXCHANGE], sizeof(int) * 4u * (size_t)m->size);
    int *sd, *rc_, *rd, r, fine = 1, all;
    void* out = NULL;
    long long sent = 0, recvd = 0, at = 0;
    *got = 0;
    *limit = 0;
    if (sc != NULL)
        for (r = 0; r < m->size; ++r) {
            const long long bytes_r = (long long)counts[r] * (long long)size;
            if (bytes_r > INT_MAX || at + bytes_r > INT_MAX) fine = 0, *limit = 1;
            else sc[r] = (int)bytes_r, sc[m->size + r] = (int)at;
            at += bytes_r;
            if (r != m->rank) sent += bytes_r;
        }
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm);
    if (sc == NULL || !all) {
        MPI_Allreduce(limit, &all, 1, MPI_INT, MPI_MAX, m->comm);
        *limit = all;
        return NULL;
    }
    sd = sc + m->size;
    rc_ = sd + m->size;
    rd = rc_ + m->size;
    MPI_Alltoall(sc, 1, MPI_INT, rc_, 1, MPI_INT, m->comm);
    for (r = 0, at = 0; r < m->size; ++r) {
        rd[r] = (int)(at < INT_MAX ? at : 0);
        at += rc_[r];
        if (r != m->rank) recvd += rc_[r];
    }
    fine = at <= INT_MAX;
    *limit = !fine;
    if (fine && (out = ntsm_scratch(into, (size_t)at + 8)) == NULL) fine = 0;
    MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, m->comm);
    {
        int any_limit = 0;
        MPI_Allreduce(limit, &any_limit, 1, MPI_INT, MPI_MAX, m->comm);
        *limit = any_limit;
    }
    if (!all) return NULL;
    MPI_Alltoallv(send, sc, sd, MPI_BYTE, out, rc_, rd, MPI_BYTE, m->comm);
    m->stats.bytes_sent += sent;
    m->stats.bytes_received += recvd;
    *got = (int)((size_t)at / size);
    return out;
}

/* exchange's failure, the same on every rank. */
static int exchange_failed(nts_error* err, int limit) {
    return limit ? ntsm_fail(err, NTS_ELIMIT, "more than 2 GiB for one rank in one exchange (use more ranks)")
                 : ntsm_fail(err, NTS_ENOMEM, "out of memory");
}

/* This rank's answer: the shares summed at the nodes' owners, the chunks'
 * sums, the counts. */
int ntsm_sums(ntsm_scene* m, const nts_options* opt, nts_error* err) {
    const int P = m->size;
    const long long N = m->entry_off[m->bodies];
    const int nchunk = (int)((N + NTS_PART_CHUNK - 1) / NTS_PART_CHUNK);
    int np = 0, k, q, r, got = 0, rc = NTS_OK;
    const nts_part* parts = m->part ? nts_context_parts(m->ctx, &np) : NULL;
    int* counts = (int*)calloc(2u * (size_t)P, sizeof(int));
    int* fill = counts ? counts + P : NULL;
    share_msg* sh = NULL;
    sum_msg* sm = NULL;
    sum_msg* deep_mine = NULL;
    int n_sh = 0, n_sm = 0, n_deep = 0;
    share_msg* rs = NULL;
    sum_msg* rsum = NULL;
    chunk_msg* ch = NULL;
    chunk_msg* all_ch = NULL;
    sum_msg* all_deep = NULL;
    long long cnt[8], tot[8];
    int n_chunks_mine = 0;
    double maxpen = 0.0, gmax = 0.0;
    const int want_forces = (m->outputs & NTS_OUT_FORCES) != 0u;
    int limit = 0;
    rc = counts != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
        free(counts);
        return rc;
    }
    memset(cnt, 0, sizeof cnt);

    /* The shares to other ranks' nodes, grouped by the rank that owns each
     * (this rank's own nodes take theirs below, without a message). */
    for (k = 0; k < np && want_forces; ++k) {
        if (!m->entry_owned[parts[k].entry]) continue;
        for (q = 0; q < 4 && parts[k].nodes[q] >= 0; ++q)
            if (m->node_owner[parts[k].nodes[q]] != m->rank) counts[m->node_owner[parts[k].nodes[q]]]++;
    }
    for (r = 0, n_sh = 0; r < P; ++r) {
        fill[r] = n_sh;
        n_sh += counts[r];
    }
    if ((sh = (share_msg*)ntsm_scratch(&m->sc[SC_SHARES_OUT], sizeof(share_msg) * (size_t)(n_sh + 1))) == NULL)
        rc = NTS_ENOMEM;
    if (rc == NTS_OK && (sm = (sum_msg*)ntsm_scratch(&m->sc[SC_SUMS_OUT], sizeof(sum_msg) * (size_t)(np + 1))) == NULL)
        rc = NTS_ENOMEM;
    if (rc == NTS_OK &&
        (deep_mine = (sum_msg*)ntsm_scratch(&m->sc[SC_DEEP], sizeof(sum_msg) * (size_t)(np + 1))) == NULL)
        rc = NTS_ENOMEM;
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc == NTS_OK ? rc : ntsm_fail(err, rc, "out of memory"), err)) != NTS_OK)
        goto done;
    for (k = 0; k < np; ++k) {
        const nts_part* p = &parts[k];
        const int gb = m->part_ids[p->master_body];
        const int ge = (int)m->entry_global[p->entry];
        sum_msg s;
        if (!m->entry_owned[p->entry]) continue;
        for (q = 0; q < 4 && p->nodes[q] >= 0 && want_forces; ++q) {
            share_msg* o;
            if (m->node_owner[p->nodes[q]] == m->rank) continue;
            o = &sh[fill[m->node_owner[p->nodes[q]]]++];
            o->at = m->node_at[p->nodes[q]];
            o->entry = ge;
            o->body = gb;
            o->dq = p->deep << 2 | q;
            o->fx = p->force[q].x;
            o->fy = p->force[q].y;
        }
        memset(&s, 0, sizeof s);
        s.entry = ge;
        s.body = gb;
        s.s.e = p->energy;
        s.s.xx = p->virial.xx;
        s.s.yy = p->virial.yy;
        s.s.xy = p->virial.xy;
        s.s.yx = p->virial.yx;
        s.s.dis = p->dissipation;
        if (p->deep) deep_mine[n_deep++] = s;
        else sm[n_sm++] = s;
        cnt[0]++;                       /* contacts */
        cnt[2] += p->deep;              /* deep */
        cnt[3] += p->state == NTS_STICK;
        cnt[4] += p->state == NTS_SLIP;
        if (p->penetration > maxpen) maxpen = p->penetration;
    }
    /* the owned slaves' closest points within r, and their deep contacts */
    cnt[1] = (m->part ? nts_context_owned_gaps(m->ctx) : 0) + cnt[2];
    {
        int nw, w;
        const int* we;
        we = m->part ? nts_context_warning_entries(m->ctx, NTS_WARN_PENETRATION_BEYOND_RADIUS, &nw) : NULL;
        for (w = 0; we && w < nw; ++w) cnt[5] += m->entry_owned[we[w]];
        we = m->part ? nts_context_warning_entries(m->ctx, NTS_WARN_PENETRATION_BEYOND_REACH, &nw) : NULL;
        for (w = 0; we && w < nw; ++w) cnt[6] += m->entry_owned[we[w]];
    }
    MPI_Allreduce(cnt, tot, 8, MPI_LONG_LONG, MPI_SUM, m->comm);
    {
        /* the whole's candidate budget (nts_evaluate's), not each part's */
        long long budget = opt->max_candidates > 0 ? opt->max_candidates : 64LL * N + 1000000;
        if (budget > INT_MAX) budget = INT_MAX; /* the count is nts_summary.gaps, an int */
        if (tot[1] > budget) {
            rc = ntsm_fail(err, NTS_ELIMIT, "");
            snprintf(err->message, sizeof err->message,
                     "more than max_candidates = %lld closest points within the search radius: the bodies overlap "
                     "far more than contact does (or raise the limit)", budget);
            snprintf(err->option, sizeof err->option, "max_candidates");
            goto done;
        }
    }
    MPI_Allreduce(&maxpen, &gmax, 1, MPI_DOUBLE, MPI_MAX, m->comm);

    /* Each node's forces at its owner, in one process's order: a node that
     * only this rank's contacts touch takes them as they come (its parts run
     * in key order: the chunks' contacts, then the deep ones); a node that
     * others' touch too ("mixed") gets every contribution bucketed and its
     * few ordered by key. */
    rs = (share_msg*)exchange(m, sh, counts, sizeof(share_msg), &got, &m->sc[SC_SHARES_IN], &limit);
    rc = rs != NULL ? NTS_OK : exchange_failed(err, limit);
    if (rc == NTS_OK && want_forces && !ntsm_grow(&m->forces, &m->forces_cap, m->own_nodes + 1, sizeof(nts_vec2)))
        rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    if (want_forces) {
        int bad = 0, any_bad = 0, i, j, pass, n_local = 0, total;
        unsigned char* mixed = (unsigned char*)ntsm_scratch(&m->sc[SC_MIXED], (size_t)m->own_nodes + 1);
        share_msg* all;
        int* start;
        int* order;
        rc = mixed != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
        memset(mixed, 0, (size_t)m->own_nodes + 1);
        memset(m->forces, 0, sizeof(nts_vec2) * ((size_t)m->own_nodes + 1));
        for (k = 0; k < got; ++k) mixed[rs[k].at] = 1;
        /* this rank's contributions: the chunks' contacts, then the deep ones */
        for (pass = 0; pass < 2; ++pass)
            for (k = 0; k < np; ++k) {
                const nts_part* p = &parts[k];
                if (p->deep != pass || !m->entry_owned[p->entry]) continue;
                for (q = 0; q < 4 && p->nodes[q] >= 0; ++q) {
                    const int at = m->node_at[p->nodes[q]];
                    if (m->node_owner[p->nodes[q]] != m->rank) continue;
                    if (mixed[at]) {
                        ++n_local;
                        continue;
                    }
                    m->forces[at].x = m->forces[at].x + p->force[q].x;
                    m->forces[at].y = m->forces[at].y + p->force[q].y;
                }
            }
        /* the mixed nodes' contributions, this rank's after the others' */
        total = got + n_local;
        all = (share_msg*)ntsm_scratch(&m->sc[SC_MIXED_ALL], sizeof(share_msg) * ((size_t)total + 1));
        start = (int*)ntsm_scratch(&m->sc[SC_START], sizeof(int) * ((size_t)m->own_nodes + 2));
        order = (int*)ntsm_scratch(&m->sc[SC_ORDER], sizeof(int) * ((size_t)total + 1));
        rc = all != NULL && start != NULL && order != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
        memcpy(all, rs, sizeof(share_msg) * (size_t)got);
        for (k = 0, n_local = got; k < np && total > got; ++k) {
            const nts_part* p = &parts[k];
            if (!m->entry_owned[p->entry]) continue;
            for (q = 0; q < 4 && p->nodes[q] >= 0; ++q) {
                const int at = m->node_at[p->nodes[q]];
                share_msg* o;
                if (m->node_owner[p->nodes[q]] != m->rank || !mixed[at]) continue;
                o = &all[n_local++];
                o->at = at;
                o->entry = (int)m->entry_global[p->entry];
                o->body = m->part_ids[p->master_body];
                o->dq = p->deep << 2 | q;
                o->fx = p->force[q].x;
                o->fy = p->force[q].y;
            }
        }
        memset(start, 0, sizeof(int) * ((size_t)m->own_nodes + 2));
        for (k = 0; k < total; ++k) start[all[k].at + 1]++;
        for (i = 0; i < m->own_nodes; ++i) start[i + 1] += start[i];
        for (k = 0; k < total; ++k) order[start[all[k].at]++] = k;
        for (i = m->own_nodes; i > 0; --i) start[i] = start[i - 1];
        start[0] = 0;
        for (i = 0; i < m->own_nodes; ++i) {
            nts_vec2 f = {0.0, 0.0};
            if (!mixed[i]) continue;
            for (j = start[i] + 1; j < start[i + 1]; ++j) { /* insertion sort by key */
                const int x = order[j];
                int t = j;
                while (t > start[i] && cmp_share(&all[order[t - 1]], &all[x]) > 0) {
                    order[t] = order[t - 1];
                    --t;
                }
                order[t] = x;
            }
            for (j = start[i]; j < start[i + 1]; ++j) {
                f.x = f.x + all[order[j]].fx;
                f.y = f.y + all[order[j]].fy;
            }
            m->forces[i] = f;
        }
        for (k = 0; k < m->own_nodes; ++k) bad |= !isfinite(m->forces[k].x) || !isfinite(m->forces[k].y);
        MPI_Allreduce(&bad, &any_bad, 1, MPI_INT, MPI_MAX, m->comm);
        if (any_bad) {
            rc = ntsm_fail(err, NTS_ENONFINITE, "the result overflows a double (penalty or coordinates too large)");
            snprintf(err->option, sizeof err->option, "penalty");
            goto done;
        }
    }

    /* Each chunk summed by one rank in contact order, the chunks in order,
     * then the deep contacts (scatter.c's order). A chunk whose contacts are
     * all this rank's is summed here, as its parts come (key order); one
     * that several ranks' contacts share goes to its home rank. */
    {
        int* ranks_in = (int*)ntsm_scratch(&m->sc[SC_CHUNKS], sizeof(int) * 2u * ((size_t)nchunk + 1));
        int* mine_in = ranks_in != NULL ? ranks_in + nchunk + 1 : NULL;
        sum_msg* sorted = (sum_msg*)ntsm_scratch(&m->sc[SC_SUMS_SORTED], sizeof(sum_msg) * (size_t)(n_sm + 1));
        int* at = (int*)calloc((size_t)P + 1, sizeof(int));
        int n_shared = 0, nc = 0;
        rc = ranks_in != NULL && sorted != NULL && at != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
            free(at);
            goto done;
        }
        memset(mine_in, 0, sizeof(int) * ((size_t)nchunk + 1));
        for (k = 0; k < n_sm; ++k) mine_in[sm[k].entry / NTS_PART_CHUNK] = 1;
        MPI_Allreduce(mine_in, ranks_in, nchunk, MPI_INT, MPI_SUM, m->comm);
        ch = (chunk_msg*)calloc((size_t)n_sm + 1, sizeof(chunk_msg));
        rc = ch != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
            free(at);
            goto done;
        }
        memset(counts, 0, sizeof(int) * (size_t)P);
        for (k = 0; k < n_sm; ++k) {
            const int c = sm[k].entry / NTS_PART_CHUNK;
            if (ranks_in[c] > 1) {
                counts[(int)((long long)c * P / nchunk)]++;
                ++n_shared;
                continue;
            }
            if (nc == 0 || ch[nc - 1].chunk != c) {
                memset(&ch[nc], 0, sizeof ch[nc]);
                ch[nc++].chunk = c;
            }
            sums6_add(&ch[nc - 1].s, &sm[k].s);
        }
        for (r = 1; r < P; ++r) at[r] = at[r - 1] + counts[r - 1];
        for (k = 0; k < n_sm; ++k) {
            const int c = sm[k].entry / NTS_PART_CHUNK;
            if (ranks_in[c] > 1) sorted[at[(int)((long long)c * P / nchunk)]++] = sm[k];
        }
        free(at);
        (void)n_shared;
        rsum = (sum_msg*)exchange(m, sorted, counts, sizeof(sum_msg), &got, &m->sc[SC_SUMS_IN], &limit);
        rc = rsum != NULL ? NTS_OK : exchange_failed(err, limit);
        if (rc == NTS_OK && got > 1 && sort_sums(m, rsum, got) != NTS_OK) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if (rc == NTS_OK && got + nc > n_sm) { /* room for the shared chunks' sums too */
            chunk_msg* more = (chunk_msg*)realloc(ch, sizeof(chunk_msg) * ((size_t)(got + nc) + 1));
            if (more == NULL) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
            else ch = more;
        }
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
        {
            int last = -1;
            for (k = 0; k < got; ++k) {
                const int c = rsum[k].entry / NTS_PART_CHUNK;
                if (c != last) {
                    memset(&ch[nc], 0, sizeof ch[nc]);
                    ch[nc++].chunk = c;
                    last = c;
                }
                sums6_add(&ch[nc - 1].s, &rsum[k].s);
            }
        }
        n_chunks_mine = nc;
    }
    {
        const int nc = n_chunks_mine;
        /* every rank gets every chunk's sums, and every deep contact's */
        {
            int* cc = (int*)malloc(sizeof(int) * 2u * (size_t)(P + 1)); /* chunks' bytes, then the deep ones' */
            int total_c = 0, total_d = 0;
            sums6 chunks, deep; /* the chunks' sums in chunk order, then the deep contacts' */
            int mine_bytes = (int)(nc * sizeof(chunk_msg));
            if (cc == NULL) {
                rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
            }
            if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
                free(cc);
                goto done;
            }
            MPI_Allgather(&mine_bytes, 1, MPI_INT, cc, 1, MPI_INT, m->comm);
            for (r = 0; r < P; ++r) total_c += cc[r];
            {
                int* dd = (int*)malloc(sizeof(int) * (size_t)P);
                int* disp = (int*)malloc(sizeof(int) * (size_t)P);
                int deep_bytes = (int)(n_deep * sizeof(sum_msg));
                MPI_Allgather(&deep_bytes, 1, MPI_INT, cc + P, 1, MPI_INT, m->comm);
                for (r = 0; r < P; ++r) total_d += cc[P + r];
                all_ch = (chunk_msg*)malloc((size_t)total_c + sizeof(chunk_msg));
                all_deep = (sum_msg*)malloc((size_t)total_d + sizeof(sum_msg));
                rc = dd && disp && all_ch && all_deep ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
                if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
                    free(dd);
                    free(disp);
                    free(cc);
                    goto done;
                }
                for (r = 0; r < P; ++r) disp[r] = r == 0 ? 0 : disp[r - 1] + cc[r - 1];
                MPI_Allgatherv(ch, mine_bytes, MPI_BYTE, all_ch, cc, disp, MPI_BYTE, m->comm);
                for (r = 0; r < P; ++r) {
                    dd[r] = cc[P + r];
                    disp[r] = r == 0 ? 0 : disp[r - 1] + dd[r - 1];
                }
                MPI_Allgatherv(deep_mine, deep_bytes, MPI_BYTE, all_deep, dd, disp, MPI_BYTE, m->comm);
                free(dd);
                free(disp);
            }
            free(cc);
            total_c /= (int)sizeof(chunk_msg);
            total_d /= (int)sizeof(sum_msg);
            if (total_c > 1) qsort(all_ch, (size_t)total_c, sizeof(chunk_msg), cmp_chunk);
            if (total_d > 1) qsort(all_deep, (size_t)total_d, sizeof(sum_msg), cmp_sum);
            memset(&chunks, 0, sizeof chunks);
            memset(&deep, 0, sizeof deep);
            for (k = 0; k < total_c; ++k) sums6_add(&chunks, &all_ch[k].s);
            for (k = 0; k < total_d; ++k) sums6_add(&deep, &all_deep[k].s);
            m->summary.energy = chunks.e + deep.e;
            m->summary.virial.xx = chunks.xx + deep.xx;
            m->summary.virial.yy = chunks.yy + deep.yy;
            m->summary.virial.xy = chunks.xy + deep.xy;
            m->summary.virial.yx = chunks.yx + deep.yx;
            m->summary.dissipation = chunks.dis + deep.dis;
        }
    }
    m->summary.bodies = m->bodies;
    m->summary.surface_nodes = (int)N;
    m->summary.contacts = (int)tot[0];
    m->summary.gaps = (int)tot[1];
    m->summary.deep_contacts = (int)tot[2];
    m->summary.sticking = (int)tot[3];
    m->summary.slipping = (int)tot[4];
    m->summary.max_penetration = gmax;
    m->summary.loops_reversed = m->loops_reversed;
    m->warning_count = 0;
    if (tot[5] > 0) {
        m->warnings[m->warning_count].code = NTS_WARN_PENETRATION_BEYOND_RADIUS;
        m->warnings[m->warning_count++].count = tot[5];
    }
    if (tot[6] > 0) {
        m->warnings[m->warning_count].code = NTS_WARN_PENETRATION_BEYOND_REACH;
        m->warnings[m->warning_count++].count = tot[6];
    }
    {
        const nts_summary* s = &m->summary;
        if (!isfinite(s->energy) || !isfinite(s->virial.xx) || !isfinite(s->virial.yy) || !isfinite(s->virial.xy) ||
            !isfinite(s->virial.yx) || !isfinite(s->dissipation)) {
            rc = ntsm_fail(err, NTS_ENONFINITE, "the result overflows a double (penalty or coordinates too large)");
            snprintf(err->option, sizeof err->option, "penalty");
        }
    }
done:
    free(counts);
    free(ch);
    free(all_ch);
    free(all_deep);
    return rc;
}
