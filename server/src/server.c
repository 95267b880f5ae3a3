/* ntscontactd on libmicrohttpd: the access handler (one request's life), the
 * completion and connection callbacks, and the counters behind /v1/health.
 *
 * A request's life (doc/examples/largepost.c):
 *   1st call    headers only: allocate the state, route, answer at once what
 *               needs no body (GET, 404, 405, 415, 413 from Content-Length, 503);
 *   next calls  body pieces, appended to a capped buffer;
 *   last call   upload_data_size == 0: evaluate through the codec, answer;
 *   completed   log the line, free the state. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "assets.h"
#include <ntscontact/codec.h>
#include "server.h"

#define NTSD_MAX_QUERY_PARAMS 16

typedef struct ntsd_request {
    ntsd_server* server;
    ntsd_route route;
    double t0, deadline;       /* monotonic seconds: first callback, end of the upload budget */
    double t_body, t_answer;   /* the body is complete; the response is queued */
    ntsd_body body;
    size_t received;           /* body bytes received, kept or not */
    int queued;                /* a response is queued */
    int too_large;             /* the body went beyond --max-bytes: answer 413 */
    int status;                /* of the queued response */
    size_t bytes_out;
    char code[48];             /* error code of the response, or why the request ended */
    char method[16];
    char path[256];
    char peer[64];
    int http10;                /* an HTTP/1.0 request */
    char origin[256];          /* its Origin when --allow-origin names it (CORS headers), or "" */
    int preflight;             /* OPTIONS: a CORS preflight */
    char client[NTSD_CLIENT_LEN]; /* who it is, for per-client quotas and ownership (ntsd_client_key) */
    ntsd_conn* link;           /* the watcher's record of the connection (watch.c) */
    int cut_by_watcher;        /* the watcher cut its connection (counted there) */
    size_t reserved;           /* bytes held against --max-memory, given back at completion */
    int over_budget;           /* a chunked body outgrew the budget: answer 503 */
    const char* refusal;       /* why the service refused it (the metrics' reason), or NULL */
    int pretty;
    int rc;
    ntsj_response resp;
    /* Sessions: a step's body kind and answer, its query options, the Location
     * of a new session. */
    int authorized;            /* a valid bearer token (or none is configured) */
    int binary_in;             /* Content-Type: application/octet-stream */
    int answer_binary;         /* Accept: application/octet-stream */
    int param_count;
    const char* param_names[NTSD_MAX_QUERY_PARAMS];
    const char* param_values[NTSD_MAX_QUERY_PARAMS];
    int too_many_params;
    char location[16 + NTSD_SESSION_ID_MAX];
    char given_id[NTSD_SESSION_ID_MAX + 1]; /* the proxy's id for a new session (--session-id-header) */
} ntsd_request;


static void copy_str(char* dst, size_t cap, const char* src) {
    size_t n = src ? strlen(src) : 0;
    if (n >= cap) n = cap - 1;
    if (n) memcpy(dst, src, n);
    dst[n] = '\0';
}

static void peer_name(struct MHD_Connection* c, char* out, size_t cap) {
    const union MHD_ConnectionInfo* ci = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    ntsd_address_name(ci != NULL ? ci->client_addr : NULL, out, cap);
}

/* ------------------------------------------------------------- answers */

/* The headers a page of an allowed Origin may read beyond the CORS-safelisted
 * ones: a new session's Location, Retry-After of a 503, Allow of a 405,
 * WWW-Authenticate of a 401, and every header of a binary session step
 * (reply_evaluated). */
static const char cors_exposed[] =
    "Location, Retry-After, Allow, WWW-Authenticate, NTS-Energy, NTS-Virial, NTS-Contacts, NTS-Max-Penetration, "
    "NTS-Elapsed-Ms, NTS-Gaps, NTS-Loops-Reversed, NTS-Search-Radius, NTS-Cell-Size, NTS-Stiffness-Triplets, "
    "NTS-Deep-Contacts, NTS-Warnings, NTS-Dissipation, NTS-Sticking, NTS-Slipping";

/* Queue a response. `body` is freed with `free_fn` once sent (NULL: static
 * storage). `content_type` NULL: none. `close`: ask the client to close (the
 * body may be left unread). */
static enum MHD_Result reply_headers(struct MHD_Connection* c, ntsd_request* r, unsigned status, const char* code,
                                     char* body, size_t length, void (*free_fn)(void*), const char* content_type,
                                     const char* allow, int close, const char* const* extra) {
    struct MHD_Response* resp;
    enum MHD_Result ok;
    if (free_fn != NULL) {
        resp = MHD_create_response_from_buffer_with_free_callback(length, body, free_fn);
        if (resp == NULL) free_fn(body);
    } else {
        resp = MHD_create_response_from_buffer(length, body, MHD_RESPMEM_PERSISTENT);
    }
    if (resp == NULL) return MHD_NO;
    if (content_type != NULL) MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, content_type);
    /* CORS (--allow-origin): the answer depends on the Origin; an allowed
     * page may read it, and the headers a browser client needs. */
    if (r->server->config.allow_origin_count > 0) MHD_add_response_header(resp, MHD_HTTP_HEADER_VARY, "Origin");
    if (r->origin[0] != '\0') {
        MHD_add_response_header(resp, MHD_HTTP_HEADER_ACCESS_CONTROL_ALLOW_ORIGIN, r->origin);
        if (!r->preflight) MHD_add_response_header(resp, "Access-Control-Expose-Headers", cors_exposed);
    }
    if (allow != NULL) MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW, allow);
    if (status == MHD_HTTP_SERVICE_UNAVAILABLE) MHD_add_response_header(resp, MHD_HTTP_HEADER_RETRY_AFTER, "1");
    if (close) MHD_add_response_header(resp, MHD_HTTP_HEADER_CONNECTION, "close");
    for (; extra != NULL && extra[0] != NULL; extra += 2)
        if (extra[0][0] != '\0') MHD_add_response_header(resp, extra[0], extra[1]); /* "": a header left out */
    ok = MHD_queue_response(c, status, resp);
    MHD_destroy_response(resp);
    if (ok == MHD_YES) {
        r->t_answer = ntsd_now();
        if (r->t_body == 0.0) r->t_body = r->t_answer;
        r->queued = 1;
        r->status = (int)status;
        r->bytes_out = length;
        copy_str(r->code, sizeof r->code, code);
    }
    return ok;
}

static enum MHD_Result reply(struct MHD_Connection* c, ntsd_request* r, unsigned status, const char* code,
                             char* body, size_t length, void (*free_fn)(void*), const char* content_type,
                             const char* allow, int close) {
    return reply_headers(c, r, status, code, body, length, free_fn, content_type, allow, close, NULL);
}

static const char fallback_error[] =
    "{\"error\":{\"code\":\"overloaded\",\"message\":\"out of memory\",\"pointer\":\"\"}}\n";

/* An error document per error.schema.json, built by the codec; the HTTP status
 * comes from the codec's table of codes (codec/src/codes.c), so a code always
 * travels with the same status. Memory exhaustion is "overloaded" (503): the
 * client may retry, nothing is wrong with its request. */
static enum MHD_Result reply_error(struct MHD_Connection* c, ntsd_request* r, const char* code,
                                   const char* message, const char* allow, int close) {
    char* doc = ntsj_error_document(code, message, "");
    if (doc == NULL)
        return reply(c, r, MHD_HTTP_SERVICE_UNAVAILABLE, ntsj_code_name(NTSJ_OVERLOADED), (char*)fallback_error,
                     sizeof fallback_error - 1, NULL, "application/json", NULL, 1);
    return reply(c, r, (unsigned)ntsj_code_http_status(code), code, doc, strlen(doc), nts_free,
                 "application/json", allow, close);
}

