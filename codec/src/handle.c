/* ntsj_handle: one request in, one response out.
 *   size check -> strict scan (scan.c) -> cJSON parse -> decode (decode.c)
 *   -> nts_scene_create -> nts_evaluate -> encode (encode.c)
 * Every fault on the way becomes an error document with a stable code, the
 * JSON pointer of the value at fault and the HTTP status of that code. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include <assert.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include <cjson/cJSON.h>

#include "codec_internal.h"

#define NTSJ_DEFAULT_MAX_BYTES ((size_t)64 << 20)
#define NTSJ_DEFAULT_MAX_DEPTH 32

ntsj_config ntsj_default_config(void) {
    ntsj_config c;
    memset(&c, 0, sizeof c);
    c.mode = NTSJ_EVALUATE;
    c.pretty = 0;
    c.limits = nts_default_limits();
    c.max_depth = NTSJ_DEFAULT_MAX_DEPTH;
    c.max_bytes = NTSJ_DEFAULT_MAX_BYTES;
    c.max_seconds = 0.0;
    c.threads = 0;
    return c;
}

double ntsj_now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* Elapsed wall time rounded to whole microseconds: the digits beyond are noise. */
double ntsj_round_us(double ms) { return floor(ms * 1e3 + 0.5) / 1e3; }

void ntsj_keep_summary(ntsj_response* out, const nts_result* r, int friction) {
    int k;
    out->summary = r->summary;
    out->friction = friction;
    out->warning_count = r->warning_count < NTS_WARN_COUNT_ ? r->warning_count : NTS_WARN_COUNT_;
    for (k = 0; k < out->warning_count; ++k) out->warnings[k] = r->warnings[k];
}

int ntsj_finish(ntsj_response* out, ntsj_buf* b, const char* code) {
    if (b->oom || !b->data) {
        ntsj_buf_free(b);
        out->ok = 0;
        out->code = nts_status_name(NTS_ENOMEM);
        out->http_status = ntsj_code_http_status(out->code);
        out->body = NULL;
        out->length = 0;
        nts_free(out->vtk); /* attached before the body failed */
        out->vtk = NULL;
        out->vtk_length = 0;
        return NTS_ENOMEM;
    }
    out->ok = strcmp(code, "ok") == 0;
    out->http_status = ntsj_code_http_status(code);
    out->code = code;
    out->body = b->data;
    out->length = b->len;
    return 0;
}

int ntsj_respond_error(ntsj_response* out, const char* code, const char* message, const char* pointer,
                         int pretty) {
    ntsj_buf b;
    ntsj_buf_init(&b);
    ntsj_encode_error(&b, code, message, pointer, pretty);
    return ntsj_finish(out, &b, code);
}

int ntsj_respond_fault(ntsj_response* out, const ntsj_fault* f, int pretty) {
    return ntsj_respond_error(out, f->code ? f->code : nts_status_name(NTS_EINTERNAL), f->message, f->pointer, pretty);
}

static int deadline_passed(void* user) {
    const ntsj_deadline* d = user;
    return ntsj_now_ms() > d->until_ms || (d->cancel != NULL && d->cancel(d->cancel_user));
}

void ntsj_arm_deadline(nts_options* opt, ntsj_deadline* d, const ntsj_config* cfg, double t0) {
    opt->max_candidates = cfg->max_candidates;
    if (!(cfg->max_seconds > 0.0) && cfg->cancel == NULL) return;
    d->until_ms = cfg->max_seconds > 0.0 ? t0 + cfg->max_seconds * 1e3 : HUGE_VAL;
    d->cancel = cfg->cancel;
    d->cancel_user = cfg->cancel_user;
    opt->cancel = deadline_passed;
    opt->cancel_user = d;
}

int ntsj_respond_core(ntsj_response* out, const ntsj_scene* s, const nts_error* err, int status, int pretty) {
    char ptr[256];
    int code = err->code ? err->code : status;
    const char* name = nts_status_name(code);
    if (!name || !ntsj_code_known(name)) name = nts_status_name(NTS_EINTERNAL);
    ntsj_pointer_of_error(s, err, ptr, sizeof ptr);
    return ntsj_respond_error(out, name, err->message[0] ? err->message : nts_strerror(code), ptr, pretty);
}

/* The request-time limit (ntsj_config.max_seconds), checked between the
 * phases: after decoding, after building the scene and after evaluating (the
 * core asks it during the evaluation too, through ntsj_arm_deadline); a
 * request over budget gets a limit_exceeded error (400) naming the limit,
 * never a late result. */
