/* Encode results, validation reports and error documents
 * (schemas/result.schema.json, schemas/error.schema.json) with our own printer:
 * doubles through ntsj_buf_double (shortest round-trip, never NaN/Inf), only the
 * arrays asked for in `outputs`, and an optional two-space indentation where
 * arrays of numbers stay on one line. Nothing here allocates but the buffer. */
#include <string.h>

#include "codec_internal.h"

/* A streaming JSON writer over ntsj_buf. */
typedef struct writer {
    ntsj_buf* b;
    int pretty;
    int depth;
    int need_comma; /* a value was written at the current level */
    int after_key;  /* the next value follows "key": */
    int inline_at;  /* depth of the outermost one-line array, 0 when none */
} writer;

static void w_newline(writer* w) {
    static const char spaces[] = "                                ";
    int n = 2 * w->depth;
    ntsj_buf_putc(w->b, '\n');
    while (n > 0) {
        int k = n < 32 ? n : 32;
        ntsj_buf_put(w->b, spaces, (size_t)k);
        n -= k;
    }
}

static void w_pre(writer* w) {
    if (w->after_key) {
        w->after_key = 0;
        return;
    }
    if (w->need_comma) ntsj_buf_putc(w->b, ',');
    if (!w->pretty || w->depth == 0) return;
    if (w->inline_at) {
        if (w->need_comma) ntsj_buf_putc(w->b, ' ');
    } else {
        w_newline(w);
    }
}

static void w_open(writer* w, char c, int one_line) {
    w_pre(w);
    ntsj_buf_putc(w->b, c);
    ++w->depth;
    w->need_comma = 0;
    if (one_line && !w->inline_at) w->inline_at = w->depth;
}

static void w_close(writer* w, char c) {
    int had = w->need_comma;
    --w->depth;
    if (w->pretty && had && !w->inline_at) w_newline(w);
    if (w->inline_at == w->depth + 1) w->inline_at = 0;
    ntsj_buf_putc(w->b, c);
    w->need_comma = 1;
}

static void w_key(writer* w, const char* key) {
    w_pre(w);
    ntsj_buf_putc(w->b, '"');
    ntsj_buf_puts(w->b, key); /* our keys need no escapes */
    ntsj_buf_put(w->b, w->pretty ? "\": " : "\":", w->pretty ? 3 : 2);
    w->after_key = 1;
}

static void w_double(writer* w, double v) {
    w_pre(w);
    ntsj_buf_double(w->b, v);
    w->need_comma = 1;
}

static void w_int(writer* w, long long v) {
    w_pre(w);
    ntsj_buf_int(w->b, v);
    w->need_comma = 1;
}

static void w_string(writer* w, const char* s) {
    w_pre(w);
    ntsj_buf_string(w->b, s);
    w->need_comma = 1;
}

static void w_bool(writer* w, int v) {
    w_pre(w);
    ntsj_buf_puts(w->b, v ? "true" : "false");
    w->need_comma = 1;
}

static void w_vec2(writer* w, nts_vec2 v) {
    ntsj_buf* b = w->b;
    if (!w->pretty && !b->oom && b->data != NULL && b->len + 2 * NTSJ_DOUBLE_MAX + 4 < b->cap) {
        /* the arrays of forces and positions: written in place while the
         * buffer has room, the same bytes as below */
        char* p = b->data + b->len;
        if (w->after_key) w->after_key = 0;
        else if (w->need_comma) *p++ = ',';
        *p++ = '[';
        p += ntsj_format_double(p, v.x);
        *p++ = ',';
        p += ntsj_format_double(p, v.y);
        *p++ = ']';
        *p = '\0';
        b->len = (size_t)(p - b->data);
        w->need_comma = 1;
        return;
    }
    w_open(w, '[', 1);
    w_double(w, v.x);
    w_double(w, v.y);
    w_close(w, ']');
}

/* With friction the virial is not symmetric (docs/model.md (28)): yx too. */
static void w_virial(writer* w, nts_virial v, int friction) {
    w_open(w, '{', 1);
    w_key(w, "xx");
    w_double(w, v.xx);
    w_key(w, "yy");
    w_double(w, v.yy);
    w_key(w, "xy");
    w_double(w, v.xy);
    if (friction) {
        w_key(w, "yx");
        w_double(w, v.yx);
    }
    w_close(w, '}');
}

static void w_id(writer* w, const ntsj_id* id) {
    if (id->is_int) w_int(w, id->ival);
    else w_string(w, id->sval);
}

static void w_init(writer* w, ntsj_buf* b, int pretty) {
    memset(w, 0, sizeof *w);
    w->b = b;
    w->pretty = pretty;
}

