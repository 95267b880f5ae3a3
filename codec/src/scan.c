/* Strict pre-scan of a request (RFC 8259), before cJSON sees it.
 *
 * cJSON 1.7 is lenient where the contract is not: it accepts "01", "1.", "-.5",
 * raw control characters and invalid UTF-8 inside strings, truncates a string at
 * "\u0000", and nests up to 1000 levels. One linear pass here rejects all of that
 * with a line/column and the JSON pointer of the container at fault, and bounds
 * the nesting depth before any tree is built. Recursion depth is bounded by
 * max_depth (at most NTSJ_MAX_DEPTH_LIMIT). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "codec_internal.h"

typedef struct scan_level {
    int is_array;
    long index;        /* current element of an array */
    const char* key;   /* current key of an object (raw, between the quotes) */
    size_t key_len;
} scan_level;

typedef struct scanner {
    const char* p;
    const char* end;
    const char* begin;
    int depth, max_depth;
    scan_level path[NTSJ_MAX_DEPTH_LIMIT + 1];
    ntsj_fault* fault;
} scanner;

static void scan_pointer(const scanner* s, char* out, size_t size) {
    size_t n = 0;
    int i;
    out[0] = '\0';
    for (i = 0; i < s->depth; ++i) {
        const scan_level* l = &s->path[i];
        char seg[80];
        size_t k = 0, j;
        if (l->is_array) {
            if (l->index < 0) break;
            snprintf(seg, sizeof seg, "/%ld", l->index);
            k = strlen(seg);
        } else {
            if (!l->key) break;
            seg[k++] = '/';
            for (j = 0; j < l->key_len && k + 3 < sizeof seg; ++j) {
                char c = l->key[j];
                if (c == '~') { seg[k++] = '~'; seg[k++] = '0'; }
                else if (c == '/') { seg[k++] = '~'; seg[k++] = '1'; }
                else seg[k++] = c;
            }
            seg[k] = '\0';
        }
        if (n + k + 1 > size) break;
        memcpy(out + n, seg, k + 1);
        n += k;
    }
}

static int scan_fail(scanner* s, const char* code, const char* what) {
    const char* q;
    long line = 1, col = 1;
    char ptr[256];
    for (q = s->begin; q < s->p && q < s->end; ++q) {
        if (*q == '\n') { ++line; col = 1; }
        else if (((unsigned char)*q & 0xC0) != 0x80) ++col;
    }
    scan_pointer(s, ptr, sizeof ptr);
    if (s->p >= s->end)
        ntsj_fault_set(s->fault, code, ptr, "%s at end of input (line %ld, column %ld)", what, line, col);
    else
        ntsj_fault_set(s->fault, code, ptr, "%s at line %ld, column %ld (byte %ld)", what, line, col,
                       (long)(s->p - s->begin));
    return -1;
}

static void skip_ws(scanner* s) {
    while (s->p < s->end && (*s->p == ' ' || *s->p == '\t' || *s->p == '\n' || *s->p == '\r')) ++s->p;
}

static int hex4(const char* p, unsigned* out) {
    unsigned v = 0;
    int i;
    for (i = 0; i < 4; ++i) {
        char c = p[i];
        v <<= 4;
        if (c >= '0' && c <= '9') v |= (unsigned)(c - '0');
        else if (c >= 'a' && c <= 'f') v |= (unsigned)(c - 'a' + 10);
        else if (c >= 'A' && c <= 'F') v |= (unsigned)(c - 'A' + 10);
        else return -1;
    }
    *out = v;
    return 0;
}

/* One UTF-8 sequence starting at s->p (first byte >= 0x80): RFC 3629 table. */
static int scan_utf8(scanner* s) {
    const unsigned char* u = (const unsigned char*)s->p;
    size_t avail = (size_t)(s->end - s->p);
    unsigned char c = u[0], lo = 0x80, hi = 0xBF;
    size_t len, i;
    if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c >= 0xE0 && c <= 0xEF) {
        len = 3;
        if (c == 0xE0) lo = 0xA0;
        if (c == 0xED) hi = 0x9F; /* no UTF-16 surrogates */
    } else if (c >= 0xF0 && c <= 0xF4) {
        len = 4;
        if (c == 0xF0) lo = 0x90;
        if (c == 0xF4) hi = 0x8F;
    } else return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "invalid UTF-8 byte in string");
    if (avail < len) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "truncated UTF-8 sequence in string");
    if (u[1] < lo || u[1] > hi) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "invalid UTF-8 sequence in string");
    for (i = 2; i < len; ++i)
        if (u[i] < 0x80 || u[i] > 0xBF) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "invalid UTF-8 sequence in string");
    s->p += len;
    return 0;
}