static const char unknown_scene_message[] =
    "no scene session with this id (it expired, was evicted or deleted, or the daemon restarted): "
    "create it again with POST /v1/scenes";

/* GET, HEAD or DELETE /v1/scenes/{id}. */
static enum MHD_Result answer_scene(struct MHD_Connection* c, ntsd_request* r) {
    ntsd_server* s = r->server;
    ntsd_session_meta m;
    char* doc;
    int n;
    if (strcmp(r->method, "DELETE") == 0) {
        if (r->route.scene_id[0] == '\0' || ntsd_sessions_remove(&s->sessions, r->route.scene_id, r->client) != 0)
            return reply_error(c, r, ntsj_code_name(NTSJ_UNKNOWN_SCENE), unknown_scene_message, NULL, 0);
        return reply(c, r, MHD_HTTP_NO_CONTENT, "ok", (char*)"", 0, NULL, "application/json", NULL, 0);
    }
    if (r->route.scene_id[0] == '\0' || ntsd_sessions_describe(&s->sessions, r->route.scene_id, r->client, &m) != 0)
        return reply_error(c, r, ntsj_code_name(NTSJ_UNKNOWN_SCENE), unknown_scene_message, NULL, 0);
    doc = malloc(512);
    if (doc == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 0);
    n = snprintf(doc, 512,
                 "{\"id\":\"%s\",\"nodes\":%d,\"surface_nodes\":%d,\"bodies\":%d,\"expires_in_s\":%.3f,"
                 "\"steps\":%llu,\"memory_bytes\":%zu,\"age_s\":%.3f,\"idle_s\":%.3f}\n",
                 r->route.scene_id, m.nodes, m.surface_nodes, m.bodies, m.expires_in_s, m.steps, m.memory_bytes,
                 m.age_s, m.idle_s);
    return reply(c, r, MHD_HTTP_OK, "ok", doc, (size_t)n, free, "application/json", NULL, 0);
}

/* GET or HEAD /v1/scenes/{id}/surface: the session's surface nodes
 * (ntsj_session_surface), the order of a step with ?nodes=surface. The list
 * is fixed at creation: read without the step lock. */
static enum MHD_Result answer_surface(struct MHD_Connection* c, ntsd_request* r) {
    ntsd_server* s = r->server;
    /* A read of what the session holds: not a use (as GET /v1/scenes/{id}). */
    ntsd_session_entry* e =
        r->route.scene_id[0] ? ntsd_sessions_acquire(&s->sessions, r->route.scene_id, r->client, 0) : NULL;
    const int* nodes;
    int count, k;
    size_t cap, n = 0;
    char* doc;
    if (e == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_UNKNOWN_SCENE), unknown_scene_message, NULL, 0);
    nodes = ntsj_session_surface(e->session, &count);
    cap = 32 + 12 * (size_t)count; /* an int and a comma each */
    doc = malloc(cap);
    if (doc != NULL) {
        n = (size_t)snprintf(doc, cap, "{\"count\":%d,\"nodes\":[", count);
        for (k = 0; k < count; ++k) n += (size_t)snprintf(doc + n, cap - n, k ? ",%d" : "%d", nodes[k]);
        n += (size_t)snprintf(doc + n, cap - n, "]}\n");
    }
    ntsd_sessions_release(&s->sessions, e, 0);
    if (doc == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 0);
    return reply(c, r, MHD_HTTP_OK, "ok", doc, n, free, "application/json", NULL, 0);
}

/* GET /metrics: a snapshot of the counters, formatted outside the lock. */
static enum MHD_Result answer_metrics(struct MHD_Connection* c, ntsd_request* r) {
    ntsd_server* s = r->server;
    ntsd_metrics* m = malloc(sizeof *m);
    ntsd_stats st = ntsd_server_stats(s);
    ntsd_sessions_stats ss = ntsd_sessions_get_stats(&s->sessions);
    size_t n = 0;
    char* doc = NULL;
    if (m != NULL) {
        pthread_mutex_lock(&s->lock);
        *m = s->metrics;
        pthread_mutex_unlock(&s->lock);
        doc = ntsd_metrics_document(m, &st, &ss, &s->config, &n);
        free(m);
    }
    if (doc == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 0);
    return reply(c, r, MHD_HTTP_OK, "ok", doc, n, free, "text/plain; version=0.0.4; charset=utf-8", NULL, 0);
}

/* GET /v1/health: open without a token, which then says only whether it is up. */
static enum MHD_Result answer_health(struct MHD_Connection* c, ntsd_request* r) {
    size_t n = 0;
    ntsd_stats st = ntsd_server_stats(r->server);
    ntsd_sessions_stats ss = ntsd_sessions_get_stats(&r->server->sessions);
    char* doc = ntsd_health_document(&r->server->config, &st, &ss, r->authorized, &n);
    if (doc == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 0);
    return reply(c, r, MHD_HTTP_OK, "ok", doc, n, free, "application/json", NULL, 0);
}

/* GET /v1/openapi.json, /v1/schemas/{name}: an embedded file (the router bound it). */
static enum MHD_Result answer_asset(struct MHD_Connection* c, ntsd_request* r) {
    const ntsd_asset* a = &ntsd_assets[r->route.asset];
    return reply(c, r, MHD_HTTP_OK, "ok", (char*)a->data, a->size, NULL, a->content_type, NULL, 0);
}

/* At most config.threads evaluations at once (per-connection threads would
 * otherwise oversubscribe the cores); waiting here holds no lock. Large
 * requests (ntsd_large_request) take at most threads - 1 slots when there are
 * two or more: a few long evaluations cannot make a small request wait for
 * them (issue 23: two brute-force scenes made a normal POST wait 18.5 s). A
 * freed slot goes to a waiting small request first (it is quick), else to a
 * large one if a large slot is free: one waiter woken, not the herd. */
static int large_slots(const ntsd_server* s) {
    return s->config.threads >= 2 ? s->config.threads - 1 : 1;
}

static void gate_enter(ntsd_server* s, int large) {
    pthread_mutex_lock(&s->lock);
    if (large) {
        s->waiting_large++;
        while (s->evaluating >= s->config.threads || s->evaluating_large >= large_slots(s))
            pthread_cond_wait(&s->changed_large, &s->lock);
        s->waiting_large--;
        s->evaluating_large++;
    } else {
        s->waiting_small++;
        while (s->evaluating >= s->config.threads) pthread_cond_wait(&s->changed, &s->lock);
        s->waiting_small--;
    }
    s->evaluating++;
    pthread_mutex_unlock(&s->lock);
}

static void gate_leave(ntsd_server* s, int large) {
    pthread_mutex_lock(&s->lock);
    s->evaluating--;
    if (large) s->evaluating_large--;
    if (s->waiting_small > 0)
        pthread_cond_signal(&s->changed);
    else if (s->waiting_large > 0 && s->evaluating_large < large_slots(s))
        pthread_cond_signal(&s->changed_large);
    pthread_mutex_unlock(&s->lock);
}

/* Large: a body of NTSD_LARGE_BYTES or more, or a session step over
 * NTSD_LARGE_NODES nodes (a step's work is its session's size, whatever its
 * body): about 10,000 nodes or more, milliseconds of work and up. */
enum { NTSD_LARGE_BYTES = 256 * 1024, NTSD_LARGE_NODES = 16384 };

static int query_flag(struct MHD_Connection* c, const char* name) {
    const char* v = MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, name);
    if (v == NULL) return 0;
    return *v == '\0' || strcmp(v, "1") == 0 || strcmp(v, "true") == 0;
}

