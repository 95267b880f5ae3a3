/* ntscontactd internals: the configuration from the command line, the daemon's
 * shared state and one request's state. One file per concept:
 *   args.c     command line          log.c     one line per request, the clock
 *   body.c     capped body buffer    routes.c  URL + method -> route (no state)
 *   routes.h   the routes table (NTSD_ROUTE_MAP), what all the rest route by
 *   health.c   GET /v1/health from a snapshot of the counters
 *   sessions.c the scene-session store (ids, LRU, TTL, memory budget)
 *   server.c   libmicrohttpd callbacks, counters, start/stop
 *   watch.c    open connections: the header deadline, clients that left
 *   metrics.c  GET /metrics (Prometheus text format)
 *   auth.c     bearer tokens
 *   main.c     signals and lifetime
 * A thread per connection, evaluations gated to --threads; why (against
 * libmicrohttpd's thread pool, removed in 0.2): docs/benchmarks.md, "Server". */
#ifndef NTSD_SERVER_H
#define NTSD_SERVER_H

#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <sys/socket.h>

#include <microhttpd.h>

#include <ntscontact/codec.h>

#include "routes.h"

/* ------------------------------------------------------------------ args */

#define NTSD_ALLOW_MAX 8 /* names in each allow-list (--allow-origin, --allow-host) */

typedef struct ntsd_config {
    char host[64];           /* numeric IPv4 or IPv6 address */
    unsigned port;           /* 0: any free port (printed on stdout) */
    int threads;             /* evaluations at once; default: online cores */

    unsigned timeout_s;      /* idle connection timeout and body upload budget; default 30 */
    unsigned max_connections;/* default 256 */
    int quiet;
    unsigned drain_seconds;  /* a terminating signal waits at most this long for the requests in flight */
    unsigned max_per_client; /* connections from one address at once; beyond -> refused */
    unsigned header_seconds; /* to send a request's headers, however slowly; 0 = no limit; default 10 */
    size_t max_memory;       /* bodies in flight plus the estimated peak of the work they start
                                (ntsj_memory_estimate); default half the machine's (or cgroup's) memory */
    char log_file[512];      /* "" = standard error; SIGHUP reopens it */
    int log_json;            /* --log-format json: one JSON object a line */
    /* Access control (args.c loads them): bearer tokens from --token-file (none:
     * no authentication), the Origins a browser may post from, TLS files. */
    char token_file[512];
    char** tokens;
    int token_count;
    char allow_origin[NTSD_ALLOW_MAX][256];
    int allow_origin_count;
    char allow_host[NTSD_ALLOW_MAX][256]; /* --allow-host: the names a request's Host may give (none: any) */
    int allow_host_count;
    char session_id_header[64]; /* --session-id-header: a proxy's id for a new session ("" none) */
    /* --trusted-proxy: numeric addresses of the proxies in front (deploy/nginx.conf).
     * A request from one of them is the client's that X-Forwarded-For names last. */
    char trusted_proxy[NTSD_ALLOW_MAX][64];
    int trusted_proxy_count;
    char tls_cert[512], tls_key[512];
    /* What every request hands to the codec: max_bytes (--max-bytes, also the
     * cap of a body in flight), max_depth, limits, max_seconds. */
    ntsj_config codec;
    /* Scene sessions (sessions.c). */
    int max_sessions;        /* default 64 */
    int max_sessions_per_client; /* held by one client (ntsd_client_key); 0 until resolved
                                    (ntsd_server_start): max(4, max_sessions / 4), at most max_sessions */
    unsigned session_ttl_s;  /* since last use; default 600 */
    size_t session_memory;   /* all sessions together; default 1 GiB */
} ntsd_config;

ntsd_config ntsd_default_config(void);
size_t ntsd_default_max_memory(void);
/* 0 on success, 1 when the program should exit 0 (--help, --version), -1 on a
 * usage error (message printed). */
int ntsd_parse_args(int argc, char** argv, ntsd_config* cfg);

/* ------------------------------------------------------------------ body */

