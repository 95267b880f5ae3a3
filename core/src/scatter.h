/* The scatter (scatter.c, docs/model.md §6, §7): after the search, what the
 * active contacts give (forces, energy, virial, contacts, the tangent, the
 * pressure). The three paths an active candidate takes (direct, shares,
 * records) are in search.h, side by side; the chunks' records are read with
 * context.h's merged iterator. */
#ifndef NTSCONTACT_SCATTER_H
#define NTSCONTACT_SCATTER_H

#include "context.h"

/* The chunks' records, in slave order, into *out. */
int nts_scatter(nts_context* ctx, const nts_scene* s, const nts_options* opt, const search_env* env, const nts_run* run,
                nts_result* out, nts_error* err);

/* pressure.c: the pressure (docs/model.md (21)) of every node into
 * ctx->pressure from the chunks' records and deep contacts (the records
 * path: NTS_OUT_PRESSURE keeps them). NTS_OK, NTS_ENOMEM, or NTS_ENONFINITE
 * when a node's pressure overflows a double. */
int nts_pressure(nts_context* ctx, const search_env* env, const nts_run* run);

#endif