/* An error document as the codec's answer (r->resp), for the sessions' own faults. */
static void resp_error(ntsd_request* r, const char* code, const char* message) {
    memset(&r->resp, 0, sizeof r->resp);
    r->resp.body = ntsj_error_document(code, message, "");
    r->resp.length = r->resp.body ? strlen(r->resp.body) : 0;
    r->resp.code = code;
    r->resp.http_status = ntsj_code_http_status(code);
    r->rc = r->resp.body ? 0 : NTS_ENOMEM;
}

/* POST /v1/scenes: build the session, hand it to the store, answer 201. */
static void evaluate_create(ntsd_request* r, const ntsj_config* jc) {
    ntsd_server* s = r->server;
    ntsj_session* ss = NULL;
    char id[NTSD_SESSION_ID_MAX + 1];
    ntsj_session_info info;
    int rc;
    r->rc = ntsj_session_create(r->body.data ? r->body.data : "", r->body.length, jc, &ss, &r->resp);
    if (ss == NULL) return;
    info = ntsj_session_get_info(ss);
    rc = ntsd_sessions_add(&s->sessions, ss, r->client, r->given_id[0] ? r->given_id : NULL, id);
    if (rc == NTSD_SESSIONS_TOO_LARGE) {
        char msg[160];
        snprintf(msg, sizeof msg, "the session would hold %zu bytes, more than --session-memory = %zu",
                 info.memory_bytes, s->config.session_memory);
        ntsj_session_destroy(ss);
        resp_error(r, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE), msg);
        return;
    }
    if (rc == NTSD_SESSIONS_QUOTA) {
        char msg[200];
        snprintf(msg, sizeof msg,
                 "this client holds --max-sessions-per-client = %d scene sessions, every one in use; retry later, "
                 "or delete one", s->config.max_sessions_per_client);
        ntsj_session_destroy(ss);
        resp_error(r, ntsj_code_name(NTSJ_OVERLOADED), msg);
        return;
    }
    if (rc != 0) {
        ntsj_session_destroy(ss);
        resp_error(r, ntsj_code_name(NTSJ_OVERLOADED),
                   "the scene sessions are full (--max-sessions, --session-memory) and none that may make room is "
                   "idle; retry later");
        return;
    }
    memset(&r->resp, 0, sizeof r->resp);
    r->resp.body = nts_alloc(256);
    if (r->resp.body == NULL) {
        ntsd_sessions_remove(&s->sessions, id, r->client);
        resp_error(r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory");
        return;
    }
    r->resp.length = (size_t)snprintf(r->resp.body, 256,
                                      "{\"id\":\"%s\",\"nodes\":%d,\"surface_nodes\":%d,\"bodies\":%d,"
                                      "\"expires_in_s\":%u}\n",
                                      id, info.nodes, info.surface_nodes, info.bodies, s->config.session_ttl_s);
    r->resp.ok = 1;
    r->resp.code = "ok";
    r->resp.http_status = MHD_HTTP_CREATED;
    snprintf(r->location, sizeof r->location, "/v1/scenes/%s", id);
    r->rc = 0;
}

static int budget_reserve(ntsd_server* s, ntsd_request* r, size_t total);

/* The answer of a step is held until sent: it counts against --max-memory
 * (a 0-byte step may have asked for gaps on a wide radius). */
static void budget_answer(ntsd_request* r) {
    ntsd_server* s = r->server;
    char msg[200];
    int alone;
    if (!r->resp.ok || budget_reserve(s, r, r->reserved + r->resp.length)) return;
    r->refusal = "max_memory";
    alone = r->resp.length > s->config.max_memory;
    if (alone)
        snprintf(msg, sizeof msg, "this step's answer (%zu bytes) alone exceeds --max-memory = %zu", r->resp.length,
                 s->config.max_memory);
    else
        snprintf(msg, sizeof msg, "the memory budget (--max-memory = %zu) is in use by other requests; retry later",
                 s->config.max_memory);
    ntsj_response_free(&r->resp);
    resp_error(r, ntsj_code_name(alone ? NTSJ_PAYLOAD_TOO_LARGE : NTSJ_OVERLOADED), msg);
}

/* POST /v1/scenes/{id}/contact: one step, serialised per session. What the
 * step may add to its session is the room --session-memory leaves it
 * (ntsj_config.step_memory). After it, the session's memory is settled in the
 * store, which may ask for the session's context buffers back: after one
 * large step (ntsd_sessions_settle), or when the store has no room for what
 * the step grew. */
static void evaluate_step(ntsd_request* r, const ntsj_config* jc) {
    ntsd_server* s = r->server;
    ntsd_session_entry* e;
    ntsj_config sc = *jc;
    ntsj_step st;
    int large;
    if (r->too_many_params) {
        resp_error(r, ntsj_code_name(NTSJ_INVALID_VALUE), "too many query parameters");
        return;
    }
    e = r->route.scene_id[0] ? ntsd_sessions_acquire(&s->sessions, r->route.scene_id, r->client, 1) : NULL;
    if (e == NULL) {
        resp_error(r, ntsj_code_name(NTSJ_UNKNOWN_SCENE), unknown_scene_message);
        return;
    }
    memset(&st, 0, sizeof st);
    st.kind = r->body.length == 0 ? NTSJ_STEP_EMPTY : r->binary_in ? NTSJ_STEP_BINARY : NTSJ_STEP_JSON;
    st.body = r->body.data;
    st.length = r->body.length;
    st.answer_binary = r->answer_binary;
    st.param_count = r->param_count;
    st.param_names = r->param_names;
    st.param_values = r->param_values;
    st.defer_commit = 1; /* until the answer is within the budget (below) */
    sc.step_memory_name = "--session-memory";
    pthread_mutex_lock(&e->step_lock);
    large = r->body.length >= NTSD_LARGE_BYTES || ntsj_session_get_info(e->session).nodes >= NTSD_LARGE_NODES;
    gate_enter(s, large);
    sc.step_memory = ntsd_sessions_step_room(&s->sessions, e);
    r->rc = ntsj_session_step(e->session, &st, &sc, &r->resp);
    gate_leave(s, large);
    /* Held by this request: the store neither trims nor frees it meanwhile. */
    if (ntsd_sessions_settle(&s->sessions, e, ntsj_session_get_info(e->session).memory_bytes, r->resp.ok, 0)) {
        ntsj_session_trim(e->session);
        ntsd_sessions_settle(&s->sessions, e, ntsj_session_get_info(e->session).memory_bytes, 0, 1);
    }
    /* The answer within --max-memory (else refused): only then are the
     * step's contacts the ones the next step is matched against. */
    budget_answer(r);
    if (r->resp.ok) ntsj_session_commit(e->session);
    pthread_mutex_unlock(&e->step_lock);
    ntsd_sessions_release(&s->sessions, e, 1);
}

/* The work of each body route, on the codec's configuration for this request. */
typedef void (*route_work)(ntsd_request* r, ntsj_config* jc);

/* POST /v1/contact: the whole scene evaluated. */
static void work_contact(ntsd_request* r, ntsj_config* jc) {
    int large = r->body.length >= NTSD_LARGE_BYTES;
    gate_enter(r->server, large);
    r->rc = ntsj_handle(r->body.data ? r->body.data : "", r->body.length, jc, &r->resp);
    gate_leave(r->server, large);
}

/* POST /v1/validate: the same, checked only. */
static void work_validate(ntsd_request* r, ntsj_config* jc) {
    jc->mode = NTSJ_VALIDATE;
    work_contact(r, jc);
}

/* POST /v1/scenes: a session made. */
static void work_create(ntsd_request* r, ntsj_config* jc) {
    int large = r->body.length >= NTSD_LARGE_BYTES;
    gate_enter(r->server, large);
    evaluate_create(r, jc);
    gate_leave(r->server, large);
}

