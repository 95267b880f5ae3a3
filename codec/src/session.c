/* Sessions: one scene decoded once, evaluated at many positions.
 *
 * A step reads positions (JSON or raw little-endian float64), lets the core
 * check them against the scene (nts_scene_update_positions: every check of
 * nts_scene_create, and the same normalisation), and evaluates with the warm
 * context. When the core says the positions would give another scene (a loop
 * turned over, a body mirrored) or fail a check, the scene is created anew
 * from them exactly as ntsj_handle would, so the answer, error or result, is
 * the full call's, bit for bit (elapsed_ms aside), with the session's
 * reference configuration: the scene's "reference" where it gives one, else
 * the positions it was created with. A session's answer at given positions
 * thus never depends on the steps before (penalty per length measures the
 * tributary lengths there). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "codec_internal.h"

struct ntsj_session {
    ntsj_scene js;       /* decoded request: ids, options, topology; node arrays are scratch for rebuilds,
                            js.refs[b] the reference configuration of every body */
    nts_scene* scene;    /* the authority on the stored positions */
    nts_context* ctx;
    nts_vec2* next;      /* node_count: a step's positions before the core takes them */
    const nts_vec2* in;  /* the step's positions: next, or the binary request's own bytes when they can be
                            read in place (little-endian doubles, aligned); valid during the step only */
    int limits_set;
    nts_limits limits;
    unsigned long long steps;
    nts_contact_memory* memory; /* "session": {"keep_contacts": true}; else NULL */
    /* Friction (docs/model.md §14; NULL without): the committed anchors each
     * step is a trial from, and a committing step's anchors until the answer
     * is sent (defer_commit: ntsj_session_commit swaps them in). */
    nts_history* history;
    nts_history* staged;
    int staged_pending;
    /* The kept candidate list (docs/model.md §15): every step replays it
     * while it holds (the same answer, bit for bit); NULL with
     * "session": {"keep_candidates": false}. */
    nts_candidates* candidates;
    /* The nodes on loops, each once, ascending: the positions and forces of a
     * surface exchange (?nodes=surface), in that order. Fixed at creation (a
     * rebuild keeps the topology). */
    int* surface;
    int surface_count;
};

static size_t decoded_bytes(const ntsj_scene* s) {
    size_t n = (size_t)s->body_count * (sizeof(nts_body_def) + sizeof(ntsj_id) + sizeof(int) + 4 * sizeof(void*));
    int b;
    for (b = 0; b < s->body_count; ++b) {
        const nts_body_def* d = &s->defs[b];
        n += (size_t)d->node_count * sizeof(nts_vec2) * (s->refs && s->refs[b] ? 2u : 1u);
        if (d->triangle_count > 0) n += 3 * (size_t)d->triangle_count * sizeof(int);
        else if (d->loop_count > 0) n += ((size_t)d->loop_start[d->loop_count] + (size_t)d->loop_count + 1) * sizeof(int);
        if (!s->ids[b].is_int && s->ids[b].sval) n += strlen(s->ids[b].sval) + 1;
        if (d->surface != NULL) n += 2 * (size_t)d->surface_count * sizeof(int);
    }
    return n;
}

ntsj_session_info ntsj_session_get_info(const ntsj_session* ss) {
    ntsj_session_info i;
    memset(&i, 0, sizeof i);
    if (ss == NULL) return i;
    i.bodies = nts_scene_body_count(ss->scene);
    i.nodes = nts_scene_node_count(ss->scene);
    i.surface_nodes = nts_scene_surface_node_count(ss->scene);
    i.steps = ss->steps;
    i.memory_bytes = sizeof *ss + decoded_bytes(&ss->js) + nts_scene_memory_bytes(ss->scene) +
                     nts_context_memory_bytes(ss->ctx) + (size_t)i.nodes * sizeof(nts_vec2) +
                     nts_contact_memory_bytes(ss->memory) + nts_history_bytes(ss->history) +
                     nts_history_bytes(ss->staged) + nts_candidates_bytes(ss->candidates) +
                     (size_t)ss->surface_count * sizeof(int);
    return i;
}

void ntsj_session_trim(ntsj_session* ss) {
    if (ss != NULL) nts_context_trim(ss->ctx);
}

void ntsj_session_destroy(ntsj_session* ss) {
    if (ss == NULL) return;
    nts_context_destroy(ss->ctx);
    nts_contact_memory_destroy(ss->memory);
    nts_history_destroy(ss->history);
    nts_history_destroy(ss->staged);
    nts_candidates_destroy(ss->candidates);
    nts_scene_destroy(ss->scene);
    nts_free(ss->next);
    nts_free(ss->surface);
    ntsj_scene_free(&ss->js);
    nts_free(ss);
}

static nts_scene_def scene_def_of(const ntsj_scene* s, const nts_limits* limits) {
    nts_scene_def def = nts_default_scene_def();
    def.bodies = s->defs;
    def.body_count = s->body_count;
    def.lx = s->has_periodic ? s->lx : 0.0;
    def.ly = s->has_periodic ? s->ly : 0.0;
    def.limits = *limits;
    return def;
}

/* The evaluation options of ntsj_handle: the summary is always complete. */
/* An evaluation of the session's scene: nts_evaluate, or the front end's own
 * (ntsj_config.evaluate: ntscontact-mpi's), given the scene's definition at
 * the stored positions (each body's reference its first ones). */
