/* Logging to standard error: one line per request, written with one write(2)
 * so lines from concurrent threads never interleave. Two formats: text for a
 * terminal, or (--log-format json) one JSON object a line for a log pipeline:
 * {"time", "level", "event": "request" | "message", ...}. */
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "server.h"

static int log_quiet;
static int log_json;

void ntsd_log_set_quiet(int quiet) { log_quiet = quiet; }
void ntsd_log_set_json(int json) { log_json = json; }

/* `src` as a JSON string, quotes included, cut to fit `cap`. Control
 * characters and bytes over 0x7f are escaped (\u00XX): the line is valid JSON
 * whatever a client sent. */
static void json_string(char* dst, size_t cap, const char* src) {
    static const char hex[] = "0123456789abcdef";
    size_t i = 0;
    if (src == NULL) src = "";
    dst[i++] = '"';
    for (; *src != '\0' && i + 8 < cap; src++) {
        unsigned char ch = (unsigned char)*src;
        if (ch == '"' || ch == '\\') {
            dst[i++] = '\\';
            dst[i++] = (char)ch;
        } else if (ch < 0x20 || ch >= 0x7f) {
            dst[i++] = '\\';
            dst[i++] = 'u';
            dst[i++] = '0';
            dst[i++] = '0';
            dst[i++] = hex[ch >> 4];
            dst[i++] = hex[ch & 15];
        } else {
            dst[i++] = (char)ch;
        }
    }
    dst[i++] = '"';
    dst[i] = '\0';
}

/* The UTC time of now, ISO 8601 with milliseconds. */
static void now_stamp(char* out, size_t cap) {
    struct timespec ts;
    struct tm tm;
    size_t n;
    clock_gettime(CLOCK_REALTIME, &ts);
    gmtime_r(&ts.tv_sec, &tm);
    n = strftime(out, cap, "%Y-%m-%dT%H:%M:%S", &tm);
    if (n + 6 <= cap) snprintf(out + n, cap - n, ".%03dZ", (int)(ts.tv_nsec / 1000000L) % 1000);
}

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

/* A printable copy of `src` for a text line, cut to fit `cap`: control bytes,
 * DEL, bytes over 0x7f and the backslash (and, in a field of a request line,
 * the space that separates the fields) are written \xNN, so a line is plain
 * ASCII whatever a client sent and reads back unambiguously. */
static void text_escape(char* dst, size_t cap, const char* src, int escape_space) {
    static const char hex[] = "0123456789abcdef";
    size_t i = 0;
    if (src == NULL) src = "-";
    for (; *src != '\0'; src++) {
        unsigned char ch = (unsigned char)*src;
        if (ch < 0x20 || ch >= 0x7f || ch == '\\' || (ch == ' ' && escape_space)) {
            if (i + 4 >= cap) break;
            dst[i++] = '\\';
            dst[i++] = 'x';
            dst[i++] = hex[ch >> 4];
            dst[i++] = hex[ch & 15];
        } else {
            if (i + 1 >= cap) break;
            dst[i++] = (char)ch;
        }
    }
    dst[i] = '\0';
}

static void log_line(const char* level, const char* source, const char* fmt, va_list ap) {
    char line[1280];
    int n;
    if (log_json) {
        char text[768], quoted[1024], stamp[40];
        vsnprintf(text, sizeof text, fmt, ap);
        json_string(quoted, sizeof quoted, text);
        now_stamp(stamp, sizeof stamp);
        n = snprintf(line, sizeof line, "{\"time\":\"%s\",\"level\":\"%s\",\"event\":\"message\",\"source\":\"%s\","
                     "\"message\":%s}", stamp, level, source, quoted);
    } else {
        /* A message may quote what a client sent (libmicrohttpd's do): escaped
         * like a request line's fields, its own line end aside. */
        char text[768], escaped[1024];
        size_t k;
        vsnprintf(text, sizeof text, fmt, ap);
        k = strlen(text);
        while (k > 0 && (text[k - 1] == '\n' || text[k - 1] == '\r')) text[--k] = '\0';
        text_escape(escaped, sizeof escaped, text, 0);
        n = snprintf(line, sizeof line, "ntscontactd: %s%s", strcmp(source, "libmicrohttpd") == 0 ? "libmicrohttpd: " : "",
                     escaped);
    }
    write_line(line, n, sizeof line);
}

void ntsd_log_message(const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    log_line("error", "ntscontactd", fmt, ap);
    va_end(ap);
}

void ntsd_log_info(const char* fmt, ...) {
    va_list ap;
    if (log_quiet) return;
    va_start(ap, fmt);
    log_line("info", "ntscontactd", fmt, ap);
    va_end(ap);
}

void ntsd_log_mhd(void* cls, const char* fmt, va_list ap) {
    (void)cls;
    if (log_quiet) return;
    log_line("warning", "libmicrohttpd", fmt, ap);
}

void ntsd_log_request(const char* peer, const char* method, const char* path, int status,
                      const char* code, size_t bytes_in, size_t bytes_out, double ms) {
    char line[1536], m[64], p[1024], q_code[128], stamp[40];
    int n;
    if (log_quiet) return;
    now_stamp(stamp, sizeof stamp);
    if (log_json) {
        char q_peer[160];
        json_string(m, sizeof m, method);
        json_string(p, sizeof p, path);
        json_string(q_peer, sizeof q_peer, peer);
        json_string(q_code, sizeof q_code, code ? code : status > 0 ? "-" : "aborted");
        n = snprintf(line, sizeof line,
                     "{\"time\":\"%s\",\"level\":\"info\",\"event\":\"request\",\"peer\":%s,\"method\":%s,"
                     "\"path\":%s,\"status\":%d,\"code\":%s,\"bytes_in\":%zu,\"bytes_out\":%zu,\"ms\":%.3f}",
                     stamp, q_peer, m, p, status, q_code, bytes_in, status > 0 ? bytes_out : 0, ms);
    } else {
        text_escape(m, sizeof m, method, 1);
        text_escape(p, sizeof p, path, 1);
        text_escape(q_code, sizeof q_code, code ? code : status > 0 ? "-" : "aborted", 1);
        if (status > 0)
            n = snprintf(line, sizeof line, "%s %s %s %s %d %s in=%zu out=%zu %.3fms", stamp, peer, m, p, status,
                         q_code, bytes_in, bytes_out, ms);
        else
            n = snprintf(line, sizeof line, "%s %s %s %s - %s in=%zu out=0 %.3fms", stamp, peer, m, p,
                         q_code, bytes_in, ms);
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