/* POST /v1/scenes/{id}/contact: it waits for the session before taking an
 * evaluation slot (evaluate_step): a step queued behind another on the same
 * session must not hold one. */
static void work_step(ntsd_request* r, ntsj_config* jc) { evaluate_step(r, jc); }

/* Run the route's work on the whole body, on the connection's own thread:
 * fills r->resp and r->rc, frees the body. At most --threads at once (the gate). */
static void evaluate(ntsd_request* r, route_work work) {
    ntsd_server* s = r->server;
    ntsj_config jc = s->config.codec;
    jc.mode = NTSJ_EVALUATE;
    jc.pretty = r->pretty;
    if (r->link != NULL) { /* the work stops when its client leaves */
        jc.cancel = ntsd_conn_client_left;
        jc.cancel_user = r->link;
    }
    memset(&r->resp, 0, sizeof r->resp);
    work(r, &jc);
    ntsd_body_free(&r->body);
}

/* Queue the codec's answer. */
static enum MHD_Result reply_evaluated(struct MHD_Connection* c, ntsd_request* r) {
    char* body = r->resp.body;
    if (r->rc != 0 || body == NULL) {
        ntsj_response_free(&r->resp);
        return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 1);
    }
    r->resp.body = NULL; /* to libmicrohttpd without a copy, freed by nts_free */
    if (r->resp.ok && r->resp.binary) {
        /* The forces as raw bytes, the summary in headers that read back
         * bitwise (the codec's list, which the in-process engine reads too). */
        ntsj_binary_headers h;
        const char* extra[2 * NTSJ_BINARY_HEADERS_MAX + 1];
        int k;
        ntsj_binary_headers_of(&r->resp, &h);
        for (k = 0; k < h.count; ++k) {
            extra[2 * k] = h.names[k];
            extra[2 * k + 1] = h.values[k];
        }
        extra[2 * h.count] = NULL; /* a NULL name ends the list */
        return reply_headers(c, r, (unsigned)r->resp.http_status, "ok", body, r->resp.length, nts_free,
                             "application/octet-stream", NULL, 0, extra);
    }
    if (r->location[0] != '\0' && r->resp.ok) {
        const char* extra[] = {MHD_HTTP_HEADER_LOCATION, r->location, NULL};
        return reply_headers(c, r, (unsigned)r->resp.http_status, "ok", body, r->resp.length, nts_free,
                             "application/json", NULL, 0, extra);
    }
    return reply(c, r, (unsigned)r->resp.http_status, r->resp.code ? r->resp.code : "-", body, r->resp.length,
                 nts_free, "application/json", NULL, 0);
}

/* ------------------------------------------------------- memory budget */

/* Raise this request's reservation against --max-memory to `total` bytes:
 * 1, or 0 when the budget has no room now (the reservation is unchanged). */
static int budget_reserve(ntsd_server* s, ntsd_request* r, size_t total) {
    int ok = 1;
    if (total <= r->reserved) return 1;
    pthread_mutex_lock(&s->lock);
    if (total - r->reserved > s->config.max_memory - s->memory_in_use) {
        ok = 0;
        s->memory_refused++;
    } else {
        s->memory_in_use += total - r->reserved;
        r->reserved = total;
    }
    pthread_mutex_unlock(&s->lock);
    return ok;
}

static void budget_release(ntsd_server* s, ntsd_request* r) {
    if (r->reserved == 0) return;
    pthread_mutex_lock(&s->lock);
    s->memory_in_use -= r->reserved;
    pthread_mutex_unlock(&s->lock);
    r->reserved = 0;
}

/* 413 when the request alone needs more than the budget (it never fits),
 * 503 with Retry-After when others hold the room now. */
static enum MHD_Result reply_over_budget(struct MHD_Connection* c, ntsd_request* r, size_t need, int close) {
    char msg[200];
    r->refusal = "max_memory";
    if (need > r->server->config.max_memory) {
        snprintf(msg, sizeof msg, "this request would need about %zu bytes at its peak, more than --max-memory = %zu",
                 need, r->server->config.max_memory);
        return reply_error(c, r, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE), msg, NULL, close);
    }
    snprintf(msg, sizeof msg, "the memory budget (--max-memory = %zu) is in use by other requests; retry later",
             r->server->config.max_memory);
    return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), msg, NULL, close);
}

/* The peak a request's work may need: the JSON tree and the scene, or a
 * binary step's positions (a copy), plus the body. */
static size_t work_estimate(const ntsd_request* r) {
    if (r->body.length == 0) return 0;
    if (r->binary_in) return 2 * r->body.length;
    return ntsj_memory_estimate(r->body.data, r->body.length);
}

/* POST /v1/contact and /v1/validate: the whole body is here. */
static enum MHD_Result collect_param(void* cls, enum MHD_ValueKind kind, const char* key, const char* value) {
    ntsd_request* r = cls;
    (void)kind;
    if (key == NULL || strcmp(key, "pretty") == 0) return MHD_YES;
    if (r->param_count == NTSD_MAX_QUERY_PARAMS) {
        r->too_many_params = 1;
        return MHD_NO;
    }
    r->param_names[r->param_count] = key;
    r->param_values[r->param_count] = value != NULL ? value : "";
    r->param_count++;
    return MHD_YES;
}

static enum MHD_Result answer_post(struct MHD_Connection* c, ntsd_request* r, route_work work) {
    ntsd_server* s = r->server;
    size_t need = work_estimate(r);
    if (!budget_reserve(s, r, need)) {
        ntsd_body_free(&r->body);
        return reply_over_budget(c, r, need, 0);
    }
    r->pretty = query_flag(c, "pretty");
    r->t_body = ntsd_now();
    if (r->route.body == NTSD_BODY_STEP) /* a step's query carries its options */
        MHD_get_connection_values(c, MHD_GET_ARGUMENT_KIND, collect_param, r);
    evaluate(r, work);
    return reply_evaluated(c, r);
}

/* The body routes' handlers (NTSD_ROUTE_MAP), once the body is in. */
static enum MHD_Result answer_contact(struct MHD_Connection* c, ntsd_request* r) {
    return answer_post(c, r, work_contact);
}
static enum MHD_Result answer_validate(struct MHD_Connection* c, ntsd_request* r) {
    return answer_post(c, r, work_validate);
}
static enum MHD_Result answer_create(struct MHD_Connection* c, ntsd_request* r) {
    return answer_post(c, r, work_create);
}
static enum MHD_Result answer_step(struct MHD_Connection* c, ntsd_request* r) { return answer_post(c, r, work_step); }

/* Each route's handler, by kind, from NTSD_ROUTE_MAP (routes.h). */
typedef enum MHD_Result (*route_handler)(struct MHD_Connection* c, ntsd_request* r);
#define ROUTE_HANDLER_(id, pattern, methods, param, body, auth, handler, label, evaluates) handler,
static const route_handler route_handlers[NTSD_ROUTE_KINDS] = {NULL, NTSD_ROUTE_MAP(ROUTE_HANDLER_)};
#undef ROUTE_HANDLER_

/* ------------------------------------------------------------- callbacks */

/* The request is one whose route reads a body (the table's body column; such
 * routes take POST only), with an allowed method. */
static int is_post_route(const ntsd_request* r) {
    return r->route.method_ok && r->route.body != NTSD_BODY_NONE;
}

/* Accept names application/octet-stream (a session step's binary answer). */
static int accepts_octet_stream(const char* accept) {
    const char* p;
    if (accept == NULL) return 0;
    for (p = accept; *p; ++p)
        if (strncasecmp(p, "application/octet-stream", 24) == 0) return 1;
    return 0;
}