static int session_evaluate(ntsj_session* ss, const ntsj_config* cfg, const nts_options* opt, nts_result* result,
                            nts_error* err) {
    nts_scene_def def;
    nts_body_def* bodies;
    const nts_vec2* pos;
    int b, rc;
    if (cfg->evaluate == NULL) return nts_evaluate(ss->ctx, ss->scene, opt, result, err);
    bodies = (nts_body_def*)nts_alloc(sizeof(nts_body_def) * (size_t)(ss->js.body_count + 1));
    if (bodies == NULL) {
        if (err != NULL) {
            *err = nts_error_none();
            err->code = NTS_ENOMEM;
            snprintf(err->message, sizeof err->message, "out of memory");
        }
        return NTS_ENOMEM;
    }
    pos = nts_scene_positions(ss->scene);
    for (b = 0; b < ss->js.body_count; ++b) {
        bodies[b] = ss->js.defs[b];
        bodies[b].nodes = pos + nts_scene_body_node_offset(ss->scene, b);
    }
    {
        const nts_limits limits = ss->limits_set ? ss->limits : nts_default_limits();
        def = scene_def_of(&ss->js, &limits);
    }
    def.bodies = bodies;
    rc = cfg->evaluate(cfg->evaluate_user, &def, ss->scene, opt, result, err);
    nts_free(bodies);
    return rc;
}

static nts_options eval_options(nts_options o, int answer_binary, int vtk) {
    o.outputs |= NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    if (answer_binary) o.outputs |= NTS_OUT_FORCES;
    if (vtk) o.outputs |= NTS_OUT_FORCES | NTS_OUT_CONTACTS;
    return o;
}

/* The nodes on the scene's loops, each once, in ascending global order
 * (ss->surface): a surface exchange carries their positions and forces,
 * the only ones contact reads and writes (a mesh's interior nodes get no
 * force). */
static int surface_list(ntsj_session* ss) {
    const nts_scene* s = ss->scene;
    const int n = nts_scene_node_count(s), nb = nts_scene_body_count(s);
    unsigned char* on = (unsigned char*)nts_alloc(n > 0 ? (size_t)n : 1u);
    int b, l, k, count = 0;
    if (on == NULL) return NTS_ENOMEM;
    memset(on, 0, n > 0 ? (size_t)n : 1u);
    for (b = 0; b < nb; ++b) {
        const int off = nts_scene_body_node_offset(s, b), loops = nts_scene_body_loop_count(s, b);
        for (l = 0; l < loops; ++l) {
            const int* idx = NULL;
            const int len = nts_scene_body_loop(s, b, l, &idx);
            for (k = 0; k < len; ++k) on[off + idx[k]] = 1;
        }
    }
    for (k = 0; k < n; ++k) count += on[k];
    ss->surface = (int*)nts_alloc(sizeof(int) * (size_t)(count > 0 ? count : 1));
    if (ss->surface == NULL) {
        nts_free(on);
        return NTS_ENOMEM;
    }
    for (k = 0, ss->surface_count = 0; k < n; ++k)
        if (on[k]) ss->surface[ss->surface_count++] = k;
    nts_free(on);
    return NTS_OK;
}

const int* ntsj_session_surface(const ntsj_session* ss, int* count) {
    if (count != NULL) *count = ss != NULL ? ss->surface_count : 0;
    return ss != NULL ? ss->surface : NULL;
}

int ntsj_session_create(const char* json, size_t length, const ntsj_config* config, ntsj_session** out,
                        ntsj_response* error) {
    ntsj_config cfg = config ? *config : ntsj_default_config();
    ntsj_session* ss;
    nts_scene_def def;
    nts_error err = nts_error_none();
    nts_result result;
    ntsj_fault fault;
    cJSON* root;
    int rc, b, keeps_history;

    *out = NULL;
    memset(error, 0, sizeof *error);
    memset(&fault, 0, sizeof fault);
    cfg.mode = NTSJ_EVALUATE;
    if (cfg.max_depth <= 0) cfg.max_depth = 32;
    if (cfg.max_bytes == 0) cfg.max_bytes = (size_t)64 << 20;
    /* The size, emptiness and grammar checks of ntsj_handle, with its answers:
     * run it in validation mode on what is not a valid scene. Cheap in both
     * cases compared with what follows. */
    if (json == NULL || length > cfg.max_bytes || ntsj_scan(json, length, cfg.max_depth, &fault) != 0) {
        cfg.mode = NTSJ_VALIDATE;
        rc = ntsj_handle(json, length, &cfg, error);
        if (rc == 0 && error->ok) { /* a valid document: the scan itself ran out of memory */
            ntsj_response_free(error);
            return ntsj_respond_fault(error, &fault, cfg.pretty);
        }
        return rc;
    }
    ss = (ntsj_session*)nts_alloc(sizeof *ss);
    if (ss == NULL) return ntsj_respond_error(error, nts_status_name(NTS_ENOMEM), "out of memory", "", cfg.pretty);
    memset(ss, 0, sizeof *ss);
    root = cJSON_ParseWithLengthOpts(json, length, NULL, 0);
    if (root == NULL) {
        nts_free(ss);
        return ntsj_respond_error(error, nts_status_name(NTS_ENOMEM), "out of memory while parsing the request", "", cfg.pretty);
    }
    rc = ntsj_decode(root, &cfg, &ss->js, &fault);
    cJSON_Delete(root);
    if (rc != 0) {
        nts_free(ss);
        return ntsj_respond_fault(error, &fault, cfg.pretty);
    }
    if (nts_options_validate(&ss->js.options, &err) != 0) {
        rc = ntsj_respond_core(error, &ss->js, &err, NTS_EINVALID_OPTION, cfg.pretty);
        ntsj_session_destroy(ss);
        return rc;
    }
    /* The reference configuration of every body, kept across rebuilds: the
     * scene's own "reference", or the positions the session starts from. */
    for (b = 0; b < ss->js.body_count; ++b) {
        nts_body_def* bd = &ss->js.defs[b];
        if (ss->js.refs[b] != NULL) continue;
        ss->js.refs[b] = (nts_vec2*)nts_alloc(sizeof(nts_vec2) * (size_t)bd->node_count);
        if (ss->js.refs[b] == NULL) {
            ntsj_session_destroy(ss);
            return ntsj_respond_error(error, nts_status_name(NTS_ENOMEM), "out of memory", "", cfg.pretty);
        }
        memcpy(ss->js.refs[b], bd->nodes, sizeof(nts_vec2) * (size_t)bd->node_count);
        bd->reference = ss->js.refs[b];
    }
    ss->limits = cfg.limits;
    def = scene_def_of(&ss->js, &ss->limits);
    ss->scene = nts_scene_create(&def, &err);
    if (ss->scene == NULL) {
        rc = ntsj_respond_core(error, &ss->js, &err, NTS_EINTERNAL, cfg.pretty);
        ntsj_session_destroy(ss);
        return rc;
    }
    ss->ctx = nts_context_create();
    ss->next = (nts_vec2*)nts_alloc(sizeof(nts_vec2) * (size_t)nts_scene_node_count(ss->scene));
    if (ss->js.keep_contacts) ss->memory = nts_contact_memory_create();
    if (ss->js.keep_candidates) ss->candidates = nts_candidates_create(ss->js.skin);
    keeps_history = nts_friction_on(ss->scene, &ss->js.options) || ss->js.has_history;
    if (keeps_history) {
        ss->history = nts_history_create();
        ss->staged = nts_history_create();
    }
    if (ss->ctx == NULL || ss->next == NULL || surface_list(ss) != NTS_OK ||
        (ss->js.keep_contacts && ss->memory == NULL) ||
        (ss->js.keep_candidates && ss->candidates == NULL) ||
        (keeps_history && (ss->history == NULL || ss->staged == NULL))) {
        ntsj_session_destroy(ss);
        return ntsj_respond_error(error, nts_status_name(NTS_ENOMEM), "out of memory", "", cfg.pretty);
    }
    /* A scene that carries a "history" starts from it (a client that had to
     * create its session anew gives the last committed anchors back). */
    if (ss->js.has_history && ntsj_set_history(ss->history, &ss->js, ss->scene, error, cfg.pretty, &rc)) {
        ntsj_session_destroy(ss);
        return rc;
    }
    /* "Valid" means "evaluates": faults that depend on the options and the
     * whole scene (a periodic box too small for the search reach) show now. */
    {
        nts_options opt = ss->js.options;
        opt.outputs = 0u;
        opt.history = ss->history;
        opt.candidates = ss->candidates;
        rc = session_evaluate(ss, &cfg, &opt, &result, &err);
        if (rc != 0) {
            rc = ntsj_respond_core(error, &ss->js, &err, rc, cfg.pretty);
            ntsj_session_destroy(ss);
            return rc;
        }
        if (ntsj_result_overflows(&ss->js, ss->scene, &result, &fault)) {
            rc = ntsj_respond_fault(error, &fault, cfg.pretty);
            ntsj_session_destroy(ss);
            return rc;
        }
    }
    *out = ss;
    error->ok = 1;
    error->http_status = 201;
    error->code = "ok";
    return 0;
}

