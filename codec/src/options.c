/* The options of a request, from every door the codec has, by one table
 * (NTS_OPTION_MAP, tables.h): a scene's "options" (decode.c), a session
 * step's "options" and a binary step's query parameters (session.c). Each
 * kind of value is read here once; the doors differ only in which rows they
 * accept (the table's doors) and in how text is read (a query's values are
 * text, JSON's are typed). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "codec_internal.h"

const char* ntsj_json_type_name(const cJSON* v) {
    if (cJSON_IsObject(v)) return "an object";
    if (cJSON_IsArray(v)) return "an array";
    if (cJSON_IsString(v)) return "a string";
    if (cJSON_IsNumber(v)) return "a number";
    if (cJSON_IsBool(v)) return "a boolean";
    if (cJSON_IsNull(v)) return "null";
    return "an invalid value";
}

static int fault(ntsj_fault* f, const char* code, const char* ptr, const char* fmt, const char* a, const char* b) {
    ntsj_fault_set(f, code, ptr, fmt, a, b);
    return -1;
}

/* A number's range, where the codec checks it (the table's CODEC rows:
 * the core reads a negative search_radius as "the median segment", which
 * JSON says by leaving it out). */
int ntsj_option_number_check(int id, double v, const char* ptr, nts_option_value* out, ntsj_fault* f) {
    const nts_option_info* r = nts_option_info_of(id);
    if (r->check == NTS_OPTION_CHECK_CODEC && !nts_option_in_range(id, v)) {
        char range[48];
        nts_option_range_text(id, range, sizeof range);
        return fault(f, nts_status_name(NTS_EINVALID_OPTION), ptr, "%s must be %s", r->json, range);
    }
    out->number = v;
    return 0;
}

static int enum_value(int id, const char* name, nts_option_value* out) {
    const nts_option_info* r = nts_option_info_of(id);
    int k;
    for (k = 0; k < r->name_count; ++k)
        if (strcmp(name, r->names[k]) == 0) {
            out->enumerated = r->values[k];
            return 0;
        }
    return -1;
}

int ntsj_decode_outputs(const cJSON* v, const char* ptr, unsigned* out, ntsj_fault* f) {
    const cJSON* e;
    unsigned flags = 0;
    int i = 0;
    if (!cJSON_IsArray(v)) return fault(f, ntsj_code_name(NTSJ_INVALID_TYPE), ptr, "expected %s, got %s", "an array of output names", ntsj_json_type_name(v));
    cJSON_ArrayForEach(e, v) {
        char p[80];
        unsigned fl;
        snprintf(p, sizeof p, "%.60s/%d", ptr, i++);
        if (!cJSON_IsString(e)) return fault(f, ntsj_code_name(NTSJ_INVALID_TYPE), p, "expected %s, got %s", "an output name (a string)", ntsj_json_type_name(e));
        fl = ntsj_output_flag(e->valuestring, strlen(e->valuestring));
        if (!fl) {
            char names[160];
            ntsj_output_names_text(" or ", names, sizeof names);
            return fault(f, ntsj_code_name(NTSJ_INVALID_VALUE), p, "unknown output (expected %s)%s", names, "");
        }
        if (flags & fl) return fault(f, ntsj_code_name(NTSJ_INVALID_VALUE), p, "%s%s", "output listed twice", "");
        flags |= fl;
    }
    *out = flags;
    return 0;
}

int ntsj_option_json(int id, const cJSON* v, const char* ptr, nts_option_value* out, ntsj_fault* f) {
    const nts_option_info* r = nts_option_info_of(id);
    char names[160];
    switch (r->kind) {
    case NTS_OPTION_KIND_NUMBER:
        if (!cJSON_IsNumber(v)) return fault(f, ntsj_code_name(NTSJ_INVALID_TYPE), ptr, "expected %s, got %s", "a number", ntsj_json_type_name(v));
        if (!isfinite(v->valuedouble))
            return fault(f, nts_status_name(NTS_ENONFINITE), ptr, "%s%s", "number is not finite (out of the double range)", "");
        return ntsj_option_number_check(id, v->valuedouble, ptr, out, f);
    case NTS_OPTION_KIND_ENUM:
        if (!cJSON_IsString(v)) return fault(f, ntsj_code_name(NTSJ_INVALID_TYPE), ptr, "expected %s, got %s", "a string", ntsj_json_type_name(v));
        if (enum_value(id, v->valuestring, out) == 0) return 0;
        nts_option_names_text(id, names, sizeof names);
        /* "unknown solver (expected closed_form or newton)" */
        return fault(f, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "unknown %s (expected %s)", r->json, names);
    case NTS_OPTION_KIND_OUTPUTS:
        return ntsj_decode_outputs(v, ptr, &out->flags, f);
    default:
        return fault(f, "internal_error", ptr, "%s%s", "not a value option", "");
    }
}

