/* Decode a request (schemas/scene.schema.json) from a cJSON tree into the
 * core's nts_scene_def, checking everything the schema says and more: types,
 * required and unknown fields, duplicate keys (cJSON keeps them all, so each
 * object's children are walked once against its field table), finite numbers,
 * integer indices in range, unique body ids. Every fault carries the JSON pointer
 * of the value at fault. Geometry (short loops aside) is left to
 * nts_scene_create, whose error record ntsj_pointer_of_error maps back.
 *
 * Arrays are walked with cJSON_ArrayForEach only: cJSON_GetArrayItem in a loop
 * is quadratic. Lookups are by our own field tables, so case-sensitive. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "codec_internal.h"

#define NTSJ_MAX_ID_BYTES 256
#define NTSJ_MAX_INDEX 2147483647.0

typedef struct decoder {
    const ntsj_config* cfg;
    ntsj_fault* fault;
    ntsj_scene* scene;
    int oom;
    int* order; /* the bodies in id order (check_unique_ids), for the history's lookups; or NULL */
    int part;   /* a part of a scene (ntsj_decode_part): no bodies is fine */
} decoder;

/* ---------------------------------------------------------- pointers */

/* Append "/<token>" with RFC 6901 escapes (~ -> ~0, / -> ~1), bounded. */
void ntsj_pointer_append_key(char* ptr, size_t size, const char* key) {
    size_t n = strlen(ptr), i;
    if (n + 2 >= size) return;
    ptr[n++] = '/';
    for (i = 0; key[i] && n + 3 < size; ++i) {
        if (key[i] == '~') { ptr[n++] = '~'; ptr[n++] = '0'; }
        else if (key[i] == '/') { ptr[n++] = '~'; ptr[n++] = '1'; }
        else ptr[n++] = key[i];
    }
    ptr[n] = '\0';
}

static int fail(decoder* d, const char* code, const char* ptr, const char* msg) {
    ntsj_fault_set(d->fault, code, ptr, "%s", msg);
    return -1;
}

#define type_name ntsj_json_type_name

static int fail_type(decoder* d, const char* ptr, const cJSON* v, const char* expected) {
    ntsj_fault_set(d->fault, ntsj_code_name(NTSJ_INVALID_TYPE), ptr, "expected %s, got %s", expected, type_name(v));
    return -1;
}

/* ------------------------------------------------------------ fields */

/* Walk the members of `obj` once: each must be one of `names` (exact, case-
 * sensitive) and appear once. found[i] gets the member named names[i] or NULL. */
static int take_fields(decoder* d, const cJSON* obj, const char* ptr, const char* const* names, int count,
                       const cJSON** found) {
    const cJSON* m;
    int i;
    for (i = 0; i < count; ++i) found[i] = NULL;
    cJSON_ArrayForEach(m, obj) {
        const char* key = m->string ? m->string : "";
        for (i = 0; i < count; ++i)
            if (strcmp(key, names[i]) == 0) break;
        if (i == count || found[i]) {
            char p[256];
            snprintf(p, sizeof p, "%s", ptr);
            ntsj_pointer_append_key(p, sizeof p, key);
            ntsj_fault_set(d->fault, i == count ? ntsj_code_name(NTSJ_UNKNOWN_FIELD) : ntsj_code_name(NTSJ_DUPLICATE_KEY), p,
                           i == count ? "unknown field \"%.64s\"" : "key \"%.64s\" appears more than once", key);
            return -1;
        }
        found[i] = m;
    }
    return 0;
}

static int get_number(decoder* d, const cJSON* v, const char* ptr, double* out) {
    if (!cJSON_IsNumber(v)) return fail_type(d, ptr, v, "a number");
    if (!isfinite(v->valuedouble)) return fail(d, nts_status_name(NTS_ENONFINITE), ptr, "number is not finite (out of the double range)");
    *out = v->valuedouble;
    return 0;
}

/* An integer index in [0, bound). The pointer is only formatted on a fault
 * (printf-ing one per element would cost more than the rest of decoding). */
static int get_index(decoder* d, const cJSON* v, int bound, int* out, int body, const char* list, int item, int k) {
    double x;
    const char* code;
    char ptr[128], msg[96];
    if (cJSON_IsNumber(v)) {
        x = v->valuedouble;
        if (x >= 0.0 && x < (double)bound && x == floor(x)) {
            *out = (int)x;
            return 0;
        }
        if (!isfinite(x) || x != floor(x)) {
            code = ntsj_code_name(NTSJ_INVALID_VALUE);
            snprintf(msg, sizeof msg, "a node index must be an integer");
        } else {
            code = nts_status_name(NTS_EINDEX_RANGE);
            snprintf(msg, sizeof msg, "node index %.17g is out of range [0, %d)", x, bound);
        }
    } else {
        code = ntsj_code_name(NTSJ_INVALID_TYPE);
        snprintf(msg, sizeof msg, "expected an integer node index, got %s", type_name(v));
    }
    snprintf(ptr, sizeof ptr, "/bodies/%d/%s/%d/%d", body, list, item, k);
    ntsj_fault_set(d->fault, code, ptr, "%s", msg);
    return -1;
}

static int array_size(const cJSON* a) {
    const cJSON* e;
    long n = 0;
    cJSON_ArrayForEach(e, a) { if (n < 2147483647L) ++n; }
    return (int)n;
}

/* ----------------------------------------------------------- options */

/* The names of a scene's options, in the table's order (NTS_OPTION_MAP). */
static const char* const option_fields[NTS_OPT_COUNT_] = {
#define NTSJ_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) json,
    NTS_OPTION_MAP(NTSJ_XX_)
#undef NTSJ_XX_
};

static int decode_periodic(decoder* d, const cJSON* v) {
    static const char* const names[] = {"lx", "ly"};
    const cJSON* f[2];
    int i;
    double side[2];
    if (!cJSON_IsObject(v)) return fail_type(d, "/options/periodic", v, "an object {\"lx\", \"ly\"}");
    if (take_fields(d, v, "/options/periodic", names, 2, f) != 0) return -1;
    for (i = 0; i < 2; ++i) {
        char p[64];
        snprintf(p, sizeof p, "/options/periodic/%s", names[i]);
        if (!f[i]) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), p, i ? "periodic box needs \"ly\"" : "periodic box needs \"lx\"");
        if (get_number(d, f[i], p, &side[i]) != 0) return -1;
        if (!(side[i] > 0.0)) return fail(d, nts_status_name(NTS_EINVALID_OPTION), p, "periodic box side must be > 0");
    }
    d->scene->lx = side[0];
    d->scene->ly = side[1];
    d->scene->has_periodic = 1;
    return 0;
}