/* A string; s->p at the opening quote. */
static int scan_string(scanner* s) {
    ++s->p;
    while (s->p < s->end) {
        unsigned char c = (unsigned char)*s->p;
        if (c == '"') {
            ++s->p;
            return 0;
        }
        if (c < 0x20) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unescaped control character in string");
        if (c == '\\') {
            if (s->end - s->p < 2) break;
            switch (s->p[1]) {
            case '"': case '\\': case '/': case 'b': case 'f': case 'n': case 'r': case 't':
                s->p += 2;
                break;
            case 'u': {
                unsigned cp, lo;
                if (s->end - s->p < 6 || hex4(s->p + 2, &cp) != 0)
                    return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "bad \\u escape in string");
                if (cp == 0) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "\\u0000 is not allowed in strings");
                if (cp >= 0xDC00 && cp <= 0xDFFF)
                    return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unpaired UTF-16 surrogate in string");
                if (cp >= 0xD800 && cp <= 0xDBFF) {
                    if (s->end - s->p < 12 || s->p[6] != '\\' || s->p[7] != 'u' || hex4(s->p + 8, &lo) != 0 ||
                        lo < 0xDC00 || lo > 0xDFFF)
                        return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unpaired UTF-16 surrogate in string");
                    s->p += 12;
                } else {
                    s->p += 6;
                }
                break;
            }
            default:
                return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "invalid escape in string");
            }
            continue;
        }
        if (c >= 0x80) {
            if (scan_utf8(s) != 0) return -1;
            continue;
        }
        ++s->p;
    }
    return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unterminated string");
}

static int is_digit(char c) { return c >= '0' && c <= '9'; }

/* -? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)? */
static int scan_number(scanner* s) {
    const char* p = s->p;
    if (p < s->end && *p == '-') ++p;
    if (p >= s->end || !is_digit(*p)) {
        s->p = p;
        return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "invalid number");
    }
    if (*p == '0') {
        ++p;
        if (p < s->end && is_digit(*p)) {
            s->p = p;
            return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "leading zero in number");
        }
    } else {
        while (p < s->end && is_digit(*p)) ++p;
    }
    if (p < s->end && *p == '.') {
        ++p;
        if (p >= s->end || !is_digit(*p)) {
            s->p = p;
            return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "digit expected after decimal point");
        }
        while (p < s->end && is_digit(*p)) ++p;
    }
    if (p < s->end && (*p == 'e' || *p == 'E')) {
        ++p;
        if (p < s->end && (*p == '+' || *p == '-')) ++p;
        if (p >= s->end || !is_digit(*p)) {
            s->p = p;
            return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "digit expected in exponent");
        }
        while (p < s->end && is_digit(*p)) ++p;
    }
    s->p = p;
    return 0;
}

static int scan_literal(scanner* s, const char* word) {
    size_t n = strlen(word);
    if ((size_t)(s->end - s->p) < n || memcmp(s->p, word, n) != 0)
        return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unexpected character");
    s->p += n;
    return 0;
}

static int scan_value(scanner* s);

static int scan_container(scanner* s) {
    int is_array = *s->p == '[';
    char close = is_array ? ']' : '}';
    scan_level* l;
    if (s->depth >= s->max_depth) {
        char msg[80];
        snprintf(msg, sizeof msg, "nesting deeper than max_depth = %d levels", s->max_depth);
        return scan_fail(s, ntsj_code_name(NTSJ_TOO_DEEP), msg);
    }
    l = &s->path[s->depth++];
    l->is_array = is_array;
    l->index = -1;
    l->key = NULL;
    l->key_len = 0;
    ++s->p;
    skip_ws(s);
    if (s->p < s->end && *s->p == close) {
        ++s->p;
        --s->depth;
        return 0;
    }
    for (;;) {
        if (is_array) {
            ++l->index;
        } else {
            const char* k;
            l->key = NULL; /* a fault before the next key points at the object */
            skip_ws(s);
            if (s->p >= s->end || *s->p != '"') return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "object key (a string) expected");
            k = s->p + 1;
            if (scan_string(s) != 0) return -1;
            l->key = k;
            l->key_len = (size_t)(s->p - 1 - k);
            skip_ws(s);
            if (s->p >= s->end || *s->p != ':') return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "':' expected after object key");
            ++s->p;
        }
        if (scan_value(s) != 0) return -1;
        skip_ws(s);
        if (s->p < s->end && *s->p == ',') {
            ++s->p;
            continue;
        }
        if (s->p < s->end && *s->p == close) {
            ++s->p;
            --s->depth;
            return 0;
        }
        return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), is_array ? "',' or ']' expected" : "',' or '}' expected");
    }
}