/* --------------------------------------------------------------- positions */

static int host_is_little_endian(void) {
    const uint16_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 1;
}

/* Little-endian float64 at p. */
static double read_le_double(const unsigned char* p) {
    uint64_t u = 0;
    double d;
    int i;
    for (i = 7; i >= 0; --i) u = (u << 8) | (uint64_t)p[i];
    memcpy(&d, &u, sizeof d);
    return d;
}

/* Position k of the request (node `node`: k itself, unless `surface`, an
 * exchange of the surface nodes alone) is not finite: named at
 * /positions/k, its body's node in the message. */
static int position_fault(const ntsj_session* ss, int k, int node, int surface, const char* what, ntsj_fault* f) {
    int b, nb = nts_scene_body_count(ss->scene);
    for (b = nb - 1; b > 0 && nts_scene_body_node_offset(ss->scene, b) > node; --b) continue;
    if (!surface)
        ntsj_fault_set(f, nts_status_name(NTS_ENONFINITE), "", "position %d (/bodies/%d/nodes/%d) has a non-finite %s", k,
                       b, node - nts_scene_body_node_offset(ss->scene, b), what);
    else
        ntsj_fault_set(f, nts_status_name(NTS_ENONFINITE), "",
                       "surface position %d (node %d, /bodies/%d/nodes/%d) has a non-finite %s", k, node, b,
                       node - nts_scene_body_node_offset(ss->scene, b), what);
    snprintf(f->pointer, sizeof f->pointer, "/positions/%d", k);
    return -1;
}

/* A binary step's positions: every node's (16 N bytes), or in a surface
 * exchange the surface nodes' (16 S bytes, ss->surface's order) put in
 * their places of ss->next, whose other entries the evaluation does not
 * read (nts_evaluate_surface_positions; complete_surface before any other
 * use). */
static int read_binary(ntsj_session* ss, const char* body, size_t length, int surface, ntsj_fault* f) {
    int n = nts_scene_node_count(ss->scene), k;
    const int m = surface ? ss->surface_count : n;
    size_t expected = (size_t)m * 16u;
    if (length != expected) {
        if (surface)
            ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "",
                           "expected 16*S = 16 * %d = %lu bytes (little-endian float64, x then y for every surface node, "
                           "in the order of GET /v1/scenes/{id}/surface), got %lu",
                           m, (unsigned long)expected, (unsigned long)length);
        else
            ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "",
                           "expected 16*N = 16 * %d = %lu bytes (little-endian float64, x then y for every node), got %lu",
                           n, (unsigned long)expected, (unsigned long)length);
        return -1;
    }
    if (surface) {
        const unsigned char* p = (const unsigned char*)body;
        const int le = host_is_little_endian() && sizeof(nts_vec2) == 16;
        for (k = 0; k < m; ++k) {
            if (le) memcpy(&ss->next[ss->surface[k]], p + 16 * (size_t)k, 16);
            else ss->next[ss->surface[k]] = nts_v2(read_le_double(p + 16 * (size_t)k), read_le_double(p + 16 * (size_t)k + 8));
        }
    } else if (host_is_little_endian() && sizeof(nts_vec2) == 16 && (uintptr_t)(const void*)body % sizeof(double) == 0) {
        /* read in place: a copy of 16 N bytes less a step (the core copies
         * them into the scene once they pass its checks) */
        ss->in = (const nts_vec2*)(const void*)body;
    } else if (host_is_little_endian() && sizeof(nts_vec2) == 16) {
        memcpy(ss->next, body, expected);
    } else {
        const unsigned char* p = (const unsigned char*)body;
        for (k = 0; k < n; ++k) ss->next[k] = nts_v2(read_le_double(p + 16 * (size_t)k), read_le_double(p + 16 * (size_t)k + 8));
    }
    return 0;
}