/* "friction": {"coefficient": mu, "tangential_penalty": eps_T} (docs/model.md
 * §14). The ranges are the core's (nts_options_validate), whose faults
 * ntsj_pointer_of_error points back here. */
static int decode_friction(decoder* d, const cJSON* v) {
    static const char* const names[] = {"coefficient", "tangential_penalty"};
    const cJSON* f[2];
    double x[2] = {0.0, 0.0};
    int i;
    if (!cJSON_IsObject(v)) return fail_type(d, "/options/friction", v, "an object {\"coefficient\", \"tangential_penalty\"}");
    if (take_fields(d, v, "/options/friction", names, 2, f) != 0) return -1;
    if (!f[0]) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), "/options/friction/coefficient", "friction needs a \"coefficient\" (Coulomb's mu)");
    for (i = 0; i < 2; ++i) {
        char p[64];
        snprintf(p, sizeof p, "/options/friction/%s", names[i]);
        if (f[i] && get_number(d, f[i], p, &x[i]) != 0) return -1;
    }
    d->scene->options.friction = x[0];
    d->scene->options.tangential_penalty = x[1]; /* 0: the penalty */
    return 0;
}

/* A scene's "options": every row of the table, in its order; `given` gets a
 * bit for each option present (the required ones are checked with the
 * overrides, which may supply them). */
static int decode_options(decoder* d, const cJSON* v, unsigned* given) {
    const cJSON* f[NTS_OPT_COUNT_];
    int id;
    if (!cJSON_IsObject(v)) return fail_type(d, "/options", v, "an object");
    if (take_fields(d, v, "/options", option_fields, NTS_OPT_COUNT_, f) != 0) return -1;
    for (id = 0; id < NTS_OPT_COUNT_; ++id) {
        char ptr[64];
        nts_option_value val;
        if (!f[id]) continue;
        *given |= 1u << id;
        if (nts_option_info_of(id)->kind == NTS_OPTION_KIND_OBJECT) {
            if ((id == NTS_OPT_PERIODIC ? decode_periodic(d, f[id]) : decode_friction(d, f[id])) != 0) return -1;
            continue;
        }
        snprintf(ptr, sizeof ptr, "/options/%s", option_fields[id]);
        memset(&val, 0, sizeof val);
        if (ntsj_option_json(id, f[id], ptr, &val, d->fault) != 0) return -1;
        nts_option_store(&d->scene->options, id, &val);
    }
    return 0;
}

/* ------------------------------------------------------------ bodies */

static int decode_id(decoder* d, const cJSON* v, const char* ptr, ntsj_id* id) {
    if (cJSON_IsString(v)) {
        size_t n = strlen(v->valuestring);
        if (n == 0) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "a body id must not be empty");
        if (n > NTSJ_MAX_ID_BYTES) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "a body id is at most 256 bytes");
        id->sval = (char*)nts_alloc(n + 1);
        if (!id->sval) {
            d->oom = 1;
            return -1;
        }
        memcpy(id->sval, v->valuestring, n + 1);
        id->is_int = 0;
        return 0;
    }
    if (cJSON_IsNumber(v)) {
        double x = v->valuedouble;
        /* Integers that a double holds exactly, so they echo back unchanged:
         * |id| < 2^53, since 2^53 itself may be 2^53 + 1 rounded by the parser
         * (two different ids would then collide). */
        if (!isfinite(x) || x != floor(x) || fabs(x) >= 9007199254740992.0)
            return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr,
                        "a numeric body id must be an integer with |id| < 2^53 (9007199254740992); larger ids do "
                        "not survive a JSON number: send them as strings");
        id->is_int = 1;
        id->ival = (long long)x;
        return 0;
    }
    return fail_type(d, ptr, v, "a string or an integer");
}

static const char* const body_fields[] = {"id", "nodes", "loops", "triangles", "alpha", "role", "mesh_points",
                                          "reference", "surface", "friction", "self_contact"};
enum { BODY_ID, BODY_NODES, BODY_LOOPS, BODY_TRIANGLES, BODY_ALPHA, BODY_ROLE, BODY_MESH_POINTS, BODY_REFERENCE,
       BODY_SURFACE, BODY_FRICTION, BODY_SELF_CONTACT, BODY_COUNT };

/* "mesh_points": the mesh point of each node (a converted mesh's map, kept for
 * the caller: the core does not use it). Checked: one non-negative integer per node. */
static int check_mesh_points(decoder* d, int b, const cJSON* v) {
    char p[96];
    const cJSON* e;
    int k = 0, n = d->scene->defs[b].node_count;
    snprintf(p, sizeof p, "/bodies/%d/mesh_points", b);
    if (!cJSON_IsArray(v)) return fail_type(d, p, v, "an array of mesh point indices, one per node");
    cJSON_ArrayForEach(e, v) {
        if (!cJSON_IsNumber(e) || !(e->valuedouble >= 0.0) || e->valuedouble != floor(e->valuedouble) ||
            e->valuedouble > NTSJ_MAX_INDEX) {
            snprintf(p, sizeof p, "/bodies/%d/mesh_points/%d", b, k);
            return fail(d, cJSON_IsNumber(e) ? ntsj_code_name(NTSJ_INVALID_VALUE) : ntsj_code_name(NTSJ_INVALID_TYPE), p,
                        "a mesh point index is a non-negative integer");
        }
        ++k;
    }
    if (k != n) {
        char msg[96];
        snprintf(msg, sizeof msg, "%d mesh points for %d nodes (one per node)", k, n);
        return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, msg);
    }
    return 0;
}

/* The points of `v` ([x, y] pairs of finite numbers) into `out`, which has
 * room for all of them; faults named under `ptr` ("/bodies/B/nodes" or
 * "/bodies/B/reference"). */