static int scan_value(scanner* s) {
    skip_ws(s);
    if (s->p >= s->end) return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "value expected");
    switch (*s->p) {
    case '{': case '[': return scan_container(s);
    case '"': return scan_string(s);
    case 't': return scan_literal(s, "true");
    case 'f': return scan_literal(s, "false");
    case 'n': return scan_literal(s, "null");
    default:
        if (*s->p == '-' || is_digit(*s->p)) return scan_number(s);
        return scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unexpected character");
    }
}

int ntsj_scan(const char* json, size_t length, int max_depth, ntsj_fault* fault) {
    /* The scanner carries the path stack (~12 KiB): keep it off small thread stacks. */
    scanner* s = (scanner*)nts_alloc(sizeof *s);
    int rc;
    if (!s) {
        ntsj_fault_set(fault, nts_status_name(NTS_ENOMEM), "", "out of memory");
        return -1;
    }
    s->begin = s->p = json;
    s->end = json + length;
    s->depth = 0;
    s->max_depth = max_depth < 1 ? 1 : (max_depth > NTSJ_MAX_DEPTH_LIMIT ? NTSJ_MAX_DEPTH_LIMIT : max_depth);
    s->fault = fault;
    /* A UTF-8 byte order mark is not JSON (RFC 8259 section 8.1 lets us refuse it). */
    rc = scan_value(s);
    if (rc == 0) {
        skip_ws(s);
        if (s->p < s->end) rc = scan_fail(s, ntsj_code_name(NTSJ_INVALID_JSON), "unexpected data after the JSON value");
    }
    nts_free(s);
    return rc;
}

const char* ntsj_json_check(const char* json, size_t length, int max_depth, char* pointer, size_t pointer_size,
                            char* message, size_t message_size) {
    ntsj_fault fault;
    memset(&fault, 0, sizeof fault);
    if (pointer_size) pointer[0] = '\0';
    if (message_size) message[0] = '\0';
    if (json == NULL) { /* (no text: none of it read, whatever length says) */
        json = "";
        length = 0;
    }
    if (ntsj_scan(json, length, max_depth < 1 ? ntsj_default_config().max_depth : max_depth, &fault) == 0) return NULL;
    if (pointer_size) snprintf(pointer, pointer_size, "%s", fault.pointer);
    if (message_size) snprintf(message, message_size, "%s", fault.message);
    return fault.code != NULL ? fault.code : ntsj_code_name(NTSJ_INVALID_JSON);
}

size_t ntsj_memory_estimate(const char* json, size_t length) {
    /* Every value but the first follows a ',', a ':' or an opening bracket;
     * counting those (in strings too) can only over-count. */
    size_t i = 0, values = 1;
#if defined(__SSE2__)
    /* 16 bytes at a time (a 4 MB step body is read once per request). */
    {
        const __m128i comma = _mm_set1_epi8(','), colon = _mm_set1_epi8(':'), bracket = _mm_set1_epi8('['),
                      brace = _mm_set1_epi8('{');
        for (; i + 16 <= length; i += 16) {
            const __m128i v = _mm_loadu_si128((const __m128i*)(const void*)(json + i));
            const __m128i hit = _mm_or_si128(_mm_or_si128(_mm_cmpeq_epi8(v, comma), _mm_cmpeq_epi8(v, colon)),
                                             _mm_or_si128(_mm_cmpeq_epi8(v, bracket), _mm_cmpeq_epi8(v, brace)));
            unsigned m = (unsigned)_mm_movemask_epi8(hit);
            for (; m != 0; m &= m - 1) ++values; /* (the bits set; no popcount instruction assumed) */
        }
    }
#endif
    for (; i < length; ++i) {
        char c = json[i];
        values += c == ',' || c == ':' || c == '[' || c == '{';
    }
    if (values > (SIZE_MAX - length) / NTSJ_BYTES_PER_VALUE) return SIZE_MAX;
    return length + values * NTSJ_BYTES_PER_VALUE;
}