int ntsj_past_budget(const ntsj_config* cfg, double t0) {
    return cfg->max_seconds > 0.0 && ntsj_now_ms() - t0 > cfg->max_seconds * 1e3;
}

int ntsj_over_budget(const ntsj_config* cfg, double t0, ntsj_response* out, const char* phase, int* rc) {
    double elapsed;
    char msg[160];
    if (!ntsj_past_budget(cfg, t0)) return 0;
    elapsed = ntsj_now_ms() - t0;
    snprintf(msg, sizeof msg, "the request took %.3f ms up to %s, more than max_seconds = %g s", elapsed, phase,
             cfg->max_seconds);
    *rc = ntsj_respond_error(out, nts_status_name(NTS_ELIMIT), msg, "", cfg->pretty);
    return 1;
}

static int vec_ok(nts_vec2 v) { return isfinite(v.x) && isfinite(v.y); }
static int virial_ok(nts_virial v) { return isfinite(v.xx) && isfinite(v.yy) && isfinite(v.xy); }

/* Finite input can still overflow (a penalty of 1e200 times gaps of 1e100): the
 * contract has no NaN, no Infinity and no null, so such a result is refused as
 * non_finite. The pointer is the penalty whatever the outputs asked for (so
 * --validate answers alike); the message names the first contact or gap at
 * fault (an overflowing force the core refuses itself, with the pointer). */
int ntsj_result_overflows(const ntsj_scene* s, const nts_scene* scene, const nts_result* r, ntsj_fault* f) {
    const nts_summary* sm = &r->summary;
    int i;
    /* The forces are not read again: the core answers NTS_ENONFINITE when
     * one overflows (nts_evaluate), and a pass over every node cost 6% of a
     * step of a mesh of 66k nodes (1,776 on its surface). */
#ifndef NDEBUG
    {
        int b, k;
        for (b = 0; r->forces && b < s->body_count; ++b) {
            int off = nts_scene_body_node_offset(scene, b), n = nts_scene_body_node_count(scene, b);
            for (k = 0; k < n; ++k) assert(vec_ok(r->forces[off + k]));
        }
    }
#else
    (void)s;
    (void)scene;
#endif
    for (i = 0; r->contacts && i < r->contact_count; ++i) {
        const nts_contact* c = &r->contacts[i];
        if (!vec_ok(c->force) || !virial_ok(c->virial) || !isfinite(c->gap) || !vec_ok(c->point) ||
            !vec_ok(c->normal) || !isfinite(c->param) || !isfinite(c->weights[0])) {
            ntsj_fault_set(f, nts_status_name(NTS_ENONFINITE), "/options/penalty",
                           "the contact of /bodies/%d/nodes/%d overflows a double (reduce the penalty or the "
                           "coordinates)", c->slave_body, c->slave_node);
            return 1;
        }
    }
    for (i = 0; r->gaps && i < r->gap_count; ++i) {
        if (!isfinite(r->gaps[i].gap)) {
            ntsj_fault_set(f, nts_status_name(NTS_ENONFINITE), "/options/penalty", "the gap of /bodies/%d/nodes/%d overflows a double",
                           r->gaps[i].slave_body, r->gaps[i].slave_node);
            return 1;
        }
    }
    if (!isfinite(sm->energy) || !virial_ok(sm->virial) || !isfinite(sm->max_penetration) ||
        !isfinite(sm->search_radius) || !isfinite(sm->cell_size)) {
        ntsj_fault_set(f, nts_status_name(NTS_ENONFINITE), "/options/penalty",
                       "the energy or the virial overflows a double (reduce the penalty or the coordinates)");
        return 1;
    }
    return 0;
}

static int is_blank(const char* p, size_t n) {
    size_t i;
    for (i = 0; i < n; ++i)
        if (p[i] != ' ' && p[i] != '\t' && p[i] != '\n' && p[i] != '\r') return 0;
    return 1;
}

int ntsj_set_history(nts_history* h, const ntsj_scene* s, const nts_scene* scene, ntsj_response* out, int pretty,
                     int* rc) {
    nts_error err = nts_error_none();
    const int code = h == NULL ? NTS_ENOMEM : nts_history_set(h, scene, s->history, s->history_count, &err);
    if (code == 0) return 0;
    *rc = code == NTS_ENOMEM ? ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty)
                             : ntsj_respond_core(out, s, &err, code, pretty);
    return 1;
}

