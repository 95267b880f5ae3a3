/* The flat calls of ntscontact/mpi_engine.h (ntscontact.mpi in Python):
 * each rank's part of the scene decoded by the codec, as the daemon decodes
 * a scene, evaluated across the ranks by ntsm_evaluate; the answer as the
 * daemon's binary session answer (this rank's forces and the summary's
 * header lines), an error as its error document, the same on every rank. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include <ntscontact/mpi_engine.h>

#include "../../codec/src/codec_internal.h"
#include "internal.h"

struct ntsm_engine {
    MPI_Comm comm;
    int rank, size, threads;
    ntsj_scene s;          /* this rank's bodies, as decoded */
    nts_scene* own;        /* the same, built (the pointers of errors, friction): its first positions */
    int* ids;
    ntsm_scene* scene;
    long long counts[3];
};

/* An error document (malloc'd copy of the codec's). */
static char* doc_of(const char* code, const char* message, const char* pointer) {
    char* d = ntsj_error_document(code, message, pointer);
    char* out = d != NULL ? (char*)malloc(strlen(d) + 1) : NULL;
    if (out != NULL) strcpy(out, d);
    nts_free(d);
    return out;
}

/* Which rank's fault every rank raises: as one process meets them, the
 * faults of the documents (decoding) before the core's (a scene's checks),
 * then by global body (-1, none, first), then the lowest rank. agree_doc:
 * the error document every rank agrees on from `mine` (this rank's, or
 * NULL) and its key; NULL when none failed. */
enum { FAULT_DOCUMENT = 0, FAULT_CORE = 1 };

static long long fault_key(int stage, int body, int rank, int size) {
    return (((long long)stage << 40) + (long long)body + 1) * size + rank;
}

/* The global body a document fault's pointer names ("/bodies/K..."), or -1. */
static int pointer_body(const char* pointer) {
    int k;
    return sscanf(pointer, "/bodies/%d", &k) == 1 && k >= 0 ? k : -1;
}

static char* agree_doc(MPI_Comm comm, int rank, char* mine, long long key) {
    long long me = mine != NULL ? key : LLONG_MAX, least;
    int size, first, len;
    char* doc = NULL;
    MPI_Comm_size(comm, &size);
    MPI_Allreduce(&me, &least, 1, MPI_LONG_LONG, MPI_MIN, comm);
    if (least == LLONG_MAX) return NULL;
    first = (int)(least % size);
    len = rank == first ? (int)strlen(mine) : 0;
    MPI_Bcast(&len, 1, MPI_INT, first, comm);
    if (rank == first) {
        doc = mine;
        mine = NULL;
    } else if ((doc = (char*)malloc((size_t)len + 1)) != NULL) {
        doc[len] = '\0';
    }
    {
        /* every rank takes part in the broadcast, even one short of memory */
        char* buf = doc != NULL ? doc : (char*)malloc((size_t)len + 1);
        MPI_Bcast(buf, len, MPI_BYTE, first, comm);
        if (doc == NULL) free(buf);
    }
    free(mine);
    return doc != NULL ? doc : doc_of("out_of_memory", "out of memory", "");
}


/* "/bodies/K..." with K this rank's index of a body: K its global index. */
static void pointer_global(char* p, size_t size, const int* ids, int count) {
    int k, used = 0;
    if (sscanf(p, "/bodies/%d%n", &k, &used) == 1 && k >= 0 && k < count) {
        char out[320];
        snprintf(out, sizeof out, "/bodies/%d%s", ids[k], p + used);
        snprintf(p, size, "%.*s", (int)size - 1, out);
    }
}

/* A core error of the distributed scene (err->body global): its document,
 * made where the body is (the pointer needs its JSON), given to all. */
