/* Options with defaults (ntscontact.h) and their validation at the boundary.
 * The defaults, ranges and names come from NTS_OPTION_MAP (tables.h); the
 * checks below the generated ones are of the fields no front end sets. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

/* ------------------------------------------------------------ the table */

#define NTS_NAME_(value, name) name,
#define NTS_VALUE_(value, name) (int)(value),
#define NTS_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    static const char* const names_##ID[] = {names(NTS_NAME_) NULL};                                              \
    static const int values_##ID[] = {names(NTS_VALUE_) 0};
NTS_OPTION_MAP(NTS_XX_)
#undef NTS_XX_

static const nts_option_info option_rows[NTS_OPT_COUNT_] = {
#define NTS_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    {json, flag, meta, help, NTS_OPTION_KIND_##kind, lo, hi, NTS_OPTION_BOUND_##bound, NTS_OPTION_CHECK_##check,  \
     NTS_PRESENCE_##presence, NTS_OPTION_DOORS_##doors, names_##ID, values_##ID,                                  \
     (int)(sizeof names_##ID / sizeof names_##ID[0]) - 1},
#define NTS_PRESENCE_REQUIRED 1
#define NTS_PRESENCE_OPTIONAL 0
    NTS_OPTION_MAP(NTS_XX_)
#undef NTS_XX_
};

const nts_option_info* nts_option_info_of(int id) {
    return id >= 0 && id < NTS_OPT_COUNT_ ? &option_rows[id] : NULL;
}

int nts_option_find(const char* json, size_t n) {
    int i;
    if (!json) return -1;
    for (i = 0; i < NTS_OPT_COUNT_; ++i)
        if (strlen(option_rows[i].json) == n && memcmp(option_rows[i].json, json, n) == 0) return i;
    return -1;
}

/* Each kind's store: a field of its C type (an OBJECT is the decoder's). */
#define NTS_STORE_NUMBER(o, field, ctype, v) (o)->field = (v)->number
#define NTS_STORE_ENUM(o, field, ctype, v) (o)->field = (ctype)(v)->enumerated
#define NTS_STORE_OUTPUTS(o, field, ctype, v) (o)->field = (v)->flags
#define NTS_STORE_OBJECT(o, field, ctype, v) (void)(v)

void nts_option_store(nts_options* o, int id, const nts_option_value* v) {
    switch (id) {
#define NTS_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    case NTS_OPT_##ID: NTS_STORE_##kind(o, field, ctype, v); break;
        NTS_OPTION_MAP(NTS_XX_)
#undef NTS_XX_
    default: break;
    }
}

int nts_option_in_range(int id, double v) {
    const nts_option_info* r = nts_option_info_of(id);
    if (!r) return 0;
    switch (r->bound) {
    case NTS_OPTION_BOUND_CLOSED: return v >= r->min && v <= r->max;
    case NTS_OPTION_BOUND_ABOVE: return v > r->min && nts_is_valid_double(v);
    case NTS_OPTION_BOUND_FROM: return v >= r->min;
    default: return 1;
    }
}

int nts_option_range_text(int id, char* out, size_t size) {
    const nts_option_info* r = nts_option_info_of(id);
    int n = 0;
    if (!r || size == 0) return 0;
    out[0] = '\0';
    switch (r->bound) {
    case NTS_OPTION_BOUND_CLOSED: n = snprintf(out, size, "in [%g, %g]", r->min, r->max); break;
    case NTS_OPTION_BOUND_ABOVE: n = snprintf(out, size, "> %g", r->min); break;
    case NTS_OPTION_BOUND_FROM: n = snprintf(out, size, ">= %g", r->min); break;
    default: break;
    }
    return n < 0 ? 0 : n;
}

int nts_option_names_text(int id, char* out, size_t size) {
    const nts_option_info* r = nts_option_info_of(id);
    size_t n = 0;
    int k;
    if (!r || size == 0) return 0;
    out[0] = '\0';
    for (k = 0; k < r->name_count; ++k) {
        const char* sep = k == 0 ? "" : k + 1 == r->name_count ? " or " : ", ";
        int w = snprintf(out + n, size - n, "%s%s", sep, r->names[k]);
        if (w < 0 || (size_t)w >= size - n) break;
        n += (size_t)w;
    }
    return (int)n;
}

/* ------------------------------------------------- defaults and checks */

#define NTS_DEFAULT_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, \
                     help)                                                                                      \
    NTS_OPT_HAS_FIELD_##kind(o.field = (def);)