static void w_finish(writer* w) { ntsj_buf_putc(w->b, '\n'); }

static const char* kind_name(nts_kind k) {
    switch (k) {
    case NTS_KIND_SEGMENT: return "segment";
    case NTS_KIND_CORNER: return "corner";
    default: return "vertex";
    }
}

static const char* state_name(int state) {
    switch (state) {
    case NTS_STICK: return "stick";
    case NTS_SLIP: return "slip";
    default: return "frictionless";
    }
}

/* A feature's nodes: a segment's two, a corner's three, a vertex's one. */
static int kind_nodes(nts_kind k) { return k == NTS_KIND_SEGMENT ? 2 : k == NTS_KIND_CORNER ? 3 : 1; }

/* An anchor's feature (§14, (23)): {"kind", "nodes", "param"}, members of an
 * open object. */
static void w_anchor_feature(writer* w, const nts_anchor* a) {
    int i;
    w_key(w, "kind");
    w_string(w, kind_name(a->kind));
    w_key(w, "nodes");
    w_open(w, '[', 1);
    for (i = 0; i < kind_nodes(a->kind); ++i) w_int(w, a->nodes[i]);
    w_close(w, ']');
    w_key(w, "param");
    w_double(w, a->param);
}

/* One entry of "history": the key (slave body and node, master body) and
 * the anchor's feature (result.schema.json's anchor). */
static void w_history_entry(writer* w, const ntsj_scene* s, const nts_anchor* a) {
    w_open(w, '{', 1);
    w_key(w, "slave");
    w_open(w, '{', 1);
    w_key(w, "body");
    w_id(w, &s->ids[a->slave_body]);
    w_key(w, "node");
    w_int(w, a->slave_node);
    w_close(w, '}');
    w_key(w, "master");
    w_id(w, &s->ids[a->master_body]);
    w_anchor_feature(w, a);
    w_close(w, '}');
}

void ntsj_encode_history(ntsj_buf* b, const ntsj_scene* s, const nts_anchor* anchors, int count) {
    writer w;
    int i;
    w_init(&w, b, 0);
    ntsj_buf_hint(b, (size_t)count * 96u + 16u);
    w_open(&w, '{', 0);
    w_key(&w, "history");
    w_open(&w, '[', 0);
    for (i = 0; i < count; ++i) w_history_entry(&w, s, &anchors[i]);
    w_close(&w, ']');
    w_close(&w, '}');
    w_finish(&w);
}

/* `m`: the contact's match to the session's previous step (keep_contacts),
 * or NULL; `a`: its anchor after the step with friction on, or NULL. */
static void w_contact(writer* w, const ntsj_scene* s, const nts_contact* c, int full, const nts_contact_match* m,
                      const nts_anchor* a) {
    int i;
    w_open(w, '{', 0);
    w_key(w, "slave");
    w_open(w, '{', 1);
    w_key(w, "body");
    w_id(w, &s->ids[c->slave_body]);
    w_key(w, "node");
    w_int(w, c->slave_node);
    w_close(w, '}');
    w_key(w, "master");
    w_open(w, '{', 1);
    w_key(w, "body");
    w_id(w, &s->ids[c->master_body]);
    if (full) {
        w_key(w, "kind");
        w_string(w, kind_name(c->kind));
        w_key(w, "nodes");
        w_open(w, '[', 1);
        for (i = 0; i < c->master_count && i < 3; ++i) w_int(w, c->master_nodes[i]);
        w_close(w, ']');
        w_key(w, "weights");
        w_open(w, '[', 1);
        for (i = 0; i < c->master_count && i < 3; ++i) w_double(w, c->weights[i]);
        w_close(w, ']');
        if (c->kind == NTS_KIND_CORNER) {
            w_key(w, "xi");
            w_double(w, c->param);
        } else if (c->kind == NTS_KIND_SEGMENT) {
            w_key(w, "s");
            w_double(w, c->param);
        }
    }
    w_close(w, '}');
    w_key(w, "gap");
    w_double(w, c->gap);
    if (full) {
        w_key(w, "normal");
        w_vec2(w, c->normal);
        w_key(w, "point");
        w_vec2(w, c->point);
        w_key(w, "force");
        w_vec2(w, c->force);
        w_key(w, "virial");
        w_virial(w, c->virial, a != NULL);
    }
    if (full && a != NULL) { /* friction (§14): the tangential part of `force`, the state, the slip, the anchor */
        w_key(w, "tangential_force");
        w_vec2(w, c->tangential_force);
        w_key(w, "state");
        w_string(w, state_name(c->state));
        w_key(w, "slip");
        w_double(w, c->slip);
        w_key(w, "anchor");
        w_open(w, '{', 1);
        w_anchor_feature(w, a);
        w_close(w, '}');
    }
    if (m != NULL) {
        /* the previous step's contact of the same pair (its index in that
         * step's contacts), and whether it is at the same feature */
        w_key(w, "previous");
        w_int(w, m->previous);
        w_key(w, "persisted");
        w_bool(w, m->persisted);
    }
    w_close(w, '}');
}