/* A surface exchange's positions made every node's, for the paths that
 * read them all (the update's check, a rebuild): the stored positions of
 * the nodes off the loops. */
static void complete_surface(ntsj_session* ss) {
    const nts_vec2* stored = nts_scene_positions(ss->scene);
    const int n = nts_scene_node_count(ss->scene);
    int k, j = 0;
    for (k = 0; k < n; ++k) {
        if (j < ss->surface_count && ss->surface[j] == k) {
            ++j;
            continue;
        }
        ss->next[k] = stored[k];
    }
}

/* A binary step's first non-finite coordinate, named as its place in the
 * request (/positions/k). Asked only when the positions are to be taken
 * apart, or when the evaluation refused them: the core checks every
 * coordinate itself (nts_evaluate_positions), and a pass over 16 N bytes
 * before it cost a tenth of a step of a 66k-node mesh. */
static int binary_fault(ntsj_session* ss, int surface, ntsj_fault* f) {
    const int m = surface ? ss->surface_count : nts_scene_node_count(ss->scene);
    int k;
    for (k = 0; k < m; ++k) {
        const int node = surface ? ss->surface[k] : k;
        if (!isfinite(ss->in[node].x)) return position_fault(ss, k, node, surface, "x", f);
        if (!isfinite(ss->in[node].y)) return position_fault(ss, k, node, surface, "y", f);
    }
    return 0;
}

static int read_json_positions(ntsj_session* ss, const cJSON* v, ntsj_fault* f) {
    int n = nts_scene_node_count(ss->scene), k = 0, m = 0;
    const cJSON* e;
    if (!cJSON_IsArray(v)) {
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_TYPE), "/positions", "expected an array of [x, y] pairs");
        return -1;
    }
    cJSON_ArrayForEach(e, v) { if (m < 2147483647) ++m; }
    if (m != n) {
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "/positions",
                       "expected %d positions (every node, bodies in scene order, nodes in body order), got %d", n, m);
        return -1;
    }
    cJSON_ArrayForEach(e, v) {
        const cJSON* x = cJSON_IsArray(e) ? e->child : NULL;
        const cJSON* y = x ? x->next : NULL;
        if (!x || !y || y->next || !cJSON_IsNumber(x) || !cJSON_IsNumber(y)) {
            ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_TYPE), "", "expected a pair of numbers [x, y]");
            snprintf(f->pointer, sizeof f->pointer, "/positions/%d", k);
            return -1;
        }
        ss->next[k] = nts_v2(x->valuedouble, y->valuedouble);
        if (!isfinite(ss->next[k].x) || !isfinite(ss->next[k].y))
            return position_fault(ss, k, k, 0, isfinite(ss->next[k].x) ? "y" : "x", f);
        ++k;
    }
    return 0;
}

/* The JSON step a solver sends most: {"positions": [[x, y], ...]} and maybe
 * "commit", read in one pass without a tree (cJSON makes three nodes a
 * position). Only a document that is well formed (RFC 8259), holds nothing
 * else, each key once, exactly the scene's node count of pairs of finite
 * numbers, is taken (1); anything else (0) goes the general way, which
 * answers the same positions, or the error naming its place. The numbers
 * are converted to strtod's bits, as cJSON converts them (numparse.c). */
typedef struct fast_reader {
    const char *p, *end;
} fast_reader;

static void fast_ws(fast_reader* r) {
    while (r->p < r->end && (*r->p == ' ' || *r->p == '\t' || *r->p == '\n' || *r->p == '\r')) ++r->p;
}

static int fast_char(fast_reader* r, char c) {
    fast_ws(r);
    if (r->p < r->end && *r->p == c) {
        ++r->p;
        return 1;
    }
    return 0;
}

/* A JSON number (RFC 8259's grammar: not strtod's, which would take more:
 * hex, inf, a leading '+' or '.'), read by ntsj_parse_number. */
static int fast_number(fast_reader* r, double* out) {
    size_t n;
    fast_ws(r);
    if ((n = ntsj_parse_number(r->p, r->end, out)) == 0) return 0;
    r->p += n;
    return isfinite(*out) != 0;
}

static int fast_key(fast_reader* r, const char* key) {
    const size_t n = strlen(key);
    fast_ws(r);
    if ((size_t)(r->end - r->p) < n + 2 || r->p[0] != '"' || memcmp(r->p + 1, key, n) != 0 || r->p[n + 1] != '"')
        return 0;
    r->p += n + 2;
    return fast_char(r, ':');
}

