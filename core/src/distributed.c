/* A distributed host's seam (ntscontact/distributed.h, docs/distributed.md):
 * the frame a part of a scene takes from the whole, and the parts an
 * evaluation leaves (scatter.c: parts_make). nts_scene_frame is in
 * evaluate.c, beside the phases it repeats. */
#include <limits.h>
#include <stdio.h>

#include "context.h"

void nts_context_set_frame(nts_context* ctx, const nts_frame* frame) {
    if (ctx == NULL) return;
    ctx->frame_set = frame != NULL;
    if (frame != NULL) ctx->frame = *frame;
}

void nts_context_set_parts(nts_context* ctx, int on) {
    if (ctx != NULL) ctx->parts_on = on != 0;
}

const nts_part* nts_context_parts(const nts_context* ctx, int* count) {
    *count = ctx->parts_on ? ctx->part_count : 0;
    return ctx->parts_on ? ctx->parts : NULL;
}

void nts_context_set_owned(nts_context* ctx, const unsigned char* owned) {
    if (ctx != NULL) ctx->owned = owned;
}

long long nts_context_owned_gaps(const nts_context* ctx) { return ctx->parts_on ? ctx->owned_gaps : 0; }

long long nts_candidate_budget(const nts_options* opt, long long surface_nodes) {
    const long long budget = opt->max_candidates > 0 ? opt->max_candidates : 64LL * surface_nodes + 1000000;
    return budget > INT_MAX ? INT_MAX : budget;
}

void nts_candidate_budget_message(char* out, size_t size, long long budget, int deeper) {
    snprintf(out, size, "more than max_candidates = %lld closest points within the search radius%s: the bodies "
             "overlap far more than contact does (or raise the limit)", budget, deeper ? " and deeper" : "");
}

const int* nts_context_gap_entries(const nts_context* ctx, int* count) {
    *count = ctx->parts_on ? ctx->gap_entry_count : 0;
    return ctx->parts_on ? ctx->gap_entries : NULL;
}

const int* nts_context_warning_entries(const nts_context* ctx, int code, int* count) {
    static const int none = 0;
    const nts_reach* r = &ctx->reach;
    *count = 0;
    if (code == NTS_WARN_PENETRATION_BEYOND_RADIUS) {
        *count = (int)r->beyond;
        return r->beyond > 0 ? r->beyond_slaves : &none;
    }
    if (code == NTS_WARN_PENETRATION_BEYOND_REACH) {
        *count = (int)r->unresolved;
        return r->unresolved > 0 ? r->unresolved_slaves : &none;
    }
    return &none;
}

void nts_scene_entry(const nts_scene* s, int e, int* body, int* node) {
    assert(e >= 0 && e < s->surface_count);
    *body = s->surf_body[e];
    *node = s->surf_local[e];
}

int nts_scene_body_entry_start(const nts_scene* s, int b) {
    assert(b >= 0 && b <= s->body_count);
    return s->loop_start[s->body_loop_start[b]];
}
