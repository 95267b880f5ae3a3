/* Each rank's part (docs/distributed.md): the bodies that reach into its
 * slab, sent whole, and kept between evaluations while the skin allows. */
#include <assert.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"




typedef struct part_body {
    int id, arrival, parts;
    size_t at;
} part_body;

static int cmp_part_body(const void* pa, const void* pb) {
    const part_body* a = (const part_body*)pa;
    const part_body* b = (const part_body*)pb;
    return (a->id > b->id) - (a->id < b->id);
}

/* Send each owned body to every slab it reaches; build this rank's part. */
int ntsm_part_build(ntsm_scene* m, const slabs* sl, double halo, double lx, double ly, nts_error* err) {
    const int P = m->size;
    int* counts = (int*)calloc((size_t)P, sizeof(int));
    size_t* sizes = (size_t*)calloc((size_t)P, sizeof(size_t));
    unsigned char* to = (unsigned char*)calloc((size_t)m->count * (size_t)P + 1, 1); /* kept: m->to */
    int* sc = (int*)calloc(4u * (size_t)P, sizeof(int));
    char* send = NULL;
    part_body* pb = NULL;
    nts_body_def* defs = NULL;
    int k, r, got = 0, rc = NTS_OK;
    size_t at, total = 0;
    if (!counts || !sizes || !to || !sc) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < m->count && rc == NTS_OK; ++k) {
        const nts_body_def* d = &m->own_defs[k];
        const size_t bytes_k = (k + 1 < m->count ? m->own_at[k + 1] : m->own_bytes.n) - m->own_at[k];
        double a = HUGE_VAL, b = -HUGE_VAL;
        int i;
        for (i = 0; i < d->node_count; ++i) {
            const double c = ntsm_axis_coord(sl, d->nodes[i]);
            if (c < a) a = c;
            if (c > b) b = c;
        }
        for (r = 0; r < P; ++r)
            if (d->node_count > 0 && ntsm_meets(sl, r, a - halo, b + halo)) {
                to[(size_t)k * P + r] = 1;
                sizes[r] += bytes_k;
                total += bytes_k;
            }
    }
    for (r = 0; r < P && rc == NTS_OK; ++r)
        if (sizes[r] > INT_MAX) rc = ntsm_fail(err, NTS_ELIMIT, "more than 2 GiB of bodies for one rank");
    if (rc == NTS_OK && total > INT_MAX) rc = ntsm_fail(err, NTS_ELIMIT, "more than 2 GiB of bodies from one rank");
    if (rc == NTS_OK && (send = (char*)malloc(total + 8)) == NULL) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    for (r = 0, at = 0; r < P; ++r) {
        sc[r] = (int)sizes[r];
        sc[P + r] = (int)at;
        for (k = 0; k < m->count; ++k)
            if (to[(size_t)k * P + r]) {
                const size_t bytes_k = (k + 1 < m->count ? m->own_at[k + 1] : m->own_bytes.n) - m->own_at[k];
                int parts = 0, v;
                for (v = 0; v < P; ++v) parts += to[(size_t)k * P + v];
                memcpy(send + at, m->own_bytes.p + m->own_at[k], bytes_k);
                ntsm_body_set_parts(send + at, parts); /* how many parts hold it (sums.c) */
                at += bytes_k;
            }
    }
    MPI_Alltoall(sc, 1, MPI_INT, sc + 2 * P, 1, MPI_INT, m->comm);
    for (r = 0, at = 0; r < P; ++r) {
        sc[3 * P + r] = (int)at;
        at += (size_t)sc[2 * P + r];
        if (r != m->rank) {
            m->stats.bytes_sent += sc[r];
            m->stats.bytes_received += sc[2 * P + r];
        }
    }
    free(m->recv.p);
    memset(&m->recv, 0, sizeof m->recv);
    rc = at > INT_MAX                                ? ntsm_fail(err, NTS_ELIMIT, "more than 2 GiB of bodies for one rank")
         : ntsm_bytes_room(&m->recv, at + 8) != NULL ? NTS_OK
                                                     : ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    MPI_Alltoallv(send, sc, sc + P, MPI_BYTE, m->recv.p, sc + 2 * P, sc + 3 * P, MPI_BYTE, m->comm);
    /* The bodies received, by global index (one process's order). */
    {
        size_t p = 0;
        int cap = 0, id;
        nts_body_def d;
        while (p < at && rc == NTS_OK) {
            if (!ntsm_grow(&pb, &cap, got + 1, sizeof(part_body))) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
            else {
                pb[got].at = p;
                pb[got].arrival = got;
                pb[got].parts = ntsm_body_parts(m->recv.p + p);
                p += ntsm_body_read(m->recv.p + p, &d, &id);
                pb[got++].id = id;
            }
        }
    }
    if (rc == NTS_OK && got > 1) qsort(pb, (size_t)got, sizeof(part_body), cmp_part_body);
    if (rc == NTS_OK && (defs = (nts_body_def*)calloc((size_t)got + 1, sizeof(nts_body_def))) == NULL)
        rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK && !ntsm_grow(&m->part_ids, &m->part_cap_ids, got + 1, sizeof(int)))
        rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK && !ntsm_grow(&m->part_single, &m->part_single_cap, got + 1, 1))
        rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < got && rc == NTS_OK; ++k) {
        ntsm_body_read(m->recv.p + pb[k].at, &defs[k], &m->part_ids[k]);
        m->part_single[k] = pb[k].parts == 1;
    }
    /* each arrival's nodes and place in the part, for the positions of the
     * evaluations that keep this decomposition */
    free(m->arrival_nodes);
    free(m->arrival_off);
    m->arrival_nodes = (int*)malloc(sizeof(int) * (size_t)(got + 1));
    m->arrival_off = (int*)malloc(sizeof(int) * (size_t)(got + 1));
    m->arrivals = got;
    if (rc == NTS_OK && (m->arrival_nodes == NULL || m->arrival_off == NULL)) rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK) {
        int off = 0;
        for (k = 0; k < got; ++k) {
            m->arrival_nodes[pb[k].arrival] = defs[k].node_count;
            m->arrival_off[pb[k].arrival] = off;
            off += defs[k].node_count;
        }
    }
    nts_scene_destroy(m->part);
    m->part = NULL;
    if (rc == NTS_OK && got > 0) {
        nts_scene_def def = nts_default_scene_def();
        def.bodies = defs;
        def.body_count = got;
        def.lx = lx;
        def.ly = ly;
        def.limits.max_bodies = INT_MAX;
        def.limits.max_nodes_per_body = INT_MAX;
        def.limits.max_nodes = LLONG_MAX;
        if ((m->part = nts_scene_create(&def, err)) == NULL) {
            rc = err != NULL && err->code != 0 ? err->code : NTS_ENOMEM;
            ntsm_global_body(err, m->part_ids, got);
        }
    }
    m->stats.part_bodies = got;
    rc = ntsm_agree(m, m->comm, m->rank, P, rc, err);