/* 401 with the scheme the client must use (RFC 6750). */
static enum MHD_Result reply_unauthorized(struct MHD_Connection* c, ntsd_request* r, int close) {
    static const char msg[] = "this service needs Authorization: Bearer <token> (--token-file)";
    const char* extra[] = {MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer realm=\"ntscontactd\"", NULL};
    char* doc = ntsj_error_document(ntsj_code_name(NTSJ_UNAUTHORIZED), msg, "");
    if (doc == NULL) return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "out of memory", NULL, 1);
    return reply_headers(c, r, MHD_HTTP_UNAUTHORIZED, ntsj_code_name(NTSJ_UNAUTHORIZED), doc, strlen(doc), nts_free,
                         "application/json", NULL, close, extra);
}

/* A CORS preflight (OPTIONS) from an allowed Origin (first_call refused any
 * other): 204 with the route's methods and the request headers the service
 * reads from a browser. No token needed (a browser sends none with it) and
 * nothing looked up: it says what the route table says. */
static enum MHD_Result answer_preflight(struct MHD_Connection* c, ntsd_request* r) {
    const char* extra[] = {MHD_HTTP_HEADER_ACCESS_CONTROL_ALLOW_METHODS, r->route.methods,
                           "Access-Control-Allow-Headers", "Authorization, Content-Type, Accept",
                           "Access-Control-Max-Age", "600", NULL};
    if (r->route.kind == NTSD_ROUTE_NONE)
        return reply_error(c, r, ntsj_code_name(NTSJ_NOT_FOUND), "no such resource", NULL, 0);
    return reply_headers(c, r, MHD_HTTP_NO_CONTENT, "ok", (char*)"", 0, NULL, NULL, r->route.allow, 0, extra);
}

/* The answers that need no body. Sent from the first call only when the request
 * carries a body (libmicrohttpd then closes the connection rather than read
 * it); otherwise from the last call, so the connection stays alive. */
static enum MHD_Result answer_bodiless(struct MHD_Connection* c, ntsd_request* r) {
    if (r->preflight) return answer_preflight(c, r);
    if (!r->authorized && r->route.auth != NTSD_AUTH_OPEN) return reply_unauthorized(c, r, 0);
    if (r->route.kind == NTSD_ROUTE_NONE)
        return reply_error(c, r, ntsj_code_name(NTSJ_NOT_FOUND), "no such resource", NULL, 0);
    if (!r->route.method_ok) {
        char msg[96];
        snprintf(msg, sizeof msg, "method not allowed; allowed: %s", r->route.allow);
        return reply_error(c, r, ntsj_code_name(NTSJ_METHOD_NOT_ALLOWED), msg, r->route.allow, 0);
    }
    return route_handlers[r->route.kind](c, r);
}

/* The Host header names one of --allow-host (the port aside): a page whose
 * name was rebound to this machine's address (DNS rebinding) names its own. */
static int host_allowed(const ntsd_config* cfg, const char* host) {
    size_t n;
    int i;
    if (host == NULL) return 0;
    n = host[0] == '[' ? strcspn(host, "]") + 1 : strcspn(host, ":");
    for (i = 0; i < cfg->allow_host_count; ++i)
        if (strlen(cfg->allow_host[i]) == n && strncasecmp(host, cfg->allow_host[i], n) == 0) return 1;
    return 0;
}

/* The headers a request may give once: libmicrohttpd keeps every copy and
 * its lookup gives the first, where a proxy in front may take another. */
static const char* const once_headers[] = {MHD_HTTP_HEADER_AUTHORIZATION, MHD_HTTP_HEADER_HOST, "Origin",
                                           MHD_HTTP_HEADER_CONTENT_LENGTH, MHD_HTTP_HEADER_TRANSFER_ENCODING};
#define NTSD_ONCE_HEADERS (sizeof once_headers / sizeof once_headers[0])

typedef struct header_scan {
    int bad_name;          /* a name that is not a token */
    const char* twice;     /* the first of once_headers given twice, or NULL */
    int seen[NTSD_ONCE_HEADERS];
} header_scan;

/* tchar of RFC 9110 5.6.2: what a header's name is made of. */
static int is_token_char(unsigned char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
           (ch != '\0' && strchr("!#$%&'*+-.^_`|~", ch) != NULL);
}

static enum MHD_Result scan_header(void* cls, enum MHD_ValueKind kind, const char* key, const char* value) {
    header_scan* h = cls;
    const char* k = key != NULL ? key : "";
    size_t i;
    (void)kind;
    (void)value;
    if (*k == '\0') h->bad_name = 1;
    for (; *k != '\0'; ++k)
        if (!is_token_char((unsigned char)*k)) h->bad_name = 1;
    for (i = 0; key != NULL && i < NTSD_ONCE_HEADERS; ++i)
        if (strcasecmp(key, once_headers[i]) == 0 && h->seen[i]++ == 1 && h->twice == NULL) h->twice = once_headers[i];
    return MHD_YES;
}

/* Headers that two parsers may read two ways (request smuggling, RFC 9112
 * 6.1, 6.3 and 5.1): one 400 and a close, or MHD_YES to go on. libmicrohttpd
 * 0.9.75 keeps a name with a space before its colon as a name of its own
 * (`Transfer-Encoding : chunked` was no framing: the chunks were read as the
 * next request), and reads a Transfer-Encoding other than `chunked` as a body
 * that lasts until the connection closes (the request hung until --timeout). */
static int refuse_framing(struct MHD_Connection* c, ntsd_request* r, const char* cl, const char* te,
                          enum MHD_Result* answer) {
    header_scan h;
    char msg[200];
    memset(&h, 0, sizeof h);
    MHD_get_connection_values(c, MHD_HEADER_KIND, scan_header, &h);
    if (h.bad_name)
        snprintf(msg, sizeof msg, "a header name with whitespace or a character outside RFC 9110's token "
                                  "(a space before the colon?)");
    else if (h.twice != NULL)
        snprintf(msg, sizeof msg, "the %s header is given twice: Authorization, Host, Origin, Content-Length "
                                  "and Transfer-Encoding may come once each", h.twice);
    else if (te != NULL && r->http10)
        snprintf(msg, sizeof msg, "Transfer-Encoding in an HTTP/1.0 request: the framing is faulty");
    else if (te != NULL && strcasecmp(te, "chunked") != 0)
        snprintf(msg, sizeof msg, "Transfer-Encoding other than chunked alone: the body's length cannot be known");
    else if (cl != NULL && te != NULL)
        /* libmicrohttpd 0.9.75 takes the chunks */
        snprintf(msg, sizeof msg, "Content-Length and Transfer-Encoding together: ambiguous framing");
    else
        return 0;
    r->refusal = h.bad_name || h.twice != NULL ? "bad_header" : "bad_framing";
    *answer = reply_error(c, r, ntsj_code_name(NTSJ_BAD_REQUEST), msg, NULL, 1);
    return 1;
}

