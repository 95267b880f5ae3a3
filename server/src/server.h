/* ntscontactd internals: the configuration from the command line, the daemon's
 * shared state and one request's state. One file per concept:
 *   args.c   command line            log.c     one line per request
 *   body.c   capped body buffer      routes.c  URL + method -> answer
 *   server.c libmicrohttpd callbacks, counters, start/stop
 *   workers.c evaluation threads of the pool model
 *   main.c   signals and lifetime
 * The threading models and why per-connection is the default: docs/benchmarks.md, "Server". */
#ifndef NTSD_SERVER_H
#define NTSD_SERVER_H

#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>

#include <microhttpd.h>

/* ------------------------------------------------------------------ args */

typedef enum ntsd_threading {
    NTSD_THREAD_PER_CONNECTION = 0, /* default: one thread per connection, evaluations gated to --threads */
    NTSD_THREAD_POOL = 1            /* --threads epoll polling threads; evaluations of large bodies
                                       on --threads workers (suspend/resume), small ones inline */
} ntsd_threading;

typedef struct ntsd_config {
    char host[64];           /* numeric IPv4 or IPv6 address */
    unsigned port;           /* 0: any free port (printed on stdout) */
    int threads;             /* evaluations at once (and pool size); default: online cores */
    size_t max_body;         /* bytes; default 64 MiB */
    unsigned timeout_s;      /* idle connection timeout and body upload budget; default 30 */
    unsigned max_connections;/* default 256 */
    ntsd_threading threading;
    size_t inline_max;       /* pool model: bodies up to this size are evaluated by the polling
                                thread itself; default 64 KiB (NTSD_INLINE_MAX_BYTES) */
    int quiet;
    /* Limits handed to the codec for every request (issue 7). */
    int max_depth;           /* JSON nesting; default 32 */
    int max_bodies;          /* bodies in a scene; default 1,000,000 */
    int max_nodes_per_body;  /* default 10,000,000 */
    long long max_nodes;     /* all nodes of a scene; default 50,000,000 */
    double max_seconds;      /* wall-clock budget of one request's codec work, 0 = none */
} ntsd_config;

ntsd_config ntsd_default_config(void);
/* 0 on success, 1 when the program should exit 0 (--help, --version), -1 on a
 * usage error (message printed). */
int ntsd_parse_args(int argc, char** argv, ntsd_config* cfg);
const char* ntsd_threading_name(ntsd_threading t);

/* ------------------------------------------------------------------ body */

/* A request body accumulated in pieces, never beyond `max` bytes. */
typedef struct ntsd_body {
    char* data;   /* NUL-terminated when not NULL */
    size_t length, capacity, max;
} ntsd_body;

void ntsd_body_init(ntsd_body* b, size_t max);
/* Reserve room for an announced Content-Length (<= max). 0 or -1 (no memory). */
int ntsd_body_reserve(ntsd_body* b, size_t expected);
/* 0, -1 (no memory) or 1 (the body would exceed `max`; nothing appended). */
int ntsd_body_append(ntsd_body* b, const char* data, size_t size);
void ntsd_body_free(ntsd_body* b);

/* ------------------------------------------------------------------- log */

void ntsd_log_set_quiet(int quiet);
#if defined(__GNUC__)
#define NTSD_PRINTF_LIKE __attribute__((format(printf, 1, 2)))
#else
#define NTSD_PRINTF_LIKE
#endif
/* A line "ntscontactd: ..." for a fault: printed even when quiet. */
void ntsd_log_message(const char* fmt, ...) NTSD_PRINTF_LIKE;
/* A line "ntscontactd: ..." about the daemon's life: silent when quiet. */
void ntsd_log_info(const char* fmt, ...) NTSD_PRINTF_LIKE;
/* One line per request: method, path, status, code, bytes in/out, milliseconds. */
void ntsd_log_request(const char* peer, const char* method, const char* path, int status,
                      const char* code, size_t bytes_in, size_t bytes_out, double ms);
/* libmicrohttpd's own diagnostics (MHD_OPTION_EXTERNAL_LOGGER). */
void ntsd_log_mhd(void* cls, const char* fmt, va_list ap);

/* --------------------------------------------------------------- workers */

/* A job for the evaluation threads; `next` belongs to the queue. */
typedef struct ntsd_job {
    void (*run)(void* arg);
    void* arg;
    struct ntsd_job* next;
} ntsd_job;

typedef struct ntsd_workers {
    pthread_t* threads;
    int count;
    pthread_mutex_t lock;
    pthread_cond_t ready;
    ntsd_job *head, *tail;
    int queued, stopping;
} ntsd_workers;

/* Start `count` threads. 0 or -1. */
int ntsd_workers_start(ntsd_workers* w, int count);
void ntsd_workers_push(ntsd_workers* w, ntsd_job* job);
/* Run what is queued, then join the threads. */
void ntsd_workers_stop(ntsd_workers* w);

/* ---------------------------------------------------------------- server */

/* Default of --inline-max: in the pool model, bodies up to this size are
 * evaluated by the polling thread itself (well under a millisecond); larger
 * ones go to the evaluation threads. */
#define NTSD_INLINE_MAX_BYTES ((size_t)64 * 1024)

typedef struct ntsd_server {
    ntsd_config config;
    struct MHD_Daemon* daemon;
    ntsd_workers workers;      /* pool model: the evaluation threads */
    unsigned port;             /* the bound port */
    double started;            /* monotonic seconds */

    pthread_mutex_t lock;      /* guards everything below */
    pthread_cond_t changed;    /* an evaluation slot was freed */
    int shutting_down;
    int in_flight;             /* requests between their first callback and completion */
    int evaluating;            /* evaluations running (<= config.threads) */
    unsigned connections;      /* open connections */
    unsigned long long served; /* requests answered completely */
    /* Seconds summed over the requests answered: from the headers to the whole
     * body (receiving), in the codec and the core (handling), from the queued
     * response to its last byte (sending). GET /v1/health reports them. */
    double receiving_s, handling_s, sending_s;
} ntsd_server;

/* Start listening. 0, or -1 with a message printed. */
int ntsd_server_start(ntsd_server* s, const ntsd_config* cfg);
/* Stop accepting connections; requests arriving on open connections get 503. */
void ntsd_server_quiesce(ntsd_server* s);
/* Requests between their first callback and their completion. */
int ntsd_server_in_flight(ntsd_server* s);
/* Close every connection and join the threads. */
void ntsd_server_stop(ntsd_server* s);
double ntsd_now(void);

/* ---------------------------------------------------------------- routes */

typedef enum ntsd_route_kind {
    NTSD_ROUTE_NONE = 0,
    NTSD_ROUTE_CONTACT,
    NTSD_ROUTE_VALIDATE,
    NTSD_ROUTE_HEALTH,
    NTSD_ROUTE_ASSET
} ntsd_route_kind;

typedef struct ntsd_route {
    ntsd_route_kind kind;
    const char* allow;   /* the Allow header of the path ("POST", "GET, HEAD") */
    int method_ok;       /* the method is one of `allow` */
    int asset;           /* index in ntsd_assets for NTSD_ROUTE_ASSET */
} ntsd_route;

/* Match a path (without query) and a method. kind NONE: 404. !method_ok: 405. */
ntsd_route ntsd_route_find(const char* path, const char* method);
/* 1 when a Content-Type header value names JSON (application/json, *+json). */
int ntsd_is_json_media_type(const char* content_type);
/* The /v1/health document (malloc'ed, ends with '\n'), or NULL. */
char* ntsd_health_document(ntsd_server* s, size_t* length);

#endif
