/* The whole answer on a root (ntsm_gather): what nts_evaluate gives, in
 * its order, for a front end that writes it (ntscontact-mpi). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"


/* Every rank's bytes, one after the other on root (malloc; NULL elsewhere). */
/* Whether every rank is fine (a collective: every rank calls it). */
static int all_ok(ntsm_scene* m, int ok) {
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, m->comm);
    return all;
}

/* Every rank's bytes, one after the other on root (malloc; NULL elsewhere).
 * *ok: every rank's verdict (a rank short of memory, or more than 2 GiB on
 * root, fails them all, and nobody sends). */
static char* gather_bytes(ntsm_scene* m, int root, const void* mine, size_t n, size_t* total, int* ok) {
    int mine_n = (int)n, r;
    int* cc = (int*)malloc(sizeof(int) * 2u * (size_t)m->size);
    char* all = NULL;
    long long t = 0;
    *total = 0;
    if (!all_ok(m, *ok && cc != NULL && n <= INT_MAX)) {
        free(cc);
        *ok = 0;
        return NULL;
    }
    MPI_Gather(&mine_n, 1, MPI_INT, cc, 1, MPI_INT, root, m->comm);
    if (m->rank == root) {
        for (r = 0; r < m->size; ++r) {
            cc[m->size + r] = (int)(t < INT_MAX ? t : 0);
            t += cc[r];
        }
        if (t > INT_MAX || (all = (char*)malloc((size_t)t + 8)) == NULL) *ok = 0;
    }
    *ok = all_ok(m, *ok);
    if (*ok) MPI_Gatherv(mine, mine_n, MPI_BYTE, all, cc, cc + m->size, MPI_BYTE, root, m->comm);
    *total = (size_t)t;
    free(cc);
    if (!*ok) {
        free(all);
        all = NULL;
    }
    return all;
}

typedef struct keyed_contact {
    int entry, body;
    nts_contact c;
} keyed_contact;

typedef struct keyed_anchor {
    int entry, body;
    nts_anchor a;
} keyed_anchor;

typedef struct keyed_triplet {
    int entry, body, seq, row, col, pad;
    double v;
} keyed_triplet;

