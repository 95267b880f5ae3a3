/* The open connections, watched: deadlines that trickled bytes cannot
 * extend, room made for a new connection by cutting the slowest, and the
 * question "has this request's client left?" asked by the core while it
 * evaluates.
 *
 * Deadlines. libmicrohttpd 0.9.75 calls the access handler only once a
 * request's headers are complete, and every byte resets its idle timer, so a
 * client sending one header byte every few seconds holds its connection for
 * as long as it likes (F2 in docs/reliability.md). The watcher gives each
 * connection --header-seconds from its opening (a TLS handshake included) or
 * from the end of its previous request to deliver the next request's
 * headers, and --timeout from its headers to deliver its body; past either
 * it shuts the socket down (shutdown(2), not close: the descriptor stays
 * libmicrohttpd's, which sees the end of the stream and closes the
 * connection itself). The evaluation has its own budget (--max-seconds).
 *
 * Room. Clients from a few addresses reopening every connection they lose
 * must not lock the others out (issue 23). A new connection past
 * --max-per-client from its address cuts that address's slowest connection.
 * Past --max-connections in all, it cuts the slowest connection of the
 * address holding the most: a few addresses holding most of the room lose
 * their own connections to each other, however fast they reopen them, and a
 * client with one connection keeps it. The slowest: the one longest at a
 * request it has not finished sending (from its opening or the end of its
 * previous request: its handshake, headers and body), then one idle between
 * requests, the longest first. A connection being handled or answered is
 * never cut. With nothing to cut, the new connection is refused: its
 * request gets 503 with Retry-After. A --trusted-proxy's connections are not
 * counted per client, and cut only when no client's can be (the proxy
 * limits its own clients: deploy/nginx.conf). */
#define _GNU_SOURCE /* POLLRDHUP */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

#include "server.h"

/* Cut connection k (the caller holds s->lock): the socket is shut down,
 * libmicrohttpd ends the connection. */
static void cut(ntsd_server* s, ntsd_conn* k, const char* reason) {
    shutdown(k->fd, SHUT_RDWR);
    k->cut = reason;
    s->live--;
    ntsd_metrics_refusal(&s->metrics, reason);
}

static void* watch_main(void* arg) {
    ntsd_server* s = arg;
    pthread_mutex_lock(&s->lock);
    while (!s->watch_stop) {
        struct timespec until;
        double now = ntsd_now();
        ntsd_conn* k;
        for (k = s->conns; k != NULL; k = k->next) {
            /* Under the lock: the connection cannot be closed (and its
             * descriptor reused) before it is unlinked by on_connection. */
            if (k->cut) continue;
            if (k->state == NTSD_CONN_WAITING && s->config.header_seconds > 0 &&
                now - k->since > (double)s->config.header_seconds) {
                cut(s, k, "header_timeout");
                s->header_timeouts++;
                ntsd_log_info("a connection sent no complete request headers within --header-seconds %u: closed",
                              s->config.header_seconds);
            } else if (k->state == NTSD_CONN_RECEIVING && now - k->since > (double)s->config.timeout_s) {
                cut(s, k, "upload_timeout");
                s->body_timeouts++;
                ntsd_log_info("a connection sent no complete request body within --timeout %u: closed",
                              s->config.timeout_s);
            }
        }
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_nsec += 250L * 1000 * 1000;
        if (until.tv_nsec >= 1000L * 1000 * 1000) {
            until.tv_sec += 1;
            until.tv_nsec -= 1000L * 1000 * 1000;
        }
        pthread_cond_timedwait(&s->watch_wake, &s->lock, &until);
    }
    pthread_mutex_unlock(&s->lock);
    return NULL;
}

int ntsd_watch_start(ntsd_server* s) {
    if (pthread_cond_init(&s->watch_wake, NULL) != 0) return -1;
    s->watch_stop = 0;
    s->watching = pthread_create(&s->watcher, NULL, watch_main, s) == 0;
    if (!s->watching) {
        pthread_cond_destroy(&s->watch_wake);
        return -1;
    }
    return 0;
}

void ntsd_watch_stop(ntsd_server* s) {
    if (s->watching) {
        pthread_mutex_lock(&s->lock);
        s->watch_stop = 1;
        pthread_cond_signal(&s->watch_wake);
        pthread_mutex_unlock(&s->lock);
        pthread_join(s->watcher, NULL);
        s->watching = 0;
    }
    pthread_cond_destroy(&s->watch_wake);
}

/* How slow a connection is, to be cut first: larger is slower, 0 is never
 * (being handled or answered, or cut already). The rank orders the kinds (see
 * the top of the file); within one, the longer it has been at it, the slower. */
static double slowness(const ntsd_conn* k, double now) {
    if (k->cut || k->state == NTSD_CONN_WORKING) return 0.0;
    if (k->state == NTSD_CONN_RECEIVING || k->requests == 0) return 2e9 + (now - k->begun);
    return 1e9 + (now - k->since);
}

static const char* const state_names[] = {"waiting for a request", "sending a body", "being served"};

/* Cut connection v to make room for a new one, and say so. */
static void make_room(ntsd_server* s, ntsd_conn* v, const char* reason, double now) {
    ntsd_log_info("a connection from %s (%s for %.3f s, %u request(s) done) cut to make room (%s)", v->addr,
                  state_names[v->state], now - v->since, v->requests,
                  strcmp(reason, "max_per_client") == 0 ? "--max-per-client" : "--max-connections");
    cut(s, v, reason);
    s->shed++;
}

/* The slowest connection from `addr`, or NULL; *from_addr: how many are
 * open from it. */
