/* The open connections, watched: a header deadline that trickled bytes cannot
 * extend, and the question "has this request's client left?" asked by the
 * core while it evaluates.
 *
 * libmicrohttpd 0.9.75 calls the access handler only once a request's headers
 * are complete, and every byte resets its idle timer, so a client sending one
 * header byte every few seconds holds its connection for as long as it likes
 * (F2 in docs/reliability.md). The watcher gives each connection
 * --header-seconds from its opening, or from the end of its previous request,
 * to deliver the next request's headers; past that it shuts the socket down
 * (shutdown(2), not close: the descriptor stays libmicrohttpd's, which sees
 * the end of the stream and closes the connection itself). Once the headers
 * are in, the body has its own budget (--timeout, server.c) and the
 * evaluation its own (--max-seconds). */
#define _GNU_SOURCE /* POLLRDHUP */
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

#include "server.h"

static void* watch_main(void* arg) {
    ntsd_server* s = arg;
    pthread_mutex_lock(&s->lock);
    while (!s->watch_stop) {
        struct timespec until;
        double now = ntsd_now();
        ntsd_conn* k;
        for (k = s->conns; k != NULL; k = k->next) {
            if (k->busy || k->cut || now - k->since <= (double)s->config.header_seconds) continue;
            /* Under the lock: the connection cannot be closed (and its
             * descriptor reused) before it is unlinked by on_connection. */
            shutdown(k->fd, SHUT_RDWR);
            k->cut = 1;
            s->header_timeouts++;
            ntsd_metrics_refusal(&s->metrics, "header_timeout");
            ntsd_log_info("a connection sent no complete request headers within --header-seconds %u: closed",
                          s->config.header_seconds);
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
    s->watching = s->config.header_seconds > 0 && pthread_create(&s->watcher, NULL, watch_main, s) == 0;
    if (s->config.header_seconds > 0 && !s->watching) {
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

ntsd_conn* ntsd_conn_open(ntsd_server* s, int fd) {
    ntsd_conn* k = calloc(1, sizeof *k);
    if (k == NULL) return NULL;
    k->fd = fd;
    k->since = ntsd_now();
    pthread_mutex_lock(&s->lock);
    k->next = s->conns;
    if (s->conns != NULL) s->conns->prev = k;
    s->conns = k;
    pthread_mutex_unlock(&s->lock);
    return k;
}

void ntsd_conn_close(ntsd_server* s, ntsd_conn* k) {
    if (k == NULL) return;
    pthread_mutex_lock(&s->lock);
    if (k->prev != NULL) k->prev->next = k->next;
    else s->conns = k->next;
    if (k->next != NULL) k->next->prev = k->prev;
    pthread_mutex_unlock(&s->lock);
    free(k);
}

void ntsd_conn_busy(ntsd_server* s, ntsd_conn* k, int busy) {
    if (k == NULL) return;
    pthread_mutex_lock(&s->lock);
    k->busy = busy;
    if (!busy) k->since = ntsd_now();
    pthread_mutex_unlock(&s->lock);
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