static enum MHD_Result first_call(ntsd_server* s, struct MHD_Connection* c, ntsd_request* r) {
    const char* ct = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
    const char* cl = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    const char* te = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_TRANSFER_ENCODING);
    /* libmicrohttpd has checked the Content-Length syntax already. */
    unsigned long long length = cl != NULL ? strtoull(cl, NULL, 10) : 0;
    int has_body = length > 0 || te != NULL;
    int shutting;
    const char* refused;

    pthread_mutex_lock(&s->lock);
    shutting = s->shutting_down;
    refused = r->link != NULL ? r->link->refused : NULL;
    pthread_mutex_unlock(&s->lock);

    if (shutting) {
        r->refusal = "shutting_down";
        return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED), "the server is shutting down", NULL, 1);
    }
    if (refused != NULL) { /* no room when it opened, and nothing slower to cut (watch.c) */
        r->refusal = refused;
        return reply_error(c, r, ntsj_code_name(NTSJ_OVERLOADED),
                           strcmp(refused, "max_per_client") == 0
                               ? "too many connections from this address (--max-per-client); retry later"
                               : "too many connections (--max-connections); retry later",
                           NULL, 1);
    }
    {
        enum MHD_Result answer;
        if (refuse_framing(c, r, cl, te, &answer)) return answer;
    }
    if (s->config.allow_host_count > 0 && !host_allowed(&s->config, MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST))) {
        r->refusal = "forbidden";
        return reply_error(c, r, ntsj_code_name(NTSJ_FORBIDDEN),
                           "this Host is not one of the service's names (--allow-host)", NULL, 1);
    }
    {
        /* A web page in a browser sends its Origin: refused unless named. */
        const char* origin = MHD_lookup_connection_value(c, MHD_HEADER_KIND, "Origin");
        int i, allowed = origin == NULL;
        for (i = 0; !allowed && i < s->config.allow_origin_count; ++i)
            allowed = strcmp(origin, s->config.allow_origin[i]) == 0;
        if (!allowed)
            return reply_error(c, r, ntsj_code_name(NTSJ_FORBIDDEN),
                               "requests from a web page of this Origin are refused (--allow-origin)", NULL, 1);
        if (origin != NULL) copy_str(r->origin, sizeof r->origin, origin);
        if (strcmp(r->method, "OPTIONS") == 0) {
            /* A CORS preflight: answered for an allowed Origin only, no token. */
            if (origin == NULL)
                return reply_error(c, r, ntsj_code_name(NTSJ_FORBIDDEN),
                                   "OPTIONS answers the CORS preflight of a web page whose Origin --allow-origin "
                                   "names", NULL, 1);
            r->preflight = 1;
            return has_body ? answer_bodiless(c, r) : MHD_YES;
        }
        int token = -1;
        pthread_rwlock_rdlock(&s->tokens_lock); /* SIGHUP may swap the list */
        r->authorized = ntsd_authorized(
            &s->config, MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION), &token);
        ntsd_client_key(&s->config, r->peer, MHD_lookup_connection_value(c, MHD_HEADER_KIND, "X-Forwarded-For"),
                        token, r->client);
        pthread_rwlock_unlock(&s->tokens_lock);
        if (!r->authorized && r->route.auth != NTSD_AUTH_OPEN && (has_body || is_post_route(r)))
            return reply_unauthorized(c, r, 1);
    }
    if (!is_post_route(r)) return has_body ? answer_bodiless(c, r) : MHD_YES;

    if (r->route.kind == NTSD_ROUTE_SCENES && s->config.session_id_header[0] != '\0') {
        /* Behind a proxy that routes sessions by id (deploy/nginx.conf): the
         * proxy names the new session, so that its steps hash where it lives. */
        const char* given = MHD_lookup_connection_value(c, MHD_HEADER_KIND, s->config.session_id_header);
        if (given != NULL && ntsd_is_session_id(given, strlen(given))) copy_str(r->given_id, sizeof r->given_id, given);
    }
    if (r->route.body == NTSD_BODY_STEP) {
        /* A step: JSON positions, raw float64 positions, or nothing at all. */
        const char* accept = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT);
        r->answer_binary = accepts_octet_stream(accept);
        if (ct != NULL && ntsd_is_media_type(ct, "application/octet-stream"))
            r->binary_in = 1;
        else if (has_body && !ntsd_is_json_media_type(ct))
            return reply_error(c, r, ntsj_code_name(NTSJ_UNSUPPORTED_MEDIA_TYPE),
                               "a step's body must be application/json or application/octet-stream", NULL, 1);
    } else if (ct == NULL || !ntsd_is_json_media_type(ct)) {
        /* No Content-Type is not JSON: a browser's plain form post must not
         * reach the service (docs/reliability.md). */
        return reply_error(c, r, ntsj_code_name(NTSJ_UNSUPPORTED_MEDIA_TYPE),
                           "the request body must be Content-Type: application/json", NULL, 1);
    }
    /* Answer before reading the body when its announced length is too large. */
    if (length > (unsigned long long)s->config.codec.max_bytes)
        return reply_error(c, r, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE),
                           "the request body is larger than --max-bytes", NULL, 1);
    /* A body that can never fit the budget is refused before it is read. One
     * that may is counted against --max-memory as its bytes arrive, not as
     * announced: sockets announcing large bodies and sending nothing hold
     * nothing (issue 23). */
    if (length > (unsigned long long)s->config.max_memory) return reply_over_budget(c, r, (size_t)length, 1);
    ntsd_body_expect(&r->body, (size_t)length);
    if (has_body) ntsd_conn_enter(s, r->link, NTSD_CONN_RECEIVING);
    return MHD_YES;
}

static enum MHD_Result on_request(void* cls, struct MHD_Connection* c, const char* url, const char* method,
                                  const char* version, const char* upload_data, size_t* upload_data_size,
                                  void** con_cls) {
    ntsd_server* s = cls;
    ntsd_request* r = *con_cls;

    if (r == NULL) {
        r = calloc(1, sizeof *r);
        if (r == NULL) return MHD_NO;
        r->server = s;
        r->t0 = ntsd_now();
        r->deadline = r->t0 + (double)s->config.timeout_s;
        ntsd_body_init(&r->body, s->config.codec.max_bytes);
        copy_str(r->method, sizeof r->method, method);
        copy_str(r->path, sizeof r->path, url);
        r->http10 = version != NULL && strcmp(version, MHD_HTTP_VERSION_1_0) == 0;
        peer_name(c, r->peer, sizeof r->peer);
        r->route = ntsd_route_find(url, method);
        {
            const union MHD_ConnectionInfo* ci = MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
            r->link = ci != NULL ? ci->socket_context : NULL;
            ntsd_conn_enter(s, r->link, NTSD_CONN_WORKING);
        }
        *con_cls = r;
        pthread_mutex_lock(&s->lock);
        s->in_flight++;
        pthread_mutex_unlock(&s->lock);
        return first_call(s, c, r);
    }

    if (*upload_data_size > 0) {
        size_t n = *upload_data_size;
        *upload_data_size = 0;
        r->received += n;
        if (r->queued) return MHD_YES; /* answered early: drop the rest */
        if (ntsd_now() > r->deadline) {
            /* A client trickling its body: cut it off (the idle timeout alone
             * would let one byte every few seconds hold the connection). */
            copy_str(r->code, sizeof r->code, "upload_timeout");
            return MHD_NO;
        }
        if (r->too_large || !is_post_route(r)) return MHD_YES;
        if (r->over_budget) return MHD_YES;
        switch (ntsd_body_append(&r->body, upload_data, n)) {
        case 0:
            if (!budget_reserve(s, r, r->body.capacity)) { /* the bytes held, as they grow */
                r->over_budget = 1;
                ntsd_body_free(&r->body);
            }
            return MHD_YES;
        case 1: /* chunked or unannounced: the cap is found while reading */
            r->too_large = 1;
            ntsd_body_free(&r->body);
            return MHD_YES;
        default:
            ntsd_body_free(&r->body);
            copy_str(r->code, sizeof r->code, nts_status_name(NTS_ENOMEM));
            return MHD_NO;
        }
    }

    if (r->queued) return MHD_YES;
    ntsd_conn_enter(s, r->link, NTSD_CONN_WORKING);
    if (!is_post_route(r)) return answer_bodiless(c, r);
    if (r->too_large)
        return reply_error(c, r, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE),
                           "the request body is larger than --max-bytes", NULL, 1);
    if (r->over_budget) return reply_over_budget(c, r, r->received, 1);
    return route_handlers[r->route.kind](c, r);
}