int ntsj_output_list(const char* text, int policy, unsigned* out, const char** bad, size_t* bad_length) {
    unsigned flags = 0;
    const char* p = text;
    while (*p) {
        size_t n = strcspn(p, ",");
        unsigned fl = ntsj_output_flag(p, n);
        *bad = p;
        *bad_length = n;
        if (!fl) return NTSJ_LIST_UNKNOWN;
        if ((flags & fl) && !(policy & NTSJ_LIST_DUPLICATES_OK)) return NTSJ_LIST_DUPLICATE;
        flags |= fl;
        p += n;
        if (*p == ',') {
            ++p;
            if (!*p && !(policy & NTSJ_LIST_TRAILING_COMMA_OK)) {
                *bad = p;
                *bad_length = 0;
                return NTSJ_LIST_UNKNOWN;
            }
        }
    }
    *out = flags;
    return 0;
}

int ntsj_option_text(int id, const char* text, const char* ptr, nts_option_value* out, ntsj_fault* f) {
    const nts_option_info* r = nts_option_info_of(id);
    char names[160];
    switch (r->kind) {
    case NTS_OPTION_KIND_NUMBER: {
        double v = 0.0;
        const int rc = ntsj_parse_double(text, &v); /* (a JSON number, read as the body's are) */
        if (rc < 0)
            return fault(f, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "query parameter %.64s=%.32s is not a number", r->json, text);
        if (rc > 0) return fault(f, nts_status_name(NTS_ENONFINITE), ptr, "%s is not a finite number%s", r->json, "");
        return ntsj_option_number_check(id, v, ptr, out, f);
    }
    case NTS_OPTION_KIND_ENUM:
        if (enum_value(id, text, out) == 0) return 0;
        nts_option_names_text(id, names, sizeof names);
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "unknown %s \"%.32s\" (expected %s)", r->json, text, names);
        return -1;
    case NTS_OPTION_KIND_OUTPUTS: {
        const char* bad = text;
        size_t n = 0;
        int rc = ntsj_output_list(text, 0, &out->flags, &bad, &n);
        if (rc == 0) return 0;
        ntsj_fault_set(f, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "outputs=%.64s: %s \"%.*s\"", text,
                       rc == NTSJ_LIST_DUPLICATE ? "output listed twice:" : "unknown output", (int)(n > 32 ? 32 : n), bad);
        return -1;
    }
    default:
        return fault(f, "internal_error", ptr, "%s%s", "not a value option", "");
    }
}

int ntsj_option_door_names(int door, char* out, size_t size) {
    size_t n = 0;
    int id, first = 1;
    if (size == 0) return 0;
    out[0] = '\0';
    for (id = 0; id < NTS_OPT_COUNT_; ++id) {
        int w;
        if (!(nts_option_info_of(id)->doors & door)) continue;
        w = snprintf(out + n, size - n, "%s%s", first ? "" : ", ", nts_option_info_of(id)->json);
        if (w < 0 || (size_t)w >= size - n) break;
        n += (size_t)w;
        first = 0;
    }
    return (int)n;
}

/* ------------------------------------------------------------ overrides */

#define NTSJ_OVERRIDE_SET_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, \
                           names, help)                                                                       \
    NTS_OPT_IS_##doors(case NTS_OPT_##ID: {                                                                   \
        nts_options tmp_ = nts_default_options();                                                             \
        nts_option_store(&tmp_, id, v);                                                                       \
        ov->field = tmp_.field;                                                                               \
        ov->has_##field = 1;                                                                                  \
        return 0;                                                                                             \
    })

int ntsj_override_set(ntsj_overrides* ov, int id, const nts_option_value* v) {
    switch (id) {
        NTS_OPTION_MAP(NTSJ_OVERRIDE_SET_)
    default: return -1;
    }
}

#define NTSJ_OVERRIDE_APPLY_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, \
                             names, help)                                                                       \
    NTS_OPT_IS_##doors(if (ov->has_##field) o->field = ov->field;)

void ntsj_overrides_apply(const ntsj_overrides* ov, nts_options* o) {
    NTS_OPTION_MAP(NTSJ_OVERRIDE_APPLY_)
}

int ntsj_override_given(const ntsj_overrides* ov, int id) {
    switch (id) {
#define NTSJ_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    NTS_OPT_IS_##doors(case NTS_OPT_##ID: return ov->has_##field;)
        NTS_OPTION_MAP(NTSJ_XX_)
#undef NTSJ_XX_
    default: return 0;
    }
}

double ntsj_override_number(const ntsj_overrides* ov, int id) {
    switch (id) {
#define NTSJ_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    NTS_OPT_IS_##doors(case NTS_OPT_##ID: return (double)ov->field;)
        NTS_OPTION_MAP(NTSJ_XX_)
#undef NTSJ_XX_
    default: return 0.0;
    }
}