static int decode_points(decoder* d, const char* ptr, const cJSON* v, nts_vec2* out) {
    const cJSON* e;
    int i = 0;
    cJSON_ArrayForEach(e, v) {
        char p[112], pc[128];
        const cJSON* c;
        double xy[2];
        int k = 0;
        if (!cJSON_IsArray(e)) {
            snprintf(p, sizeof p, "%s/%d", ptr, i);
            return fail_type(d, p, e, "a node [x, y]");
        }
        cJSON_ArrayForEach(c, e) {
            if (k < 2 && cJSON_IsNumber(c) && isfinite(c->valuedouble)) {
                xy[k++] = c->valuedouble;
                continue;
            }
            snprintf(pc, sizeof pc, "%s/%d/%d", ptr, i, k);
            if (k >= 2) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), pc, "a node has exactly two coordinates [x, y]");
            if (!cJSON_IsNumber(c)) return fail_type(d, pc, c, "a coordinate (a number)");
            return fail(d, nts_status_name(NTS_ENONFINITE), pc, "coordinate is not a finite number");
        }
        if (k != 2) {
            snprintf(p, sizeof p, "%s/%d", ptr, i);
            return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, "a node has exactly two coordinates [x, y]");
        }
        out[i++] = nts_v2(xy[0], xy[1]);
    }
    return 0;
}

static int decode_nodes(decoder* d, int b, const cJSON* v, long long* total) {
    char ptr[96];
    nts_vec2* nodes;
    int n;
    snprintf(ptr, sizeof ptr, "/bodies/%d/nodes", b);
    if (!cJSON_IsArray(v)) return fail_type(d, ptr, v, "an array of [x, y] nodes");
    n = array_size(v);
    if (n == 0) return fail(d, nts_status_name(NTS_ENO_NODES), ptr, "body has no nodes");
    if (n > d->cfg->limits.max_nodes_per_body) {
        ntsj_fault_set(d->fault, nts_status_name(NTS_ELIMIT), ptr, "body has %d nodes, more than max_nodes_per_body = %d", n,
                       d->cfg->limits.max_nodes_per_body);
        return -1;
    }
    *total += n;
    if (*total > d->cfg->limits.max_nodes) {
        ntsj_fault_set(d->fault, nts_status_name(NTS_ELIMIT), ptr, "scene has more nodes than max_nodes = %lld",
                       d->cfg->limits.max_nodes);
        return -1;
    }
    nodes = (nts_vec2*)nts_alloc((size_t)n * sizeof *nodes);
    if (!nodes) {
        d->oom = 1;
        return -1;
    }
    d->scene->nodes[b] = nodes;
    d->scene->defs[b].nodes = nodes;
    d->scene->defs[b].node_count = n;
    return decode_points(d, ptr, v, nodes);
}

/* "reference": the body's reference configuration (nts_body_def.reference),
 * one [x, y] per node. */
static int decode_reference(decoder* d, int b, const cJSON* v) {
    char ptr[96];
    nts_vec2* ref;
    int n = d->scene->defs[b].node_count, m;
    snprintf(ptr, sizeof ptr, "/bodies/%d/reference", b);
    if (!cJSON_IsArray(v)) return fail_type(d, ptr, v, "an array of [x, y] points, one per node");
    m = array_size(v);
    if (m != n) {
        ntsj_fault_set(d->fault, ntsj_code_name(NTSJ_INVALID_VALUE), ptr,
                       "%d reference points for %d nodes (one per node, in the order of \"nodes\")", m, n);
        return -1;
    }
    ref = (nts_vec2*)nts_alloc((size_t)n * sizeof *ref);
    if (!ref) {
        d->oom = 1;
        return -1;
    }
    d->scene->refs[b] = ref;
    d->scene->defs[b].reference = ref;
    return decode_points(d, ptr, v, ref);
}

static int decode_loops(decoder* d, int b, const cJSON* v) {
    char ptr[96];
    const cJSON* loop;
    int loops, total = 0, l = 0, pos = 0, *ints;
    int node_count = d->scene->defs[b].node_count;
    snprintf(ptr, sizeof ptr, "/bodies/%d/loops", b);
    if (!cJSON_IsArray(v)) return fail_type(d, ptr, v, "an array of loops");
    loops = array_size(v);
    if (loops == 0) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "loops must hold at least one loop (or be omitted)");
    cJSON_ArrayForEach(loop, v) {
        char p[112];
        int n = cJSON_IsArray(loop) ? array_size(loop) : -1;
        if (n < 3 || n > 2147483647 - 1 - loops - total) {
            snprintf(p, sizeof p, "%s/%d", ptr, l);
            if (n < 0) return fail_type(d, p, loop, "a loop (an array of node indices)");
            if (n < 3) return fail(d, nts_status_name(NTS_ELOOP_TOO_SHORT), p, "loop has fewer than 3 nodes");
            return fail(d, nts_status_name(NTS_ELIMIT), p, "loops are too long");
        }
        total += n;
        ++l;
    }
    ints = (int*)nts_alloc(((size_t)total + (size_t)loops + 1) * sizeof *ints);
    if (!ints) {
        d->oom = 1;
        return -1;
    }
    d->scene->ints[b] = ints;
    d->scene->defs[b].loop_nodes = ints;
    d->scene->defs[b].loop_start = ints + total;
    d->scene->defs[b].loop_count = loops;
    l = 0;
    cJSON_ArrayForEach(loop, v) {
        const cJSON* e;
        int k = 0;
        ints[total + l] = pos;
        cJSON_ArrayForEach(e, loop) {
            if (get_index(d, e, node_count, &ints[pos], b, "loops", l, k) != 0) return -1;
            ++pos;
            ++k;
        }
        ++l;
    }
    ints[total + loops] = pos;
    return 0;
}

/* Fill out[] (room for `size` indices per item) with the index tuples of
 * array `v`, each an array of exactly `size` node indices in range, named
 * under /bodies/B/<list>/I/K; `item` and `exactly` say what an item is, for
 * the messages ("a triangle [i, j, k]", "a triangle has exactly three node
 * indices"). */