static int fast_positions_step(ntsj_session* ss, const char* body, size_t length, int* commit) {
    const int n = nts_scene_node_count(ss->scene);
    fast_reader r;
    int seen_positions = 0, seen_commit = 0, k, c = *commit;
    r.p = body;
    r.end = body + length;
    if (!fast_char(&r, '{')) return 0;
    do {
        if (!seen_commit && fast_key(&r, "commit")) {
            seen_commit = 1;
            fast_ws(&r);
            if ((size_t)(r.end - r.p) >= 4 && memcmp(r.p, "true", 4) == 0) {
                c = 1;
                r.p += 4;
            } else if ((size_t)(r.end - r.p) >= 5 && memcmp(r.p, "false", 5) == 0) {
                c = 0;
                r.p += 5;
            } else {
                return 0;
            }
        } else if (!seen_positions && fast_key(&r, "positions")) {
            seen_positions = 1;
            if (!fast_char(&r, '[')) return 0;
            for (k = 0; k < n; ++k) {
                if ((k > 0 && !fast_char(&r, ',')) || !fast_char(&r, '[') || !fast_number(&r, &ss->next[k].x) ||
                    !fast_char(&r, ',') || !fast_number(&r, &ss->next[k].y) || !fast_char(&r, ']'))
                    return 0;
            }
            if (!fast_char(&r, ']')) return 0;
        } else {
            return 0;
        }
    } while (fast_char(&r, ','));
    if (!fast_char(&r, '}') || !seen_positions) return 0;
    fast_ws(&r);
    if (r.p != r.end) return 0;
    *commit = c;
    return 1;
}

/* ----------------------------------------------------------------- options */

/* A step overrides the options of the table's STEP door (NTS_OPTION_MAP):
 * the row of `name`, or -1 with *f set to unknown_field naming them. */
static int step_option(const char* name, const char* ptr, const char* what, ntsj_fault* f) {
    int id = nts_option_find(name, strlen(name));
    char names[160];
    if (id >= 0 && (nts_option_info_of(id)->doors & NTS_OPTION_DOOR_STEP)) return id;
    ntsj_option_door_names(NTS_OPTION_DOOR_STEP, names, sizeof names);
    ntsj_fault_set(f, ntsj_code_name(NTSJ_UNKNOWN_FIELD), ptr, "unknown %s \"%.64s\" (a step overrides %s%s)", what, name,
                   names, strcmp(what, "query parameter") == 0 ? "; and takes commit" : "");
    return -1;
}

static int json_options(const cJSON* v, nts_options* o, ntsj_fault* f) {
    const cJSON* m;
    unsigned seen = 0;
    if (!cJSON_IsObject(v)) {
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_TYPE), "/options", "expected an object of option overrides");
        return -1;
    }
    cJSON_ArrayForEach(m, v) {
        const char* key = m->string ? m->string : "";
        char ptr[96];
        nts_option_value val;
        int i;
        snprintf(ptr, sizeof ptr, "/options/%.64s", key);
        if ((i = step_option(key, ptr, "option", f)) < 0) return -1;
        if (seen & (1u << i)) {
            ntsj_fault_set(f, ntsj_code_name(NTSJ_DUPLICATE_KEY), ptr, "key \"%.64s\" appears more than once", key);
            return -1;
        }
        seen |= 1u << i;
        memset(&val, 0, sizeof val);
        if (ntsj_option_json(i, m, ptr, &val, f) != 0) return -1;
        nts_option_store(o, i, &val);
    }
    return 0;
}

/* Query parameter "nodes" (read before the body, whose length it decides):
 * "all" (the default: every node's position and force) or "surface" (the
 * surface nodes' alone, ss->surface's order: a binary body, or none, and a
 * binary answer). */
static int query_nodes(const ntsj_step* st, int* surface, ntsj_fault* f) {
    int k, seen = 0;
    *surface = 0;
    for (k = 0; k < st->param_count; ++k) {
        const char* name = st->param_names[k] ? st->param_names[k] : "";
        const char* val = st->param_values[k] ? st->param_values[k] : "";
        if (strcmp(name, "nodes") != 0) continue;
        if (seen++ || (strcmp(val, "all") != 0 && strcmp(val, "surface") != 0)) {
            ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "/nodes",
                           seen > 1 ? "query parameter nodes given twice" : "nodes=%.32s: expected all or surface", val);
            return -1;
        }
        *surface = strcmp(val, "surface") == 0;
    }
    if (*surface && (st->kind == NTSJ_STEP_JSON || !st->answer_binary)) {
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "/nodes",
                       "nodes=surface exchanges raw float64 positions and forces: send application/octet-stream (or "
                       "no body) and accept application/octet-stream");
        return -1;
    }
    return 0;
}

/* Query parameters (binary steps): the same names, values as text; and
 * "commit" (true or false: whether a step's friction anchors become the
 * session's history, §14), which is not an option; "nodes" (query_nodes). */
static int query_options(const ntsj_step* st, nts_options* o, int* commit, ntsj_fault* f) {
    int k, seen_commit = 0;
    unsigned seen = 0; /* a parameter twice is refused, as nodes and commit twice are (the last one won) */
    for (k = 0; k < st->param_count; ++k) {
        const char* name = st->param_names[k] ? st->param_names[k] : "";
        const char* val = st->param_values[k] ? st->param_values[k] : "";
        char ptr[96];
        nts_option_value v;
        int i;
        if (strcmp(name, "nodes") == 0) continue; /* query_nodes */
        if (strcmp(name, "commit") == 0) {
            if (seen_commit++ || (strcmp(val, "true") != 0 && strcmp(val, "false") != 0)) {
                ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), "/commit",
                               seen_commit > 1 ? "query parameter commit given twice" : "commit=%.32s: expected true or false", val);
                return -1;
            }
            *commit = strcmp(val, "true") == 0;
            continue;
        }
        snprintf(ptr, sizeof ptr, "/options/%.64s", name);
        if ((i = step_option(name, ptr, "query parameter", f)) < 0) return -1;
        if (seen & (1u << i)) {
            ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "query parameter %.64s given twice", name);
            return -1;
        }
        seen |= 1u << i;
        memset(&v, 0, sizeof v);
        if (ntsj_option_text(i, val, ptr, &v, f) != 0) return -1;
        nts_option_store(o, i, &v);
    }
    return 0;
}

/* ------------------------------------------------------------------- steps */

/* The positions in ss->in would make another scene, or fail a check: build
 * it as ntsj_handle would. On success the new scene replaces the old one. */
