/* The tangent's triplets, one dense block per active contact (the block is
 * the contact law's: contact_law.c), and sparse triplets summed into CSR. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_law.h"
#include "internal.h"

int nts_kbuf_reserve(nts_kbuf* k, int extra) {
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
    law_block blk;
    int k, l, a, b, rc;
    nts_law_tangent(s, c, alpha, &blk);
    if ((rc = nts_kbuf_reserve(kb, 4 * (blk.m + 1) * (blk.m + 1))) != NTS_OK) return rc;
    for (k = 0; k <= blk.m; ++k)
        for (l = 0; l <= blk.m; ++l)
            for (a = 0; a < 2; ++a)
                for (b = 0; b < 2; ++b) {
                    kb->rows[kb->count] = 2 * blk.node[k] + a;
                    kb->cols[kb->count] = 2 * blk.node[l] + b;
                    kb->values[kb->count] = blk.k[2 * k + a][2 * l + b];
                    ++kb->count;
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
