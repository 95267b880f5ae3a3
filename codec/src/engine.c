/* The codec in process for foreign-function hosts (engine.h): the daemon's
 * work without HTTP, behind opaque handles. Each call is the daemon's route:
 * ntsj_handle for POST /v1/contact and /v1/validate, ntsj_session_create for
 * POST /v1/scenes, ntsj_session_step for a step, with the same configuration
 * defaults, so that the answers are the daemon's bytes. */
#include <stdio.h>
#include <string.h>

#include <ntscontact/engine.h>

struct ntsj_engine {
    ntsj_config config;
};

struct ntsj_answer {
    ntsj_response response;
    char* headers; /* a binary answer's "Name: value\n" lines, else NULL */
};

ntsj_engine* ntsj_engine_create_sized(int threads, size_t max_bytes) {
    ntsj_engine* e = (ntsj_engine*)nts_alloc(sizeof *e);
    if (e == NULL) return NULL;
    e->config = ntsj_default_config();
    e->config.threads = threads > 0 ? threads : 0;
    if (max_bytes > 0) e->config.max_bytes = max_bytes;
    return e;
}

ntsj_engine* ntsj_engine_create(int threads) { return ntsj_engine_create_sized(threads, 0); }

void ntsj_engine_destroy(ntsj_engine* engine) { nts_free(engine); }

static ntsj_answer* answer_new(void) {
    ntsj_answer* a = (ntsj_answer*)nts_alloc(sizeof *a);
    if (a != NULL) memset(a, 0, sizeof *a);
    return a;
}

/* An answer whose codec call failed even to build its error document. */
static ntsj_answer* answer_or_null(ntsj_answer* a, int rc) {
    if (rc == 0 && a->response.body != NULL) return a;
    ntsj_answer_free(a);
    return NULL;
}

ntsj_answer* ntsj_engine_contact(const ntsj_engine* engine, const char* json, size_t length, int validate) {
    ntsj_config c = engine->config;
    ntsj_answer* a = answer_new();
    if (a == NULL) return NULL;
    c.mode = validate ? NTSJ_VALIDATE : NTSJ_EVALUATE;
    return answer_or_null(a, ntsj_handle(json != NULL ? json : "", length, &c, &a->response));
}

ntsj_answer* ntsj_engine_session_create(const ntsj_engine* engine, const char* json, size_t length,
                                        ntsj_session** session) {
    ntsj_answer* a = answer_new();
    int rc;
    *session = NULL;
    if (a == NULL) return NULL;
    rc = ntsj_session_create(json != NULL ? json : "", length, &engine->config, session, &a->response);
    if (rc != 0) {
        ntsj_answer_free(a);
        return NULL;
    }
    if (*session != NULL) { /* made: an empty ok answer (the error document otherwise) */
        a->response.ok = 1;
        a->response.http_status = 201;
        a->response.code = "ok";
        if (a->response.body == NULL) {
            a->response.body = (char*)nts_alloc(1);
            if (a->response.body == NULL) {
                ntsj_session_destroy(*session);
                *session = NULL;
                ntsj_answer_free(a);
                return NULL;
            }
            a->response.body[0] = '\0';
            a->response.length = 0;
        }
    }
    return answer_or_null(a, 0);
}

/* The header lines of a binary answer, as the daemon sends them. */
static int answer_headers(ntsj_answer* a) {
    ntsj_binary_headers h;
    size_t size = 1, k = 0;
    int i;
    ntsj_binary_headers_of(&a->response, &h);
    for (i = 0; i < h.count; ++i) size += strlen(h.names[i]) + strlen(h.values[i]) + 3;
    a->headers = (char*)nts_alloc(size);
    if (a->headers == NULL) return -1;
    for (i = 0; i < h.count; ++i) k += (size_t)snprintf(a->headers + k, size - k, "%s: %s\n", h.names[i], h.values[i]);
    a->headers[k] = '\0';
    return 0;
}

ntsj_answer* ntsj_engine_step(const ntsj_engine* engine, ntsj_session* session, int kind, const char* body,
                              size_t length, int answer_binary, int param_count, const char* const* param_names,
                              const char* const* param_values) {
    ntsj_step st;
    ntsj_answer* a = answer_new();
    int rc;
    if (a == NULL) return NULL;
    memset(&st, 0, sizeof st);
    st.kind = kind == NTSJ_STEP_BINARY ? NTSJ_STEP_BINARY : kind == NTSJ_STEP_JSON ? NTSJ_STEP_JSON : NTSJ_STEP_EMPTY;
    st.body = body;
    st.length = st.kind == NTSJ_STEP_EMPTY ? 0 : length;
    st.answer_binary = answer_binary != 0;
    st.param_count = param_count > 0 ? param_count : 0;
    st.param_names = param_names;
    st.param_values = param_values;
    st.defer_commit = 0; /* nothing between the answer and its caller may refuse it */
    rc = ntsj_session_step(session, &st, &engine->config, &a->response);
    if (rc == 0 && a->response.ok && a->response.binary && answer_headers(a) != 0) rc = NTS_ENOMEM;
    return answer_or_null(a, rc);
}

void ntsj_engine_session_counts(const ntsj_session* session, long long out[5]) {
    ntsj_session_info info = ntsj_session_get_info(session);
    out[0] = info.bodies;
    out[1] = info.nodes;
    out[2] = info.surface_nodes;
    out[3] = (long long)info.steps;
    out[4] = (long long)info.memory_bytes;
}

int ntsj_answer_ok(const ntsj_answer* a) { return a->response.ok; }
int ntsj_answer_status(const ntsj_answer* a) { return a->response.http_status; }
const char* ntsj_answer_code(const ntsj_answer* a) { return a->response.code != NULL ? a->response.code : ""; }
const char* ntsj_answer_body(const ntsj_answer* a) { return a->response.body; }
size_t ntsj_answer_length(const ntsj_answer* a) { return a->response.length; }
int ntsj_answer_binary(const ntsj_answer* a) { return a->response.ok && a->response.binary; }
const char* ntsj_answer_headers(const ntsj_answer* a) { return a->headers != NULL ? a->headers : ""; }

void ntsj_answer_free(ntsj_answer* a) {
    if (a == NULL) return;
    ntsj_response_free(&a->response);
    nts_free(a->headers);
    nts_free(a);
}
