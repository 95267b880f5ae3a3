/* The consistent tangent of the penalty contact (docs/model.md, "Tangent
 * stiffness"), and sparse triplets summed into CSR.
 *
 * For an active contact (g < 0) the energy is phi = eps/2 g^2 = eps psi with
 * psi(x) = 1/2 |r(xi, x)|^2 at the closest point xi = xi(x), where
 * r = Xs - X(xi) = sum_k w_k(xi) x_k is linear in the nodes for fixed xi:
 * w = (1, -N_1, ..., -N_m) over (slave, master nodes). xi is a stationary
 * point of psi (psi_xi = -F = 0, docs/model.md §4), so by the
 * implicit function theorem dxi/dx = -psi_xix / psi_xixi and
 *   K = eps (psi_xx - psi_xxi psi_xix^T / psi_xixi),
 *   psi_xx  (block k, l) = w_k w_l I,
 *   psi_xxi (block k)    = v_k = w_k r_xi + w'_k r,
 *   psi_xixi             = |r_xi|^2 + r . r_xixi,
 * with r_xi = -sum N'_k x_k (minus the tangent) and r_xixi = -sum N''_k x_k
 * (the curvature of the Hermite polynomial enters here). The segment is the
 * same with xi = s (N = 1-s, s; N'' = 0); the vertex (alpha = 0) has no xi:
 * K = eps w w^T (x) I, a radial spring. K is symmetric by construction. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

static int kbuf_reserve(nts_kbuf* k, int extra) {
    int need = k->count + extra, cap = k->cap, rc;
    if (need <= k->cap) return NTS_OK;
    if ((rc = nts_grow((void**)&k->rows, &cap, need, sizeof(int))) != NTS_OK) return rc;
    cap = k->cap;
    if ((rc = nts_grow((void**)&k->cols, &cap, need, sizeof(int))) != NTS_OK) return rc;
    cap = k->cap;
    if ((rc = nts_grow((void**)&k->values, &cap, need, sizeof(double))) != NTS_OK) return rc;
    k->cap = cap;
    return NTS_OK;
}

void nts_kbuf_free(nts_kbuf* k) {
    nts_free(k->rows);
    nts_free(k->cols);
    nts_free(k->values);
    memset(k, 0, sizeof *k);
}

int nts_stiffness_add(nts_kbuf* kb, const nts_scene* s, const nts_contact* c, double alpha) {
    int node[4], m = c->master_count, k, l, rc;
    double w[4], w1[4], w2[4], eps = c->penalty, pxx = 0.0, scale;
    nts_vec2 v[4], r, rx = {0.0, 0.0}, rxx = {0.0, 0.0};
    const int sb = s->body_node_start[c->slave_body], mb = s->body_node_start[c->master_body];
    const nts_vec2 xs = s->pos[sb + c->slave_node];
    assert(m >= 1 && m <= 3);
    node[0] = sb + c->slave_node;
    w[0] = 1.0;
    w1[0] = w2[0] = 0.0;
    for (k = 0; k < m; ++k) {
        node[k + 1] = mb + c->master_nodes[k];
        w[k + 1] = -c->weights[k];
    }
    if (c->kind == NTS_KIND_SEGMENT) {
        w1[1] = 1.0; /* -N'_0 = -(-1) */
        w1[2] = -1.0;
        w2[1] = w2[2] = 0.0;
    } else if (c->kind == NTS_KIND_CORNER) {
        /* N2 = a(1-x)^2/4, N3 = 1 - a(1+x^2)/2, N4 = a(1+x)^2/4 (docs/model.md §12, correction 1). */
        double x = c->param;
        w1[1] = alpha * (1.0 - x) / 2.0;
        w1[2] = alpha * x;
        w1[3] = -alpha * (1.0 + x) / 2.0;
        w2[1] = -alpha / 2.0;
        w2[2] = alpha;
        w2[3] = -alpha / 2.0;
    } else {
        w1[1] = w2[1] = 0.0;
    }
    /* r = g n at the closest point (the force is -eps r); its xi-derivatives
     * from the master nodes relative to the slave (minimum image): the weights
     * of each derivative sum to zero, so only differences enter. */
    r = nts_scale(c->gap, c->normal);
    for (k = 1; k <= m; ++k) {
        nts_vec2 rel = nts_scene_diff(s, s->pos[node[k]], xs);
        rx = nts_mul_add(rx, w1[k], rel);
        rxx = nts_mul_add(rxx, w2[k], rel);
    }
    if (c->kind != NTS_KIND_VERTEX) pxx = nts_dot(rx, rx) + nts_dot(r, rxx);
    for (k = 0; k <= m; ++k) v[k] = nts_add(nts_scale(w[k], rx), nts_scale(w1[k], r));
    /* psi_xixi > 0 at a strict minimum; it vanishes only for a slave at a
     * centre of curvature (on the evolute), where xi(x) is not differentiable:
     * there the xi term is left out (docs/model.md). */
    scale = c->kind == NTS_KIND_VERTEX || !(pxx > 1e-12 * nts_dot(rx, rx)) ? 0.0 : 1.0 / pxx;
    if ((rc = kbuf_reserve(kb, 4 * (m + 1) * (m + 1))) != NTS_OK) return rc;
    for (k = 0; k <= m; ++k)
        for (l = 0; l <= m; ++l) {
            int a, b;
            double vk[2] = {v[k].x, v[k].y}, vl[2] = {v[l].x, v[l].y};
            for (a = 0; a < 2; ++a)
                for (b = 0; b < 2; ++b) {
                    double val = eps * ((a == b ? w[k] * w[l] : 0.0) - vk[a] * vl[b] * scale);
                    kb->rows[kb->count] = 2 * node[k] + a;
                    kb->cols[kb->count] = 2 * node[l] + b;
                    kb->values[kb->count] = val;
                    ++kb->count;
                }
        }
    return NTS_OK;
}

