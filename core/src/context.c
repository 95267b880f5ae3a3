/* The evaluation context: its buffers (they only grow, so a warm context
 * allocates nothing), its per-thread workers and chunks, and the phase
 * profile. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "context.h"

nts_profile nts_context_profile(const nts_context* ctx) {
    nts_profile p;
    memset(&p, 0, sizeof p);
    if (ctx == NULL) return p;
    p.segments = ctx->phase[0];
    p.cells = ctx->phase[1];
    p.search = ctx->phase[2];
    p.scatter = ctx->phase[3];
    p.median_from = ctx->median_from;
    return p;
}

size_t nts_context_memory_bytes(const nts_context* ctx) {
    size_t n;
    int i;
    if (ctx == NULL) return 0;
    n = sizeof *ctx + (ctx->seg_block != NULL ? (size_t)ctx->seg_cap * sizeof(seg_data) + NTS_SEG_ALIGN : 0) +
        (size_t)ctx->keys.cap * (3 * sizeof(float) + sizeof(int)) + (size_t)ctx->cells.cap_cells * sizeof(int) +
        (size_t)ctx->long_m_cap * sizeof(long_master) + (size_t)ctx->long_start_cap * sizeof(int) +
        (size_t)ctx->long_items_cap * sizeof(int) + (size_t)ctx->scratch_cap * sizeof(int) + (size_t)ctx->self_u_cap * sizeof(nts_vec2) +
        (size_t)(ctx->self_y_cap + ctx->area_perim_cap) * sizeof(double) + (size_t)(ctx->self_first_cap + ctx->self_start_cap + ctx->self_items_cap + ctx->entry_of_cap) * sizeof(int) +
        (size_t)ctx->hist_cap * sizeof(int) + (size_t)ctx->chunk_cap * sizeof(chunk_info) +
        (size_t)ctx->forces_cap * sizeof(nts_vec2) + (size_t)ctx->pressure_cap * sizeof(double) + (size_t)ctx->shares_cap * sizeof(force_shares) + (size_t)ctx->contacts_cap * sizeof(nts_contact) +
        (size_t)ctx->gaps_cap * sizeof(nts_contact) + (size_t)ctx->stiffness.cap * (2 * sizeof(int) + sizeof(double)) +
        (size_t)(ctx->fric_cap + ctx->fric_deep_cap) * sizeof(friction_out) +
        (size_t)ctx->anchors_cap * sizeof(nts_anchor) +
        ctx->pool_cap[STREAM_RECORDS] + ctx->pool_cap[STREAM_REACH] + nts_reach_memory_bytes(&ctx->reach);
    for (i = 0; i < ctx->worker_count; ++i) {
        const worker* w = &ctx->workers[i];
        n += sizeof *w + (size_t)ctx->slot_cap * sizeof(int) + (size_t)w->best_cap * sizeof(candidate) +
             (size_t)w->rec_cap * sizeof(candidate) + (size_t)w->share_cap * sizeof(force_shares) +
             (size_t)w->item_cap * sizeof(reach_item) + (size_t)w->last_cap * sizeof(candidate) +
             w->spill_cap[STREAM_RECORDS] + w->spill_cap[STREAM_REACH];
    }
    return n;
}

int nts_context_set_parallel(nts_context* ctx, const nts_parallel* backend) {
    if (ctx == NULL) return NTS_EINVALID_ARGUMENT;
    if (backend == NULL) {
        memset(&ctx->host, 0, sizeof ctx->host);
        ctx->host_set = 0;
        return NTS_OK;
    }
    if (backend->enqueue == NULL || backend->finish == NULL || backend->worker_count < 1)
        return NTS_EINVALID_ARGUMENT;
    ctx->host = *backend;
    ctx->host_set = 1;
    return NTS_OK;
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
        nts_free(ctx->workers[i].items);
        nts_free(ctx->workers[i].last);
        nts_free(ctx->workers[i].spill[STREAM_RECORDS]);
        nts_free(ctx->workers[i].spill[STREAM_REACH]);
    }
    nts_free(ctx->workers);
    ctx->workers = NULL;
    ctx->worker_count = 0;
    ctx->slot_cap = 0;
}

/* Every buffer of the context, given back (the struct itself kept). */
static void buffers_free(nts_context* ctx) {
    nts_free(ctx->seg_block);
    nts_cells_free(&ctx->cells);
    nts_free(ctx->keys.block);
    nts_free(ctx->long_m);
    nts_free(ctx->long_start);
    nts_free(ctx->long_items);
    nts_free(ctx->scratch);
    nts_free(ctx->self_u);
    nts_free(ctx->self_y);
    nts_free(ctx->self_first);
    nts_free(ctx->self_start);
    nts_free(ctx->self_items);
    nts_free(ctx->area_perim);
    nts_free(ctx->entry_of);
    nts_free(ctx->hist);
    workers_free(ctx);
    nts_free(ctx->chunks);
    nts_free(ctx->forces);
    nts_free(ctx->pressure);
    nts_free(ctx->shares);
    nts_free(ctx->pool[STREAM_RECORDS]);
    nts_free(ctx->pool[STREAM_REACH]);
    nts_reach_free(&ctx->reach);
    nts_free(ctx->contacts);
    nts_free(ctx->gaps);
    nts_kbuf_free(&ctx->stiffness);
    nts_free(ctx->fric);
    nts_free(ctx->fric_deep);
    nts_free(ctx->anchors);
    nts_free(ctx->parts);
    nts_free(ctx->gap_entries);
}

