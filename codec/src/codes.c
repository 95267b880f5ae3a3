/* The stable error codes of the JSON contract (schemas/error.schema.json) and
 * the HTTP status each maps to. The core's codes come from NTS_ERRNO_MAP
 * (base.h); the codec and the front ends add theirs here. Never rename, only
 * append (and add the name to the schema's enum: a test checks both lists). */
#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

typedef struct code_entry {
    const char* name;
    int http_status;
} code_entry;

static const code_entry codec_codes[] = {
#define NTSJ_XX_(e, name, status) {name, status},
    NTSJ_CODE_MAP(NTSJ_XX_)
#undef NTSJ_XX_
};

const char* ntsj_code_name(ntsj_code code) {
    return (int)code >= 0 && code < NTSJ_CODE_COUNT_ ? codec_codes[code].name : "internal_error";
}

/* The core's statuses: input faults are 400; the service's passing states are
 * 503 (retry later: memory ran short, or the service stopped the work); a bug
 * (internal, a bad argument that only a codec bug can pass) is 500. */
static int core_status_http(int status) {
    switch (status) {
    case NTS_ECANCELLED: return 503; /* the service stopped it (its deadline, a client that left) */
    case NTS_ENOMEM: return 503;     /* nothing wrong with the request: memory ran short now */
    case NTS_EINTERNAL:
    case NTS_EINVALID_ARGUMENT: return 500;
    default: return 400;
    }
}

static const int core_codes[] = {
#define NTSJ_XX_(e, v, name, msg) NTS_E##e,
    NTS_ERRNO_MAP(NTSJ_XX_)
#undef NTSJ_XX_
};

int ntsj_code_http_status(const char* code) {
    size_t i;
    if (!code || strcmp(code, "ok") == 0) return 200;
    for (i = 0; i < sizeof codec_codes / sizeof codec_codes[0]; ++i)
        if (strcmp(code, codec_codes[i].name) == 0) return codec_codes[i].http_status;
    for (i = 0; i < sizeof core_codes / sizeof core_codes[0]; ++i)
        if (strcmp(code, nts_status_name(core_codes[i])) == 0) return core_status_http(core_codes[i]);
    return 500;
}

int ntsj_code_known(const char* code) {
    size_t i;
    if (!code) return 0;
    for (i = 0; i < sizeof codec_codes / sizeof codec_codes[0]; ++i)
        if (strcmp(code, codec_codes[i].name) == 0) return 1;
    for (i = 0; i < sizeof core_codes / sizeof core_codes[0]; ++i)
        if (strcmp(code, nts_status_name(core_codes[i])) == 0) return 1;
    return 0;
}

/* ------------------------------------------------------------ names */

static const struct {
    const char* name;
    unsigned flag;
} output_names[] = {
#define NTSJ_XX_(ID, bit, name, result, records) {name, NTS_OUT_##ID},
    NTS_OUTPUT_MAP(NTSJ_XX_)
#undef NTSJ_XX_
};

unsigned ntsj_output_flag(const char* name, size_t n) {
    size_t i;
    if (!name) return 0;
    for (i = 0; i < sizeof output_names / sizeof output_names[0]; ++i)
        if (strlen(output_names[i].name) == n && memcmp(name, output_names[i].name, n) == 0) return output_names[i].flag;
    return 0;
}

/* The solver's names are NTS_SOLVER_NAMES (tables.h). */
#define NTSJ_SOLVER_FROM_(value, text) else if (strcmp(name, text) == 0) *out = value;
int ntsj_output_names_text(const char* last_sep, char* out, size_t size) {
    size_t i, n = 0, count = sizeof output_names / sizeof output_names[0];
    if (size == 0) return 0;
    out[0] = '\0';
    for (i = 0; i < count; ++i) {
        const char* sep = i == 0 ? "" : i + 1 == count && last_sep ? last_sep : last_sep ? ", " : ",";
        int w = snprintf(out + n, size - n, "%s%s", sep, output_names[i].name);
        if (w < 0 || (size_t)w >= size - n) break;
        n += (size_t)w;
    }
    return (int)n;
}

const char* ntsj_output_name(unsigned flag) {
    size_t i;
    for (i = 0; i < sizeof output_names / sizeof output_names[0]; ++i)
        if (output_names[i].flag == flag) return output_names[i].name;
    return NULL;
}

int ntsj_solver_from_name(const char* name, nts_solver* out) {
    if (!name) return -1;
    NTS_SOLVER_NAMES(NTSJ_SOLVER_FROM_)
    else return -1;
    return 0;
}

#define NTSJ_SOLVER_NAME_(value, text) if (solver == value) return text;
const char* ntsj_solver_name(nts_solver solver) {
    NTS_SOLVER_NAMES(NTSJ_SOLVER_NAME_)
    return "closed_form";
}

int ntsj_parse_count(const char* text, int suffixes, unsigned long long lo, unsigned long long hi,
                     unsigned long long* out) {
    char* end = NULL;
    unsigned long long v, mul = 1;
    if (text == NULL || *text < '0' || *text > '9') return -1; /* no sign, no space */
    errno = 0;
    v = strtoull(text, &end, 10);
    if (errno != 0 || end == text) return -1;
    if (suffixes && *end != '\0' && end[1] == '\0') {
        switch (*end) {
        case 'k': case 'K': mul = 1ull << 10; ++end; break;
        case 'm': case 'M': mul = 1ull << 20; ++end; break;
        case 'g': case 'G': mul = 1ull << 30; ++end; break;
        default: break;
        }
    }
    if (*end != '\0' || v > ULLONG_MAX / mul) return -1;
    v *= mul;
    if (v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

/* A fault: its code, where (a JSON pointer) and a message, formatted. */
void ntsj_fault_set(ntsj_fault* f, const char* code, const char* pointer, const char* fmt, ...) {
    va_list ap;
    f->code = code;
    snprintf(f->pointer, sizeof f->pointer, "%s", pointer ? pointer : "");
    va_start(ap, fmt);
    vsnprintf(f->message, sizeof f->message, fmt, ap);
    va_end(ap);
}