/* A request body accumulated in pieces, never beyond `max` bytes. */
typedef struct ntsd_body {
    char* data;   /* NUL-terminated when not NULL */
    size_t length, capacity, max;
    size_t expected; /* an announced Content-Length (0: none): the buffer grows no further */
} ntsd_body;

void ntsd_body_init(ntsd_body* b, size_t max);
/* An announced Content-Length: the buffer grows to it as bytes arrive, no further. */
void ntsd_body_expect(ntsd_body* b, size_t expected);
/* 0, -1 (no memory) or 1 (the body would exceed `max`; nothing appended). */
int ntsd_body_append(ntsd_body* b, const char* data, size_t size);
void ntsd_body_free(ntsd_body* b);

/* ------------------------------------------------------------------- log */

void ntsd_log_set_quiet(int quiet);
/* One JSON object a line (--log-format json) instead of text. */
void ntsd_log_set_json(int json);
#if defined(__GNUC__)
#define NTSD_PRINTF_LIKE __attribute__((format(printf, 1, 2)))
#else
#define NTSD_PRINTF_LIKE
#endif
/* Send the log lines to `path` (append), again after a rotation. 0 or -1. */
int ntsd_log_reopen(const char* path);
/* A line "ntscontactd: ..." for a fault: printed even when quiet. */
void ntsd_log_message(const char* fmt, ...) NTSD_PRINTF_LIKE;
/* A line "ntscontactd: ..." about the daemon's life: silent when quiet. */
void ntsd_log_info(const char* fmt, ...) NTSD_PRINTF_LIKE;
/* One line per request: method, path, status, code, bytes in/out, milliseconds. */
void ntsd_log_request(const char* peer, const char* method, const char* path, int status,
                      const char* code, size_t bytes_in, size_t bytes_out, double ms);
/* Monotonic seconds, for timings and deadlines. */
double ntsd_now(void);
/* libmicrohttpd's own diagnostics (MHD_OPTION_EXTERNAL_LOGGER). */
void ntsd_log_mhd(void* cls, const char* fmt, va_list ap);

/* -------------------------------------------------------------- sessions */

#define NTSD_CLIENT_LEN 80 /* who a client is: ntsd_client_key (auth.c) */
#define NTSD_SESSION_ID_LEN 43 /* the ids it makes: 256 random bits in base64url */
/* An id given by a proxy in --session-id-header (nginx's $request_id: 128
 * random bits in hex) may be 32 to 64 URL-safe characters. */
#define NTSD_SESSION_ID_MIN 32
#define NTSD_SESSION_ID_MAX 64

/* A client's part of the store: what it holds, for its quota and for the
 * choice of whom a full store takes from. */
typedef struct ntsd_session_client {
    char key[NTSD_CLIENT_LEN];  /* ntsd_client_key */
    int count;                   /* sessions it holds */
    size_t memory;               /* their memory */
    struct ntsd_session_entry *head, *tail; /* its sessions, most recently used first */
    struct ntsd_session_entry* pick;        /* scratch of make_room: the one it would give */
    struct ntsd_session_client* next;
} ntsd_session_client;

typedef struct ntsd_session_entry {
    char id[NTSD_SESSION_ID_MAX + 1];
    char owner[NTSD_CLIENT_LEN]; /* its creator's ntsd_client_key: for anyone else it does not exist */
    ntsd_session_client* client;  /* the owner's counts, while linked */
    ntsj_session* session;
    pthread_mutex_t step_lock; /* one step at a time */
    int users;                 /* requests holding it: never evicted or freed meanwhile */
    int doomed;                /* unlinked while in use: the last user frees it */
    int linked;
    struct ntsd_session_entry *cprev, *cnext; /* in its client's list, most recently used first */
    int cold;                  /* its context's buffers were given back since its last step */
    double created, last_used; /* monotonic seconds */
    size_t memory;             /* counted against --session-memory */
    size_t created_memory;     /* what it held when created (sessions.c, keep_limit) */
    int bodies, nodes, surface_nodes; /* fixed for the session's life */
    unsigned long long steps;  /* successful steps */
    struct ntsd_session_entry *prev, *next; /* LRU list, most recent first */
    struct ntsd_session_entry* hnext;       /* hash chain */
} ntsd_session_entry;

