/* ntscontactd: node-to-segment contact over HTTP.
 * Lifetime: parse the flags, ignore SIGPIPE, block SIGTERM and SIGINT in every
 * thread (libmicrohttpd's threads inherit the mask), start, print the bound
 * address, wait for a signal, stop accepting, let the requests in flight finish,
 * stop, exit 0. A second signal while waiting abandons them: exit 1 at once. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "server.h"

int main(int argc, char** argv) {
    ntsd_config cfg = ntsd_default_config();
    ntsd_server server;
    struct sigaction ignore;
    sigset_t stop_signals;
    int rc, sig = 0;

    rc = ntsd_parse_args(argc, argv, &cfg);
    if (rc != 0) return rc > 0 ? 0 : 2;
    ntsd_log_set_quiet(cfg.quiet);

    /* A client that goes away mid-response must not kill the process. */
    memset(&ignore, 0, sizeof ignore);
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    sigaction(SIGPIPE, &ignore, NULL);

    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGTERM);
    sigaddset(&stop_signals, SIGINT);
    pthread_sigmask(SIG_BLOCK, &stop_signals, NULL);

    if (ntsd_server_start(&server, &cfg) != 0) return 1;
    if (strchr(cfg.host, ':') != NULL)
        printf("ntscontactd listening on [%s]:%u\n", cfg.host, server.port);
    else
        printf("ntscontactd listening on %s:%u\n", cfg.host, server.port);
    fflush(stdout);
    ntsd_log_info("threading=%s threads=%d max-body=%zu timeout=%us max-connections=%u",
                         ntsd_threading_name(cfg.threading), cfg.threads, cfg.codec.max_bytes, cfg.timeout_s,
                         cfg.max_connections);

    /* Wait for a stop signal; every few seconds, drop the expired sessions so
     * that their memory does not wait for the next request. */
    for (;;) {
        struct timespec tick = {5, 0};
        rc = sigtimedwait(&stop_signals, NULL, &tick);
        if (rc > 0) {
            sig = rc;
            break;
        }
        ntsd_sessions_sweep(&server.sessions);
    }

    ntsd_log_info("%s: stopping, %d request(s) in flight", sig == SIGINT ? "SIGINT" : "SIGTERM",
                     ntsd_server_in_flight(&server));
    ntsd_server_quiesce(&server);
    while (ntsd_server_in_flight(&server) > 0) {
        struct timespec tick = {0, 50 * 1000 * 1000};
        if (sigtimedwait(&stop_signals, NULL, &tick) > 0) {
            /* Evaluations cannot be interrupted and libmicrohttpd would wait
             * for them (and for suspended connections): leave at once. */
            ntsd_log_message("second signal: abandoning %d request(s) in flight", ntsd_server_in_flight(&server));
            _exit(1);
        }
    }
    ntsd_server_stop(&server);
    ntsd_log_info("stopped after %llu request(s)", server.served);
    return 0;
}
