/* GET /v1/health: the document, written from a snapshot of the server's
 * counters (ntsd_server_stats), the configuration and the session store. */
#include <stdio.h>
#include <stdlib.h>

#include <ntscontact/config.h> /* what GET /v1/health reports of the build */
#include <ntscontact/ntscontact.h>
#include "server.h"

char* ntsd_health_document(const ntsd_config* c, const ntsd_stats* st, const ntsd_sessions_stats* ss,
                           int details, size_t* length) {
    char* doc = malloc(2048);
    int n;
    if (doc == NULL) return NULL;
    if (!details) { /* no token: only whether it is up, no build or configuration details */
        n = snprintf(doc, 2048, "{\"status\":\"%s\"}\n", st->shutting_down ? "shutting_down" : "ok");
        *length = (size_t)n;
        return doc;
    }
    n = snprintf(doc, 2048,
                 "{\"status\":\"%s\",\"version\":\"%s\","
                 "\"build\":{\"type\":\"%s\",\"openmp\":%s,\"sanitize\":%s,\"libmicrohttpd\":\"%s\"},"
                 "\"server\":{\"threading\":\"%s\",\"threads\":%d,\"max_body\":%zu,\"timeout_s\":%u,"
                 "\"max_connections\":%u,\"max_seconds\":%g},"
                 "\"uptime_s\":%.3f,\"requests_served\":%llu,\"requests_in_flight\":%d,"
                 "\"evaluations_running\":%d,\"connections_open\":%u,"
                 "\"time_s\":{\"receiving\":%.6f,\"handling\":%.6f,\"sending\":%.6f},"
                 "\"sessions\":{\"held\":%d,\"memory_bytes\":%zu,\"max\":%d,\"ttl_s\":%u,\"memory_max\":%zu,"
                 "\"created\":%llu,\"evicted\":%llu,\"expired\":%llu,\"deleted\":%llu,"
                 "\"max_per_client\":%d,\"clients\":%d,\"evicted_own\":%llu,\"refused\":%llu,\"trimmed\":%llu},"
                 "\"memory\":{\"budget_bytes\":%zu,\"in_use_bytes\":%zu,\"refused\":%llu},"
                 "\"header_timeouts\":%llu,\"body_timeouts\":%llu,\"shed\":%llu,\"client_left\":%llu}\n",
                 st->shutting_down ? "shutting_down" : "ok", NTS_VERSION_STRING, NTS_CONFIG_BUILD_TYPE,
                 NTS_CONFIG_OPENMP ? "true" : "false", NTS_CONFIG_SANITIZE ? "true" : "false", MHD_get_version(),
                 "per-connection", c->threads, c->codec.max_bytes, c->timeout_s,
                 c->max_connections, c->codec.max_seconds, st->uptime_s, st->served, st->in_flight, st->evaluating,
                 st->connections,
                 st->receiving_s, st->handling_s, st->sending_s, ss->held, ss->memory, c->max_sessions,
                 c->session_ttl_s, c->session_memory, ss->created, ss->evicted, ss->expired, ss->deleted,
                 c->max_sessions_per_client, ss->clients, ss->evicted_own, ss->refused, ss->trimmed,
                 c->max_memory, st->memory_in_use, st->memory_refused, st->header_timeouts, st->body_timeouts, st->shed,
                 st->client_left);
    if (n < 0 || n >= 2048) {
        free(doc);
        return NULL;
    }
    *length = (size_t)n;
    return doc;
}