static char* core_doc(ntsm_engine* e, const nts_error* err) {
    int owner = 0, k, local = -1;
    char* mine = NULL;
    for (k = 0; k < e->s.body_count; ++k)
        if (e->ids[k] == err->body) local = k;
    {
        int me = local >= 0 ? e->rank : 1 << 30;
        MPI_Allreduce(&me, &owner, 1, MPI_INT, MPI_MIN, e->comm);
        if (owner == 1 << 30) owner = 0;
    }
    if (e->rank == owner) {
        char pointer[320] = "";
        nts_error le = *err;
        le.body = local;
        if (local >= 0) {
            ntsj_pointer_of_error(&e->s, &le, pointer, sizeof pointer);
            pointer_global(pointer, sizeof pointer, e->ids, e->s.body_count);
        } else if (err->option[0] != '\0') {
            snprintf(pointer, sizeof pointer, "/options/%s", err->option);
        } else if (err->code == NTS_EEMPTY_SCENE) { /* (every rank's part empty) */
            snprintf(pointer, sizeof pointer, "/bodies");
        }
        mine = doc_of(nts_status_name(err->code), err->message, pointer);
        if (mine == NULL) mine = doc_of("out_of_memory", "out of memory", "");
    }
    {
        /* the owner's document to every rank */
        int len = mine != NULL ? (int)strlen(mine) : 0;
        char* doc;
        MPI_Bcast(&len, 1, MPI_INT, owner, e->comm);
        doc = e->rank == owner ? mine : (char*)malloc((size_t)len + 1);
        if (doc == NULL) doc = (char*)calloc(1, (size_t)len + 1);
        MPI_Bcast(doc, len, MPI_BYTE, owner, e->comm);
        doc[len] = '\0';
        return doc;
    }
}

void ntsm_engine_free_text(char* text) { free(text); }

static int has_body_friction(const ntsm_engine* e) {
    int k;
    for (k = 0; k < e->s.body_count; ++k)
        if (e->s.defs[k].has_friction && e->s.defs[k].friction > 0.0) return 1;
    return 0;
}

void ntsm_engine_destroy(ntsm_engine* e) {
    if (e == NULL) return;
    ntsm_scene_destroy(e->scene);
    nts_scene_destroy(e->own);
    ntsj_scene_free(&e->s);
    free(e->ids);
    free(e);
}

void ntsm_engine_counts(const ntsm_engine* e, long long out[3]) { memcpy(out, e->counts, sizeof e->counts); }

/* One process decodes the bodies in global order and names the first body
 * with a fault; a rank's document holds them in the order it was given.
 * After a fault at a body, a rank whose bodies are not in ascending global
 * order decodes its document again with them so (the array reordered in
 * place: root is the caller's, freed after) and takes that fault, its
 * pointer's body made global. Returns 1 when it did (the pointer global). */
static int global_order_fault(cJSON* root, const ntsj_config* cfg, const int* ids, int count, ntsj_fault* fault) {
    cJSON* bodies = cJSON_GetObjectItemCaseSensitive(root, "bodies");
    cJSON** items;
    int* order;
    ntsj_scene again;
    ntsj_fault f2;
    int k, done = 0;
    if (ntsm_ascending(ids, count) || !cJSON_IsArray(bodies) || cJSON_GetArraySize(bodies) != count) return 0;
    items = (cJSON**)malloc(sizeof(cJSON*) * (size_t)(count + 1));
    order = ntsm_global_order(ids, count);
    if (items == NULL || order == NULL) {
        free(items);
        free(order);
        return 0; /* (the fault found stays) */
    }
    for (k = 0; k < count; ++k) items[k] = cJSON_DetachItemFromArray(bodies, 0);
    for (k = 0; k < count; ++k) cJSON_AddItemToArray(bodies, items[order[k]]);
    memset(&f2, 0, sizeof f2);
    if (ntsj_decode_part(root, cfg, &again, &f2) == 0) ntsj_scene_free(&again);
    if (f2.code != NULL && strcmp(f2.code, "out_of_memory") != 0) {
        int b = -1, used = 0;
        if (sscanf(f2.pointer, "/bodies/%d%n", &b, &used) == 1 && b >= 0 && b < count) {
            char out[sizeof f2.pointer + 16];
            snprintf(out, sizeof out, "/bodies/%d%s", ids[order[b]], f2.pointer + used);
            memcpy(f2.pointer, out, sizeof f2.pointer - 1); /* (cut to its room) */
            f2.pointer[sizeof f2.pointer - 1] = '\0';
        }
        *fault = f2;
        done = 1;
    }
    free(items);
    free(order);
    return done;
}