static int decode_tuples(decoder* d, int b, const cJSON* v, const char* list, int size, int* out, const char* item,
                         const char* exactly) {
    const cJSON* t;
    const int node_count = d->scene->defs[b].node_count;
    int i = 0;
    cJSON_ArrayForEach(t, v) {
        char p[112];
        const cJSON* e;
        int k = 0;
        if (!cJSON_IsArray(t)) {
            snprintf(p, sizeof p, "/bodies/%d/%s/%d", b, list, i);
            return fail_type(d, p, t, item);
        }
        cJSON_ArrayForEach(e, t) {
            if (k >= size) {
                snprintf(p, sizeof p, "/bodies/%d/%s/%d/%d", b, list, i, k);
                return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, exactly);
            }
            if (get_index(d, e, node_count, &out[size * i + k], b, list, i, k) != 0) return -1;
            ++k;
        }
        if (k != size) {
            snprintf(p, sizeof p, "/bodies/%d/%s/%d", b, list, i);
            return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, exactly);
        }
        ++i;
    }
    return 0;
}

static int decode_triangles(decoder* d, int b, const cJSON* v) {
    char ptr[96];
    int count, *tri;
    snprintf(ptr, sizeof ptr, "/bodies/%d/triangles", b);
    if (!cJSON_IsArray(v)) return fail_type(d, ptr, v, "an array of triangles [i, j, k]");
    count = array_size(v);
    if (count == 0) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "triangles must hold at least one triangle");
    if (count > 2 * d->cfg->limits.max_nodes_per_body) return fail(d, nts_status_name(NTS_ELIMIT), ptr, "more triangles than twice max_nodes_per_body");
    tri = (int*)nts_alloc((size_t)count * 3 * sizeof *tri);
    if (!tri) {
        d->oom = 1;
        return -1;
    }
    d->scene->ints[b] = tri;
    d->scene->defs[b].triangles = tri;
    d->scene->defs[b].triangle_count = count;
    return decode_tuples(d, b, v, "triangles", 3, tri, "a triangle [i, j, k]", "a triangle has exactly three node indices");
}

/* "surface": the body's contact surface (docs/model.md §13), pairs [i, j]
 * of node indices in range; whether each names a boundary segment, once, is
 * the core's to say (a mesh's boundary is known there): the error's item
 * maps back to /bodies/B/surface/K. */
static int decode_surface(decoder* d, int b, const cJSON* v) {
    char ptr[96];
    int count, *ints;
    const int node_count = d->scene->defs[b].node_count;
    snprintf(ptr, sizeof ptr, "/bodies/%d/surface", b);
    if (!cJSON_IsArray(v)) return fail_type(d, ptr, v, "an array of boundary segments [i, j]");
    count = array_size(v);
    /* each pair is a segment, each once: never more pairs than nodes */
    if (count > node_count) {
        ntsj_fault_set(d->fault, ntsj_code_name(NTSJ_INVALID_VALUE), ptr,
                       "%d surface segments for a body of %d nodes (each boundary segment at most once)", count,
                       node_count);
        return -1;
    }
    if ((ints = (int*)nts_alloc(2 * (size_t)count * sizeof *ints + sizeof *ints)) == NULL) {
        d->oom = 1;
        return -1;
    }
    d->scene->surfs[b] = ints;
    d->scene->defs[b].surface = ints;
    d->scene->defs[b].surface_count = count;
    return decode_tuples(d, b, v, "surface", 2, ints, "a boundary segment [i, j] (two node indices)",
                         "a surface segment has exactly two node indices");
}

static int decode_body(decoder* d, int b, const cJSON* v, long long* total) {
    const cJSON* f[BODY_COUNT];
    char ptr[64];
    snprintf(ptr, sizeof ptr, "/bodies/%d", b);
    if (!cJSON_IsObject(v)) return fail_type(d, ptr, v, "a body (an object)");
    if (take_fields(d, v, ptr, body_fields, BODY_COUNT, f) != 0) return -1;
    {
        char p[80];
        snprintf(p, sizeof p, "%s/id", ptr);
        if (!f[BODY_ID]) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), p, "a body needs an \"id\" (a string or an integer)");
        if (decode_id(d, f[BODY_ID], p, &d->scene->ids[b]) != 0) return -1;
    }
    if (!f[BODY_NODES]) {
        char p[80];
        snprintf(p, sizeof p, "%s/nodes", ptr);
        return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), p, "a body needs \"nodes\"");
    }
    if (decode_nodes(d, b, f[BODY_NODES], total) != 0) return -1;
    if (f[BODY_MESH_POINTS] && check_mesh_points(d, b, f[BODY_MESH_POINTS]) != 0) return -1;
    if (f[BODY_REFERENCE] && decode_reference(d, b, f[BODY_REFERENCE]) != 0) return -1;
    if (f[BODY_ALPHA]) {
        /* Per-body smoothing: this body's surface (docs/model.md, "Per-body options"). */
        char p[80];
        nts_body_def* bd = &d->scene->defs[b];
        snprintf(p, sizeof p, "%s/alpha", ptr);
        if (get_number(d, f[BODY_ALPHA], p, &bd->alpha) != 0) return -1;
        if (!(bd->alpha >= 0.0 && bd->alpha <= 0.5)) return fail(d, nts_status_name(NTS_EINVALID_OPTION), p, "alpha must be in [0, 0.5]");
        bd->has_alpha = 1;
    }
    if (f[BODY_FRICTION]) {
        /* The body's own Coulomb coefficient (§14; its range: the core's). */
        char p[80];
        nts_body_def* bd = &d->scene->defs[b];
        snprintf(p, sizeof p, "%s/friction", ptr);
        if (get_number(d, f[BODY_FRICTION], p, &bd->friction) != 0) return -1;
        bd->has_friction = 1;
    }
    if (f[BODY_SELF_CONTACT]) {
        /* Its nodes meet its own surface too (docs/model.md §16). */
        char p[80];
        snprintf(p, sizeof p, "%s/self_contact", ptr);
        if (!cJSON_IsBool(f[BODY_SELF_CONTACT])) return fail_type(d, p, f[BODY_SELF_CONTACT], "true or false");
        d->scene->defs[b].self_contact = cJSON_IsTrue(f[BODY_SELF_CONTACT]) ? 1 : 0;
    }
    if (f[BODY_ROLE]) {
        char p[80];
        const cJSON* r = f[BODY_ROLE];
        nts_body_def* bd = &d->scene->defs[b];
        snprintf(p, sizeof p, "%s/role", ptr);
        if (!cJSON_IsString(r)) return fail_type(d, p, r, "a role (\"both\", \"master\" or \"slave\")");
        if (strcmp(r->valuestring, "both") == 0) bd->role = NTS_ROLE_BOTH;
        else if (strcmp(r->valuestring, "master") == 0) bd->role = NTS_ROLE_MASTER;
        else if (strcmp(r->valuestring, "slave") == 0) bd->role = NTS_ROLE_SLAVE;
        else return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, "unknown role (expected both, master or slave)");
    }
    if (f[BODY_SURFACE] && decode_surface(d, b, f[BODY_SURFACE]) != 0) return -1;
    if (f[BODY_LOOPS] && f[BODY_TRIANGLES]) {
        char p[80];
        snprintf(p, sizeof p, "%s/triangles", ptr);
        return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, "give either \"loops\" or \"triangles\", not both");
    }
    if (f[BODY_LOOPS]) {
        d->scene->has_loops[b] = 1;
        return decode_loops(d, b, f[BODY_LOOPS]);
    }
    if (f[BODY_TRIANGLES]) return decode_triangles(d, b, f[BODY_TRIANGLES]);
    return 0;
}