typedef struct ntsd_sessions {
    pthread_mutex_t lock;
    ntsd_session_entry** buckets;
    unsigned bucket_count;     /* a power of two */
    ntsd_session_entry *head, *tail;
    ntsd_session_client* clients; /* those holding a session */
    int count, max, max_per_client, client_count;
    unsigned ttl_s;
    size_t memory, memory_max;
    unsigned long long created, evicted, expired, deleted;
    unsigned long long evicted_own; /* of the evicted: the client's own, for its new one (quota, or it held the most) */
    unsigned long long refused;     /* creations refused: no idle session could fairly make room */
    unsigned long long trimmed;     /* idle sessions whose context buffers were given back for room */
} ntsd_sessions;

typedef struct ntsd_sessions_stats {
    int held, clients;
    size_t memory;
    unsigned long long created, evicted, expired, deleted, evicted_own, refused, trimmed;
} ntsd_sessions_stats;

/* NTSD_SESSIONS_QUOTA: the client holds --max-sessions-per-client sessions,
 * every one in use. */
enum { NTSD_SESSIONS_FULL = -1, NTSD_SESSIONS_TOO_LARGE = -2, NTSD_SESSIONS_QUOTA = -3 };

int ntsd_sessions_init(ntsd_sessions* st, int max, int max_per_client, unsigned ttl_s, size_t memory_max);
void ntsd_sessions_free(ntsd_sessions* st);
/* Take ownership of `session` for `client` (ntsd_client_key) under
 * `given_id` (a proxy's, already checked; NULL, or taken: a new random id):
 * 0, NTSD_SESSIONS_FULL or NTSD_SESSIONS_QUOTA (no idle session may make
 * room; the caller keeps `session`), or NTSD_SESSIONS_TOO_LARGE (it alone
 * exceeds --session-memory). Room is made fairly (sessions.c, make_room):
 * a client at its quota gives its own least recently used idle session; a
 * full store takes from the client holding the most. */
int ntsd_sessions_add(ntsd_sessions* st, ntsj_session* session, const char* client, const char* given_id,
                      char id_out[NTSD_SESSION_ID_MAX + 1]);
/* The session of `id` if `client` owns it, held until ntsd_sessions_release;
 * NULL otherwise (missing and foreign look the same). `use`: a step, which
 * makes the session the most recently used and restarts its idle time (at
 * the release too); 0 for a read of what the session holds (GET .../surface),
 * which, like GET /v1/scenes/{id}, keeps no session alive. */
ntsd_session_entry* ntsd_sessions_acquire(ntsd_sessions* st, const char* id, const char* client, int use);
/* What one step may add to a held session: --session-memory less what it
 * holds (at least 1; ntsj_config.step_memory). */
size_t ntsd_sessions_step_room(ntsd_sessions* st, const ntsd_session_entry* e);
/* After a step, under its step lock: the session holds `memory` now
 * (ntsj_session_get_info); `stepped`: it succeeded. 1 when the session must
 * give back its context's buffers: it holds more than it may keep after one
 * step (sessions.c, keep_limit), or the store is over --session-memory and
 * idle sessions' buffers, given back from the client holding the most, were
 * not enough. The caller then trims it (ntsj_session_trim) and calls again
 * with `last` set, which may evict. 0 otherwise. */