done:
    free(counts);
    free(sizes);
    free(m->to);
    m->to = to;
    free(sc);
    free(send);
    free(pb);
    free(defs);
    return rc;
}

/* The kept decomposition's positions: each owned body's to the ranks it
 * went to, in the same order, gathered in the part's node order into
 * *moved (scratch, valid until the next move; NULL without a part) for the
 * part's evaluation to take (nts_evaluate_positions: the positions checked
 * in its segment pass, not apart: their owners checked them already, body
 * by body, and a body's verdicts are its own). The same bits as sending the
 * bodies again. NTS_OK, NTS_ENOMEM or NTS_ELIMIT, on every rank alike. */
int ntsm_part_move(ntsm_scene* m, const nts_vec2** moved, nts_error* err) {
    const int P = m->size, self = m->rank;
    int* sc = (int*)calloc(4u * (size_t)P, sizeof(int));
    nts_vec2* send = NULL;
    nts_vec2* recv = NULL;
    nts_vec2* pos = NULL;
    long long n_send = 0, n_recv = 0;
    int k, r, a, rc = NTS_OK;
    const int nn = m->part ? nts_scene_node_count(m->part) : 0;
    *moved = NULL;
    /* (this rank's own bodies in its part go straight into place, not
     * through the buffers and the exchange) */
    for (k = 0; k < m->count; ++k)
        for (r = 0; r < P; ++r) n_send += m->to[(size_t)k * P + r] && r != self ? m->own_defs[k].node_count : 0;
    for (a = 0; a < m->arrivals; ++a) n_recv += m->arrival_nodes[a];
    for (k = 0; k < m->count; ++k) n_recv -= m->to[(size_t)k * P + self] ? m->own_defs[k].node_count : 0;
    send = (nts_vec2*)ntsm_scratch(&m->sc[SC_POS_SEND], sizeof(nts_vec2) * (size_t)(n_send + 1));
    recv = (nts_vec2*)ntsm_scratch(&m->sc[SC_POS_RECV], sizeof(nts_vec2) * (size_t)(n_recv + 1));
    pos = (nts_vec2*)ntsm_scratch(&m->sc[SC_POS_PART], sizeof(nts_vec2) * (size_t)(nn + 1));
    if (16 * n_send > INT_MAX || 16 * n_recv > INT_MAX)
        rc = ntsm_fail(err, NTS_ELIMIT, "more than 2 GiB of positions for one rank");
    else if (sc == NULL || send == NULL || recv == NULL || pos == NULL)
        rc = ntsm_fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = ntsm_agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    {
        long long at = 0;
        for (r = 0; r < P; ++r) {
            sc[P + r] = (int)(at * (long long)sizeof(nts_vec2));
            for (k = 0; k < m->count && r != self; ++k)
                if (m->to[(size_t)k * P + r]) {
                    memcpy(send + at, m->own_defs[k].nodes, sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
                    at += m->own_defs[k].node_count;
                }
            sc[r] = (int)(at * (long long)sizeof(nts_vec2)) - sc[P + r];
            m->stats.bytes_sent += sc[r];
        }
    }
    MPI_Alltoall(sc, 1, MPI_INT, sc + 2 * P, 1, MPI_INT, m->comm);
    for (r = 0; r < P; ++r) {
        sc[3 * P + r] = r == 0 ? 0 : sc[3 * P + r - 1] + sc[2 * P + r - 1];
        m->stats.bytes_received += sc[2 * P + r];
    }
    MPI_Alltoallv(send, sc, sc + P, MPI_BYTE, recv, sc + 2 * P, sc + 3 * P, MPI_BYTE, m->comm);
    {
        /* The arrivals in the order the part was built from: by source rank,
         * each source's bodies in its order (ntsm_part_build). */
        long long at = 0;
        for (r = 0, a = 0; r < P; ++r) {
            if (r == self) {
                for (k = 0; k < m->count; ++k)
                    if (m->to[(size_t)k * P + r]) {
                        assert(a < m->arrivals && m->arrival_nodes[a] == m->own_defs[k].node_count);
                        memcpy(pos + m->arrival_off[a++], m->own_defs[k].nodes,
                               sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
                    }
            } else {
                const long long end = at + sc[2 * P + r] / (int)sizeof(nts_vec2);
                while (at < end) {
                    assert(a < m->arrivals);
                    memcpy(pos + m->arrival_off[a], recv + at, sizeof(nts_vec2) * (size_t)m->arrival_nodes[a]);
                    at += m->arrival_nodes[a++];
                }
                assert(at == end);
            }
        }
        assert(a == m->arrivals);
    }
    *moved = m->part != NULL ? pos : NULL;
done:
    free(sc);
    return rc;
}

/* The part's entries: whether this rank owns each one's slave, at the
 * positions `moved` (ntsm_part_move's, not yet the part's) or else the
 * part's; and, when the part is new (`all`), each entry's global index and
 * each node's global index, owner and place among its owner's nodes (kept
 * while the part is). */
int ntsm_part_maps(ntsm_scene* m, const slabs* sl, int all, const nts_vec2* moved) {
    const int nb = m->part ? nts_scene_body_count(m->part) : 0;
    const int ne = m->part ? nts_scene_surface_node_count(m->part) : 0;
    const int nn = m->part ? nts_scene_node_count(m->part) : 0;
    const nts_vec2* pos = moved != NULL ? moved : m->part ? nts_scene_positions(m->part) : NULL;
    int b, e, owned = 0;
    if (!ntsm_grow(&m->entry_owned, &m->entry_cap, ne + 1, sizeof(int)) ||
        !ntsm_grow(&m->owned_mask, &m->owned_mask_cap, ne + 1, 1))
        return NTS_ENOMEM;
    {
        int cap = m->entry_cap - 1;
        if (!ntsm_grow(&m->entry_global, &cap, m->entry_cap, sizeof(long long))) return NTS_ENOMEM;
    }
    if (!ntsm_grow(&m->part_node, &m->part_node_cap, nn + 1, sizeof(long long)) ||
        !ntsm_grow(&m->node_owner, &m->node_owner_cap, nn + 1, sizeof(int)) ||
        !ntsm_grow(&m->node_at, &m->node_at_cap, nn + 1, sizeof(int)) ||
        !ntsm_grow(&m->entry_node, &m->entry_node_cap, ne + 1, sizeof(int)) ||
        !ntsm_grow(&m->node_single, &m->node_single_cap, nn + 1, 1) ||
        !ntsm_grow(&m->ps_slot, &m->ps_slot_cap, nn + 1, sizeof(int)))
        return NTS_ENOMEM;
    for (b = 0; all && b < nb; ++b) {
        const int id = m->part_ids[b], n0 = nts_scene_body_node_offset(m->part, b);
        const int e0 = nts_scene_body_entry_start(m->part, b), e1 = nts_scene_body_entry_start(m->part, b + 1);
        int i;
        for (i = 0; i < nts_scene_body_node_count(m->part, b); ++i) {
            m->part_node[n0 + i] = m->node_off[id] + i;
            m->node_owner[n0 + i] = m->owner[id];
            m->node_at[n0 + i] = m->owner_node_at[id] + i;
            m->node_single[n0 + i] = m->part_single[b];
            m->ps_slot[n0 + i] = -1;
        }
        for (e = e0; e < e1; ++e) {
            int body, node;
            nts_scene_entry(m->part, e, &body, &node);
            m->entry_global[e] = m->entry_off[id] + (e - e0);
            m->entry_node[e] = n0 + node;
        }
    }
    for (e = 0; e < ne; ++e) { /* who owns each slave: the slab its node lies in now */
        m->entry_owned[e] = ntsm_slab_of(sl, m->size, ntsm_axis_of(sl, pos[m->entry_node[e]])) == m->rank;
        m->owned_mask[e] = (unsigned char)m->entry_owned[e];
        owned += m->entry_owned[e];
    }
    m->stats.owned_slaves = owned;
    m->stats.part_entries = ne;
    return NTS_OK;
}