void nts_context_destroy(nts_context* ctx) {
    if (ctx == NULL) return;
    buffers_free(ctx);
    nts_free(ctx);
}

/* A context keeps the largest buffers it has met (so that a warm one
 * allocates nothing); one large evaluation, such as gaps on a wide radius,
 * would leave them held for every smaller one after it. Trimming gives them
 * all back: the context is as nts_context_create made it. */
void nts_context_trim(nts_context* ctx) {
    if (ctx == NULL) return;
    buffers_free(ctx);
    memset(ctx, 0, sizeof *ctx);
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
    ctx->pool_at[STREAM_RECORDS] = ctx->pool_at[STREAM_REACH] = 0;
    for (i = 0; i < count; ++i) {
        ctx->workers[i].rec_count = 0;
        ctx->workers[i].share_count = 0;
        ctx->workers[i].item_count = 0;
        ctx->workers[i].last_count = 0;
        ctx->workers[i].last_slave = ctx->workers[i].first_slave = -1;
        ctx->workers[i].fifo_head = ctx->workers[i].fifo_count = 0;
        ctx->workers[i].forces_bad = 0;
        ctx->workers[i].spill_used[STREAM_RECORDS] = ctx->workers[i].spill_used[STREAM_REACH] = 0;
        ctx->workers[i].gaps = 0;
        ctx->workers[i].owned_gaps = 0;
        ctx->workers[i].pruned = 0;
        ctx->workers[i].best_count = 0;
        ctx->workers[i].best_most = 0;
        ctx->workers[i].status = NTS_OK;
    }
    return NTS_OK;
}

/* Room for `need` bytes and an eighth more (the contents kept). */
static int grow_bytes(char** p, size_t* cap, size_t need) {
    const size_t want = need + need / 8;
    char* q;
    if (need <= *cap) return NTS_OK;
    q = (char*)nts_alloc(want);
    if (q == NULL) return NTS_ENOMEM;
    if (*p != NULL && *cap > 0) memcpy(q, *p, *cap);
    nts_free(*p);
    *p = q;
    *cap = want;
    return NTS_OK;
}

void nts_chunk_keep(nts_context* ctx, worker* w, chunk_info* ch, int stream, const void* staged, size_t bytes) {
    chunk_part* part = &ch->part[stream];
    size_t at;
    if (bytes == 0) return;
    at = nts_atomic_add_size(&ctx->pool_at[stream], bytes); /* workers claim their room at once */
    if (at + bytes <= ctx->pool_cap[stream]) { /* claimed: no other chunk writes there */
        memcpy(ctx->pool[stream] + at, staged, bytes);
        part->spilled = 0;
        part->at = at;
        return;
    }
    if (grow_bytes(&w->spill[stream], &w->spill_cap[stream], w->spill_used[stream] + bytes) != NTS_OK) {
        w->status = NTS_ENOMEM;
        return;
    }
    memcpy(w->spill[stream] + w->spill_used[stream], staged, bytes);
    part->spilled = 1;
    part->at = w->spill_used[stream];
    w->spill_used[stream] += bytes;
}

