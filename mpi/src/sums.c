/* The sums in one process's order (docs/distributed.md): each node's
 * forces at its owner, each chunk's energy and virial at its home, then the
 * chunks and the deep contacts in order (core/src/scatter.c's order). */
#include <assert.h>
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

/* The mixed nodes' contributions: by node, then in one process's order. */
static int cmp_mixed(const void* pa, const void* pb) {
    const share_msg* a = (const share_msg*)pa;
    const share_msg* b = (const share_msg*)pb;
    if (a->at != b->at) return a->at < b->at ? -1 : 1;
    return cmp_share(a, b);
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
                      int* limit, int* from) {
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
    if (from != NULL) /* the records each rank sent, in rank order */
        for (r = 0; r < m->size; ++r) from[r] = (int)((size_t)rc_[r] / size);
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

/* Room in the outgoing shares (*tmp, with their destinations *dest) for
 * the one after the first n: grown by doubling as the shares come; 0 when
 * none can be had (the old room, and what it holds, are kept). */
static int tmp_room(ntsm_scene* m, share_msg** tmp, int** dest, int* cap, int n) {
    long long want;
    share_msg* t;
    int* d;
    if (n < *cap) return 1;
    want = 2LL * *cap + 1024;
    if (want > INT_MAX) want = INT_MAX;
    if (n >= want) return 0;
    t = (share_msg*)ntsm_scratch(&m->sc[SC_SHARES_TMP], sizeof(share_msg) * (size_t)want);
    if (t != NULL) *tmp = t;
    d = t != NULL ? (int*)ntsm_scratch(&m->sc[SC_SHARES_DEST], sizeof(int) * (size_t)want) : NULL;
    if (d != NULL) *dest = d;
    if (t == NULL || d == NULL) return 0;
    *cap = (int)want;
    return 1;
}

/* An own node's source: SRC_NONE, the one rank whose contacts touch it,
 * or SRC_MIXED (several). */
enum { SRC_NONE = -1, SRC_MIXED = -2 };

static void src_tag(int* src, int at, int rank) {
    src[at] = src[at] == SRC_NONE || src[at] == rank ? rank : SRC_MIXED;
}

/* Contact p's share of its node q, with its key, for the node's owner. */
static share_msg share_of(const ntsm_scene* m, const nts_part* p, int q) {
    share_msg o;
    o.at = m->node_at[p->nodes[q]];
    o.entry = (int)m->entry_global[p->entry];
    o.body = m->part_ids[p->master_body];
    o.dq = p->deep << 2 | q;
    o.fx = p->force[q].x;
    o.fy = p->force[q].y;
    return o;
}

/* The rank that sums chunk c of nchunk when several ranks own its slaves. */
static int chunk_home(int c, int P, int nchunk) { return (int)((long long)c * P / nchunk); }

/* Sums s into the chunk sums ch[0..*nc): the last one when it is chunk c,
 * else a new one from zero (the contacts come chunk by chunk). */
static void chunk_add(chunk_msg* ch, int* nc, int c, const sums6* s) {
    if (*nc == 0 || ch[*nc - 1].chunk != c) {
        memset(&ch[*nc], 0, sizeof ch[*nc]);
        ch[(*nc)++].chunk = c;
    }
    sums6_add(&ch[*nc - 1].s, s);
}

/* This rank's answer: the shares summed at the nodes' owners, the chunks'
 * sums, the counts. */
int ntsm_sums(ntsm_scene* m, const nts_options* opt, nts_error* err) {
    const int P = m->size;
    const long long N = m->entry_off[m->bodies];
    const int nchunk = (int)((N + NTS_PART_CHUNK - 1) / NTS_PART_CHUNK);
    int np = 0, k, q, r, got = 0, rc = NTS_OK;
    const nts_part* parts = m->part ? nts_context_parts(m->ctx, &np) : NULL;
    int* counts = (int*)calloc(3u * (size_t)P, sizeof(int));
    int* fill = counts ? counts + P : NULL;
    int* from = counts ? counts + 2 * P : NULL; /* the shares each rank sent this one */
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
    int nc = 0; /* the chunks' sums this rank holds, in ch */
    int* ranks_in = NULL; /* how many ranks own slaves of each chunk */
    double maxpen = 0.0, gmax = 0.0;
    const int want_forces = (m->outputs & NTS_OUT_FORCES) != 0u;
    int limit = 0;
    rc = counts != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
        free(counts);
        return rc;
    }
    memset(cnt, 0, sizeof cnt);

    /* The chunks whose slaves only this rank owns: their sums are taken
     * here as the parts come (key order), in the pass below; the others'
     * contacts go to the chunk's home rank (below). */
    {
        const int ne = m->part ? nts_scene_surface_node_count(m->part) : 0;
        int* mine_in;
        ranks_in = (int*)ntsm_scratch(&m->sc[SC_CHUNKS], sizeof(int) * 2u * ((size_t)nchunk + 1));
        ch = (chunk_msg*)ntsm_scratch(&m->sc[SC_CHUNK_SUMS], sizeof(chunk_msg) * (2u * (size_t)nchunk + 2));
        rc = ranks_in != NULL && ch != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
            free(counts);
            return rc;
        }
        mine_in = ranks_in + nchunk + 1;
        memset(mine_in, 0, sizeof(int) * ((size_t)nchunk + 1));
        for (k = 0; k < ne; ++k)
            if (m->entry_owned[k]) mine_in[m->entry_global[k] / NTS_PART_CHUNK] = 1;
        MPI_Allreduce(mine_in, ranks_in, nchunk, MPI_INT, MPI_SUM, m->comm);
    }

    /* One pass over the parts, which it reads once (160 bytes a contact):
     * each owned contact's sums (the chunks', the deep ones'), the counts,
     * its forces on this rank's nodes added as they come (the chunks'
     * contacts in key order; the deep ones after them, in key order), its
     * shares for other ranks' nodes in key order (grouped by destination
     * below), each own node's source (this rank here, the others' once their
     * shares are in, or MIXED), and the places of its own nodes (own_at):
     * a node that turns out mixed takes its contributions from there. */
    sm = (sum_msg*)ntsm_scratch(&m->sc[SC_SUMS_OUT], sizeof(sum_msg) * (size_t)(np + 1));
    deep_mine = (sum_msg*)ntsm_scratch(&m->sc[SC_DEEP], sizeof(sum_msg) * (size_t)(np + 1));
    {
        int* lists = (int*)ntsm_scratch(&m->sc[SC_DEEP_AT], sizeof(int) * (6u * (size_t)np + 1));
        int* src = (int*)ntsm_scratch(&m->sc[SC_MIXED], sizeof(int) * ((size_t)m->own_nodes + 1));
        int* own_k = lists;                                  /* owned contacts */
        int* deep_own = lists != NULL ? lists + np : NULL;   /* the deep ones' places in own_k */
        int* own_at = lists != NULL ? lists + 2 * np : NULL; /* their nodes' places here (-1: another rank's, or none) */
        share_msg* tmp = NULL;                            /* the shares in key order, */
        int* dest = NULL;                                 /* and their destinations */
        int n_deep_at = 0, n_own = 0, n_tmp = 0, tmp_cap = 0;
        int* ps_node = NULL;                              /* the part nodes summed here for another rank, */
        nts_vec2* ps_f = NULL;                            /* and their sums so far */
        int n_ps = 0, ps_cap = 0;
        if (sm == NULL || deep_mine == NULL || lists == NULL || src == NULL) rc = NTS_ENOMEM;
        if (rc == NTS_OK && want_forces && !ntsm_grow(&m->forces, &m->forces_cap, m->own_nodes + 1, sizeof(nts_vec2)))
            rc = NTS_ENOMEM;
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc == NTS_OK ? rc : ntsm_fail(err, rc, "out of memory"), err)) !=
            NTS_OK)
            goto done;
        for (k = 0; k < m->own_nodes; ++k) src[k] = SRC_NONE;
        if (want_forces) memset(m->forces, 0, sizeof(nts_vec2) * ((size_t)m->own_nodes + 1));
        for (k = 0; k < np + n_deep_at && rc == NTS_OK; ++k) {
            /* the parts in key order, then the deep ones again (their forces) */
            const int again = k >= np, c = again ? own_k[deep_own[k - np]] : k;
            int own;
            const nts_part* p = &parts[c];
            sum_msg s;
            if (!again) {
                if (!m->entry_owned[p->entry]) continue;
                memset(&s, 0, sizeof s);
                s.entry = (int)m->entry_global[p->entry];
                s.body = m->part_ids[p->master_body];
                s.s.e = p->energy;
                s.s.xx = p->virial.xx;
                s.s.yy = p->virial.yy;
                s.s.xy = p->virial.xy;
                s.s.yx = p->virial.yx;
                s.s.dis = p->dissipation;
                if (p->deep) {
                    deep_mine[n_deep++] = s;
                } else if (ranks_in[s.entry / NTS_PART_CHUNK] > 1) {
                    sm[n_sm++] = s; /* for the chunk's home */
                } else {
                    assert(nc == 0 || ch[nc - 1].chunk <= s.entry / NTS_PART_CHUNK); /* the parts come in key order */
                    chunk_add(ch, &nc, s.entry / NTS_PART_CHUNK, &s.s);
                    assert(nc <= nchunk);
                }
                cnt[0]++;                       /* contacts */
                cnt[2] += p->deep;              /* deep */
                cnt[3] += p->state == NTS_STICK;
                cnt[4] += p->state == NTS_SLIP;
                if (p->penetration > maxpen) maxpen = p->penetration;
                if (!want_forces) continue;
                if (p->deep) deep_own[n_deep_at++] = n_own;
                own_k[n_own] = c;
                for (q = 0; q < 4; ++q) own_at[4 * (size_t)n_own + q] = -1;
                own = n_own++;
            } else {
                own = deep_own[k - np];
            }
            if (!want_forces || p->deep != again) continue; /* a deep contact's forces come after the chunks' */
            for (q = 0; q < 4 && p->nodes[q] >= 0; ++q) {
                const int owner = m->node_owner[p->nodes[q]], at = m->node_at[p->nodes[q]];
                if (owner != m->rank && m->node_single[p->nodes[q]]) {
                    /* Another rank's node of a body in this part alone:
                     * every contribution to it is this rank's, so it is
                     * summed here in the order the owner would add them
                     * (from zero, key order) and sent once (below). */
                    const int n = p->nodes[q];
                    int slot = m->ps_slot[n];
                    if (slot < 0) {
                        if (n_ps == ps_cap) { /* (the old room kept when none is had: the slots are reset below) */
                            const long long cap = 2LL * ps_cap + 1024;
                            const int want = cap > INT_MAX ? INT_MAX : (int)cap;
                            int* nodes = (int*)ntsm_scratch(&m->sc[SC_PRESUM_NODE], sizeof(int) * (size_t)want);
                            nts_vec2* f = nodes != NULL ? (nts_vec2*)ntsm_scratch(&m->sc[SC_PRESUM_F],
                                                                                  sizeof(nts_vec2) * (size_t)want)
                                                        : NULL;
                            if (nodes != NULL) ps_node = nodes; /* (a failed realloc leaves the old block) */
                            if (f == NULL || n_ps == want) {
                                rc = NTS_ENOMEM;
                                break;
                            }
                            ps_f = f;
                            ps_cap = want;
                        }
                        slot = m->ps_slot[n] = n_ps++;
                        ps_node[slot] = n;
                        ps_f[slot].x = 0.0;
                        ps_f[slot].y = 0.0;
                    }
                    ps_f[slot].x = ps_f[slot].x + p->force[q].x;
                    ps_f[slot].y = ps_f[slot].y + p->force[q].y;
                } else if (owner != m->rank) {
                    if (!tmp_room(m, &tmp, &dest, &tmp_cap, n_tmp)) { /* grown as the shares come: none on one rank */
                        rc = NTS_ENOMEM;
                        break;
                    }
                    counts[owner]++;
                    dest[n_tmp] = owner;
                    tmp[n_tmp++] = share_of(m, p, q);
                } else {
                    src_tag(src, at, m->rank);
                    m->forces[at].x = m->forces[at].x + p->force[q].x;
                    m->forces[at].y = m->forces[at].y + p->force[q].y;
                    own_at[4 * (size_t)own + q] = at;
                }
            }
        }
        /* The sums for other ranks' nodes, each one message after the
         * keyed shares (entry -1: the owner adds it to zero, which gives it
         * back unchanged); every slot back to -1, whatever happened. */
        for (k = 0; k < n_ps; ++k) {
            const int n = ps_node[k];
            m->ps_slot[n] = -1;
            if (rc != NTS_OK) continue;
            if (!tmp_room(m, &tmp, &dest, &tmp_cap, n_tmp)) {
                rc = NTS_ENOMEM;
                continue;
            }
            counts[m->node_owner[n]]++;
            dest[n_tmp] = m->node_owner[n];
            memset(&tmp[n_tmp], 0, sizeof tmp[n_tmp]);
            tmp[n_tmp].at = m->node_at[n];
            tmp[n_tmp].entry = -1;
            tmp[n_tmp].fx = ps_f[k].x;
            tmp[n_tmp++].fy = ps_f[k].y;
        }
        {
            int ranks_to = 0; /* the ranks this one sends shares to */
            for (r = 0, n_sh = 0; r < P; ++r) {
                fill[r] = n_sh;
                n_sh += counts[r];
                ranks_to += counts[r] > 0;
            }
            /* Shares for one rank alone (two ranks, or a slab with one
             * neighbour that owns nodes here) are grouped already: sent
             * from where they are, not copied (layout 2 on two ranks: 16 MB
             * a step). */
            if (ranks_to == 1)
                sh = tmp;
            else if (rc == NTS_OK &&
                     (sh = (share_msg*)ntsm_scratch(&m->sc[SC_SHARES_OUT], sizeof(share_msg) * (size_t)(n_sh + 1))) ==
                         NULL)
                rc = NTS_ENOMEM;
            if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc == NTS_OK ? rc : ntsm_fail(err, rc, "out of memory"),
                                 err)) != NTS_OK)
                goto done;
            /* each rank's shares in key order (the chunks' contacts, then
             * the deep ones), so that a node only one other rank's contacts
             * touch can take them as they come (below) */
            if (sh != tmp)
                for (k = 0; k < n_tmp; ++k) sh[fill[dest[k]]++] = tmp[k];
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
            const long long budget = ntsm_candidate_budget(m, opt);
            /* as nts_evaluate counts them: the closest points within r, then
             * those deeper, found (the default radius: tot[2]) or counted
             * and left out (an explicit one: tot[5], the owned slaves'
             * penetration_beyond_radius) */
            if (tot[1] + tot[5] > budget) {
                /* one process's words: those within r alone over it, or only with the deeper ones */
                rc = ntsm_fail(err, NTS_ELIMIT, "");
                nts_candidate_budget_message(err->message, sizeof err->message, budget, tot[1] - tot[2] <= budget);
                snprintf(err->option, sizeof err->option, "max_candidates");
                goto done;
            }
        }
        MPI_Allreduce(&maxpen, &gmax, 1, MPI_DOUBLE, MPI_MAX, m->comm);

        /* Each node's forces at its owner, in one process's order: a node
         * that one rank's contacts alone touch takes them as they come (that
         * rank's parts and shares run in key order: this rank's are in); a
         * node that several ranks' touch ("mixed") gets every contribution
         * bucketed and its few ordered by key. */
        rs = (share_msg*)exchange(m, sh, counts, sizeof(share_msg), &got, &m->sc[SC_SHARES_IN], &limit, from);
        rc = rs != NULL ? NTS_OK : exchange_failed(err, limit);
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
        if (want_forces) {
            int bad = 0, any_bad = 0, n_mixed = 0, total, at0;
            size_t z;
            share_msg* all;
            for (r = 0, at0 = 0; r < P; at0 += from[r++])
                for (k = at0; k < at0 + from[r]; ++k)
                    if (rs[k].entry >= 0) src_tag(src, rs[k].at, r);
            /* the others', each rank's in its order, on the nodes that
             * contacts of that rank alone touch */
            for (r = 0, at0 = 0; r < P; at0 += from[r++])
                for (k = at0; k < at0 + from[r]; ++k) {
                    const int at = rs[k].at;
                    if (rs[k].entry < 0) { /* a node's whole force: no other contribution */
                        assert(src[at] == SRC_NONE);
                        m->forces[at].x = m->forces[at].x + rs[k].fx;
                        m->forces[at].y = m->forces[at].y + rs[k].fy;
                        continue;
                    }
                    if (src[at] != r) {
                        ++n_mixed;
                        continue;
                    }
                    m->forces[at].x = m->forces[at].x + rs[k].fx;
                    m->forces[at].y = m->forces[at].y + rs[k].fy;
                }
            /* the mixed nodes' contributions (those near a slab's edge), by
             * node and key: every mixed node has some other rank's */
            if (n_mixed > 0)
                for (z = 0; z < 4 * (size_t)n_own; ++z) n_mixed += own_at[z] >= 0 && src[own_at[z]] == SRC_MIXED;
            total = n_mixed;
            all = (share_msg*)ntsm_scratch(&m->sc[SC_MIXED_ALL], sizeof(share_msg) * ((size_t)total + 1));
            rc = all != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
            if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
            for (k = 0, n_mixed = 0; k < got && total > 0; ++k)
                if (rs[k].entry >= 0 && src[rs[k].at] == SRC_MIXED) all[n_mixed++] = rs[k];
            for (z = 0; z < 4 * (size_t)n_own && total > 0; ++z)
                if (own_at[z] >= 0 && src[own_at[z]] == SRC_MIXED) all[n_mixed++] = share_of(m, &parts[own_k[z / 4]], (int)(z % 4));
            assert(n_mixed == total);
            if (total > 1) qsort(all, (size_t)total, sizeof(share_msg), cmp_mixed); /* (the keys are distinct) */
            for (k = 0; k < total;) {
                const int at = all[k].at;
                nts_vec2 f = {0.0, 0.0};
                for (; k < total && all[k].at == at; ++k) {
                    f.x = f.x + all[k].fx;
                    f.y = f.y + all[k].fy;
                }
                m->forces[at] = f;
            }
            for (k = 0; k < m->own_nodes; ++k) bad |= !isfinite(m->forces[k].x) || !isfinite(m->forces[k].y);
            MPI_Allreduce(&bad, &any_bad, 1, MPI_INT, MPI_MAX, m->comm);
            if (any_bad) {
                rc = ntsm_fail(err, NTS_ENONFINITE, "the result overflows a double (penalty or coordinates too large)");
                snprintf(err->option, sizeof err->option, "penalty");
                goto done;
            }
        }
    }

    /* Each chunk summed by one rank in contact order, the chunks in order,
     * then the deep contacts (scatter.c's order). A chunk whose slaves are
     * all this rank's was summed in the pass above, as its parts came (key
     * order); the contacts of one whose slaves several ranks own go to its
     * home rank, which sorts them by key and sums them from zero (the same
     * bits: a chunk's sum starts at zero and runs in key order either way). */
    {
        sum_msg* sorted = (sum_msg*)ntsm_scratch(&m->sc[SC_SUMS_SORTED], sizeof(sum_msg) * (size_t)(n_sm + 1));
        int* at = (int*)calloc((size_t)P + 1, sizeof(int));
        rc = sorted != NULL && at != NULL ? NTS_OK : ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
            free(at);
            goto done;
        }
        memset(counts, 0, sizeof(int) * (size_t)P);
        for (k = 0; k < n_sm; ++k) counts[chunk_home(sm[k].entry / NTS_PART_CHUNK, P, nchunk)]++;
        for (r = 1; r < P; ++r) at[r] = at[r - 1] + counts[r - 1];
        for (k = 0; k < n_sm; ++k) sorted[at[chunk_home(sm[k].entry / NTS_PART_CHUNK, P, nchunk)]++] = sm[k];
        free(at);
        rsum = (sum_msg*)exchange(m, sorted, counts, sizeof(sum_msg), &got, &m->sc[SC_SUMS_IN], &limit, NULL);
        rc = rsum != NULL ? NTS_OK : exchange_failed(err, limit);
        if (rc == NTS_OK && got > 1 && sort_sums(m, rsum, got) != NTS_OK) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
        if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
        /* (a shared chunk is never one of this rank's own: a new entry) */
        for (k = 0; k < got; ++k) chunk_add(ch, &nc, rsum[k].entry / NTS_PART_CHUNK, &rsum[k].s);
        assert(nc <= 2 * nchunk + 2);
    }
    {
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
    /* no half-summed forces for ntsm_gather after a failure (the forces are
     * added as the parts come) */
    if (rc != NTS_OK && m->forces != NULL && m->forces_cap > m->own_nodes)
        memset(m->forces, 0, sizeof(nts_vec2) * ((size_t)m->own_nodes + 1));
    free(counts);
    free(all_ch);
    free(all_deep);
    return rc;
}

long long ntsm_candidate_budget(const ntsm_scene* m, const nts_options* opt) {
    return nts_candidate_budget(opt, m->entry_off[m->bodies]);
}