void ntsj_encode_result(ntsj_buf* b, const ntsj_scene* s, const nts_scene* scene, const nts_result* r,
                        double elapsed_ms, int pretty) {
    writer w;
    const nts_summary* sm = &r->summary;
    unsigned outputs = s->options.outputs;
    const int friction = nts_friction_on(scene, &s->options) && (r->anchor_count == 0 || r->anchors != NULL);
    int i, k;
    w_init(&w, b, pretty);
    /* Reserve roughly what the forces and the pressure will take up front:
     * fewer regrowths. */
    {
        const size_t per_node = ((outputs & NTS_OUT_FORCES) ? 48u : 0u) + ((outputs & NTS_OUT_PRESSURE) ? 24u : 0u);
        if (per_node > 0) ntsj_buf_hint(b, (size_t)nts_scene_node_count(scene) * per_node + 512u);
    }
    w_open(&w, '{', 0);
    w_key(&w, "version");
    w_int(&w, 1);
    w_key(&w, "summary");
    w_open(&w, '{', 0);
    w_key(&w, "bodies");
    w_int(&w, sm->bodies);
    w_key(&w, "nodes");
    w_int(&w, nts_scene_node_count(scene));
    w_key(&w, "surface_nodes");
    w_int(&w, sm->surface_nodes);
    w_key(&w, "contacts");
    w_int(&w, sm->contacts);
    w_key(&w, "gaps");
    w_int(&w, sm->gaps);
    w_key(&w, "deep_contacts");
    w_int(&w, sm->deep_contacts);
    w_key(&w, "energy");
    w_double(&w, sm->energy);
    w_key(&w, "virial");
    w_virial(&w, sm->virial, friction);
    if (friction) { /* §14, (27) */
        w_key(&w, "dissipation");
        w_double(&w, sm->dissipation);
        w_key(&w, "sticking");
        w_int(&w, sm->sticking);
        w_key(&w, "slipping");
        w_int(&w, sm->slipping);
    }
    w_key(&w, "max_penetration");
    w_double(&w, sm->max_penetration);
    w_key(&w, "loops_reversed");
    w_int(&w, sm->loops_reversed);
    w_key(&w, "search_radius");
    w_double(&w, sm->search_radius);
    w_key(&w, "cell_size");
    w_double(&w, sm->cell_size);
    w_key(&w, "elapsed_ms");
    w_double(&w, elapsed_ms);
    if (s->changes != NULL) { /* a session that keeps contacts: this step's against the last */
        w_key(&w, "contact_changes");
        w_open(&w, '{', 1);
        w_key(&w, "persisted");
        w_int(&w, s->changes->persisted);
        w_key(&w, "moved");
        w_int(&w, s->changes->moved);
        w_key(&w, "added");
        w_int(&w, s->changes->added);
        w_key(&w, "ended");
        w_int(&w, s->changes->ended);
        w_close(&w, '}');
    }
    w_close(&w, '}');
    /* What the result may lack, always there (empty: nothing). */
    w_key(&w, "warnings");
    w_open(&w, '[', 0);
    for (i = 0; i < r->warning_count; ++i) {
        w_open(&w, '{', 0);
        w_key(&w, "code");
        w_string(&w, nts_warning_name(r->warnings[i].code));
        w_key(&w, "count");
        w_int(&w, r->warnings[i].count);
        w_key(&w, "message");
        w_string(&w, nts_warning_message(r->warnings[i].code));
        w_close(&w, '}');
    }
    w_close(&w, ']');

    if (((outputs & NTS_OUT_FORCES) && r->forces) || ((outputs & NTS_OUT_PRESSURE) && r->pressure)) {
        /* Per body, per node: the forces and the pressure asked for. */
        const int forces = (outputs & NTS_OUT_FORCES) && r->forces;
        const int pressure = (outputs & NTS_OUT_PRESSURE) && r->pressure;
        w_key(&w, "bodies");
        w_open(&w, '[', 0);
        for (i = 0; i < s->body_count; ++i) {
            int off = nts_scene_body_node_offset(scene, i);
            int n = nts_scene_body_node_count(scene, i);
            w_open(&w, '{', 0);
            w_key(&w, "id");
            w_id(&w, &s->ids[i]);
            if (forces) {
                w_key(&w, "forces");
                w_open(&w, '[', 0);
                for (k = 0; k < n; ++k) w_vec2(&w, r->forces[off + k]);
                w_close(&w, ']');
            }
            if (pressure) {
                w_key(&w, "pressure");
                w_open(&w, '[', 1);
                for (k = 0; k < n; ++k) w_double(&w, r->pressure[off + k]);
                w_close(&w, ']');
            }
            w_close(&w, '}');
        }
        w_close(&w, ']');
    }
    if ((outputs & NTS_OUT_CONTACTS) && r->contacts) {
        w_key(&w, "contacts");
        w_open(&w, '[', 0);
        for (i = 0; i < r->contact_count; ++i)
            w_contact(&w, s, &r->contacts[i], 1, s->match != NULL ? &s->match[i] : NULL,
                      friction && i < r->anchor_count ? &r->anchors[i] : NULL);
        w_close(&w, ']');
    } else if (outputs & NTS_OUT_CONTACTS) {
        w_key(&w, "contacts");
        w_open(&w, '[', 0);
        w_close(&w, ']');
    }
    if ((outputs & NTS_OUT_GAPS)) {
        w_key(&w, "gaps");
        w_open(&w, '[', 0);
        for (i = 0; r->gaps && i < r->gap_count; ++i) w_contact(&w, s, &r->gaps[i], 0, NULL, NULL);
        w_close(&w, ']');
    }
    if (outputs & NTS_OUT_STIFFNESS) {
        /* The tangent as triplets over dof = 2 node + component (global node
         * order), duplicates to be summed (result.schema.json). */
        const nts_triplets* t = &r->stiffness;
        ntsj_buf_hint(b, (size_t)t->count * 40u + 64u);
        w_key(&w, "stiffness");
        w_open(&w, '{', 0);
        w_key(&w, "size");
        w_int(&w, 2LL * nts_scene_node_count(scene));
        w_key(&w, "rows");
        w_open(&w, '[', 1);
        for (i = 0; i < t->count; ++i) w_int(&w, t->rows[i]);
        w_close(&w, ']');
        w_key(&w, "cols");
        w_open(&w, '[', 1);
        for (i = 0; i < t->count; ++i) w_int(&w, t->cols[i]);
        w_close(&w, ']');
        w_key(&w, "values");
        w_open(&w, '[', 1);
        for (i = 0; i < t->count; ++i) w_double(&w, t->values[i]);
        w_close(&w, ']');
        w_close(&w, '}');
    }
    if (friction) {
        /* The anchors after this step, whatever the outputs: what a session
         * commits, and what the next stateless request may carry as its
         * "history" to go on from here (§14). */
        ntsj_buf_hint(b, (size_t)r->anchor_count * 96u + 16u);
        w_key(&w, "history");
        w_open(&w, '[', 0);
        for (i = 0; i < r->anchor_count; ++i) w_history_entry(&w, s, &r->anchors[i]);
        w_close(&w, ']');
    }
    w_close(&w, '}');
    w_finish(&w);
}