/* The rank's own bodies as a scene definition (e->own's, and the box the
 * distributed scene is made with). */
static nts_scene_def own_def(const ntsm_engine* e) {
    nts_scene_def def = nts_default_scene_def();
    def.bodies = e->s.defs;
    def.body_count = e->s.body_count;
    def.lx = e->s.has_periodic ? e->s.lx : 0.0;
    def.ly = e->s.has_periodic ? e->s.ly : 0.0;
    def.limits.max_bodies = 1 << 30;
    return def;
}

ntsm_engine* ntsm_engine_create(int comm_f, const char* json, size_t length, const int* ids, int count, int threads,
                                char** error) {
    ntsm_engine* e = (ntsm_engine*)calloc(1, sizeof *e);
    ntsj_config cfg = ntsj_default_config();
    ntsj_fault fault;
    nts_error err = nts_error_none();
    char* mine = NULL;
    MPI_Comm comm = MPI_Comm_f2c(comm_f);
    int rank, size, decoded = 0, k, fault_global = 0;
    long long mine_key;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    mine_key = fault_key(FAULT_DOCUMENT, -1, rank, size); /* (out of memory: no body) */
    *error = NULL;
    memset(&fault, 0, sizeof fault);
    if (e == NULL || (e->ids = (int*)malloc(sizeof(int) * (size_t)(count + 1))) == NULL) {
        mine = doc_of("out_of_memory", "out of memory", "");
    } else {
        cJSON* root = NULL;
        e->comm = comm;
        e->rank = rank;
        e->size = size;
        e->threads = threads;
        for (k = 0; k < count; ++k) e->ids[k] = ids[k];
        if (json == NULL || length == 0) fault.code = "empty_body";
        else if (ntsj_scan(json, length, cfg.max_depth > 0 ? cfg.max_depth : 32, &fault) == 0 &&
                 (root = cJSON_ParseWithLength(json, length)) == NULL)
            ntsj_fault_set(&fault, "out_of_memory", "", "out of memory while parsing the scene");
        if (fault.code == NULL && root != NULL) {
            if (ntsj_decode_part(root, &cfg, &e->s, &fault) == 0) decoded = 1; /* (a rank may own no body) */
            else if (fault.code == NULL) ntsj_fault_set(&fault, "out_of_memory", "", "out of memory");
            else if (pointer_body(fault.pointer) >= 0) fault_global = global_order_fault(root, &cfg, ids, count, &fault);
        }
        cJSON_Delete(root);
        if (fault.code == NULL && decoded && e->s.body_count != count)
            ntsj_fault_set(&fault, "invalid_value", "/bodies", "%d bodies and %d global indices", e->s.body_count,
                           count);
        if (fault.code != NULL) {
            char message[300];
            if (!fault_global) pointer_global(fault.pointer, sizeof fault.pointer, ids, count);
            snprintf(message, sizeof message, "rank %d: %s", rank, fault.message);
            mine = doc_of(fault.code, message, fault.pointer);
            mine_key = fault_key(FAULT_DOCUMENT, pointer_body(fault.pointer), rank, size);
        } else {
            nts_scene_def def = own_def(e);
            if (def.body_count > 0 && (e->own = nts_scene_create(&def, &err)) == NULL) {
                /* the body one process names among this rank's (its checks
                 * meet them in global order), named by its global index */
                char pointer[320] = "";
                ntsm_lowest_failing(&def, ids, NULL, NULL, &err);
                ntsj_pointer_of_error(&e->s, &err, pointer, sizeof pointer);
                pointer_global(pointer, sizeof pointer, ids, count);
                ntsm_global_body(&err, ids, count);
                mine = doc_of(nts_status_name(err.code), err.message, pointer);
                mine_key = fault_key(FAULT_CORE, err.body, rank, size);
            }
        }
    }
    if (mine == NULL && e == NULL) mine = doc_of("out_of_memory", "out of memory", "");
    if ((*error = agree_doc(comm, rank, mine, mine_key)) != NULL) {
        ntsm_engine_destroy(e);
        return NULL;
    }
    /* every rank has its part: the same box everywhere, then the distributed scene */
    {
        double box[2], lo[2], hi[2];
        box[0] = e->s.has_periodic ? e->s.lx : 0.0;
        box[1] = e->s.has_periodic ? e->s.ly : 0.0;
        MPI_Allreduce(box, lo, 2, MPI_DOUBLE, MPI_MIN, comm);
        MPI_Allreduce(box, hi, 2, MPI_DOUBLE, MPI_MAX, comm);
        if (lo[0] != hi[0] || lo[1] != hi[1]) {
            *error = doc_of("invalid_value", "the ranks' scenes give different periodic boxes", "/options/periodic");
            ntsm_engine_destroy(e);
            return NULL;
        }
        e->scene = ntsm_scene_create(comm, e->s.defs, e->ids, count, box[0], box[1], cfg.limits, &err);
    }
    if (e->scene == NULL) {
        *error = core_doc(e, &err);
        ntsm_engine_destroy(e);
        return NULL;
    }
    e->counts[0] = e->own != NULL ? nts_scene_node_count(e->own) : 0;
    e->counts[1] = e->scene->bodies;
    e->counts[2] = e->scene->entry_off[e->scene->bodies];
    return e;
}