static int cmp_keyed_contact(const void* pa, const void* pb) {
    const keyed_contact* a = (const keyed_contact*)pa;
    const keyed_contact* b = (const keyed_contact*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

static int cmp_keyed_anchor(const void* pa, const void* pb) {
    const keyed_anchor* a = (const keyed_anchor*)pa;
    const keyed_anchor* b = (const keyed_anchor*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

static int cmp_keyed_triplet(const void* pa, const void* pb) {
    const keyed_triplet* a = (const keyed_triplet*)pa;
    const keyed_triplet* b = (const keyed_triplet*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    if (a->body != b->body) return a->body < b->body ? -1 : 1;
    return (a->seq > b->seq) - (a->seq < b->seq);
}

static nts_contact contact_global(const ntsm_scene* m, nts_contact c) {
    c.slave_body = m->part_ids[c.slave_body];
    c.master_body = m->part_ids[c.master_body];
    return c;
}

void ntsm_gathered_free(ntsm_scene* m) {
    free(m->g_forces);
    free(m->g_pressure);
    free(m->g_contacts);
    free(m->g_gaps);
    free(m->g_anchors);
    free(m->g_rows);
    free(m->g_cols);
    free(m->g_vals);
    m->g_forces = NULL;
    m->g_pressure = NULL;
    m->g_contacts = m->g_gaps = NULL;
    m->g_anchors = NULL;
    m->g_rows = m->g_cols = NULL;
    m->g_vals = NULL;
}

int ntsm_gather(ntsm_scene* m, int root, nts_result* out, nts_error* err) {
    const long long nodes = m->node_off[m->bodies];
    const nts_result* pr = &m->part_result;
    int np = 0, ng = 0, k, ok = 1, rc = NTS_OK;
    const nts_part* parts = m->part ? nts_context_parts(m->ctx, &np) : NULL;
    const int* gap_entries = m->part ? nts_context_gap_entries(m->ctx, &ng) : NULL;
    bytes b;
    char* all;
    size_t total;
    nts_error e = nts_error_none();
    memset(out, 0, sizeof *out);
    memset(&b, 0, sizeof b);
    ntsm_gathered_free(m);
    if (m->rank == root) {
        out->summary = m->summary;
        out->warnings = m->warning_count > 0 ? m->warnings : NULL;
        out->warning_count = m->warning_count;
    }

    /* The forces: each rank's bodies (index, then its nodes' forces). */
    if (m->outputs & NTS_OUT_FORCES) {
        int at = 0;
        for (k = 0; k < m->count; ++k) {
            long long head[2];
            head[0] = m->ids[k];
            head[1] = m->own_defs[k].node_count;
            ntsm_bytes_put(&b, head, sizeof head);
            ntsm_bytes_put(&b, m->forces + at, sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
            at += m->own_defs[k].node_count;
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            size_t p = 0;
            if ((m->g_forces = (nts_vec2*)calloc((size_t)nodes + 1, sizeof(nts_vec2))) == NULL) ok = 0;
            while (ok && p < total) {
                const long long* head = (const long long*)(const void*)(all + p);
                p += 2 * sizeof(long long);
                memcpy(m->g_forces + m->node_off[head[0]], all + p, sizeof(nts_vec2) * (size_t)head[1]);
                p += ntsm_al8(sizeof(nts_vec2) * (size_t)head[1]);
            }
            out->forces = m->g_forces;
        }
        free(all);
        b.n = 0;
        if (!all_ok(m, ok)) goto oom;
    }

    /* The pressure: each owned slave's node, from the part that owns it. */
    if (m->outputs & NTS_OUT_PRESSURE) {
        const int ne = m->part ? nts_scene_surface_node_count(m->part) : 0;
        for (k = 0; k < ne; ++k)
            if (m->entry_owned[k]) {
                int body, node;
                long long g;
                double v[2];
                nts_scene_entry(m->part, k, &body, &node);
                g = m->node_off[m->part_ids[body]] + node;
                memcpy(&v[0], &g, sizeof g);
                v[1] = pr->pressure[nts_scene_body_node_offset(m->part, body) + node];
                ntsm_bytes_put(&b, v, sizeof v);
            }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            size_t p;
            if ((m->g_pressure = (double*)calloc((size_t)nodes + 1, sizeof(double))) == NULL) ok = 0;
            for (p = 0; ok && p < total; p += 2 * sizeof(double)) {
                long long g;
                memcpy(&g, all + p, sizeof g);
                memcpy(&m->g_pressure[g], all + p + sizeof(double), sizeof(double));
            }
            out->pressure = m->g_pressure;
        }
        free(all);
        b.n = 0;
        if (!all_ok(m, ok)) goto oom;
    }

    /* The contacts and the anchors (contact order: parts' order). */
    {
        const int want_c = (m->outputs & NTS_OUT_CONTACTS) != 0 && pr->contacts != NULL;
        const int want_a = pr->anchors != NULL;
        int pass;
        for (pass = 0; pass < 2; ++pass) {
            size_t one = pass == 0 ? sizeof(keyed_contact) : sizeof(keyed_anchor);
            int any = pass == 0 ? (m->outputs & NTS_OUT_CONTACTS) != 0 : 1, has;
            MPI_Allreduce(pass == 0 ? &want_c : &want_a, &has, 1, MPI_INT, MPI_MAX, m->comm);
            if (!any || !has) continue;
            for (k = 0; k < np; ++k) {
                if (!m->entry_owned[parts[k].entry]) continue;
                if (pass == 0 && want_c) {
                    keyed_contact kc;
                    kc.entry = (int)m->entry_global[parts[k].entry];
                    kc.body = m->part_ids[parts[k].master_body];
                    kc.c = contact_global(m, pr->contacts[k]);
                    ntsm_bytes_put(&b, &kc, sizeof kc);
                } else if (pass == 1 && want_a) {
                    keyed_anchor ka;
                    ka.entry = (int)m->entry_global[parts[k].entry];
                    ka.body = m->part_ids[parts[k].master_body];
                    ka.a = pr->anchors[k];
                    ka.a.slave_body = m->part_ids[ka.a.slave_body];
                    ka.a.master_body = m->part_ids[ka.a.master_body];
                    ntsm_bytes_put(&b, &ka, sizeof ka);
                }
            }
            ok = !b.oom;
            all = gather_bytes(m, root, b.p, b.n, &total, &ok);
            if (ok && m->rank == root) {
                const int n = (int)(total / ntsm_al8(one));
                if (pass == 0) {
                    keyed_contact* kc = (keyed_contact*)(void*)all;
                    if (n > 1) qsort(kc, (size_t)n, sizeof(keyed_contact), cmp_keyed_contact);
                    if ((m->g_contacts = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(n + 1))) == NULL) ok = 0;
                    for (k = 0; ok && k < n; ++k) m->g_contacts[k] = kc[k].c;
                    out->contacts = n > 0 ? m->g_contacts : NULL; /* (as nts_evaluate: none, NULL) */
                    out->contact_count = n;
                } else {
                    keyed_anchor* ka = (keyed_anchor*)(void*)all;
                    if (n > 1) qsort(ka, (size_t)n, sizeof(keyed_anchor), cmp_keyed_anchor);
                    if ((m->g_anchors = (nts_anchor*)malloc(sizeof(nts_anchor) * (size_t)(n + 1))) == NULL) ok = 0;
                    for (k = 0; ok && k < n; ++k) m->g_anchors[k] = ka[k].a;
                    out->anchors = n > 0 ? m->g_anchors : NULL;
                    out->anchor_count = n;
                }
            }
            free(all);
            b.n = 0;
            if (!all_ok(m, ok)) goto oom;
        }
    }

    /* The gaps. */
    if (m->outputs & NTS_OUT_GAPS) {
        for (k = 0; k < ng; ++k) {
            keyed_contact kc;
            if (!m->entry_owned[gap_entries[k]]) continue;
            kc.c = contact_global(m, pr->gaps[k]);
            kc.entry = (int)m->entry_global[gap_entries[k]];
            kc.body = kc.c.master_body;
            ntsm_bytes_put(&b, &kc, sizeof kc);
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            const int n = (int)(total / ntsm_al8(sizeof(keyed_contact)));
            keyed_contact* kc = (keyed_contact*)(void*)all;
            if (n > 1) qsort(kc, (size_t)n, sizeof(keyed_contact), cmp_keyed_contact);
            if ((m->g_gaps = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(n + 1))) == NULL) ok = 0;
            for (k = 0; ok && k < n; ++k) m->g_gaps[k] = kc[k].c;
            out->gaps = n > 0 ? m->g_gaps : NULL;
            out->gap_count = n;
        }
        free(all);
        b.n = 0;
        if (!all_ok(m, ok)) goto oom;
    }

    /* The tangent: each active contact's block in contact order. */
    if (m->outputs & NTS_OUT_STIFFNESS) {
        for (k = 0; k < np; ++k) {
            int t;
            if (!m->entry_owned[parts[k].entry]) continue;
            for (t = 0; t < parts[k].stiff_count; ++t) {
                const int at = parts[k].stiff_at + t;
                const int row = pr->stiffness.rows[at], col = pr->stiffness.cols[at];
                keyed_triplet kt;
                kt.entry = (int)m->entry_global[parts[k].entry];
                kt.body = m->part_ids[parts[k].master_body];
                kt.seq = t;
                kt.row = (int)(2 * m->part_node[row / 2] + row % 2);
                kt.col = (int)(2 * m->part_node[col / 2] + col % 2);
                kt.pad = 0;
                kt.v = pr->stiffness.values[at];
                ntsm_bytes_put(&b, &kt, sizeof kt);
            }
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            const int n = (int)(total / sizeof(keyed_triplet));
            keyed_triplet* kt = (keyed_triplet*)(void*)all;
            if (n > 1) qsort(kt, (size_t)n, sizeof(keyed_triplet), cmp_keyed_triplet);
            m->g_rows = (int*)malloc(sizeof(int) * (size_t)(n + 1));
            m->g_cols = (int*)malloc(sizeof(int) * (size_t)(n + 1));
            m->g_vals = (double*)malloc(sizeof(double) * (size_t)(n + 1));
            if (!m->g_rows || !m->g_cols || !m->g_vals) ok = 0;
            for (k = 0; ok && k < n; ++k) {
                m->g_rows[k] = kt[k].row;
                m->g_cols[k] = kt[k].col;
                m->g_vals[k] = kt[k].v;
            }
            out->stiffness.rows = n > 0 ? m->g_rows : NULL;
            out->stiffness.cols = n > 0 ? m->g_cols : NULL;
            out->stiffness.values = n > 0 ? m->g_vals : NULL;
            out->stiffness.count = n;
        }
        free(all);
        b.n = 0;
        if (!all_ok(m, ok)) goto oom;
    }
    if (m->rank == root && (m->outputs & NTS_OUT_STIFFNESS)) out->stiffness.size = (int)(2 * nodes); /* (as nts_evaluate) */
    free(b.p);
    rc = ntsm_agree(m, m->comm, m->rank, m->size, NTS_OK, &e);
    if (err != NULL) *err = e;
    return rc;
oom:
    free(b.p);
    rc = ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e);
    if (err != NULL) *err = e;
    return rc;
}