static const char* termination_name(enum MHD_RequestTerminationCode toe) {
    switch (toe) {
    case MHD_REQUEST_TERMINATED_COMPLETED_OK: return "completed";
    case MHD_REQUEST_TERMINATED_WITH_ERROR: return "error";
    case MHD_REQUEST_TERMINATED_TIMEOUT_REACHED: return ntsj_code_name(NTSJ_TIMEOUT);
    case MHD_REQUEST_TERMINATED_DAEMON_SHUTDOWN: return "daemon_shutdown";
    case MHD_REQUEST_TERMINATED_READ_ERROR: return "read_error";
    case MHD_REQUEST_TERMINATED_CLIENT_ABORT: return "client_abort";
    default: return "aborted";
    }
}

/* The reason a request counts as refused by the service (not a fault of its
 * scene): the limits, access control, the budgets; NULL otherwise. */
static const char* refusal_of(const ntsd_request* r, int ok) {
    if (!ok) /* (a connection the watcher cut is counted there) */
        return r->cut_by_watcher ? NULL
               : strcmp(r->code, "upload_timeout") == 0 || strcmp(r->code, "client_left") == 0 ? r->code : NULL;
    if (r->refusal != NULL) return r->refusal;
    switch (r->status) {
    case MHD_HTTP_UNAUTHORIZED:
    case MHD_HTTP_FORBIDDEN:
    case MHD_HTTP_CONTENT_TOO_LARGE:
    case MHD_HTTP_UNSUPPORTED_MEDIA_TYPE:
    case MHD_HTTP_SERVICE_UNAVAILABLE: return r->code;
    case MHD_HTTP_BAD_REQUEST: return strcmp(r->code, "limit_exceeded") == 0 || strcmp(r->code, "too_deep") == 0 ? r->code : NULL;
    default: return NULL;
    }
}

/* The path as the logs show it: what follows "/scenes/" is a session id
 * and becomes its tag, "/v1/scenes/~1a2b3c4d/contact" (ntsd_session_tag):
 * the id is the session's only key, and logs travel further than the
 * service. Every segment after it but "contact" is tagged, so that a
 * mistyped path ("/v1/scenes//ID", "/v1/scenes/ID/contacts") shows no id
 * either. */
static const char* logged_path(const char* path, char* out, size_t cap) {
    const char* at = strstr(path, "/scenes/");
    size_t k;
    if (at == NULL) return path;
    at += 8;
    k = (size_t)snprintf(out, cap, "%.*s", (int)(at - path), path);
    while (*at != '\0' && k < cap) {
        size_t n = strcspn(at, "/");
        if (n == 0 || (n == 7 && strncmp(at, "contact", 7) == 0)) {
            k += (size_t)snprintf(out + k, cap - k, "%.*s", (int)n, at);
        } else {
            char tag[NTSD_SESSION_TAG_LEN + 1];
            ntsd_session_tag(at, n, tag);
            k += (size_t)snprintf(out + k, cap - k, "%s", tag);
        }
        at += n;
        if (*at == '/' && k < cap) {
            k += (size_t)snprintf(out + k, cap - k, "/");
            at++;
        }
    }
    return out;
}

static void on_completed(void* cls, struct MHD_Connection* c, void** con_cls, enum MHD_RequestTerminationCode toe) {
    ntsd_server* s = cls;
    ntsd_request* r = *con_cls;
    int ok = toe == MHD_REQUEST_TERMINATED_COMPLETED_OK && r != NULL && r->queued;
    double t_end = ntsd_now();
    char path[2 * sizeof r->path]; /* logged_path: a tag may be longer than a short segment */
    (void)c;
    if (r == NULL) return;
    ntsd_conn_enter(s, r->link, NTSD_CONN_WAITING);
    if (!ok && r->link != NULL) { /* cut by the watcher (a deadline, or room made): say why */
        pthread_mutex_lock(&s->lock);
        if (r->link->cut != NULL) {
            r->cut_by_watcher = 1;
            if (r->code[0] == '\0') copy_str(r->code, sizeof r->code, r->link->cut);
        }
        pthread_mutex_unlock(&s->lock);
    }
    if (r->resp.code != NULL && strcmp(r->resp.code, nts_status_name(NTS_ECANCELLED)) == 0 && r->link != NULL &&
        ntsd_conn_client_left(r->link)) {
        copy_str(r->code, sizeof r->code, "client_left");
        pthread_mutex_lock(&s->lock);
        s->client_left++;
        pthread_mutex_unlock(&s->lock);
    }
    ntsd_log_request(r->peer, r->method, logged_path(r->path, path, sizeof path), ok ? r->status : 0,
                     ok || r->code[0] ? r->code : termination_name(toe), r->received,
                     ok ? r->bytes_out : 0, 1e3 * (t_end - r->t0));
    pthread_mutex_lock(&s->lock);
    s->in_flight--;
    ntsd_metrics_request(&s->metrics, r->route.kind, ok ? r->status : 0, t_end - r->t0, refusal_of(r, ok));
    if (ok && r->resp.ok && r->route.evaluates) {
        s->metrics.evaluations++;
        s->metrics.surface_nodes += (unsigned long long)r->resp.summary.surface_nodes;
        s->metrics.contacts += (unsigned long long)r->resp.summary.contacts;
    }
    if (ok) {
        s->served++;
        s->receiving_s += r->t_body - r->t0;
        s->handling_s += r->t_answer - r->t_body;
        s->sending_s += t_end - r->t_answer;
    }
    pthread_mutex_unlock(&s->lock);
    ntsd_body_free(&r->body);
    ntsj_response_free(&r->resp); /* evaluated, but the client left before the answer */
    budget_release(s, r);
    free(r);
    *con_cls = NULL;
}

static void on_connection(void* cls, struct MHD_Connection* c, void** socket_context,
                          enum MHD_ConnectionNotificationCode toe) {
    ntsd_server* s = cls;
    if (toe == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo* ci = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
        char addr[64];
        peer_name(c, addr, sizeof addr);
        *socket_context = ci != NULL ? ntsd_conn_open(s, ci->connect_fd, addr) : NULL;
    } else {
        ntsd_conn_close(s, *socket_context);
        *socket_context = NULL;
    }
}

/* ------------------------------------------------------------ start/stop */

/* The soft limit of open descriptors raised to `need` (within the hard
 * limit): a thread per connection, each with its socket. Said when short. */
static void ensure_descriptors(unsigned need) {
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur >= need) return;
    rl.rlim_cur = rl.rlim_max == RLIM_INFINITY || rl.rlim_max > need ? need : rl.rlim_max;
    if (setrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur < need)
        ntsd_log_message("open descriptors limited to %llu, fewer than the %u that --max-connections may use",
                         (unsigned long long)rl.rlim_cur, need);
}

/* A whole (PEM) file as a NUL-terminated string, or NULL. */
static char* read_file(const char* path) {
    FILE* f = fopen(path, "rb");
    char* buf = NULL;
    long n;
    if (f == NULL) return NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && n < (1L << 20) && fseek(f, 0, SEEK_SET) == 0 &&
        (buf = malloc((size_t)n + 1)) != NULL) {
        if (fread(buf, 1, (size_t)n, f) != (size_t)n) {
            free(buf);
            buf = NULL;
        } else {
            buf[n] = '\0';
        }
    }
    fclose(f);
    return buf;
}