/* Room for `need` elements of `size` bytes, an eighth more (grow_bytes). */
static int reserve(void** p, int* cap, int need, size_t size) {
    size_t bytes = (size_t)*cap * size;
    char* q = (char*)*p;
    if (need <= *cap) return NTS_OK;
    if (grow_bytes(&q, &bytes, (size_t)need * size) != NTS_OK) return NTS_ENOMEM;
    *p = q;
    *cap = bytes / size < (size_t)INT_MAX ? (int)(bytes / size) : INT_MAX;
    return NTS_OK;
}

/* One stream's chunks in its pool: when some spilled, a new pool with room
 * for all, every chunk's items in chunk order, and the spills given back.
 * Sets each chunk's `data`; *largest is the most items of one chunk. */
static int settle_stream(nts_context* ctx, int stream, size_t size, int* largest) {
    size_t total = 0;
    int c, t, spilled = 0;
    *largest = 0;
    for (c = 0; c < ctx->chunk_count; ++c) {
        const chunk_part* part = &ctx->chunks[c].part[stream];
        total += (size_t)part->count * size;
        if (part->count > *largest) *largest = part->count;
        spilled |= part->count > 0 && part->spilled;
    }
    if (spilled) {
        const size_t want = total + total / 8;
        char* pool = (char*)nts_alloc(want);
        size_t at = 0;
        if (pool == NULL) return NTS_ENOMEM;
        for (c = 0; c < ctx->chunk_count; ++c) {
            chunk_part* part = &ctx->chunks[c].part[stream];
            const size_t bytes = (size_t)part->count * size;
            if (bytes == 0) continue;
            memcpy(pool + at,
                   (part->spilled ? ctx->workers[ctx->chunks[c].worker].spill[stream] : ctx->pool[stream]) + part->at,
                   bytes);
            part->spilled = 0;
            part->at = at;
            at += bytes;
        }
        nts_free(ctx->pool[stream]);
        ctx->pool[stream] = pool;
        ctx->pool_cap[stream] = want;
        for (t = 0; t < ctx->worker_count; ++t) { /* nothing left there: give it back */
            worker* w = &ctx->workers[t];
            nts_free(w->spill[stream]);
            w->spill[stream] = NULL;
            w->spill_cap[stream] = w->spill_used[stream] = 0;
        }
    }
    for (c = 0; c < ctx->chunk_count; ++c) {
        chunk_part* part = &ctx->chunks[c].part[stream];
        part->data = part->count > 0 ? (const void*)(ctx->pool[stream] + part->at) : NULL;
    }
    return NTS_OK;
}

int nts_chunks_settle(nts_context* ctx, int nthreads, int shares) {
    int t, largest, most_items, best = 0;
    if (settle_stream(ctx, STREAM_RECORDS, shares ? sizeof(force_shares) : sizeof(candidate), &largest) != NTS_OK ||
        settle_stream(ctx, STREAM_REACH, sizeof(reach_item), &most_items) != NTS_OK)
        return NTS_ENOMEM;
    /* What every worker must hold is sized by the scene's needs (the largest
     * chunk, the most candidates of a slave), never by another worker's
     * capacity: capacities depend on which worker ran what, and sizing one
     * by another's grew each by an eighth at every evaluation (issue 22). */
    for (t = 0; t < nthreads; ++t)
        if (ctx->workers[t].best_most > best) best = ctx->workers[t].best_most;
    for (t = 0; t < nthreads && nthreads > 1; ++t) {
        worker* w = &ctx->workers[t];
        if ((!shares && reserve((void**)&w->recs, &w->rec_cap, largest, sizeof(candidate)) != NTS_OK) ||
            (shares && reserve((void**)&w->shares, &w->share_cap, largest, sizeof(force_shares)) != NTS_OK) ||
            reserve((void**)&w->items, &w->item_cap, most_items, sizeof(reach_item)) != NTS_OK ||
            reserve((void**)&w->best, &w->best_cap, best, sizeof(candidate)) != NTS_OK ||
            reserve((void**)&w->last, &w->last_cap, best, sizeof(candidate)) != NTS_OK)
            return NTS_ENOMEM;
    }
    return NTS_OK;
}