int ntsd_sessions_settle(ntsd_sessions* st, ntsd_session_entry* e, size_t memory, int stepped, int last);
void ntsd_sessions_release(ntsd_sessions* st, ntsd_session_entry* e, int use);
/* 0, or -1 when `client` has no such session. */
int ntsd_sessions_remove(ntsd_sessions* st, const char* id, const char* client);
void ntsd_sessions_sweep(ntsd_sessions* st); /* drop the expired ones */
ntsd_sessions_stats ntsd_sessions_get_stats(ntsd_sessions* st);
typedef struct ntsd_session_meta {
    int bodies, nodes, surface_nodes;
    unsigned long long steps;
    size_t memory_bytes;
    double expires_in_s, age_s, idle_s;
} ntsd_session_meta;
/* What GET /v1/scenes/{id} shows, without counting as a use: 0 or -1 (none, or not `client`'s). */
int ntsd_sessions_describe(ntsd_sessions* st, const char* id, const char* client, ntsd_session_meta* out);
/* What the logs show for a session id (n bytes): "~" and the first 8 hex
 * digits of the id's SHA-256 (tag.c). It says which lines are one session's,
 * and an operator given an id finds its lines (printf %s ID | sha256sum), but
 * it cannot be turned back into the id, the session's only key. */
#define NTSD_SESSION_TAG_LEN 9
void ntsd_session_tag(const char* id, size_t n, char out[NTSD_SESSION_TAG_LEN + 1]);

/* A route's kind: NONE (no route: 404), then one per row of NTSD_ROUTE_MAP
 * (routes.h), in its order; it indexes the metrics' counters. */
#define NTSD_ROUTE_ENUM_(id, pattern, methods, param, body, auth, handler, label, evaluates) NTSD_ROUTE_##id,
typedef enum ntsd_route_kind {
    NTSD_ROUTE_NONE = 0,
    NTSD_ROUTE_MAP(NTSD_ROUTE_ENUM_)
    NTSD_ROUTE_KINDS
} ntsd_route_kind;
#undef NTSD_ROUTE_ENUM_

/* ---------------------------------------------------------------- server */

/* The counters behind GET /metrics (metrics.c), guarded by the server's lock. */
#define NTSD_LATENCY_BUCKETS 14
#define NTSD_REFUSAL_KINDS 32
typedef struct ntsd_metrics {
    unsigned long long requests[NTSD_ROUTE_KINDS][500]; /* [route][status - 100] */
    unsigned long long latency[NTSD_ROUTE_KINDS][NTSD_LATENCY_BUCKETS + 1]; /* per bucket, not cumulative */
    double latency_sum[NTSD_ROUTE_KINDS];
    unsigned long long evaluations, surface_nodes, contacts;
    char refusal_names[NTSD_REFUSAL_KINDS][32];
    unsigned long long refusals[NTSD_REFUSAL_KINDS];
    int refusal_count;
} ntsd_metrics;

/* An open connection, as the watcher sees it (watch.c). */
typedef enum ntsd_conn_state {
    NTSD_CONN_WAITING = 0, /* a TLS handshake, a request's headers, or idle between requests */
    NTSD_CONN_RECEIVING,   /* a request's body */
    NTSD_CONN_WORKING      /* a request handled and answered */
} ntsd_conn_state;