/* ---------------------------------------------------------- ids */

static int compare_ids(const ntsj_id* a, const ntsj_id* b) {
    if (a->is_int != b->is_int) return a->is_int ? -1 : 1;
    if (a->is_int) return (a->ival > b->ival) - (a->ival < b->ival);
    return strcmp(a->sval, b->sval);
}

/* Sort body indices by id (ties by index) with a merge sort: qsort has no user
 * pointer in C99 and a global would not be thread-safe. O(n log n). */
static void merge_sort(int* idx, int* tmp, int n, const ntsj_id* ids) {
    int mid, i, j, k;
    if (n < 2) return;
    mid = n / 2;
    merge_sort(idx, tmp, mid, ids);
    merge_sort(idx + mid, tmp, n - mid, ids);
    i = 0;
    j = mid;
    k = 0;
    while (i < mid && j < n) {
        int c = compare_ids(&ids[idx[i]], &ids[idx[j]]);
        if (c < 0 || (c == 0 && idx[i] < idx[j])) tmp[k++] = idx[i++];
        else tmp[k++] = idx[j++];
    }
    while (i < mid) tmp[k++] = idx[i++];
    while (j < n) tmp[k++] = idx[j++];
    memcpy(idx, tmp, (size_t)n * sizeof *idx);
}

static int check_unique_ids(decoder* d) {
    int n = d->scene->body_count, i, worst = -1, first = -1;
    int* idx = (int*)nts_alloc((size_t)(2 * n + 1) * sizeof *idx);
    if (!idx) {
        d->oom = 1;
        return -1;
    }
    for (i = 0; i < n; ++i) idx[i] = i;
    merge_sort(idx, idx + n, n, d->scene->ids);
    /* Report the earliest body whose id was already used by an earlier body. */
    for (i = 1; i < n; ++i) {
        if (compare_ids(&d->scene->ids[idx[i - 1]], &d->scene->ids[idx[i]]) == 0) {
            int later = idx[i] > idx[i - 1] ? idx[i] : idx[i - 1];
            int earlier = idx[i] > idx[i - 1] ? idx[i - 1] : idx[i];
            if (worst < 0 || later < worst) {
                worst = later;
                first = earlier;
            }
        }
    }
    d->order = idx; /* kept for body_of_id, freed by ntsj_decode */
    if (worst >= 0) {
        char p[64];
        snprintf(p, sizeof p, "/bodies/%d/id", worst);
        ntsj_fault_set(d->fault, ntsj_code_name(NTSJ_DUPLICATE_ID), p, "body id already used by /bodies/%d", first);
        return -1;
    }
    return 0;
}

/* ---------------------------------------------------------- scene */

void ntsj_scene_free(ntsj_scene* s) {
    int b;
    if (!s) return;
    for (b = 0; b < s->body_count; ++b) {
        if (s->ids) nts_free(s->ids[b].sval);
        if (s->nodes) nts_free(s->nodes[b]);
        if (s->ints) nts_free(s->ints[b]);
        if (s->refs) nts_free(s->refs[b]);
        if (s->surfs) nts_free(s->surfs[b]);
    }
    nts_free(s->defs);
    nts_free(s->ids);
    nts_free(s->has_loops);
    nts_free(s->nodes);
    nts_free(s->ints);
    nts_free(s->refs);
    nts_free(s->surfs);
    nts_free(s->history);
    memset(s, 0, sizeof *s);
}

static void* alloc_zero(size_t count, size_t size) {
    void* p = nts_alloc(count * size > 0 ? count * size : 1);
    if (p) memset(p, 0, count * size);
    return p;
}

const char* const ntsj_root_fields[NTSJ_ROOT_COUNT] = {"version", "options", "bodies", "$schema", "session", "history"};
enum { ROOT_VERSION, ROOT_OPTIONS, ROOT_BODIES, ROOT_SCHEMA, ROOT_SESSION, ROOT_HISTORY }; /* ntsj_root_fields' order */

/* ---------------------------------------------------------- history */

/* The body whose id is `v` (a string or an integer), by bisection of the ids
 * in order (check_unique_ids): -1 when there is none. */
static int body_of_id(const decoder* d, const cJSON* v) {
    ntsj_id key;
    int lo = 0, hi = d->scene->body_count;
    memset(&key, 0, sizeof key);
    if (cJSON_IsString(v)) {
        key.sval = v->valuestring;
    } else if (cJSON_IsNumber(v) && v->valuedouble == floor(v->valuedouble) && fabs(v->valuedouble) < 9007199254740992.0) {
        key.is_int = 1;
        key.ival = (long long)v->valuedouble;
    } else {
        return -1;
    }
    while (lo < hi) {
        const int mid = lo + (hi - lo) / 2;
        const int c = compare_ids(&d->scene->ids[d->order[mid]], &key);
        if (c == 0) return d->order[mid];
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

/* A history entry's body id at `ptr`: its index, or -1 with the fault. */
static int history_body(decoder* d, const cJSON* v, const char* ptr) {
    int b;
    if (!v) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), ptr, "a history entry needs this body's id");
    if (!cJSON_IsString(v) && !cJSON_IsNumber(v)) return fail_type(d, ptr, v, "a body id (a string or an integer)");
    if ((b = body_of_id(d, v)) < 0) return fail(d, nts_status_name(NTS_EINVALID_HISTORY), ptr, "no body of the scene has this id");
    return b;
}