/* Every rank, after positions the distributed scene refused (the error
 * every rank's): one process's session makes its scene anew from them, its
 * bodies' references their first positions (a loop turned over is another
 * normalisation, not a fault), and answers, or names the fault that
 * creation meets; so do the ranks. p: this rank's rows (NULL: none). */
static int remake(ntsm_engine* e, const nts_vec2* p, nts_error* err) {
    const ntsj_config cfg = ntsj_default_config(); /* (the limits the scene was made with) */
    int k, at = 0, ok = 1, all;
    ntsm_scene* fresh;
    for (k = 0; k < e->s.body_count && ok; ++k) {
        nts_body_def* d = &e->s.defs[k];
        if (e->s.refs[k] != NULL) continue;
        if ((e->s.refs[k] = (nts_vec2*)nts_alloc(sizeof(nts_vec2) * (size_t)(d->node_count + 1))) == NULL) {
            ok = 0;
            break;
        }
        memcpy(e->s.refs[k], d->nodes, sizeof(nts_vec2) * (size_t)d->node_count); /* (the first positions) */
        d->reference = e->s.refs[k];
    }
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, e->comm);
    if (!all) return ntsm_fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < e->s.body_count && p != NULL; ++k) {
        memcpy(e->s.nodes[k], p + at, sizeof(nts_vec2) * (size_t)e->s.defs[k].node_count);
        at += e->s.defs[k].node_count;
    }
    {
        const nts_scene_def def = own_def(e);
        fresh = ntsm_scene_create(e->comm, def.bodies, e->ids, def.body_count, def.lx, def.ly, cfg.limits, err);
    }
    if (fresh == NULL) return err->code != 0 ? err->code : NTS_EINTERNAL;
    ntsm_scene_destroy(e->scene);
    e->scene = fresh;
    if (e->own != NULL) {
        /* its topology now the new scene's (the same bodies, which the ranks' scene took) */
        const nts_scene_def def = own_def(e);
        nts_error e2 = nts_error_none();
        nts_scene* own;
        if ((own = nts_scene_create(&def, &e2)) != NULL) {
            nts_scene_destroy(e->own);
            e->own = own;
        }
    }
    return NTS_OK;
}