void ntsj_encode_validation(ntsj_buf* b, const nts_scene* scene, double elapsed_ms, int pretty) {
    writer w;
    w_init(&w, b, pretty);
    w_open(&w, '{', 0);
    w_key(&w, "version");
    w_int(&w, 1);
    w_key(&w, "valid");
    w_bool(&w, 1);
    w_key(&w, "summary");
    w_open(&w, '{', 0);
    w_key(&w, "bodies");
    w_int(&w, nts_scene_body_count(scene));
    w_key(&w, "nodes");
    w_int(&w, nts_scene_node_count(scene));
    w_key(&w, "surface_nodes");
    w_int(&w, nts_scene_surface_node_count(scene));
    w_key(&w, "loops_reversed");
    w_int(&w, nts_scene_loops_reversed(scene));
    w_key(&w, "elapsed_ms");
    w_double(&w, elapsed_ms);
    w_close(&w, '}');
    w_close(&w, '}');
    w_finish(&w);
}

void ntsj_encode_error(ntsj_buf* b, const char* code, const char* message, const char* pointer, int pretty) {
    writer w;
    w_init(&w, b, pretty);
    w_open(&w, '{', 0);
    w_key(&w, "error");
    w_open(&w, '{', 0);
    w_key(&w, "code");
    w_string(&w, code ? code : nts_status_name(NTS_EINTERNAL));
    w_key(&w, "message");
    w_string(&w, message ? message : "");
    w_key(&w, "pointer");
    w_string(&w, pointer ? pointer : "");
    w_close(&w, '}');
    w_close(&w, '}');
    w_finish(&w);
}
