/* GET /metrics: the counters of the service in the Prometheus text exposition
 * format (version 0.0.4), for a scraper. Requests by route template and
 * status, a latency histogram per route, the evaluations and the nodes they
 * covered, the sessions, the memory budget and the refusals by reason.
 * Counted under the server's lock at each request's completion (server.c). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "server.h"

/* Upper bounds of the latency buckets, seconds (+Inf is implied). */
static const double latency_bounds[NTSD_LATENCY_BUCKETS] = {0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                            0.1,    0.25,  0.5,    1.0,   2.5,  5.0,  10.0};

/* The route labels: each row's of NTSD_ROUTE_MAP (routes.h), "other" for no route. */
#define ROUTE_LABEL_(id, pattern, methods, param, body, auth, handler, label, evaluates) label,
static const char* const route_labels[NTSD_ROUTE_KINDS] = {"other", NTSD_ROUTE_MAP(ROUTE_LABEL_)};
#undef ROUTE_LABEL_

const char* ntsd_route_label(ntsd_route_kind kind) {
    int k = (int)kind;
    return k > 0 && k < NTSD_ROUTE_KINDS ? route_labels[k] : route_labels[0];
}

/* The counters' slot of a route: the first route with its label. Routes that
 * share a label (the two asset paths) count as one series; two series with
 * the same labels would be one Prometheus series written twice. */
static int label_slot(int k) {
    int j;
    for (j = 0; j < k; ++j)
        if (strcmp(route_labels[j], route_labels[k]) == 0) return j;
    return k;
}

void ntsd_metrics_request(ntsd_metrics* m, ntsd_route_kind kind, int status, double seconds, const char* refusal) {
    int k = (int)kind, b;
    if (k < 0 || k >= NTSD_ROUTE_KINDS) k = NTSD_ROUTE_NONE;
    k = label_slot(k);
    if (status >= 100 && status < 600) m->requests[k][status - 100]++;
    for (b = 0; b < NTSD_LATENCY_BUCKETS && seconds > latency_bounds[b]; ++b) {
    }
    m->latency[k][b]++;
    m->latency_sum[k] += seconds;
    if (refusal != NULL) ntsd_metrics_refusal(m, refusal);
}

void ntsd_metrics_refusal(ntsd_metrics* m, const char* reason) {
    int i;
    for (i = 0; i < m->refusal_count; ++i)
        if (strcmp(m->refusal_names[i], reason) == 0) break;
    if (i == m->refusal_count) {
        if (i == NTSD_REFUSAL_KINDS) return; /* the table is sized for every reason the daemon gives */
        snprintf(m->refusal_names[i], sizeof m->refusal_names[i], "%s", reason);
        m->refusal_count++;
    }
    m->refusals[i]++;
}

/* A growing text buffer; on failure it stays NULL and the caller answers 503. */
typedef struct text {
    char* data;
    size_t len, cap;
} text;