/* A node index of body b at `ptr`: 0, or -1 with the fault. */
static int history_node(decoder* d, const cJSON* v, const char* ptr, int b, int* out) {
    const int n = d->scene->defs[b].node_count;
    if (!cJSON_IsNumber(v)) return fail_type(d, ptr, v, "a node index (an integer)");
    if (v->valuedouble != floor(v->valuedouble)) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), ptr, "a node index must be an integer");
    if (!(v->valuedouble >= 0.0 && v->valuedouble < (double)n)) {
        ntsj_fault_set(d->fault, nts_status_name(NTS_EINDEX_RANGE), ptr, "node index %.17g is out of range [0, %d)",
                       v->valuedouble, n);
        return -1;
    }
    *out = (int)v->valuedouble;
    return 0;
}

static const char* const anchor_fields[] = {"slave", "master", "kind", "nodes", "param"};
enum { ANCHOR_SLAVE, ANCHOR_MASTER, ANCHOR_KIND, ANCHOR_NODES, ANCHOR_PARAM, ANCHOR_COUNT };
static const char* const slave_fields[] = {"body", "node"};

/* One entry of "history" (result.schema.json's anchor): its fields, types
 * and indices; whether it is an anchor of the scene (a segment, corner or
 * vertex of the master's boundary, each key once) is nts_history_set's. */
static int decode_anchor(decoder* d, int k, const cJSON* v, nts_anchor* a) {
    const cJSON* f[ANCHOR_COUNT];
    const cJSON* sf[2];
    const cJSON* e;
    char ptr[64], p[96];
    int i, need;
    snprintf(ptr, sizeof ptr, "/history/%d", k);
    if (!cJSON_IsObject(v)) return fail_type(d, ptr, v, "an anchor {\"slave\", \"master\", \"kind\", \"nodes\", \"param\"}");
    if (take_fields(d, v, ptr, anchor_fields, ANCHOR_COUNT, f) != 0) return -1;
    for (i = 0; i < ANCHOR_COUNT; ++i)
        if (!f[i]) {
            snprintf(p, sizeof p, "%s/%s", ptr, anchor_fields[i]);
            return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), p, "a history entry needs slave, master, kind, nodes and param");
        }
    memset(a, 0, sizeof *a);
    snprintf(p, sizeof p, "%s/slave", ptr);
    if (!cJSON_IsObject(f[ANCHOR_SLAVE])) return fail_type(d, p, f[ANCHOR_SLAVE], "an object {\"body\", \"node\"}");
    if (take_fields(d, f[ANCHOR_SLAVE], p, slave_fields, 2, sf) != 0) return -1;
    snprintf(p, sizeof p, "%s/slave/body", ptr);
    if ((a->slave_body = history_body(d, sf[0], p)) < 0) return -1;
    snprintf(p, sizeof p, "%s/slave/node", ptr);
    if (!sf[1]) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), p, "a history entry needs the slave's node");
    if (history_node(d, sf[1], p, a->slave_body, &a->slave_node) != 0) return -1;
    snprintf(p, sizeof p, "%s/master", ptr);
    if ((a->master_body = history_body(d, f[ANCHOR_MASTER], p)) < 0) return -1;
    snprintf(p, sizeof p, "%s/kind", ptr);
    if (!cJSON_IsString(f[ANCHOR_KIND])) return fail_type(d, p, f[ANCHOR_KIND], "a feature kind (a string)");
    if (strcmp(f[ANCHOR_KIND]->valuestring, "segment") == 0) a->kind = NTS_KIND_SEGMENT;
    else if (strcmp(f[ANCHOR_KIND]->valuestring, "corner") == 0) a->kind = NTS_KIND_CORNER;
    else if (strcmp(f[ANCHOR_KIND]->valuestring, "vertex") == 0) a->kind = NTS_KIND_VERTEX;
    else return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), p, "unknown kind (expected segment, corner or vertex)");
    need = a->kind == NTS_KIND_SEGMENT ? 2 : a->kind == NTS_KIND_CORNER ? 3 : 1;
    snprintf(p, sizeof p, "%s/nodes", ptr);
    if (!cJSON_IsArray(f[ANCHOR_NODES])) return fail_type(d, p, f[ANCHOR_NODES], "an array of the feature's node indices");
    if (array_size(f[ANCHOR_NODES]) != need) {
        ntsj_fault_set(d->fault, nts_status_name(NTS_EINVALID_HISTORY), p, "a %s has %d nodes", f[ANCHOR_KIND]->valuestring, need);
        return -1;
    }
    a->nodes[0] = a->nodes[1] = a->nodes[2] = -1;
    i = 0;
    cJSON_ArrayForEach(e, f[ANCHOR_NODES]) {
        snprintf(p, sizeof p, "%s/nodes/%d", ptr, i);
        if (history_node(d, e, p, a->master_body, &a->nodes[i]) != 0) return -1;
        ++i;
    }
    snprintf(p, sizeof p, "%s/param", ptr);
    return get_number(d, f[ANCHOR_PARAM], p, &a->param);
}

/* "history": the anchors of a previous result (a stateless request's, or a
 * session's start), after the bodies (it names them by id). */
static int decode_history(decoder* d, const cJSON* v) {
    const cJSON* e;
    int n, k = 0;
    if (!cJSON_IsArray(v)) return fail_type(d, "/history", v, "an array of anchors (a previous result's \"history\")");
    n = array_size(v);
    d->scene->history = (nts_anchor*)nts_alloc(sizeof(nts_anchor) * (size_t)(n > 0 ? n : 1));
    if (d->scene->history == NULL) {
        d->oom = 1;
        return -1;
    }
    d->scene->has_history = 1;
    cJSON_ArrayForEach(e, v) {
        if (decode_anchor(d, k, e, &d->scene->history[k]) != 0) return -1;
        d->scene->history_count = ++k;
    }
    return 0;
}

/* "session": what a session keeps between its steps (docs/sessions.md). */
static const char* const session_fields[] = {"keep_contacts", "keep_candidates", "skin"};
enum { SESSION_KEEP_CONTACTS, SESSION_KEEP_CANDIDATES, SESSION_SKIN, SESSION_COUNT };

