/* Logging to standard error: one line per request, written with one write(2)
 * so lines from concurrent threads never interleave. */
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "server.h"

static int log_quiet;

void ntsd_log_set_quiet(int quiet) { log_quiet = quiet; }

static void write_line(char* line, int n, size_t cap) {
    size_t len;
    ssize_t w;
    if (n < 0) return;
    len = (size_t)n < cap - 1 ? (size_t)n : cap - 2;
    if (len == 0 || line[len - 1] != '\n') line[len++] = '\n';
    while (len > 0) {
        w = write(STDERR_FILENO, line, len);
        if (w <= 0) return;
        line += w;
        len -= (size_t)w;
    }
}

static void log_line(const char* fmt, va_list ap) {
    char line[1024];
    int n = snprintf(line, sizeof line, "ntscontactd: ");
    n += vsnprintf(line + n, sizeof line - (size_t)n, fmt, ap);
    write_line(line, n, sizeof line);
}

void ntsd_log_message(const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    log_line(fmt, ap);
    va_end(ap);
}

void ntsd_log_info(const char* fmt, ...) {
    va_list ap;
    if (log_quiet) return;
    va_start(ap, fmt);
    log_line(fmt, ap);
    va_end(ap);
}

void ntsd_log_mhd(void* cls, const char* fmt, va_list ap) {
    char line[1024];
    int n;
    (void)cls;
    if (log_quiet) return;
    n = snprintf(line, sizeof line, "ntscontactd: libmicrohttpd: ");
    n += vsnprintf(line + n, sizeof line - (size_t)n, fmt, ap);
    write_line(line, n, sizeof line);
}

/* Printable copy of a client-given string: no control characters in the log. */
static void sanitize(char* dst, size_t cap, const char* src) {
    size_t i = 0;
    if (src == NULL) src = "-";
    for (; *src != '\0' && i + 1 < cap; src++) {
        unsigned char ch = (unsigned char)*src;
        dst[i++] = (ch < 0x20 || ch == 0x7f || ch == ' ') ? '?' : (char)ch;
    }
    dst[i] = '\0';
}

void ntsd_log_request(const char* peer, const char* method, const char* path, int status,
                      const char* code, size_t bytes_in, size_t bytes_out, double ms) {
    char line[1024], m[24], p[512], stamp[32];
    struct timespec ts;
    struct tm tm;
    int n;
    if (log_quiet) return;
    clock_gettime(CLOCK_REALTIME, &ts);
    gmtime_r(&ts.tv_sec, &tm);
    strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &tm);
    sanitize(m, sizeof m, method);
    sanitize(p, sizeof p, path);
    if (status > 0) {
        n = snprintf(line, sizeof line, "%s.%03ldZ %s %s %s %d %s in=%zu out=%zu %.3fms", stamp,
                     ts.tv_nsec / 1000000L, peer, m, p, status, code ? code : "-", bytes_in, bytes_out, ms);
    } else {
        n = snprintf(line, sizeof line, "%s.%03ldZ %s %s %s - %s in=%zu out=0 %.3fms", stamp,
                     ts.tv_nsec / 1000000L, peer, m, p, code ? code : "aborted", bytes_in, ms);
    }
    write_line(line, n, sizeof line);
}

double ntsd_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int ntsd_log_reopen(const char* path) {
    /* Every log line goes to stderr: point it at the file (a rotated file is
     * closed and the path opened anew). */
    if (freopen(path, "a", stderr) == NULL) {
        fprintf(stdout, "ntscontactd: cannot open --log-file %s\n", path);
        return -1;
    }
    setvbuf(stderr, NULL, _IOLBF, 0);
    return 0;
}