#if defined(__GNUC__)
static void put(text* t, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
#endif
static void put(text* t, const char* fmt, ...) {
    va_list ap;
    int n;
    if (t->data == NULL && t->cap != 0) return; /* failed before */
    for (;;) {
        size_t room = t->cap - t->len;
        va_start(ap, fmt);
        n = vsnprintf(t->data ? t->data + t->len : NULL, t->data ? room : 0, fmt, ap);
        va_end(ap);
        if (n < 0) return;
        if ((size_t)n < room) {
            t->len += (size_t)n;
            return;
        }
        {
            size_t cap = t->cap ? 2 * t->cap : 8192;
            char* grown;
            while (cap - t->len <= (size_t)n) cap *= 2;
            grown = realloc(t->data, cap);
            if (grown == NULL) {
                free(t->data);
                t->data = NULL;
                t->cap = 1;
                return;
            }
            t->data = grown;
            t->cap = cap;
        }
    }
}

char* ntsd_metrics_document(const ntsd_metrics* m, const ntsd_stats* st, const ntsd_sessions_stats* ss,
                            const ntsd_config* c, size_t* length) {
    text t = {NULL, 0, 0};
    int k, s, b;
    put(&t, "# HELP ntscontactd_requests_total Requests answered, by route template and HTTP status.\n"
            "# TYPE ntscontactd_requests_total counter\n");
    for (k = 0; k < NTSD_ROUTE_KINDS; ++k)
        for (s = 0; s < 500; ++s)
            if (m->requests[k][s] != 0)
                put(&t, "ntscontactd_requests_total{route=\"%s\",status=\"%d\"} %llu\n",
                    ntsd_route_label((ntsd_route_kind)k), s + 100, m->requests[k][s]);
    put(&t, "# HELP ntscontactd_request_duration_seconds From a request's headers to its last byte, by route.\n"
            "# TYPE ntscontactd_request_duration_seconds histogram\n");
    for (k = 0; k < NTSD_ROUTE_KINDS; ++k) {
        unsigned long long cumulative = 0;
        for (b = 0; b <= NTSD_LATENCY_BUCKETS; ++b) cumulative += m->latency[k][b];
        if (cumulative == 0) continue;
        cumulative = 0;
        for (b = 0; b < NTSD_LATENCY_BUCKETS; ++b) {
            cumulative += m->latency[k][b];
            put(&t, "ntscontactd_request_duration_seconds_bucket{route=\"%s\",le=\"%g\"} %llu\n",
                ntsd_route_label((ntsd_route_kind)k), latency_bounds[b], cumulative);
        }
        cumulative += m->latency[k][NTSD_LATENCY_BUCKETS];
        put(&t, "ntscontactd_request_duration_seconds_bucket{route=\"%s\",le=\"+Inf\"} %llu\n",
            ntsd_route_label((ntsd_route_kind)k), cumulative);
        put(&t, "ntscontactd_request_duration_seconds_sum{route=\"%s\"} %.9g\n", ntsd_route_label((ntsd_route_kind)k),
            m->latency_sum[k]);
        put(&t, "ntscontactd_request_duration_seconds_count{route=\"%s\"} %llu\n",
            ntsd_route_label((ntsd_route_kind)k), cumulative);
    }
    put(&t,
        "# HELP ntscontactd_evaluations_total Scenes evaluated with success (full scenes and session steps).\n"
        "# TYPE ntscontactd_evaluations_total counter\n"
        "ntscontactd_evaluations_total %llu\n"
        "# HELP ntscontactd_surface_nodes_evaluated_total Surface nodes over those evaluations.\n"
        "# TYPE ntscontactd_surface_nodes_evaluated_total counter\n"
        "ntscontactd_surface_nodes_evaluated_total %llu\n"
        "# HELP ntscontactd_contacts_total Active contacts found over those evaluations.\n"
        "# TYPE ntscontactd_contacts_total counter\n"
        "ntscontactd_contacts_total %llu\n",
        m->evaluations, m->surface_nodes, m->contacts);
    put(&t,
        "# HELP ntscontactd_evaluations_running Evaluations running now.\n"
        "# TYPE ntscontactd_evaluations_running gauge\n"
        "ntscontactd_evaluations_running %d\n"
        "# HELP ntscontactd_requests_in_flight Requests between their headers and their last byte.\n"
        "# TYPE ntscontactd_requests_in_flight gauge\n"
        "ntscontactd_requests_in_flight %d\n"
        "# HELP ntscontactd_connections_open Connections open now.\n"
        "# TYPE ntscontactd_connections_open gauge\n"
        "ntscontactd_connections_open %u\n",
        st->evaluating, st->in_flight, st->connections);
    put(&t,
        "# HELP ntscontactd_sessions Scene sessions held now.\n"
        "# TYPE ntscontactd_sessions gauge\n"
        "ntscontactd_sessions %d\n"
        "# HELP ntscontactd_session_memory_bytes Memory held by the sessions.\n"
        "# TYPE ntscontactd_session_memory_bytes gauge\n"
        "ntscontactd_session_memory_bytes %zu\n"
        "# HELP ntscontactd_sessions_ended_total Sessions that ended, by how.\n"
        "# TYPE ntscontactd_sessions_ended_total counter\n"
        "ntscontactd_sessions_ended_total{how=\"evicted\"} %llu\n"
        "ntscontactd_sessions_ended_total{how=\"expired\"} %llu\n"
        "ntscontactd_sessions_ended_total{how=\"deleted\"} %llu\n"
        "# HELP ntscontactd_sessions_created_total Sessions created.\n"
        "# TYPE ntscontactd_sessions_created_total counter\n"
        "ntscontactd_sessions_created_total %llu\n"
        "# HELP ntscontactd_session_clients Clients holding scene sessions now.\n"
        "# TYPE ntscontactd_session_clients gauge\n"
        "ntscontactd_session_clients %d\n"
        "# HELP ntscontactd_sessions_evicted_own_total Of the evicted sessions, those that made room for their own client's new one.\n"
        "# TYPE ntscontactd_sessions_evicted_own_total counter\n"
        "ntscontactd_sessions_evicted_own_total %llu\n"
        "# HELP ntscontactd_sessions_refused_total Sessions not created: no idle session could fairly make room.\n"
        "# TYPE ntscontactd_sessions_refused_total counter\n"
        "ntscontactd_sessions_refused_total %llu\n"
        "# HELP ntscontactd_sessions_trimmed_total Idle sessions whose evaluation buffers were given back for room.\n"
        "# TYPE ntscontactd_sessions_trimmed_total counter\n"
        "ntscontactd_sessions_trimmed_total %llu\n",
        ss->held, ss->memory, ss->evicted, ss->expired, ss->deleted, ss->created, ss->clients, ss->evicted_own,
        ss->refused, ss->trimmed);
    put(&t,
        "# HELP ntscontactd_memory_in_use_bytes Reserved against --max-memory: bodies in flight and their work.\n"
        "# TYPE ntscontactd_memory_in_use_bytes gauge\n"
        "ntscontactd_memory_in_use_bytes %zu\n"
        "# HELP ntscontactd_memory_budget_bytes --max-memory.\n"
        "# TYPE ntscontactd_memory_budget_bytes gauge\n"
        "ntscontactd_memory_budget_bytes %zu\n",
        st->memory_in_use, c->max_memory);
    put(&t, "# HELP ntscontactd_refusals_total Requests and connections refused or cut, by reason.\n"
            "# TYPE ntscontactd_refusals_total counter\n");
    for (k = 0; k < m->refusal_count; ++k)
        put(&t, "ntscontactd_refusals_total{reason=\"%s\"} %llu\n", m->refusal_names[k], m->refusals[k]);
    put(&t, "# HELP ntscontactd_uptime_seconds Since the start.\n"
            "# TYPE ntscontactd_uptime_seconds gauge\n"
            "ntscontactd_uptime_seconds %.3f\n",
        st->uptime_s);
    if (t.data == NULL) return NULL;
    *length = t.len;
    return t.data;
}