typedef struct ntsd_conn {
    struct ntsd_conn *prev, *next;
    int fd;
    char addr[64];       /* the peer's numeric address */
    int limited;         /* counted against --max-per-client (not a --trusted-proxy) */
    int state;           /* ntsd_conn_state */
    double since;        /* monotonic: the state's start (opened, headers in, request ended) */
    double begun;        /* monotonic: its current request's start (opened, or the previous one ended) */
    unsigned requests;   /* requests it has completed */
    const char* cut;     /* shut down by the watcher: why (a refusal reason), or NULL */
    const char* refused; /* no room and nothing to shed: its request gets 503 (the reason), or NULL */
} ntsd_conn;
typedef struct ntsd_server {
    /* config.tokens and config.token_count belong to the server (freed at
     * stop) and change at SIGHUP: read them only under tokens_lock (read). */
    ntsd_config config;
    pthread_rwlock_t tokens_lock;
    struct MHD_Daemon* daemon;
    ntsd_sessions sessions;
    unsigned port;             /* the bound port */
    double started;            /* monotonic seconds */
    char* tls_key;             /* PEM text, kept while the daemon runs (HTTPS) */
    char* tls_cert;

    pthread_mutex_t lock;      /* guards everything below */
    pthread_cond_t changed;    /* an evaluation slot was freed (for a small request) */
    pthread_cond_t changed_large; /* a slot a large request may take was freed */
    int evaluating_large;      /* large evaluations running (<= threads - 1 when threads >= 2) */
    int waiting_small, waiting_large; /* requests waiting at the gate */
    int shutting_down;
    int in_flight;             /* requests between their first callback and completion */
    int evaluating;            /* evaluations running (<= config.threads) */
    unsigned long long served; /* requests answered completely */
    /* Seconds summed over the requests answered: from the headers to the whole
     * body (receiving), in the codec and the core (handling), from the queued
     * response to its last byte (sending). GET /v1/health reports them. */
    double receiving_s, handling_s, sending_s;
    /* The watcher (watch.c): the open connections and the header deadline. */
    ntsd_conn* conns;
    pthread_t watcher;
    pthread_cond_t watch_wake;
    int watching, watch_stop;
    unsigned live;                      /* connections open and not cut (watch.c) */
    unsigned long long header_timeouts; /* connections cut by --header-seconds */
    unsigned long long body_timeouts;   /* connections cut by --timeout while sending a body */
    unsigned long long shed;            /* connections cut to make room (the slowest first) */
    unsigned long long client_left;     /* evaluations stopped because their client left */
    ntsd_metrics metrics;
    size_t memory_in_use;               /* reserved against --max-memory */
    unsigned long long memory_refused;  /* requests refused for the budget (503) */
} ntsd_server;

/* The watcher thread: the header and body deadlines. 0 or -1. */
int ntsd_watch_start(ntsd_server* s);
void ntsd_watch_stop(ntsd_server* s);
/* A connection opens (libmicrohttpd's connection notification) from `addr`.
 * Room is made by the rule of watch.c: past --max-per-client connections
 * from its address, that address's slowest connection is cut; past
 * --max-connections, the slowest of all. With nothing to cut, the connection
 * is marked refused (its request gets 503). NULL when out of memory. */
ntsd_conn* ntsd_conn_open(ntsd_server* s, int fd, const char* addr);
void ntsd_conn_close(ntsd_server* s, ntsd_conn* k);
/* The connection's request moves on: its headers are in (WORKING, or
 * RECEIVING while its body comes), or it ended (WAITING: the next request's
 * header deadline starts). */
void ntsd_conn_enter(ntsd_server* s, ntsd_conn* k, ntsd_conn_state state);
/* The numeric address of a socket address, or "-". */
void ntsd_address_name(const struct sockaddr* a, char* out, size_t cap);
/* 1 when the client of this connection has gone (for ntsj_config.cancel). */
int ntsd_conn_client_left(void* user);

/* Read a token file: one token a line (blank lines and # comments skipped).
 * 0 with a malloc'ed list, or -1 with why in `why` (a file that cannot be
 * opened or holds no token; no memory). */
int ntsd_read_tokens(const char* path, char*** tokens, int* count, char* why, size_t cap);
void ntsd_free_token_list(char** tokens, int count);
/* Read --token-file into cfg at the start. 0, or -1 with a message printed. */
int ntsd_load_tokens(ntsd_config* cfg);
void ntsd_free_tokens(ntsd_config* cfg);
/* SIGHUP: read --token-file again and swap the server's list under
 * tokens_lock. A file that fails to load keeps the old list (logged): 0 or -1. */
int ntsd_server_reload_tokens(ntsd_server* s);
/* 1 when `authorization` (the header's value, may be NULL) carries one of the
 * tokens, compared in constant time; 1 as well when no token is configured.
 * `which` (may be NULL): the index of the token it carries, -1 for none. */
int ntsd_authorized(const ntsd_config* cfg, const char* authorization, int* which);

/* Who a request is, for what is counted or owned per client (sessions and
 * their quotas): "token:" and 16 hex digits of a hash of its bearer token
 * when tokens are configured, otherwise "addr:" and its address: the peer's,
 * or, when the peer is a --trusted-proxy, the last address X-Forwarded-For
 * gives (the one that proxy saw). Never logged (a token's hash is not a
 * secret, but it need not travel). */