static ntsd_conn* slowest_from(ntsd_server* s, const char* addr, double now, unsigned* from_addr) {
    ntsd_conn *k, *worst = NULL;
    double w = 0.0;
    unsigned n = 0;
    for (k = s->conns; k != NULL; k = k->next) {
        double x;
        if (!k->limited || k->cut || strcmp(k->addr, addr) != 0) continue;
        n++;
        x = slowness(k, now);
        if (x > 0.0 && x >= w) { /* on a tie the older: the list runs newest first */
            w = x;
            worst = k;
        }
    }
    *from_addr = n;
    return worst;
}

static int by_address(const void* a, const void* b) {
    return strcmp((*(ntsd_conn* const*)a)->addr, (*(ntsd_conn* const*)b)->addr);
}

/* The connection to cut when the server is full: the slowest of the address
 * holding the most open connections (among those with one to cut), else the
 * slowest of a --trusted-proxy, else NULL. The clients' connections sorted
 * by address, each address is one run: O(n log n), n <= --max-connections.
 * Without memory for the sort, the slowest of all. */
static ntsd_conn* victim(ntsd_server* s, double now) {
    ntsd_conn *k, *best = NULL, **v;
    size_t n = 0, i, j;
    unsigned most = 0;
    double w = 0.0;
    v = malloc((size_t)(s->live + 1) * sizeof *v);
    if (v != NULL) {
        for (k = s->conns; k != NULL && n <= s->live; k = k->next)
            if (k->limited && !k->cut) v[n++] = k;
        qsort(v, n, sizeof *v, by_address);
        for (i = 0; i < n; i = j) {
            ntsd_conn* worst = NULL;
            double x = 0.0;
            for (j = i; j < n && strcmp(v[j]->addr, v[i]->addr) == 0; ++j) {
                double y = slowness(v[j], now);
                if (y > x || (y == x && y > 0.0 && v[j]->begun < worst->begun)) {
                    x = y;
                    worst = v[j];
                }
            }
            if (worst != NULL && ((unsigned)(j - i) > most || ((unsigned)(j - i) == most && x > w))) {
                most = (unsigned)(j - i);
                w = x;
                best = worst;
            }
        }
        free(v);
        if (best != NULL) return best;
    }
    for (k = s->conns; k != NULL; k = k->next) { /* no client's to cut: a proxy's (or any, without memory) */
        double x = slowness(k, now);
        if (x > 0.0 && x >= w) {
            w = x;
            best = k;
        }
    }
    return best;
}

ntsd_conn* ntsd_conn_open(ntsd_server* s, int fd, const char* addr) {
    ntsd_conn* k = calloc(1, sizeof *k);
    double now = ntsd_now();
    if (k == NULL) return NULL;
    k->fd = fd;
    k->since = now;
    k->begun = now;
    k->state = NTSD_CONN_WAITING;
    snprintf(k->addr, sizeof k->addr, "%s", addr);
    k->limited = !ntsd_is_trusted_proxy(&s->config, addr);
    pthread_mutex_lock(&s->lock);
    if (k->limited) {
        unsigned n;
        ntsd_conn* v = slowest_from(s, k->addr, now, &n);
        if (n >= s->config.max_per_client) {
            if (v != NULL) {
                make_room(s, v, "max_per_client", now);
            } else {
                k->refused = "max_per_client";
            }
        }
    }
    if (k->refused == NULL && s->live >= s->config.max_connections) {
        ntsd_conn* v = victim(s, now);
        if (v != NULL) {
            make_room(s, v, "shed", now);
        } else {
            k->refused = "max_connections";
        }
    }
    k->next = s->conns;
    if (s->conns != NULL) s->conns->prev = k;
    s->conns = k;
    s->live++;
    pthread_mutex_unlock(&s->lock);
    return k;
}

void ntsd_conn_close(ntsd_server* s, ntsd_conn* k) {
    if (k == NULL) return;
    pthread_mutex_lock(&s->lock);
    if (k->prev != NULL) k->prev->next = k->next;
    else s->conns = k->next;
    if (k->next != NULL) k->next->prev = k->prev;
    if (!k->cut) s->live--;
    pthread_mutex_unlock(&s->lock);
    free(k);
}

void ntsd_conn_enter(ntsd_server* s, ntsd_conn* k, ntsd_conn_state state) {
    if (k == NULL) return;
    pthread_mutex_lock(&s->lock);
    k->since = ntsd_now();
    if (state == NTSD_CONN_WAITING && k->state != NTSD_CONN_WAITING) {
        k->requests++;
        k->begun = k->since;
    }
    k->state = (int)state;
    pthread_mutex_unlock(&s->lock);
}

void ntsd_address_name(const struct sockaddr* a, char* out, size_t cap) {
    snprintf(out, cap, "-");
    if (a == NULL) return;
    if (a->sa_family == AF_INET)
        inet_ntop(AF_INET, &((const struct sockaddr_in*)(const void*)a)->sin_addr, out, (socklen_t)cap);
    else if (a->sa_family == AF_INET6)
        inet_ntop(AF_INET6, &((const struct sockaddr_in6*)(const void*)a)->sin6_addr, out, (socklen_t)cap);
}

/* The core's cancel hook for a request (ntsj_config.cancel): has the peer
 * closed its end, or reset the connection? A poll with no wait, asked every
 * 1024 slave nodes: about a microsecond against a millisecond of work. A
 * request fully sent and waiting for its answer shows nothing to read, so only
 * a hang-up (or half-close: HTTP clients do not) stops the work. */
int ntsd_conn_client_left(void* user) {
    const ntsd_conn* k = user;
    struct pollfd p;
    p.fd = k->fd;
    p.events = POLLRDHUP;
    p.revents = 0;
    return poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR)) != 0;
}