void nts_csr_free(nts_csr* csr) {
    if (csr == NULL) return;
    nts_free(csr->row_start);
    nts_free(csr->cols);
    nts_free(csr->values);
    memset(csr, 0, sizeof *csr);
}

int nts_triplets_to_csr(const nts_triplets* t, nts_csr* out, nts_error* err) {
    int* start = NULL;
    int* order = NULL;
    int* cols = NULL;
    double* vals = NULL;
    int i, r, nnz = 0;
    if (err != NULL) *err = nts_error_none();
    if (out == NULL || t == NULL || t->size < 0 || t->count < 0 || (t->count > 0 && (!t->rows || !t->cols || !t->values))) {
        return nts_error_set(err, NTS_EINVALID_ARGUMENT, nts_at(-1, -1, -1, -1), "invalid triplets");
    }
    memset(out, 0, sizeof *out);
    for (i = 0; i < t->count; ++i)
        if (t->rows[i] < 0 || t->rows[i] >= t->size || t->cols[i] < 0 || t->cols[i] >= t->size) {
            return nts_error_set(err, NTS_EINVALID_ARGUMENT, nts_at(-1, -1, -1, -1),
                                 "triplet %d is outside the %d x %d matrix", i, t->size, t->size);
        }
    start = (int*)nts_alloc(sizeof(int) * ((size_t)t->size + 1));
    order = (int*)nts_alloc(sizeof(int) * ((size_t)t->count + 1));
    cols = (int*)nts_alloc(sizeof(int) * ((size_t)t->count + 1));
    vals = (double*)nts_alloc(sizeof(double) * ((size_t)t->count + 1));
    if (!start || !order || !cols || !vals) {
        nts_free(start);
        nts_free(order);
        nts_free(cols);
        nts_free(vals);
        return nts_error_set(err, NTS_ENOMEM, nts_at(-1, -1, -1, -1), "out of memory");
    }
    /* Counting sort by row, stable: within a row the triplets keep their order. */
    memset(start, 0, sizeof(int) * ((size_t)t->size + 1));
    for (i = 0; i < t->count; ++i) ++start[t->rows[i] + 1];
    for (r = 0; r < t->size; ++r) start[r + 1] += start[r];
    for (i = 0; i < t->count; ++i) order[start[t->rows[i]]++] = i;
    for (r = t->size; r > 0; --r) start[r] = start[r - 1];
    start[0] = 0;
    /* Each row: a stable insertion sort by column (rows are short: a node's
     * contacts), then sum the duplicates in triplet order. */
    for (r = 0; r < t->size; ++r) {
        int b = start[r], e = start[r + 1], k, row_begin = nnz;
        for (k = b + 1; k < e; ++k) {
            int x = order[k], j = k - 1;
            while (j >= b && t->cols[order[j]] > t->cols[x]) {
                order[j + 1] = order[j];
                --j;
            }
            order[j + 1] = x;
        }
        for (k = b; k < e; ++k) {
            int x = order[k];
            if (nnz > row_begin && cols[nnz - 1] == t->cols[x]) {
                vals[nnz - 1] += t->values[x];
            } else {
                cols[nnz] = t->cols[x];
                vals[nnz] = t->values[x];
                ++nnz;
            }
        }
        start[r] = row_begin;
    }
    start[t->size] = nnz;
    nts_free(order);
    out->row_start = start;
    out->cols = cols;
    out->values = vals;
    out->nnz = nnz;
    out->size = t->size;
    return NTS_OK;
}
