/* ntscontactd: node-to-segment contact over HTTP.
 * Lifetime: parse the flags, ignore SIGPIPE, block the signals we handle in
 * every thread (libmicrohttpd's threads inherit the mask), start, print the
 * bound address, wait. SIGHUP reopens --log-file and reads --token-file
 * again (a file that fails to load keeps the tokens). Every terminating signal
 * (TERM, INT, QUIT, USR1, USR2, ALRM) drains: stop accepting, let the requests
 * in flight finish for at most --drain-seconds, stop, exit 0; past the deadline,
 * or at a second signal, the requests left are abandoned: exit 1. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "server.h"

static const char* signal_name(int sig) {
    switch (sig) {
    case SIGTERM: return "SIGTERM";
    case SIGINT: return "SIGINT";
    case SIGQUIT: return "SIGQUIT";
    case SIGUSR1: return "SIGUSR1";
    case SIGUSR2: return "SIGUSR2";
    case SIGALRM: return "SIGALRM";
    default: return "signal";
    }
}

int main(int argc, char** argv) {
    ntsd_config cfg = ntsd_default_config();
    ntsd_server server;
    struct sigaction ignore;
    sigset_t stop_signals;
    int rc, sig = 0;

    rc = ntsd_parse_args(argc, argv, &cfg);
    if (rc != 0) return rc > 0 ? 0 : 2;
    ntsd_log_set_quiet(cfg.quiet);
    ntsd_log_set_json(cfg.log_json);

    /* A client that goes away mid-response must not kill the process. */
    memset(&ignore, 0, sizeof ignore);
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    sigaction(SIGPIPE, &ignore, NULL);

    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGTERM);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGQUIT);
    sigaddset(&stop_signals, SIGUSR1);
    sigaddset(&stop_signals, SIGUSR2);
    sigaddset(&stop_signals, SIGALRM);
    sigaddset(&stop_signals, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &stop_signals, NULL);
    if (cfg.log_file[0] != '\0' && ntsd_log_reopen(cfg.log_file) != 0) return 1;

    if (ntsd_server_start(&server, &cfg) != 0) return 1;
    cfg.tokens = NULL; /* the server's now (SIGHUP replaces them) */
    cfg.token_count = 0;
    if (strchr(cfg.host, ':') != NULL)
        printf("ntscontactd listening on [%s]:%u\n", cfg.host, server.port);
    else
        printf("ntscontactd listening on %s:%u\n", cfg.host, server.port);
    fflush(stdout);
    ntsd_log_info("threads=%d max-bytes=%zu timeout=%us max-connections=%u max-memory=%zu", cfg.threads,
                  cfg.codec.max_bytes, cfg.timeout_s, cfg.max_connections, cfg.max_memory);

    /* Wait for a stop signal; every few seconds, drop the expired sessions so
     * that their memory does not wait for the next request. */
    for (;;) {
        struct timespec tick = {5, 0};
        rc = sigtimedwait(&stop_signals, NULL, &tick);
        if (rc == SIGHUP) { /* log rotation: write to the file anew; a revoked token goes */
            if (cfg.log_file[0] != '\0') ntsd_log_reopen(cfg.log_file);
            ntsd_log_info("SIGHUP: log reopened");
            ntsd_server_reload_tokens(&server);
            continue;
        }
        if (rc > 0) {
            sig = rc;
            break;
        }
        ntsd_sessions_sweep(&server.sessions);
    }

    ntsd_log_info("%s: stopping, %d request(s) in flight (drained for at most %u s)", signal_name(sig),
                  ntsd_server_in_flight(&server), cfg.drain_seconds);
    ntsd_server_quiesce(&server);
    {
        double deadline = ntsd_now() + (double)cfg.drain_seconds;
        while (ntsd_server_in_flight(&server) > 0) {
            struct timespec tick = {0, 50 * 1000 * 1000};
            int again = sigtimedwait(&stop_signals, NULL, &tick);
            if ((again > 0 && again != SIGHUP) || ntsd_now() > deadline) {
                /* libmicrohttpd would wait for the evaluations: leave at once. */
                ntsd_log_message("%s: abandoning %d request(s) in flight",
                                 again > 0 ? "second signal" : "--drain-seconds passed", ntsd_server_in_flight(&server));
                _exit(1);
            }
        }
    }
    ntsd_server_stop(&server); /* frees the tokens */
    ntsd_log_info("stopped after %llu request(s)", server.served);
    return 0;
}