static int rebuild(ntsj_session* ss, nts_error* err) {
    nts_scene_def def;
    nts_scene* fresh;
    int b;
    for (b = 0; b < ss->js.body_count; ++b) {
        int off = nts_scene_body_node_offset(ss->scene, b);
        memcpy(ss->js.nodes[b], ss->in + off, sizeof(nts_vec2) * (size_t)ss->js.defs[b].node_count);
    }
    def = scene_def_of(&ss->js, &ss->limits);
    fresh = nts_scene_create(&def, err);
    if (fresh == NULL) return err->code ? err->code : NTS_EINTERNAL;
    nts_scene_destroy(ss->scene);
    ss->scene = fresh;
    return NTS_OK;
}

/* The positions read (ss->in) taken by the scene, or, when they change
 * its normalisation (or fail a check), a scene made anew from them (whose
 * creation names any fault). */
static int take_positions(ntsj_session* ss, nts_error* err) {
    if (nts_scene_update_positions(ss->scene, ss->in, err) == NTS_OK) return NTS_OK;
    return rebuild(ss, err);
}

static void put_le32(char* p, int v) {
    unsigned u = (unsigned)v;
    int i;
    for (i = 0; i < 4; ++i) p[i] = (char)(unsigned char)(u >> (8 * i));
}

static void put_le64(char* p, double d) {
    uint64_t u;
    int i;
    memcpy(&u, &d, sizeof u);
    for (i = 0; i < 8; ++i) p[i] = (char)(unsigned char)(u >> (8 * i));
}

/* The forces (16 N bytes), then with the tangent its triplets: count int32
 * rows, count int32 cols, count float64 values; then with the pressure its N
 * float64 (docs/model.md (21)); all little-endian (docs/sessions.md). In a
 * surface exchange the forces and the pressure are the surface nodes' (S in
 * ss->surface's order), the triplets' indices still global. */
static void encode_binary(ntsj_buf* b, const ntsj_session* ss, const nts_result* r, int surface) {
    const int n = surface ? ss->surface_count : nts_scene_node_count(ss->scene);
    int k;
    size_t bytes = (size_t)n * 16u, tb = (size_t)r->stiffness.count * 16u;
    size_t pb = r->pressure != NULL ? (size_t)n * 8u : 0u; /* the pressure, when asked: after the tangent */
    if (ntsj_buf_reserve(b, bytes + tb + pb + 1) != 0) return;
    if (surface && host_is_little_endian() && sizeof(nts_vec2) == 16) {
        for (k = 0; k < n; ++k) memcpy(b->data + 16 * (size_t)k, &r->forces[ss->surface[k]], 16);
    } else if (surface) {
        for (k = 0; k < n; ++k) {
            put_le64(b->data + 16 * (size_t)k, r->forces[ss->surface[k]].x);
            put_le64(b->data + 16 * (size_t)k + 8, r->forces[ss->surface[k]].y);
        }
    } else if (host_is_little_endian() && sizeof(nts_vec2) == 16) {
        memcpy(b->data, r->forces, bytes);
    } else {
        for (k = 0; k < 2 * n; ++k) put_le64(b->data + 8 * (size_t)k, k % 2 ? r->forces[k / 2].y : r->forces[k / 2].x);
    }
    for (k = 0; k < r->stiffness.count; ++k) {
        put_le32(b->data + bytes + 4 * (size_t)k, r->stiffness.rows[k]);
        put_le32(b->data + bytes + 4 * ((size_t)r->stiffness.count + (size_t)k), r->stiffness.cols[k]);
        put_le64(b->data + bytes + 8 * (size_t)r->stiffness.count + 8 * (size_t)k, r->stiffness.values[k]);
    }
    for (k = 0; pb > 0 && k < n; ++k)
        put_le64(b->data + bytes + tb + 8 * (size_t)k, r->pressure[surface ? ss->surface[k] : k]);
    b->len = bytes + tb + pb;
    b->data[b->len] = '\0';
}

static int cap_candidates(const ntsj_session* ss, const ntsj_config* cfg, nts_options* eo) {
    long long budget, fits;
    if (cfg->step_memory == 0 || !(eo->outputs & (unsigned)NTS_OUT_RECORDS_)) return 0;
    budget = eo->max_candidates > 0 ? eo->max_candidates
                                    : 64LL * nts_scene_surface_node_count(ss->scene) + 1000000; /* the core's default */
    fits = (long long)(cfg->step_memory / NTSJ_STEP_BYTES_PER_CANDIDATE);
    if (fits >= budget) return 0;
    eo->max_candidates = fits > 0 ? fits : 1; /* 0 would be the default */
    return 1;
}

/* A step over config->step_memory: limit_exceeded, naming the bound. */
static int step_too_large(ntsj_response* out, const ntsj_config* cfg, const char* what, int pretty) {
    char msg[400], records[96];
    size_t n = 0;
    unsigned bit;
    for (bit = 1; bit & (unsigned)NTS_OUT_ALL; bit <<= 1) { /* the outputs that keep records */
        int w;
        if (!(bit & (unsigned)NTS_OUT_RECORDS_)) continue;
        w = snprintf(records + n, sizeof records - n, "%s%s", n ? ", " : "", ntsj_output_name(bit));
        if (w < 0 || (size_t)w >= sizeof records - n) break;
        n += (size_t)w;
    }
    snprintf(msg, sizeof msg,
             "this step's %s would need more than the %zu bytes its session may still take (%s); ask fewer "
             "outputs (%s) or a smaller search_radius",
             what, cfg->step_memory, cfg->step_memory_name ? cfg->step_memory_name : "step_memory", records);
    return ntsj_respond_error(out, nts_status_name(NTS_ELIMIT), msg, "", pretty);
}

/* The staged anchors of the last answered step with commit become the
 * history (a swap: nothing allocates). */
