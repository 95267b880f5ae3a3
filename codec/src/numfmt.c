/* The output buffer and the number printer of the codec.
 *
 * Doubles are printed in the shortest of %.15g, %.16g, %.17g that reads back
 * bitwise equal through strtod (%.17g always does for IEEE binary64), so the
 * JSON carries exactly the value the core computed; cJSON's own printer stops at
 * 15 digits when that looks equal and is not used for numbers. No setlocale is
 * ever called, so printf and strtod use the "C" locale's '.'. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

void ntsj_fault_set(ntsj_fault* f, const char* code, const char* pointer, const char* fmt, ...) {
    va_list ap;
    f->code = code;
    snprintf(f->pointer, sizeof f->pointer, "%s", pointer ? pointer : "");
    va_start(ap, fmt);
    vsnprintf(f->message, sizeof f->message, fmt, ap);
    va_end(ap);
}

void ntsj_buf_init(ntsj_buf* b) {
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
    b->oom = 0;
}

void ntsj_buf_free(ntsj_buf* b) {
    nts_free(b->data);
    ntsj_buf_init(b);
}

int ntsj_buf_reserve(ntsj_buf* b, size_t extra) {
    size_t need, cap;
    char* p;
    if (b->oom) return -1;
    if (extra > (size_t)-1 / 2 - b->len) {
        b->oom = 1;
        return -1;
    }
    need = b->len + extra + 1; /* room for the terminating NUL */
    if (need <= b->cap) return 0;
    cap = b->cap ? b->cap : 256;
    while (cap < need) cap *= 2;
    p = (char*)nts_alloc(cap);
    if (!p) {
        b->oom = 1;
        return -1;
    }
    if (b->data) memcpy(p, b->data, b->len + 1);
    else p[0] = '\0';
    nts_free(b->data);
    b->data = p;
    b->cap = cap;
    return 0;
}

void ntsj_buf_put(ntsj_buf* b, const char* s, size_t n) {
    if (ntsj_buf_reserve(b, n) != 0) return;
    memcpy(b->data + b->len, s, n);
    b->len += n;
    b->data[b->len] = '\0';
}

void ntsj_buf_puts(ntsj_buf* b, const char* s) { ntsj_buf_put(b, s, strlen(s)); }

void ntsj_buf_putc(ntsj_buf* b, char c) {
    if (ntsj_buf_reserve(b, 1) != 0) return;
    b->data[b->len++] = c;
    b->data[b->len] = '\0';
}

void ntsj_buf_int(ntsj_buf* b, long long v) {
    char tmp[32];
    int n = snprintf(tmp, sizeof tmp, "%lld", v);
    ntsj_buf_put(b, tmp, (size_t)n);
}

void ntsj_buf_string(ntsj_buf* b, const char* s) {
    static const char hex[] = "0123456789abcdef";
    const unsigned char* p = (const unsigned char*)s;
    ntsj_buf_putc(b, '"');
    for (; *p; ++p) {
        unsigned char c = *p;
        if (c == '"' || c == '\\') {
            char e[2] = {'\\', (char)c};
            ntsj_buf_put(b, e, 2);
        } else if (c < 0x20) {
            char e[6] = {'\\', 'u', '0', '0', hex[c >> 4], hex[c & 15]};
            switch (c) {
            case '\n': ntsj_buf_put(b, "\\n", 2); break;
            case '\r': ntsj_buf_put(b, "\\r", 2); break;
            case '\t': ntsj_buf_put(b, "\\t", 2); break;
            case '\b': ntsj_buf_put(b, "\\b", 2); break;
            case '\f': ntsj_buf_put(b, "\\f", 2); break;
            default: ntsj_buf_put(b, e, 6); break;
            }
        } else if (c < 0x80) {
            ntsj_buf_putc(b, (char)c);
        } else {
            /* Copy a whole UTF-8 sequence; a broken one (a message cut by
             * snprintf in the middle of a character) becomes U+FFFD. */
            size_t len = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 ? 2 : 0, i;
            for (i = 1; i < len; ++i)
                if ((p[i] & 0xC0) != 0x80) break;
            if (len == 0 || c > 0xF4 || i < len) {
                ntsj_buf_put(b, "\\ufffd", 6);
            } else {
                ntsj_buf_put(b, (const char*)p, len);
                p += len - 1;
            }
        }
    }
    ntsj_buf_putc(b, '"');
}

int ntsj_format_double(char* out, double v) {
    int n, prec, i, has_mark = 0;
    if (!isfinite(v)) {
        memcpy(out, "null", 5);
        return 4;
    }
    if (v == 0.0) {
        /* Keep the sign of zero: "-0.0" reads back as -0.0. */
        const char* z = signbit(v) ? "-0.0" : "0.0";
        n = (int)strlen(z);
        memcpy(out, z, (size_t)n + 1);
        return n;
    }
    n = 0;
    for (prec = 15; prec <= 17; ++prec) {
        n = snprintf(out, 32, "%.*g", prec, v);
        if (prec == 17 || strtod(out, NULL) == v) break;
    }
    for (i = 0; i < n; ++i) {
        if (out[i] == '.' || out[i] == 'e') {
            has_mark = 1;
            break;
        }
    }
    if (!has_mark && n + 2 < 32) {
        out[n++] = '.';
        out[n++] = '0';
        out[n] = '\0';
    }
    return n;
}

void ntsj_buf_double(ntsj_buf* b, double v) {
    char tmp[32];
    int n = ntsj_format_double(tmp, v);
    ntsj_buf_put(b, tmp, (size_t)n);
}