int ntsj_handle(const char* json, size_t length, const ntsj_config* config, ntsj_response* out) {
    ntsj_config cfg = config ? *config : ntsj_default_config();
    ntsj_fault fault;
    ntsj_scene s;
    nts_scene_def def;
    nts_scene* scene = NULL;
    nts_context* ctx = NULL;
    nts_history* history = NULL;
    nts_result result;
    nts_error err = nts_error_none();
    cJSON* root;
    ntsj_buf b;
    const char* parse_end = NULL;
    double t0 = ntsj_now_ms(), elapsed;
    ntsj_response kept;
    int rc, done = 0, pretty = cfg.pretty;

    memset(out, 0, sizeof *out);
    memset(&kept, 0, sizeof kept);
    memset(&fault, 0, sizeof fault);
    if (cfg.max_depth <= 0) cfg.max_depth = NTSJ_DEFAULT_MAX_DEPTH;
    if (cfg.max_bytes == 0) cfg.max_bytes = NTSJ_DEFAULT_MAX_BYTES;

    if (length > cfg.max_bytes) {
        char msg[128];
        /* A reader that stops at max_bytes + 1 (the CLI does) only knows "more". */
        snprintf(msg, sizeof msg, "request is more than max_bytes = %lu bytes", (unsigned long)cfg.max_bytes);
        return ntsj_respond_error(out, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE), msg, "", pretty);
    }
    if (!json || is_blank(json, length)) return ntsj_respond_error(out, ntsj_code_name(NTSJ_EMPTY_BODY), "the request is empty", "", pretty);
    if (ntsj_scan(json, length, cfg.max_depth, &fault) != 0) return ntsj_respond_fault(out, &fault, pretty);

    root = cJSON_ParseWithLengthOpts(json, length, &parse_end, 0);
    if (!root) /* the scan accepted it, so this is cJSON running out of memory */
        return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory while parsing the request", "", pretty);
    rc = ntsj_decode(root, &cfg, &s, &fault);
    cJSON_Delete(root);
    if (rc != 0) return ntsj_respond_fault(out, &fault, pretty);
    if (ntsj_over_budget(&cfg, t0, out, "decoding", &rc)) {
        ntsj_scene_free(&s);
        return rc;
    }
    /* The stateless evaluation stays stateless: only a session keeps
     * anything between requests (a scene may still be validated with it). */
    if (s.has_session && cfg.mode == NTSJ_EVALUATE) {
        ntsj_scene_free(&s);
        return ntsj_respond_error(out, ntsj_code_name(NTSJ_INVALID_VALUE),
                                  "\"session\" is for a session (POST /v1/scenes): a single evaluation keeps nothing",
                                  "/session", pretty);
    }

    if (nts_options_validate(&s.options, &err) != 0) {
        rc = ntsj_respond_core(out, &s, &err, NTS_EINVALID_OPTION, pretty);
        ntsj_scene_free(&s);
        return rc;
    }
    def = nts_default_scene_def();
    def.bodies = s.defs;
    def.body_count = s.body_count;
    def.lx = s.has_periodic ? s.lx : 0.0;
    def.ly = s.has_periodic ? s.ly : 0.0;
    def.limits = cfg.limits;
    scene = nts_scene_create(&def, &err);
    if (!scene) {
        rc = ntsj_respond_core(out, &s, &err, NTS_EINTERNAL, pretty);
        ntsj_scene_free(&s);
        return rc;
    }
    if (ntsj_over_budget(&cfg, t0, out, "building the scene", &rc)) {
        nts_scene_destroy(scene);
        ntsj_scene_free(&s);
        return rc;
    }

    /* A previous result's anchors, checked against this scene (§14). */
    if (s.has_history) {
        history = nts_history_create();
        if (ntsj_set_history(history, &s, scene, out, pretty, &rc)) {
            nts_history_destroy(history);
            nts_scene_destroy(scene);
            ntsj_scene_free(&s);
            return rc;
        }
    }

    ntsj_buf_init(&b);
    {
        nts_options opt = s.options;
        ntsj_deadline deadline;
        opt.history = history;
        /* The summary is always complete: energy and virial are always computed.
         * Validation evaluates too, with the same outputs (none of them
         * written): faults that depend on the options and the whole scene (a
         * periodic box too small for the search reach, a force or a tangent
         * that overflows a double) only show there, and "valid" must mean
         * "evaluates". */
        opt.outputs |= NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
        if (cfg.vtk && cfg.mode != NTSJ_VALIDATE) opt.outputs |= NTS_OUT_FORCES | NTS_OUT_CONTACTS;
        ntsj_arm_deadline(&opt, &deadline, &cfg, t0);
        ctx = nts_context_create();
        if (!ctx) {
            nts_history_destroy(history);
            nts_scene_destroy(scene);
            ntsj_scene_free(&s);
            return ntsj_respond_error(out, nts_status_name(NTS_ENOMEM), "out of memory", "", pretty);
        }
        rc = cfg.evaluate != NULL ? cfg.evaluate(cfg.evaluate_user, &def, scene, &opt, &result, &err)
                                  : nts_evaluate(ctx, scene, &opt, &result, &err);
        elapsed = ntsj_now_ms() - t0;
        if ((rc == 0 || rc == NTS_ECANCELLED) && ntsj_over_budget(&cfg, t0, out, "evaluating", &rc)) {
            done = 1;
        } else if (rc != 0) {
            rc = ntsj_respond_core(out, &s, &err, rc, pretty);
            done = 1;
        } else if (ntsj_result_overflows(&s, scene, &result, &fault)) {
            rc = ntsj_respond_fault(out, &fault, pretty);
            done = 1;
        } else if (cfg.mode == NTSJ_VALIDATE) {
            ntsj_encode_validation(&b, scene, ntsj_round_us(elapsed), pretty);
        } else {
            ntsj_encode_result(&b, &s, scene, &result, ntsj_round_us(elapsed), pretty);
            ntsj_keep_summary(&kept, &result, nts_friction_on(scene, &s.options));
            if (cfg.history_out && kept.friction) {
                ntsj_buf h;
                ntsj_buf_init(&h);
                ntsj_encode_history(&h, &s, result.anchors, result.anchor_count);
                if (h.oom || !h.data) b.oom = 1;
                kept.history = h.data;
                kept.history_length = h.len;
            }
            if (cfg.vtk && ntsj_attach_vtk(out, &s, scene, &result) != 0) b.oom = 1;
        }
        nts_context_destroy(ctx);
        nts_history_destroy(history);
        if (done) {
            ntsj_buf_free(&b);
            nts_scene_destroy(scene);
            ntsj_scene_free(&s);
            return rc;
        }
    }
    nts_scene_destroy(scene);
    ntsj_scene_free(&s);
    rc = ntsj_finish(out, &b, "ok");
    if (rc == 0) { /* for the front end's counters and warnings */
        out->summary = kept.summary;
        out->friction = kept.friction;
        out->history = kept.history;
        out->history_length = kept.history_length;
        kept.history = NULL;
        out->warning_count = kept.warning_count;
        memcpy(out->warnings, kept.warnings, sizeof out->warnings);
    }
    nts_free(kept.history);
    return rc;
}