static void commit_history(ntsj_session* ss) {
    nts_history* h;
    if (ss == NULL || !ss->staged_pending) return;
    h = ss->history;
    ss->history = ss->staged;
    ss->staged = h;
    ss->staged_pending = 0;
}

/* The step itself (ntsj_session_step gives back what a failed one grew). */
static int session_step(ntsj_session* ss, const ntsj_step* st, const ntsj_config* config, ntsj_response* out) {
    ntsj_config cfg = config ? *config : ntsj_default_config();
    double t0 = ntsj_now_ms();
    nts_options opt;
    nts_error err = nts_error_none();
    nts_result result;
    ntsj_fault fault;
    ntsj_buf b;
    const nts_contact_match* match = NULL;
    nts_contact_changes changes;
    int rc, pretty = cfg.pretty, have_positions = 0, binary = 0, fused, capped, commit = 1, surface = 0;
    size_t held, grown = 0;

    memset(out, 0, sizeof *out);
    memset(&fault, 0, sizeof fault);
    if (ss == NULL || st == NULL) return ntsj_respond_error(out, nts_status_name(NTS_EINTERNAL), "no session", "", pretty);
    ss->staged_pending = 0; /* an answer refused after the last step (the daemon's budget): not committed */
    if (cfg.max_depth <= 0) cfg.max_depth = 32;
    held = nts_context_memory_bytes(ss->ctx) + nts_candidates_bytes(ss->candidates);
    opt = ss->js.options;
    ss->in = ss->next; /* (read_binary may point it at the request's bytes) */

    if (query_nodes(st, &surface, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
    if (st->kind == NTSJ_STEP_BINARY && st->length > 0) {
        if (read_binary(ss, st->body, st->length, surface, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
        have_positions = binary = 1;
    } else if (st->kind == NTSJ_STEP_JSON && st->length > 0 && cfg.max_depth >= 3 &&
               fast_positions_step(ss, st->body, st->length, &commit)) {
        have_positions = 1;
    } else if (st->kind == NTSJ_STEP_JSON && st->length > 0) {
        static const char* const fields[] = {"positions", "options", "commit"};
        const cJSON* m;
        cJSON* root;
        unsigned seen = 0;
        if (ntsj_scan(st->body, st->length, cfg.max_depth, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
        root = cJSON_ParseWithLengthOpts(st->body, st->length, NULL, 0);
        if (root == NULL)
            return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory while parsing the request", "", pretty);
        if (!cJSON_IsObject(root)) {
            cJSON_Delete(root);
            return ntsj_respond_error(out, ntsj_code_name(NTSJ_INVALID_TYPE), "expected an object {\"positions\", \"options\"}", "",
                                      pretty);
        }
        rc = 0;
        cJSON_ArrayForEach(m, root) {
            const char* key = m->string ? m->string : "";
            int i = strcmp(key, fields[0]) == 0 ? 0 : strcmp(key, fields[1]) == 0 ? 1 : strcmp(key, fields[2]) == 0 ? 2 : -1;
            if (i < 0 || (seen & (1u << i))) {
                ntsj_fault_set(&fault, i < 0 ? ntsj_code_name(NTSJ_UNKNOWN_FIELD) : ntsj_code_name(NTSJ_DUPLICATE_KEY), "",
                               i < 0 ? "unknown field \"%.64s\" (a step has \"positions\", \"options\" and \"commit\")"
                                     : "key \"%.64s\" appears more than once", key);
                snprintf(fault.pointer, sizeof fault.pointer, "/%.64s", key);
                rc = -1;
                break;
            }
            seen |= 1u << i;
            if (i == 2) { /* friction (§14): whether this step's anchors become the history */
                if (!cJSON_IsBool(m)) {
                    ntsj_fault_set(&fault, ntsj_code_name(NTSJ_INVALID_TYPE), "/commit", "expected true or false, got %s",
                                   ntsj_json_type_name(m));
                    rc = -1;
                    break;
                }
                commit = cJSON_IsTrue(m);
                continue;
            }
            rc = i == 0 ? read_json_positions(ss, m, &fault) : json_options(m, &opt, &fault);
            if (rc != 0) break;
            if (i == 0) have_positions = 1;
        }
        cJSON_Delete(root);
        if (rc != 0) return ntsj_respond_fault(out, &fault, pretty);
    }
    if (query_options(st, &opt, &commit, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
    if (nts_options_validate(&opt, &err) != 0)
        return ntsj_respond_core(out, &ss->js, &err, NTS_EINVALID_OPTION, pretty);

    /* In-process evaluation checks the positions in its own segment pass
     * (nts_evaluate_positions); a host's evaluator is given them taken. */
    fused = have_positions && cfg.evaluate == NULL;
    /* A step refused here for its time has its positions taken all the same
     * (or their fault answered first), as when they were taken apart. */
    if (fused && ntsj_past_budget(&cfg, t0)) fused = 0;
    if (have_positions && !fused && binary && binary_fault(ss, surface, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
    if (have_positions && !fused && surface) complete_surface(ss);
    if (have_positions && !fused && (rc = take_positions(ss, &err)) != NTS_OK) {
        if (rc == NTS_ENOMEM) return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty);
        return ntsj_respond_core(out, &ss->js, &err, rc, pretty);
    }
    if (ntsj_over_budget(&cfg, t0, out, "reading the positions", &rc)) return rc;

    {
        nts_options eo = eval_options(opt, st->answer_binary, cfg.vtk);
        ntsj_deadline deadline;
        ntsj_arm_deadline(&eo, &deadline, &cfg, t0);
        if (ss->memory != NULL) eo.outputs |= NTS_OUT_CONTACTS; /* what the memory keeps */
        eo.history = ss->history; /* each step a trial from the committed anchors (§14) */
        eo.candidates = ss->candidates; /* replayed while it holds (§15) */
        capped = cap_candidates(ss, &cfg, &eo);
        /* (a surface exchange: the loops' nodes alone read and taken) */
        rc = fused && surface ? nts_evaluate_surface_positions(ss->ctx, ss->scene, ss->in, &eo, &result, &err)
             : fused          ? nts_evaluate_positions(ss->ctx, ss->scene, ss->in, &eo, &result, &err)
                              : session_evaluate(ss, &cfg, &eo, &result, &err);
        if (rc != NTS_OK && fused && surface && have_positions) complete_surface(ss);
        if (rc != NTS_OK && fused && nts_scene_update_positions(ss->scene, ss->in, NULL) != NTS_OK) {
            /* the positions refused (the update refuses exactly those):
             * a non-finite one named where the request has it, else a
             * scene made anew from them, or the reason it cannot be */
            if (binary && binary_fault(ss, surface, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);
            if ((rc = rebuild(ss, &err)) != NTS_OK) {
                if (rc == NTS_ENOMEM)
                    return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty);
                return ntsj_respond_core(out, &ss->js, &err, rc, pretty);
            }
            rc = session_evaluate(ss, &cfg, &eo, &result, &err); /* the same topology: the same cap */
        }
    }
    if (rc == NTS_ECANCELLED && ntsj_over_budget(&cfg, t0, out, "evaluating", &rc)) return rc;
    if (rc == NTS_ELIMIT && capped && strcmp(err.option, "max_candidates") == 0)
        return step_too_large(out, &cfg, "records", pretty);
    if (rc != 0) return ntsj_respond_core(out, &ss->js, &err, rc, pretty);
    if (ntsj_over_budget(&cfg, t0, out, "evaluating", &rc)) return rc;
    if (ntsj_result_overflows(&ss->js, ss->scene, &result, &fault)) return ntsj_respond_fault(out, &fault, pretty);
    if (nts_context_memory_bytes(ss->ctx) + nts_candidates_bytes(ss->candidates) > held)
        grown = nts_context_memory_bytes(ss->ctx) + nts_candidates_bytes(ss->candidates) - held;
    if (cfg.step_memory > 0 && grown >= cfg.step_memory) return step_too_large(out, &cfg, "records", pretty);

    /* This step's contacts matched to the last answered step's; they become
     * the kept ones only once this step is answered (below). */
    if (ss->memory != NULL) {
        if (nts_contact_memory_match(ss->memory, &result, &match, &changes) != NTS_OK)
            return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty);
        ss->js.match = match;
        ss->js.changes = &changes;
    }
    ntsj_buf_init(&b);
    if (cfg.step_memory > 0) b.max = cfg.step_memory - grown; /* the answer: what is left */
    if (st->answer_binary) {
        encode_binary(&b, ss, &result, surface);
    } else {
        /* The encoder writes what the scene's options ask for: this step's. */
        nts_options keep = ss->js.options;
        ss->js.options = opt;
        ntsj_encode_result(&b, &ss->js, ss->scene, &result, ntsj_round_us(ntsj_now_ms() - t0), pretty);
        ss->js.options = keep;
    }
    if (cfg.vtk && ntsj_attach_vtk(out, &ss->js, ss->scene, &result) != 0) b.oom = 1;
    ss->js.match = NULL;
    ss->js.changes = NULL;
    if (b.over) {
        ntsj_buf_free(&b);
        nts_free(out->vtk);
        out->vtk = NULL;
        out->vtk_length = 0;
        return step_too_large(out, &cfg, "answer", pretty);
    }
    /* A committing step's anchors, staged (the history itself stays what
     * this step was a trial from until the answer is sent). */
    ss->staged_pending = 0;
    if (ss->history != NULL && commit && b.data != NULL && !b.oom) {
        if (nts_history_commit(ss->staged, &result) != NTS_OK) b.oom = 1;
        else ss->staged_pending = 1;
    }
    rc = ntsj_finish(out, &b, "ok");
    if (rc == 0) {
        if (ss->memory != NULL && !st->defer_commit) (void)nts_contact_memory_commit(ss->memory);
        if (!st->defer_commit) commit_history(ss);
        if (cfg.history_out && ss->history != NULL) { /* the committed anchors after this step */
            ntsj_buf h;
            int count = 0;
            const nts_anchor* a = nts_history_anchors(ss->history, &count);
            ntsj_buf_init(&h);
            ntsj_encode_history(&h, &ss->js, a, count);
            out->history = h.data;
            out->history_length = h.len;
            if (h.oom || !h.data) {
                ntsj_response_free(out);
                return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty);
            }
        }
        ss->steps++;
        out->binary = st->answer_binary;
        out->triplets = st->answer_binary ? result.stiffness.count : 0;
        ntsj_keep_summary(out, &result, ss->history != NULL && nts_friction_on(ss->scene, &opt));
        out->elapsed_ms = ntsj_round_us(ntsj_now_ms() - t0);
    }
    return rc;
}

void ntsj_session_commit(ntsj_session* ss) {
    /* nothing pending (a failed step, no memory): NTS_EINVALID_ARGUMENT, ignored */
    if (ss != NULL && ss->memory != NULL) (void)nts_contact_memory_commit(ss->memory);
    commit_history(ss);
}

/* What a step grew in the context is kept for the next steps, which need the
 * same buffers, unless the step failed: a refused step (over
 * config->step_memory, over its candidate budget) may have grown the context
 * up to its bound first, and nothing after it needs that (issue 23). */
int ntsj_session_step(ntsj_session* ss, const ntsj_step* st, const ntsj_config* config, ntsj_response* out) {
    size_t before = ss != NULL ? nts_context_memory_bytes(ss->ctx) : 0;
    int rc = session_step(ss, st, config, out);
    if (ss != NULL && !out->ok && nts_context_memory_bytes(ss->ctx) > before) nts_context_trim(ss->ctx);
    return rc;
}