static int decode_session(decoder* d, const cJSON* v) {
    const cJSON* f[SESSION_COUNT];
    int k;
    if (!cJSON_IsObject(v))
        return fail_type(d, "/session", v, "an object {\"keep_contacts\", \"keep_candidates\", \"skin\"}");
    if (take_fields(d, v, "/session", session_fields, SESSION_COUNT, f) != 0) return -1;
    d->scene->has_session = 1;
    for (k = SESSION_KEEP_CONTACTS; k <= SESSION_KEEP_CANDIDATES; ++k)
        if (f[k]) {
            char p[48];
            snprintf(p, sizeof p, "/session/%s", session_fields[k]);
            if (!cJSON_IsBool(f[k])) return fail_type(d, p, f[k], "true or false");
            if (k == SESSION_KEEP_CONTACTS) d->scene->keep_contacts = cJSON_IsTrue(f[k]);
            else d->scene->keep_candidates = cJSON_IsTrue(f[k]);
        }
    if (f[SESSION_SKIN]) {
        if (get_number(d, f[SESSION_SKIN], "/session/skin", &d->scene->skin) != 0) return -1;
        if (!(d->scene->skin >= 0.0))
            return fail(d, nts_status_name(NTS_EINVALID_OPTION), "/session/skin",
                        "the skin is a length >= 0 (absent: 0.3 times the search radius)");
    }
    return 0;
}

/* ntsj_config.history: a document whose "history" replaces the request's
 * (the CLI's --history-in); its faults are named in it. */
static int history_document(decoder* d) {
    cJSON* root;
    const cJSON* h = NULL;
    const cJSON* m;
    int rc;
    if (d->cfg->max_bytes > 0 && d->cfg->history_length > d->cfg->max_bytes)
        return fail(d, ntsj_code_name(NTSJ_PAYLOAD_TOO_LARGE), "", "the history document is more than max_bytes");
    if (ntsj_scan(d->cfg->history, d->cfg->history_length, d->cfg->max_depth > 0 ? d->cfg->max_depth : 32, d->fault) != 0) {
        char msg[sizeof d->fault->message];
        snprintf(msg, sizeof msg, "the history document: %.200s", d->fault->message);
        snprintf(d->fault->message, sizeof d->fault->message, "%s", msg);
        return -1;
    }
    root = cJSON_ParseWithLengthOpts(d->cfg->history, d->cfg->history_length, NULL, 0);
    if (root == NULL) {
        d->oom = 1;
        return -1;
    }
    cJSON_ArrayForEach(m, root) if (cJSON_IsObject(root) && m->string && strcmp(m->string, "history") == 0) h = m;
    rc = h ? decode_history(d, h)
           : fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), "/history",
                  "the history document has no \"history\" (give a previous result, or a history written with it)");
    cJSON_Delete(root);
    return rc;
}

static int decode_root(decoder* d, const cJSON* root) {
    const cJSON* f[NTSJ_ROOT_COUNT];
    const cJSON* body;
    ntsj_scene* s = d->scene;
    const ntsj_overrides* ov = &d->cfg->overrides;
    unsigned given = 0;
    int n, b = 0, id;
    long long total = 0;

    if (!cJSON_IsObject(root)) return fail_type(d, "", root, "a scene (an object)");
    if (take_fields(d, root, "", ntsj_root_fields, NTSJ_ROOT_COUNT, f) != 0) return -1;
    if (f[ROOT_VERSION]) {
        if (!cJSON_IsNumber(f[ROOT_VERSION])) return fail_type(d, "/version", f[ROOT_VERSION], "the integer 1");
        if (f[ROOT_VERSION]->valuedouble != 1.0) return fail(d, ntsj_code_name(NTSJ_INVALID_VALUE), "/version", "unsupported version (this codec reads version 1)");
    }
    if (f[ROOT_SCHEMA] && !cJSON_IsString(f[ROOT_SCHEMA])) return fail_type(d, "/$schema", f[ROOT_SCHEMA], "a string");
    s->keep_candidates = 1; /* a session keeps a candidate list unless told not to */
    s->skin = -1.0;
    if (f[ROOT_SESSION] && decode_session(d, f[ROOT_SESSION]) != 0) return -1;

    s->options = nts_default_options();
    if (f[ROOT_OPTIONS] && decode_options(d, f[ROOT_OPTIONS], &given) != 0) return -1;
    ntsj_overrides_apply(ov, &s->options);
    s->options.threads = d->cfg->threads;
    for (id = 0; id < NTS_OPT_COUNT_; ++id) {
        const nts_option_info* r = nts_option_info_of(id);
        char ptr[64], msg[128];
        if (!r->required || (given & (1u << id)) || ntsj_override_given(ov, id)) continue;
        snprintf(ptr, sizeof ptr, "/options/%s", r->json);
        if (f[ROOT_OPTIONS]) snprintf(msg, sizeof msg, "options need \"%s\" (the %s)", r->json, r->help);
        else snprintf(msg, sizeof msg, "a scene needs \"options\" with at least \"%s\"", r->json);
        return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), f[ROOT_OPTIONS] ? ptr : "/options", msg);
    }
    /* An override through a range the codec checks (the CLI's --search-radius -1). */
    for (id = 0; id < NTS_OPT_COUNT_; ++id) {
        const nts_option_info* r = nts_option_info_of(id);
        nts_option_value val;
        char ptr[64];
        if (r->check != NTS_OPTION_CHECK_CODEC || r->kind != NTS_OPTION_KIND_NUMBER || !ntsj_override_given(ov, id)) continue;
        snprintf(ptr, sizeof ptr, "/options/%s", r->json);
        if (ntsj_option_number_check(id, ntsj_override_number(ov, id), ptr, &val, d->fault) != 0) return -1;
    }

    if (!f[ROOT_BODIES]) return fail(d, ntsj_code_name(NTSJ_MISSING_FIELD), "/bodies", "a scene needs \"bodies\"");
    if (!cJSON_IsArray(f[ROOT_BODIES])) return fail_type(d, "/bodies", f[ROOT_BODIES], "an array of bodies");
    n = array_size(f[ROOT_BODIES]);
    if (n == 0 && !d->part) return fail(d, nts_status_name(NTS_EEMPTY_SCENE), "/bodies", "scene has no bodies");
    if (n > d->cfg->limits.max_bodies) {
        ntsj_fault_set(d->fault, nts_status_name(NTS_ELIMIT), "/bodies", "scene has %d bodies, more than max_bodies = %d", n,
                       d->cfg->limits.max_bodies);
        return -1;
    }
    s->defs = (nts_body_def*)alloc_zero((size_t)n, sizeof *s->defs);
    s->ids = (ntsj_id*)alloc_zero((size_t)n, sizeof *s->ids);
    s->has_loops = (int*)alloc_zero((size_t)n, sizeof *s->has_loops);
    s->nodes = (nts_vec2**)alloc_zero((size_t)n, sizeof *s->nodes);
    s->ints = (int**)alloc_zero((size_t)n, sizeof *s->ints);
    s->refs = (nts_vec2**)alloc_zero((size_t)n, sizeof *s->refs);
    s->surfs = (int**)alloc_zero((size_t)n, sizeof *s->surfs);
    if (!s->defs || !s->ids || !s->has_loops || !s->nodes || !s->ints || !s->refs || !s->surfs) {
        d->oom = 1;
        return -1;
    }
    s->body_count = n;
    cJSON_ArrayForEach(body, f[ROOT_BODIES]) {
        if (decode_body(d, b, body, &total) != 0) return -1;
        ++b;
    }
    if (check_unique_ids(d) != 0) return -1;
    if (d->cfg->history != NULL) return history_document(d);
    return f[ROOT_HISTORY] ? decode_history(d, f[ROOT_HISTORY]) : 0;
}