/* Everything ntsd_server_start made, once libmicrohttpd is stopped (or never started). */
static void release(ntsd_server* s) {
    free(s->tls_key);
    free(s->tls_cert);
    s->tls_key = s->tls_cert = NULL;
    ntsd_watch_stop(s);
    ntsd_sessions_free(&s->sessions);
    pthread_cond_destroy(&s->changed);
    pthread_cond_destroy(&s->changed_large);
    pthread_mutex_destroy(&s->lock);
    pthread_rwlock_destroy(&s->tokens_lock);
    ntsd_free_tokens(&s->config);
}

int ntsd_server_start(ntsd_server* s, const ntsd_config* cfg) {
    struct MHD_OptionItem tls[3] = {{MHD_OPTION_END, 0, NULL}, {MHD_OPTION_END, 0, NULL}, {MHD_OPTION_END, 0, NULL}};
    struct sockaddr_storage addr;
    const union MHD_DaemonInfo* info;
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_ITC | MHD_USE_ERROR_LOG;
    unsigned hard_limit;

    memset(s, 0, sizeof *s);
    s->config = *cfg;
    memset(&addr, 0, sizeof addr);
    if (strchr(cfg->host, ':') != NULL) {
        struct sockaddr_in6* a6 = (struct sockaddr_in6*)(void*)&addr;
        a6->sin6_family = AF_INET6;
        a6->sin6_port = htons((unsigned short)cfg->port);
        if (inet_pton(AF_INET6, cfg->host, &a6->sin6_addr) != 1) goto bad_host;
        flags |= MHD_USE_IPv6;
    } else {
        struct sockaddr_in* a4 = (struct sockaddr_in*)(void*)&addr;
        a4->sin_family = AF_INET;
        a4->sin_port = htons((unsigned short)cfg->port);
        if (inet_pton(AF_INET, cfg->host, &a4->sin_addr) != 1) goto bad_host;
    }
    /* A thread per connection, evaluations gated to --threads: measured against
     * libmicrohttpd's thread pool, which let a large evaluation stall the other
     * connections (docs/benchmarks.md, "Server"). */
    flags |= MHD_USE_THREAD_PER_CONNECTION | MHD_USE_POLL;

    /* Room above --max-connections: a connection cut to make room (watch.c)
     * stays libmicrohttpd's until its thread sees the end of the stream, and
     * under clients reopening every cut connection on a busy machine those
     * pile up; a new connection must still be taken (and served, or cut, or
     * answered 503), never closed at accept. The descriptors are there too. */
    hard_limit = 2 * cfg->max_connections + 64;
    ensure_descriptors(hard_limit + 64);

    /* The default quota: a quarter of the store (four clients at their quota
     * fill it), but at least 4, so that a small store does not hold one
     * client's solver loop to a session or two; never above the store. */
    if (s->config.max_sessions_per_client <= 0)
        s->config.max_sessions_per_client = cfg->max_sessions / 4 > 4 ? cfg->max_sessions / 4 : 4;
    if (s->config.max_sessions_per_client > cfg->max_sessions) s->config.max_sessions_per_client = cfg->max_sessions;
    if (ntsd_sessions_init(&s->sessions, cfg->max_sessions, s->config.max_sessions_per_client, cfg->session_ttl_s,
                           cfg->session_memory) != 0) {
        ntsd_log_message("cannot allocate the session table");
        ntsd_free_tokens(&s->config);
        return -1;
    }
    pthread_mutex_init(&s->lock, NULL);
    pthread_cond_init(&s->changed, NULL);
    pthread_cond_init(&s->changed_large, NULL);
    pthread_rwlock_init(&s->tokens_lock, NULL);
    if (ntsd_watch_start(s) != 0) {
        ntsd_log_message("cannot start the connection watcher");
        ntsd_sessions_free(&s->sessions);
        pthread_cond_destroy(&s->changed);
        pthread_cond_destroy(&s->changed_large);
        pthread_mutex_destroy(&s->lock);
        pthread_rwlock_destroy(&s->tokens_lock);
        ntsd_free_tokens(&s->config);
        return -1;
    }
    s->started = ntsd_now();
    if (cfg->tls_cert[0] != '\0') {
        s->tls_cert = read_file(cfg->tls_cert);
        s->tls_key = read_file(cfg->tls_key);
        if (s->tls_cert == NULL || s->tls_key == NULL) {
            ntsd_log_message("cannot read --tls-cert %s or --tls-key %s", cfg->tls_cert, cfg->tls_key);
            release(s);
            return -1;
        }
        flags |= MHD_USE_TLS;
        tls[0].option = MHD_OPTION_HTTPS_MEM_KEY;
        tls[0].ptr_value = s->tls_key;
        tls[1].option = MHD_OPTION_HTTPS_MEM_CERT;
        tls[1].ptr_value = s->tls_cert;
    }
    s->daemon = MHD_start_daemon(
        flags, (uint16_t)cfg->port, NULL, NULL, on_request, s,
        MHD_OPTION_EXTERNAL_LOGGER, ntsd_log_mhd, NULL,
        MHD_OPTION_SOCK_ADDR, (struct sockaddr*)&addr,
        MHD_OPTION_CONNECTION_TIMEOUT, (unsigned int)cfg->timeout_s,
        MHD_OPTION_CONNECTION_LIMIT, hard_limit,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)128 * 1024,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, s,
        MHD_OPTION_NOTIFY_CONNECTION, on_connection, s,
        /* HTTPS through libmicrohttpd's GnuTLS (a key and a certificate, or nothing) */
        MHD_OPTION_ARRAY, tls,
        MHD_OPTION_END);
    if (s->daemon == NULL) {
        ntsd_log_message("cannot listen on %s port %u", cfg->host, cfg->port);
        release(s);
        return -1;
    }
    info = MHD_get_daemon_info(s->daemon, MHD_DAEMON_INFO_BIND_PORT);
    s->port = info != NULL ? info->port : cfg->port;
    return 0;
bad_host:
    ntsd_log_message("--host: not a numeric IPv4 or IPv6 address: %s", cfg->host);
    ntsd_free_tokens(&s->config);
    return -1;
}

void ntsd_server_quiesce(ntsd_server* s) {
    MHD_socket fd;
    pthread_mutex_lock(&s->lock);
    s->shutting_down = 1;
    pthread_mutex_unlock(&s->lock);
    fd = MHD_quiesce_daemon(s->daemon);
    if (fd != MHD_INVALID_SOCKET) close(fd);
}

ntsd_stats ntsd_server_stats(ntsd_server* s) {
    ntsd_stats st;
    pthread_mutex_lock(&s->lock);
    st.shutting_down = s->shutting_down;
    st.in_flight = s->in_flight;
    st.evaluating = s->evaluating;
    st.connections = s->live; /* open and not being cut: what the limits count */
    st.served = s->served;
    st.memory_in_use = s->memory_in_use;
    st.memory_refused = s->memory_refused;
    st.header_timeouts = s->header_timeouts;
    st.body_timeouts = s->body_timeouts;
    st.shed = s->shed;
    st.client_left = s->client_left;
    st.receiving_s = s->receiving_s;
    st.handling_s = s->handling_s;
    st.sending_s = s->sending_s;
    pthread_mutex_unlock(&s->lock);
    st.uptime_s = ntsd_now() - s->started;
    return st;
}

int ntsd_server_in_flight(ntsd_server* s) {
    int n;
    pthread_mutex_lock(&s->lock);
    n = s->in_flight;
    pthread_mutex_unlock(&s->lock);
    return n;
}

void ntsd_server_stop(ntsd_server* s) {
    MHD_stop_daemon(s->daemon);
    s->daemon = NULL;
    release(s);
}
