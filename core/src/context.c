/* The evaluation context: its buffers (they only grow, so a warm context
 * allocates nothing), its per-thread workers and chunks, and the phase
 * profile. */
#include <stdlib.h>

#include "stages.h"

nts_profile nts_context_profile(const nts_context* ctx) {
    nts_profile p;
    memset(&p, 0, sizeof p);
    if (ctx == NULL) return p;
    p.segments = ctx->phase[0];
    p.cells = ctx->phase[1];
    p.search = ctx->phase[2];
    p.scatter = ctx->phase[3];
    return p;
}

size_t nts_context_memory_bytes(const nts_context* ctx) {
    size_t n;
    int i;
    if (ctx == NULL) return 0;
    n = sizeof *ctx + (ctx->seg_block != NULL ? (size_t)ctx->seg_cap * sizeof(seg_data) + NTS_SEG_ALIGN : 0) +
        (size_t)ctx->keys.cap * (3 * sizeof(float) + sizeof(int)) + (size_t)ctx->cells.cap_cells * sizeof(int) +
        (size_t)ctx->long_m_cap * sizeof(long_master) + (size_t)ctx->long_start_cap * sizeof(int) +
        (size_t)ctx->long_items_cap * sizeof(int) + (size_t)ctx->scratch_cap * sizeof(int) +
        (size_t)ctx->hist_cap * sizeof(int) + (size_t)ctx->chunk_cap * sizeof(chunk_info) +
        (size_t)ctx->forces_cap * sizeof(nts_vec2) + (size_t)ctx->shares_cap * sizeof(force_shares) + (size_t)ctx->contacts_cap * sizeof(nts_contact) +
        (size_t)ctx->gaps_cap * sizeof(nts_contact) + (size_t)ctx->stiffness.cap * (2 * sizeof(int) + sizeof(double));
    for (i = 0; i < ctx->worker_count; ++i) {
        const worker* w = &ctx->workers[i];
        n += sizeof *w + (size_t)ctx->slot_cap * sizeof(int) + (size_t)w->best_cap * sizeof(candidate) +
             (size_t)w->rec_cap * sizeof(candidate) + (size_t)w->share_cap * sizeof(force_shares);
    }
    return n;
}

nts_context* nts_context_create(void) {
    nts_context* ctx = (nts_context*)nts_alloc(sizeof *ctx);
    if (ctx != NULL) memset(ctx, 0, sizeof *ctx);
    return ctx;
}

static void workers_free(nts_context* ctx) {
    int i;
    for (i = 0; i < ctx->worker_count; ++i) {
        nts_free(ctx->workers[i].slot);
        nts_free(ctx->workers[i].best);
        nts_free(ctx->workers[i].recs);
        nts_free(ctx->workers[i].shares);
    }
    nts_free(ctx->workers);
    ctx->workers = NULL;
    ctx->worker_count = 0;
    ctx->slot_cap = 0;
}

void nts_context_destroy(nts_context* ctx) {
    if (ctx == NULL) return;
    nts_free(ctx->seg_block);
    nts_cells_free(&ctx->cells);
    nts_free(ctx->keys.block);
    nts_free(ctx->long_m);
    nts_free(ctx->long_start);
    nts_free(ctx->long_items);
    nts_free(ctx->scratch);
    nts_free(ctx->hist);
    workers_free(ctx);
    nts_free(ctx->chunks);
    nts_free(ctx->forces);
    nts_free(ctx->shares);
    nts_free(ctx->contacts);
    nts_free(ctx->gaps);
    nts_kbuf_free(&ctx->stiffness);
    nts_free(ctx);
}

int nts_workers_prepare(nts_context* ctx, int count, int body_count, int chunks) {
    int i, j, rc;
    if ((rc = nts_grow((void**)&ctx->chunks, &ctx->chunk_cap, chunks, sizeof(chunk_info))) != NTS_OK) return rc;
    memset(ctx->chunks, 0, sizeof(chunk_info) * (size_t)chunks);
    ctx->chunk_count = chunks;
    if (ctx->worker_count != count || ctx->slot_cap < body_count) {
        workers_free(ctx);
        ctx->workers = (worker*)nts_alloc(sizeof(worker) * (size_t)count);
        if (ctx->workers == NULL) return NTS_ENOMEM;
        memset(ctx->workers, 0, sizeof(worker) * (size_t)count);
        ctx->worker_count = count;
        for (i = 0; i < count; ++i) {
            ctx->workers[i].slot = (int*)nts_alloc(sizeof(int) * (size_t)body_count);
            if (ctx->workers[i].slot == NULL) return NTS_ENOMEM;
            for (j = 0; j < body_count; ++j) ctx->workers[i].slot[j] = -1;
        }
        ctx->slot_cap = body_count;
    }
    for (i = 0; i < count; ++i) {
        ctx->workers[i].rec_count = 0;
        ctx->workers[i].share_count = 0;
        ctx->workers[i].fifo_head = ctx->workers[i].fifo_count = 0;
        ctx->workers[i].gaps = 0;
        ctx->workers[i].best_count = 0;
        ctx->workers[i].status = NTS_OK;
    }
    return NTS_OK;
}