static int decode(const cJSON* root, const ntsj_config* config, ntsj_scene* out, ntsj_fault* fault, int part) {
    decoder d;
    memset(out, 0, sizeof *out);
    d.cfg = config;
    d.fault = fault;
    d.scene = out;
    d.oom = 0;
    d.order = NULL;
    d.part = part;
    if (decode_root(&d, root) == 0) {
        nts_free(d.order);
        return 0;
    }
    nts_free(d.order);
    ntsj_scene_free(out);
    if (d.oom) {
        ntsj_fault_set(fault, nts_status_name(NTS_ENOMEM), "", "out of memory while decoding the request");
        return NTS_ENOMEM;
    }
    return -1;
}

int ntsj_decode(const cJSON* root, const ntsj_config* config, ntsj_scene* out, ntsj_fault* fault) {
    return decode(root, config, out, fault, 0);
}

int ntsj_decode_part(const cJSON* root, const ntsj_config* config, ntsj_scene* out, ntsj_fault* fault) {
    return decode(root, config, out, fault, 1);
}

/* ---------------------------------------------------------- core errors */

void ntsj_pointer_of_error(const ntsj_scene* s, const nts_error* err, char* out, size_t size) {
    int n;
    out[0] = '\0';
    if (err->code == NTS_EBOX_TOO_SMALL) {
        snprintf(out, size, "/options/periodic");
        return;
    }
    if (err->code == NTS_ELIMIT && strcmp(err->option, "max_candidates") == 0) return; /* the whole request */
    if (err->option[0] && err->body >= 0 && s && err->body < s->body_count) {
        /* A body's own option (alpha, role), or a point of its reference
         * configuration. */
        size_t len;
        snprintf(out, size, "/bodies/%d", err->body);
        ntsj_pointer_append_key(out, size, err->option);
        len = strlen(out);
        if (strcmp(err->option, "reference") == 0 && err->node >= 0 && len < size)
            snprintf(out + len, size - len, "/%d", err->node);
        else if (strcmp(err->option, "surface") == 0 && err->item >= 0 && err->corner >= 0 && len < size)
            snprintf(out + len, size - len, "/%d/%d", err->item, err->corner);
        else if (strcmp(err->option, "surface") == 0 && err->item >= 0 && len < size)
            snprintf(out + len, size - len, "/%d", err->item);
        return;
    }
    if (strcmp(err->option, "history") == 0) { /* nts_history_set: the entry */
        if (err->item >= 0) snprintf(out, size, "/history/%d", err->item);
        else snprintf(out, size, "/history");
        return;
    }
    if (err->option[0]) {
        if (strcmp(err->option, "friction") == 0)
            snprintf(out, size, "/options/friction/coefficient");
        else if (strcmp(err->option, "tangential_penalty") == 0)
            snprintf(out, size, "/options/friction/tangential_penalty");
        else if (strcmp(err->option, "lx") == 0 || strcmp(err->option, "ly") == 0)
            snprintf(out, size, "/options/periodic/%s", err->option);
        else if (strcmp(err->option, "periodic") == 0 || strcmp(err->option, "box") == 0)
            snprintf(out, size, "/options/periodic");
        else {
            snprintf(out, size, "/options");
            ntsj_pointer_append_key(out, size, err->option);
        }
        return;
    }
    if (err->body < 0 || !s || err->body >= s->body_count) {
        if (err->code == NTS_EEMPTY_SCENE || err->code == NTS_ELIMIT) snprintf(out, size, "/bodies");
        return;
    }
    n = snprintf(out, size, "/bodies/%d", err->body);
    if (n < 0 || (size_t)n >= size) return;
    if (err->triangle >= 0 && err->corner >= 0)
        snprintf(out + n, size - (size_t)n, "/triangles/%d/%d", err->triangle, err->corner);
    else if (err->triangle >= 0)
        snprintf(out + n, size - (size_t)n, "/triangles/%d", err->triangle);
    else if (err->code == NTS_ENO_BOUNDARY && s->defs[err->body].triangle_count > 0)
        snprintf(out + n, size - (size_t)n, "/triangles");
    else if (s->has_loops[err->body] && err->loop >= 0 && err->loop_pos >= 0)
        snprintf(out + n, size - (size_t)n, "/loops/%d/%d", err->loop, err->loop_pos);
    else if (s->has_loops[err->body] && err->loop >= 0)
        snprintf(out + n, size - (size_t)n, "/loops/%d", err->loop);
    else if (err->node >= 0)
        snprintf(out + n, size - (size_t)n, "/nodes/%d", err->node);
    else if (!s->has_loops[err->body] && s->defs[err->body].triangle_count == 0 &&
             (err->code == NTS_ELOOP_TOO_SHORT || err->code == NTS_EZERO_AREA))
        snprintf(out + n, size - (size_t)n, "/nodes"); /* the implicit loop through all nodes */
    else if (err->code == NTS_ENO_NODES)
        snprintf(out + n, size - (size_t)n, "/nodes");
}
