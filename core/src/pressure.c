/* The pressure (docs/model.md §6, (21)): the normal contact traction on each
 * node as a slave, p_i = sum over its active contacts of -eps g, divided by
 * its tributary length l_i (the scene's, §10). From the records path's
 * chunks (NTS_OUT_PRESSURE keeps records, tables.h): a slave's records and
 * deep contacts all lie in its own chunk, so each chunk writes only its own
 * slaves' nodes, adding their contacts in the merged order (slave, then
 * master body): the same bits for any number of threads. */
#include <math.h>
#include <string.h>

#include "parallel.h"
#include "scatter.h"

typedef struct pressure_task {
    nts_context* ctx;
    const search_env* env;
    int bad;
} pressure_task;

/* Chunks [begin, end): their slaves' sums of -eps g, then each divided by
 * the slave's tributary length. */
static void pressure_chunks(int begin, int end, int wi, void* p) {
    pressure_task* t = (pressure_task*)p;
    const search_env* env = t->env;
    const nts_scene* s = env->s;
    double* P = t->ctx->pressure;
    int c, i;
    (void)wi;
    for (c = begin; c < end; ++c) {
        merged it = merged_begin(t->ctx, &t->ctx->chunks[c]);
        const int i1 = (c + 1) * CHUNK_SLAVES < s->surface_count ? (c + 1) * CHUNK_SLAVES : s->surface_count;
        const candidate* rec;
        while ((rec = merged_next(&it)) != NULL)
            if (rec->gap < 0.0) P[s->surf_node[rec->slave]] += law_slave_normal(record_penalty(env, rec) * rec->gap);
        for (i = c * CHUNK_SLAVES; i < i1; ++i) {
            double* pi = &P[s->surf_node[i]];
            if (*pi == 0.0) continue; /* in no contact (or on no surface: no tributary length) */
            *pi /= s->surf_trib[i];
            if (!isfinite(*pi)) nts_atomic_or(&t->bad, 1);
        }
    }
}

int nts_pressure(nts_context* ctx, const search_env* env, const nts_run* run) {
    const nts_scene* s = env->s;
    pressure_task task;
    int rc;
    assert(!env->direct && !env->shares); /* the records path */
    if ((rc = nts_grow((void**)&ctx->pressure, &ctx->pressure_cap, s->node_count, sizeof(double))) != NTS_OK)
        return rc;
    memset(ctx->pressure, 0, sizeof(double) * (size_t)s->node_count);
    task.ctx = ctx;
    task.env = env;
    task.bad = 0;
    nts_run_each(run, pressure_chunks, ctx->chunk_count, &task);
    return task.bad ? NTS_ENONFINITE : NTS_OK;
}