int ntsm_engine_step(ntsm_engine* e, const double* positions, size_t length, int has_penalty, double penalty,
                     int has_alpha, double alpha, int has_radius, double radius, int solver, unsigned outputs,
                     double* forces, char** headers, char** error) {
    nts_options opt = e->s.options;
    nts_error err = nts_error_none();
    ntsm_result r;
    char* mine = NULL;
    const int nodes = (int)e->counts[0];
    double t0 = MPI_Wtime();
    *headers = *error = NULL;
    if (has_penalty) opt.penalty = penalty;
    if (has_alpha) opt.alpha = alpha;
    if (has_radius) opt.search_radius = radius;
    if (solver >= 0) opt.solver = (nts_solver)solver;
    if (outputs != 0u) opt.outputs = outputs;
    opt.outputs |= NTS_OUT_ENERGY | NTS_OUT_VIRIAL; /* the summary is always whole (the daemon's too) */
    opt.threads = e->threads;
    if (opt.outputs & ~(unsigned)(NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL))
        mine = doc_of("invalid_value", "a distributed session gives forces, energy and virial (the rest: ntsm_gather)",
                      "/options/outputs");
    else if (opt.friction > 0.0 || has_body_friction(e))
        mine = doc_of("invalid_value", "friction's history is not distributed yet: evaluate friction with one process",
                      "/options/friction");
    else if (positions != NULL && length != 16u * (size_t)nodes) {
        char msg[160];
        snprintf(msg, sizeof msg, "rank %d: %lu bytes of positions, expected 16 x %d nodes", e->rank,
                 (unsigned long)length, nodes);
        mine = doc_of("invalid_value", msg, "");
    } else if (nts_options_validate(&opt, &err) != 0) {
        char pointer[64];
        snprintf(pointer, sizeof pointer, "/options/%s", err.option);
        mine = doc_of(nts_status_name(err.code), err.message, pointer);
    }
    if ((*error = agree_doc(e->comm, e->rank, mine, fault_key(FAULT_DOCUMENT, -1, e->rank, e->size))) != NULL)
        return -1;
    /* every rank updates (a collective), those given none with what they hold */
    {
        /* (the distributed scene's own bodies are these, in this order: their
         * positions are the current ones; e->own keeps its first, it is read
         * for its topology only) */
        const nts_scene* cur = e->scene->own != NULL ? e->scene->own : e->own;
        const nts_vec2* p = positions != NULL ? (const nts_vec2*)(const void*)positions
                            : cur != NULL     ? nts_scene_positions(cur)
                                              : NULL; /* (a rank with no body: nothing to move) */
        if (ntsm_scene_update_positions(e->scene, p, &err) != 0 &&
            (err.code == NTS_ENOMEM || remake(e, p, &err) != NTS_OK)) {
            *error = core_doc(e, &err);
            return -1;
        }
    }
    if (ntsm_evaluate(e->scene, &opt, &r, &err) != 0) {
        *error = core_doc(e, &err);
        return -1;
    }
    if (nodes > 0 && r.forces != NULL) memcpy(forces, r.forces, sizeof(nts_vec2) * (size_t)nodes);
    else if (nodes > 0) memset(forces, 0, sizeof(nts_vec2) * (size_t)nodes);
    {
        /* the daemon's header lines of a binary answer */
        ntsj_response resp;
        ntsj_binary_headers h;
        size_t size = 1, k = 0;
        int i;
        memset(&resp, 0, sizeof resp);
        resp.ok = 1;
        resp.binary = 1;
        resp.summary = r.summary;
        resp.friction = e->own != NULL && nts_friction_on(e->own, &opt);
        resp.warning_count = r.warning_count;
        memcpy(resp.warnings, r.warnings, sizeof resp.warnings);
        resp.elapsed_ms = ntsj_round_us(1e3 * (MPI_Wtime() - t0));
        ntsj_binary_headers_of(&resp, &h);
        for (i = 0; i < h.count; ++i) size += strlen(h.names[i]) + strlen(h.values[i]) + 3;
        *headers = (char*)malloc(size);
        {
            int fine = *headers != NULL, all;
            MPI_Allreduce(&fine, &all, 1, MPI_INT, MPI_MIN, e->comm);
            if (!all) { /* every rank fails alike */
                free(*headers);
                *headers = NULL;
                *error = doc_of("out_of_memory", "out of memory", "");
                return -1;
            }
        }
        for (i = 0; i < h.count; ++i) k += (size_t)snprintf(*headers + k, size - k, "%s: %s\n", h.names[i], h.values[i]);
        (*headers)[k] = '\0';
    }
    return 0;
}