void ntsd_client_key(const ntsd_config* cfg, const char* peer, const char* forwarded_for, int token,
                     char out[NTSD_CLIENT_LEN]);
/* 1 when `peer` (a numeric address) is one of --trusted-proxy. */
int ntsd_is_trusted_proxy(const ntsd_config* cfg, const char* peer);

/* Start listening. 0, or -1 with a message printed. The server takes cfg's
 * tokens (ntsd_server_stop frees them, as does a failed start). */
int ntsd_server_start(ntsd_server* s, const ntsd_config* cfg);
/* Stop accepting connections; requests arriving on open connections get 503. */
void ntsd_server_quiesce(ntsd_server* s);
/* Requests between their first callback and their completion. */
int ntsd_server_in_flight(ntsd_server* s);
/* Close every connection and join the threads. */
void ntsd_server_stop(ntsd_server* s);

/* ---------------------------------------------------------------- routes */


typedef struct ntsd_route {
    ntsd_route_kind kind;
    const char* methods; /* the methods of the path ("POST", "GET, HEAD", "GET, HEAD, DELETE") */
    const char* allow;   /* its Allow header: those and OPTIONS ("POST, OPTIONS") */
    int method_ok;       /* the method is one of `methods` (OPTIONS is not: a preflight) */
    ntsd_body_kind body; /* what the route reads (NONE for no route) */
    ntsd_auth_kind auth; /* whether it needs the token (TOKEN for no route: 401 before 404) */
    int evaluates;       /* a success counts as an evaluation in the metrics */
    int asset;           /* index in ntsd_assets for NTSD_ROUTE_OPENAPI and NTSD_ROUTE_SCHEMA */
    char scene_id[NTSD_SESSION_ID_MAX + 1]; /* the {id} of a scene route ("" when malformed: 404) */
} ntsd_route;

/* 32 to 64 URL-safe characters: what a session id may be. */
int ntsd_is_session_id(const char* id, size_t n);
/* Match a path (without query) and a method. kind NONE: 404. !method_ok: 405
 * (or, for OPTIONS, a CORS preflight: server.c). */
ntsd_route ntsd_route_find(const char* path, const char* method);
/* 1 when a Content-Type header value names JSON (application/json, *+json); 0 for none. */
int ntsd_is_json_media_type(const char* content_type);
/* 1 when a Content-Type header value is `type` (parameters aside, any case). */
int ntsd_is_media_type(const char* content_type, const char* type);
/* -------------------------------------------------------------- health */

/* A snapshot of the server's counters. */
typedef struct ntsd_stats {
    int shutting_down, in_flight, evaluating;
    unsigned connections;
    unsigned long long served;
    size_t memory_in_use;
    unsigned long long memory_refused, header_timeouts, body_timeouts, shed, client_left;
    double uptime_s, receiving_s, handling_s, sending_s;
} ntsd_stats;
ntsd_stats ntsd_server_stats(ntsd_server* s);
/* The /v1/health document (malloc'ed, ends with '\n'), or NULL (health.c). */
char* ntsd_health_document(const ntsd_config* c, const ntsd_stats* st, const ntsd_sessions_stats* ss,
                           int details, size_t* length);

/* ---------------------------------------------------------------- metrics */

/* The Prometheus label of a route: its path template. */
const char* ntsd_route_label(ntsd_route_kind kind);
/* A request ended (status 0: no answer was sent); `refusal`: why it was refused, or NULL. */
void ntsd_metrics_request(ntsd_metrics* m, ntsd_route_kind kind, int status, double seconds, const char* refusal);
void ntsd_metrics_refusal(ntsd_metrics* m, const char* reason);
/* The /metrics document (malloc'ed), or NULL. */
char* ntsd_metrics_document(const ntsd_metrics* m, const ntsd_stats* st, const ntsd_sessions_stats* ss,
                            const ntsd_config* c, size_t* length);

#endif