nts_options nts_default_options(void) {
    nts_options o;
    memset(&o, 0, sizeof o);
    NTS_OPTION_MAP(NTS_DEFAULT_) /* alpha 0.2 as in Abaqus (docs/model.md §3) */
    o.threads = 0;
    return o;
}

static int option_error(nts_error* err, const char* name, const char* what) {
    nts_where at = nts_at(-1, -1, -1, -1);
    at.option = name;
    return nts_error_set(err, NTS_EINVALID_OPTION, at, "%s %s", name, what);
}

/* A row's check of a value: its range (the core's rows), its names, its flags. */
static int check_row(int id, double number, int enumerated, unsigned flags, nts_error* err) {
    const nts_option_info* r = &option_rows[id];
    char what[96], range[48];
    int k;
    switch (r->kind) {
    case NTS_OPTION_KIND_NUMBER:
        if (r->check != NTS_OPTION_CHECK_CORE || nts_option_in_range(id, number)) return NTS_OK;
        nts_option_range_text(id, range, sizeof range);
        /* "alpha must be in [0, 0.5]", "penalty must be a finite number > 0" */
        snprintf(what, sizeof what, "must be %s%s", r->bound == NTS_OPTION_BOUND_ABOVE ? "a finite number " : "", range);
        return option_error(err, r->json, what);
    case NTS_OPTION_KIND_ENUM:
        for (k = 0; k < r->name_count; ++k)
            if (r->values[k] == enumerated) return NTS_OK;
        memcpy(what, "must be ", 9);
        nts_option_names_text(id, what + 8, sizeof what - 8);
        return option_error(err, r->json, what);
    case NTS_OPTION_KIND_OUTPUTS:
        return (flags & ~(unsigned)NTS_OUT_ALL) == 0u ? NTS_OK : option_error(err, r->json, "has unknown flags");
    default:
        return NTS_OK;
    }
}

#define NTS_NUMBER_OF_NUMBER(o, field) (double)(o)->field
#define NTS_NUMBER_OF_ENUM(o, field) 0.0
#define NTS_NUMBER_OF_OUTPUTS(o, field) 0.0
#define NTS_ENUM_OF_NUMBER(o, field) 0
#define NTS_ENUM_OF_ENUM(o, field) (int)(o)->field
#define NTS_ENUM_OF_OUTPUTS(o, field) 0
#define NTS_FLAGS_OF_NUMBER(o, field) 0u
#define NTS_FLAGS_OF_ENUM(o, field) 0u
#define NTS_FLAGS_OF_OUTPUTS(o, field) (o)->field
#define NTS_CHECK_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    NTS_OPT_HAS_FIELD_##kind(                                                                                      \
        rc = check_row(NTS_OPT_##ID, NTS_NUMBER_OF_##kind(o, field), NTS_ENUM_OF_##kind(o, field),              \
                       NTS_FLAGS_OF_##kind(o, field), err);                                                        \
        if (rc != NTS_OK) return rc;)

int nts_options_validate(const nts_options* o, nts_error* err) {
    int rc;
    if (o == NULL) return option_error(err, "options", "missing");
    NTS_OPTION_MAP(NTS_CHECK_)
    /* The core reads a negative radius as "the median segment" (the JSON
     * doors check the table's range, CODEC); it must still be a number. */
    if (!nts_is_valid_double(o->search_radius))
        return option_error(err, "search_radius", "must be finite (negative means the median segment)");
    if (o->threads < 0 || o->threads > 1024) return option_error(err, "threads", "must be in [0, 1024]");
    if (o->max_candidates < 0) return option_error(err, "max_candidates", "must be >= 0 (0: the default)");
    if (!(o->friction >= 0.0 && o->friction <= 10.0)) return option_error(err, "friction", "must be in [0, 10]");
    if (!(o->tangential_penalty >= 0.0) || !nts_is_valid_double(o->tangential_penalty))
        return option_error(err, "tangential_penalty", "must be a finite number >= 0 (0: the penalty)");
    return NTS_OK;
}