void ntsj_response_free(ntsj_response* response) {
    if (!response) return;
    nts_free(response->body);
    nts_free(response->vtk);
    nts_free(response->history);
    response->history = NULL;
    response->history_length = 0;
    response->body = NULL;
    response->length = 0;
    response->vtk = NULL;
    response->vtk_length = 0;
}

int ntsj_attach_vtk(ntsj_response* out, const ntsj_scene* s, const nts_scene* scene, const nts_result* r) {
    ntsj_buf v;
    ntsj_buf_init(&v);
    ntsj_encode_vtk(&v, s, scene, r);
    if (v.oom || !v.data) {
        ntsj_buf_free(&v);
        return NTS_ENOMEM;
    }
    out->vtk = v.data;
    out->vtk_length = v.len;
    return 0;
}

char* ntsj_error_document(const char* code, const char* message, const char* pointer) {
    ntsj_buf b;
    ntsj_buf_init(&b);
    ntsj_encode_error(&b, code, message, pointer, 0);
    if (b.oom) {
        ntsj_buf_free(&b);
        return NULL;
    }
    return b.data;
}

static void copy_field(const cJSON* obj, const char* key, char* out, size_t size) {
    const cJSON* v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (size == 0) return;
    out[0] = '\0';
    if (cJSON_IsString(v)) snprintf(out, size, "%s", v->valuestring);
}

int ntsj_error_fields(const char* body, size_t length, char* pointer, size_t pointer_size, char* message,
                      size_t message_size) {
    cJSON* root;
    const cJSON* e;
    if (pointer_size) pointer[0] = '\0';
    if (message_size) message[0] = '\0';
    if (!body) return -1;
    root = cJSON_ParseWithLengthOpts(body, length, NULL, 0);
    e = cJSON_GetObjectItemCaseSensitive(root, "error");
    if (!cJSON_IsObject(e)) {
        cJSON_Delete(root);
        return -1;
    }
    copy_field(e, "pointer", pointer, pointer_size);
    copy_field(e, "message", message, message_size);
    cJSON_Delete(root);
    return 0;
}
