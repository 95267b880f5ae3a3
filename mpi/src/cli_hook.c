/* ntscontact-mpi: the CLI (cli/src/main.c) on rank 0, evaluating across
 * every rank of MPI_COMM_WORLD (docs/distributed.md). Rank 0 reads and
 * checks the request as ntscontact does; at the evaluation the codec calls
 * `evaluate` below, which deals the bodies to the ranks (blocks of about
 * equal nodes), gives them the whole scene's frame, evaluates with the
 * library and gathers the answer on rank 0, which the codec encodes: the
 * bytes ntscontact writes. The other ranks wait for jobs until rank 0 is
 * done. */
#define _POSIX_C_SOURCE 200809L /* mkstemp, fdopen */

#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <sys/stat.h>

#include <cjson/cJSON.h>

#include <ntscontact/codec.h>
#include <ntscontact/mpi.h>

#include "../../codec/src/codec_internal.h" /* (ntsj_pointer_append_key) */
#include "internal.h"

int nts_cli_main(int argc, char** argv);
int nts_cli_flags(int argc, char** argv, ntsj_config* cfg);
void ntsm_cli_configure(ntsj_config* cfg);

enum { JOB_STOP = 0, JOB_EVALUATE = 1 };

/* The bodies root dealt this rank: contiguous blocks of about equal nodes
 * (a host's decomposition), their global indices and definitions (pointing
 * into `data`). */
typedef struct ntsm_dealt {
    int count;
    int* ids;
    nts_body_def* defs;
    bytes data;
} ntsm_dealt;

/* Collective: root's bodies (body_count of them, only read on root) dealt
 * to the ranks, rank r's the bodies [first_of[r], first_of[r + 1]) (on
 * root: size + 1 places). NTS_OK or, on every rank, NTS_ENOMEM. */

static int deal_bodies(MPI_Comm comm, int root, const nts_body_def* bodies, int body_count, ntsm_dealt* out,
                       int* first_of) {
    int rank, size, r, k, ok = 1;
    memset(out, 0, sizeof *out);
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    if (rank == root) {
        /* contiguous blocks of about equal nodes, as a host's decomposition:
         * body b goes to the rank its first node's place falls in */
        long long nodes = 0, acc = 0;
        int b = 0;
        for (k = 0; k < body_count; ++k) nodes += bodies[k].node_count;
        for (r = 0; r < size; ++r) {
            bytes blk;
            const int first = b;
            long long head[2];
            memset(&blk, 0, sizeof blk);
            while (b < body_count && (nodes == 0 ? r == size - 1 : (int)(acc * size / nodes) == r)) {
                ntsm_body_write(&blk, &bodies[b], b, bodies[b].reference ? bodies[b].reference : bodies[b].nodes);
                acc += bodies[b++].node_count;
            }
            head[0] = b - first;
            first_of[r] = first;
            first_of[r + 1] = b;
            if (blk.oom || blk.n > INT_MAX) {
                ok = 0;
                head[0] = 0; /* nothing sent: every rank learns it below */
                blk.n = 0;
            }
            head[1] = (long long)blk.n;
            if (r == root) {
                out->count = (int)head[0];
                out->data = blk;
            } else {
                MPI_Send(head, 2, MPI_LONG_LONG, r, 71, comm);
                if (head[1] > 0) MPI_Send(blk.p, (int)blk.n, MPI_BYTE, r, 72, comm);
                free(blk.p);
            }
        }
    } else {
        long long head[2];
        MPI_Recv(head, 2, MPI_LONG_LONG, root, 71, comm, MPI_STATUS_IGNORE);
        out->count = (int)head[0];
        if (ntsm_bytes_room(&out->data, (size_t)head[1] + 8) == NULL) {
            /* nowhere to receive the bodies into: end the job, not in a crash */
            fprintf(stderr, "ntscontact-mpi: rank %d: out of memory receiving its bodies\n", rank);
            MPI_Abort(comm, 1);
        }
        out->data.n = (size_t)head[1];
        if (head[1] > 0) MPI_Recv(out->data.p, (int)head[1], MPI_BYTE, root, 72, comm, MPI_STATUS_IGNORE);
    }
    out->defs = (nts_body_def*)calloc((size_t)out->count + 1, sizeof(nts_body_def));
    out->ids = (int*)calloc((size_t)out->count + 1, sizeof(int));
    if (out->defs == NULL || out->ids == NULL) ok = 0;
    if (ok) {
        size_t p = 0;
        for (k = 0; k < out->count; ++k) p += ntsm_body_read(out->data.p + p, &out->defs[k], &out->ids[k]);
    }
    {
        int all_ok;
        MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, comm);
        return all_ok ? NTS_OK : NTS_ENOMEM;
    }
}

static void dealt_free(ntsm_dealt* d) {
    free(d->data.p);
    free(d->defs);
    free(d->ids);
    memset(d, 0, sizeof *d);
}


/* A job's state, kept until the next (its result's arrays live in it) and,
 * over --frames, for the next frame of the same scene: its distributed
 * scene then takes the frame's positions and goes on (its parts and their
 * candidate lists kept while they hold, docs/distributed.md) instead of
 * being dealt and made anew. On root, what the scene was made of: `key`,
 * every body's bytes at its reference with the box and the limits (the
 * same while only positions change: a session's bodies keep their first
 * positions as reference), and each rank's bodies (first_of). */
typedef struct job {
    ntsm_dealt dealt;
    ntsm_scene* scene;
    bytes key;
    int* first_of;
} job;

static job current;

static void job_end(void) {
    ntsm_scene_destroy(current.scene);
    dealt_free(&current.dealt);
    free(current.key.p);
    free(current.first_of);
    memset(&current, 0, sizeof current);
}

/* Root: the bytes that say which scene def is (job.key). */
static bytes scene_key(const nts_scene_def* def, const double box[2], const nts_limits* limits) {
    bytes k;
    int b;
    memset(&k, 0, sizeof k);
    ntsm_bytes_put(&k, box, 2 * sizeof(double));
    ntsm_bytes_put(&k, limits, sizeof *limits);
    for (b = 0; b < def->body_count; ++b) {
        nts_body_def d = def->bodies[b];
        const nts_vec2* ref = d.reference != NULL ? d.reference : d.nodes;
        d.nodes = ref; /* (the positions apart) */
        ntsm_body_write(&k, &d, b, ref);
    }
    return k;
}

/* Every rank: the next frame of the scene `current` holds, root's positions
 * (def's bodies') to each rank's bodies. NTS_OK, or the agreed error. */
static int frame_positions(const nts_scene_def* def, nts_error* err) {
    int rank, size, r, ok = 1, all, mine_n = 0, k;
    int* counts = NULL;
    int* displs = NULL;
    nts_vec2* whole = NULL;
    nts_vec2* mine = NULL;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    for (k = 0; k < current.dealt.count; ++k) mine_n += current.dealt.defs[k].node_count;
    if (rank == 0) {
        /* each rank's bodies are a block of the whole's: their rows, in order */
        long long n = 0, at = 0;
        int b;
        for (b = 0; b < def->body_count; ++b) n += def->bodies[b].node_count;
        counts = (int*)malloc(sizeof(int) * (size_t)size);
        displs = (int*)malloc(sizeof(int) * (size_t)size);
        whole = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)(n + 1));
        ok = counts != NULL && displs != NULL && whole != NULL && n <= INT_MAX / 2;
        for (b = 0; ok && b < def->body_count; ++b) {
            memcpy(whole + at, def->bodies[b].nodes, sizeof(nts_vec2) * (size_t)def->bodies[b].node_count);
            at += def->bodies[b].node_count;
        }
        for (r = 0, at = 0; ok && r < size; ++r) {
            long long c = 0;
            for (b = current.first_of[r]; b < current.first_of[r + 1]; ++b) c += def->bodies[b].node_count;
            counts[r] = (int)(2 * c); /* (doubles) */
            displs[r] = (int)(2 * at);
            at += c;
        }
    }
    mine = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)(mine_n + 1));
    ok = ok && mine != NULL;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (all)
        MPI_Scatterv(whole, counts, displs, MPI_DOUBLE, mine, 2 * mine_n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    free(counts);
    free(displs);
    free(whole);
    if (!all) {
        free(mine);
        *err = nts_error_none();
        err->code = NTS_ENOMEM;
        strcpy(err->message, "out of memory");
        return NTS_ENOMEM;
    }
    k = ntsm_scene_update_positions(current.scene, mine, err);
    free(mine);
    return k;
}

/* Every rank: one evaluation of the bodies root deals (def only read on
 * root), with root's options and frame. */
static int job_run(const nts_scene_def* def, nts_options* opt, nts_frame* frame, const nts_anchor* anchors, int count,
                   nts_result* out, nts_error* err) {
    double box[2] = {0.0, 0.0};
    nts_limits limits = nts_default_limits();
    int rank, size, rc, keep = 0;
    ntsm_result mine;
    bytes key;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    memset(&key, 0, sizeof key);
    if (rank == 0) {
        box[0] = def->lx;
        box[1] = def->ly;
        limits = def->limits;
        /* the scene the last job made, at other positions: go on with it */
        key = scene_key(def, box, &limits);
        keep = current.scene != NULL && !key.oom && key.n == current.key.n && memcmp(key.p, current.key.p, key.n) == 0;
    }
    MPI_Bcast(&keep, 1, MPI_INT, 0, MPI_COMM_WORLD);
    MPI_Bcast(opt, (int)sizeof *opt, MPI_BYTE, 0, MPI_COMM_WORLD);
    MPI_Bcast(frame, (int)sizeof *frame, MPI_BYTE, 0, MPI_COMM_WORLD);
    MPI_Bcast(box, 2, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Bcast(&limits, (int)sizeof limits, MPI_BYTE, 0, MPI_COMM_WORLD);
    if (keep) {
        /* A refusal (the error is every rank's): the scene made anew, as
         * without keeping it, from the positions rank 0's session took (a
         * body turned over is a scene of its own, docs/model.md) */
        if (frame_positions(def, err) != NTS_OK) {
            keep = 0;
            *err = nts_error_none();
        }
    }
    if (keep) {
        free(key.p);
    } else {
        job_end();
        current.key = key; /* (root's; a job that fails is ended by the next) */
        current.first_of = (int*)calloc((size_t)size + 1, sizeof(int));
        rc = current.first_of != NULL ? NTS_OK : NTS_ENOMEM;
        MPI_Allreduce(MPI_IN_PLACE, &rc, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (rc == NTS_OK)
            rc = deal_bodies(MPI_COMM_WORLD, 0, rank == 0 ? def->bodies : NULL, rank == 0 ? def->body_count : 0,
                             &current.dealt, current.first_of);
        if (rc != NTS_OK) {
            *err = nts_error_none();
            err->code = rc;
            strcpy(err->message, "out of memory");
            job_end();
            return rc;
        }
        current.scene = ntsm_scene_create(MPI_COMM_WORLD, current.dealt.defs, current.dealt.ids,
                                          current.dealt.count, box[0], box[1], limits, err);
        if (current.scene == NULL) {
            job_end();
            return err->code;
        }
    }
    ntsm_scene_set_frame(current.scene, frame);
    /* friction's committed anchors: rank 0's, to every rank */
    {
        nts_anchor* given = NULL;
        int ok = 1, all;
        MPI_Bcast(&count, 1, MPI_INT, 0, MPI_COMM_WORLD);
        if (count > 0) {
            given = rank == 0 ? (nts_anchor*)(uintptr_t)anchors : (nts_anchor*)malloc(sizeof(nts_anchor) * (size_t)count);
            ok = given != NULL;
        }
        MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (!all) {
            if (rank != 0) free(given);
            *err = nts_error_none();
            err->code = NTS_ENOMEM;
            strcpy(err->message, "out of memory");
            return NTS_ENOMEM;
        }
        if (count > 0) MPI_Bcast(given, (int)(sizeof(nts_anchor) * (size_t)count), MPI_BYTE, 0, MPI_COMM_WORLD);
        ok = ntsm_scene_set_history(current.scene, given, count) == NTS_OK;
        if (rank != 0) free(given);
        MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        if (!all) {
            *err = nts_error_none();
            err->code = NTS_ENOMEM;
            strcpy(err->message, "out of memory");
            return NTS_ENOMEM;
        }
    }
    if ((rc = ntsm_evaluate(current.scene, opt, &mine, err)) != NTS_OK) return rc;
    return ntsm_gather(current.scene, 0, out, err);
}

/* The codec's evaluation on rank 0. */
static int evaluate(void* user, const nts_scene_def* def, const nts_scene* scene, const nts_options* opt,
                    nts_result* out, nts_error* err) {
    int cmd = JOB_EVALUATE, rc;
    nts_options o = *opt;
    nts_frame frame;
    nts_context* ctx;
    (void)user;
    memset(out, 0, sizeof *out);
    /* the whole scene's frame, computed here where the whole scene is */
    if ((ctx = nts_context_create()) == NULL) return NTS_ENOMEM;
    rc = nts_scene_frame(ctx, scene, opt, &frame, NULL, err);
    nts_context_destroy(ctx);
    if (rc != NTS_OK) return rc;
    o.cancel = NULL; /* a deadline is rank 0's: the others cannot ask it */
    o.cancel_user = NULL;
    o.history = NULL; /* its anchors go to every rank (job_run) */
    o.candidates = NULL;
    MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
    {
        int n = 0;
        const nts_anchor* anchors = opt->history != NULL ? nts_history_anchors(opt->history, &n) : NULL;
        return job_run(def, &o, &frame, anchors, n, out, err);
    }
}

void ntsm_cli_configure(ntsj_config* cfg) {
    cfg->evaluate = evaluate;
    cfg->evaluate_user = NULL;
}

/* A JSON value as text, its numbers as the shortest %.17g that reads back
 * the same double (cJSON's own printer loses digits): the request rank 0
 * assembles is the parts' numbers, bit for bit. */
static void json_write(FILE* f, const cJSON* v) {
    const cJSON* c;
    if (cJSON_IsObject(v) || cJSON_IsArray(v)) {
        const int obj = cJSON_IsObject(v);
        fputc(obj ? '{' : '[', f);
        for (c = v->child; c != NULL; c = c->next) {
            if (c != v->child) fputc(',', f);
            if (obj) {
                cJSON* key = cJSON_CreateString(c->string);
                char* k = key != NULL ? cJSON_PrintUnformatted(key) : NULL;
                fputs(k != NULL ? k : "\"\"", f);
                fputc(':', f);
                cJSON_free(k);
                cJSON_Delete(key);
            }
            json_write(f, c);
        }
        fputc(obj ? '}' : ']', f);
    } else if (cJSON_IsNumber(v)) {
        char num[40];
        int p;
        for (p = 15; p <= 17; ++p) { /* the shortest that reads back */
            snprintf(num, sizeof num, "%.*g", p, v->valuedouble);
            if (strtod(num, NULL) == v->valuedouble) break;
        }
        fputs(num, f);
    } else {
        char* t = cJSON_PrintUnformatted(v); /* strings (escaped), true, false, null */
        fputs(t != NULL ? t : "null", f);
        cJSON_free(t);
    }
}

/* Whether text[0..n) holds nothing but JSON's white space. */
static int only_space(const char* text, size_t n) {
    size_t k;
    for (k = 0; k < n; ++k)
        if (text[k] != ' ' && text[k] != '\t' && text[k] != '\n' && text[k] != '\r') return 0;
    return 1;
}

/* A member's name and place in its object, for the search for a name that
 * appears twice (sorted by name, then place: O(k log k) for k members). */
typedef struct member {
    const char* name;
    int at;
} member;

static int by_name(const void* a, const void* b) {
    const member *x = (const member*)a, *y = (const member*)b;
    const int c = strcmp(x->name, y->name);
    return c != 0 ? c : (x->at > y->at) - (x->at < y->at);
}

/* The place of the first member of object v whose name an earlier one has
 * (-1: none; -2: out of memory). */
static int repeated_member(const cJSON* v) {
    const cJSON* c;
    member* m;
    int n = 0, k, first = -1;
    for (c = v->child; c != NULL; c = c->next) ++n;
    if (n < 2) return -1;
    if ((m = (member*)malloc(sizeof(member) * (size_t)n)) == NULL) return -2;
    for (c = v->child, k = 0; c != NULL; c = c->next, ++k) {
        m[k].name = c->string != NULL ? c->string : "";
        m[k].at = k;
    }
    qsort(m, (size_t)n, sizeof(member), by_name);
    for (k = 1; k < n; ++k)
        if (strcmp(m[k].name, m[k - 1].name) == 0 && (first < 0 || m[k].at < first)) first = m[k].at;
    free(m);
    return first;
}

/* The first fault of a part that its scan lets through (as a request's
 * decoding finds them): a number that is not finite (a JSON number beyond
 * the doubles, such as 1e999, which cJSON reads as infinite) or a key that
 * appears twice in an object. Returns its code (NULL: none), its JSON
 * pointer (RFC 6901) written at at[len..size) and why in why. The scan
 * before it bounds the depth. */
static const char* part_fault(const cJSON* v, char* at, size_t size, size_t len, char* why, size_t why_size) {
    const cJSON* c;
    int k = 0, twice = -1;
    at[len] = '\0';
    if (cJSON_IsNumber(v)) {
        if (v->valuedouble - v->valuedouble == 0.0) return NULL;
        snprintf(why, why_size, "a number beyond the doubles");
        return "non_finite";
    }
    if (!cJSON_IsObject(v) && !cJSON_IsArray(v)) return NULL;
    if (cJSON_IsObject(v) && (twice = repeated_member(v)) == -2) {
        snprintf(why, why_size, "out of memory");
        return "out_of_memory";
    }
    if (twice >= 0) { /* (an object's keys before what their values hold, as a request's decoding reads them) */
        for (c = v->child; k < twice; c = c->next) ++k;
        ntsj_pointer_append_key(at, size, c->string != NULL ? c->string : "");
        snprintf(why, why_size, "key \"%.64s\" appears more than once", c->string != NULL ? c->string : "");
        return "duplicate_key";
    }
    for (c = v->child; c != NULL; c = c->next, ++k) {
        const char* code;
        size_t n = len;
        if (cJSON_IsArray(v) && n + 1 < size) at[n++] = '/';
        if (cJSON_IsArray(v)) {
            n += (size_t)snprintf(at + n, n < size ? size - n : 0, "%d", k);
            if (n >= size) n = size - 1;
            at[n] = '\0';
        } else {
            ntsj_pointer_append_key(at, size, c->string != NULL ? c->string : "");
            n = strlen(at);
        }
        if ((code = part_fault(c, at, size, n, why, why_size)) != NULL) return code;
        at[len] = '\0';
    }
    return NULL;
}

/* Whether two JSON values are the same: numbers as the same double (not
 * cJSON_Compare's, which takes numbers within a relative DBL_EPSILON for
 * equal: a penalty of 100.00000000000001 against 100 went unseen), members
 * in any order. Nested no deeper than the parts were read (--max-depth). */
static int json_same(const cJSON* x, const cJSON* y) {
    const cJSON* c;
    if ((x->type & 0xFF) != (y->type & 0xFF)) return 0;
    switch (x->type & 0xFF) {
    case cJSON_Number:
        return x->valuedouble == y->valuedouble;
    case cJSON_String:
        return strcmp(x->valuestring, y->valuestring) == 0;
    case cJSON_Array:
        if (cJSON_GetArraySize(x) != cJSON_GetArraySize(y)) return 0;
        for (x = x->child, y = y->child; x != NULL; x = x->next, y = y->next)
            if (!json_same(x, y)) return 0;
        return 1;
    case cJSON_Object: /* (its size: its members, as an array's) */
        if (cJSON_GetArraySize(x) != cJSON_GetArraySize(y)) return 0;
        for (c = x->child; c != NULL; c = c->next) {
            const cJSON* other = cJSON_GetObjectItemCaseSensitive(y, c->string);
            if (other == NULL || !json_same(c, other)) return 0;
        }
        return 1;
    default: /* true, false, null */
        return 1;
    }
}

/* Whether parts a and b have the same member `name`, or both none. */
static int same_member(const cJSON* a, const cJSON* b, const char* name) {
    const cJSON* x = cJSON_GetObjectItemCaseSensitive(a, name);
    const cJSON* y = cJSON_GetObjectItemCaseSensitive(b, name);
    return (x == NULL && y == NULL) || (x != NULL && y != NULL && json_same(x, y));
}

/* The first member of `part` named none of `names` (n of them), or NULL. */
static const cJSON* member_not_in(const cJSON* part, const char* const* names, size_t n) {
    const cJSON* c;
    size_t k;
    for (c = part->child; c != NULL; c = c->next) {
        int ok = 0;
        for (k = 0; k < n; ++k) ok |= strcmp(c->string, names[k]) == 0;
        if (!ok) return c;
    }
    return NULL;
}

/* A part after the first holds bodies, and the options, version and
 * $schema the first's request has; anything else (a history, a session, a
 * field no scene has) would be dropped from the assembled request. Returns
 * the first such member, or NULL. */
static const cJSON* beyond_bodies(const cJSON* part) {
    static const char* const allowed[] = {"bodies", "options", "version", "$schema"};
    return member_not_in(part, allowed, sizeof allowed / sizeof allowed[0]);
}

/* A member of a part that no scene has (the decoder's root fields), or NULL. */
static const cJSON* unknown_root(const cJSON* part) { return member_not_in(part, ntsj_root_fields, NTSJ_ROOT_COUNT); }

/* The assembled request's path on rank 0, for a run stopped by a signal
 * (Ctrl-C at mpirun, which sends its ranks SIGTERM; a hangup): the handler
 * removes the file, as the end of main does, then dies of the signal. */
static char g_assembled[4096];
static volatile sig_atomic_t g_assembled_set;

static void remove_assembled(int sig) {
    if (g_assembled_set) unlink(g_assembled);
    raise(sig); /* (SA_RESETHAND: the default action now) */
}

static void on_stop_remove_assembled(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    struct sigaction sa;
    size_t k;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = remove_assembled;
    sa.sa_flags = SA_RESETHAND;
    sigemptyset(&sa.sa_mask);
    for (k = 0; k < sizeof sigs / sizeof sigs[0]; ++k) sigaction(sigs[k], &sa, NULL);
}

/* --part PATTERN: each rank reads its own part of the scene, PATTERN with
 * "%d" its rank (a scene document of its bodies, "options" the same in
 * every part). Rank 0 puts the parts together (the whole's bodies in rank
 * order, its options the parts') into one request in a temporary file, which
 * the CLI then reads, each part's JSON as strictly as a request's and
 * nested at most max_depth deep (the command line's --max-depth; 0: the
 * codec's default). Returns the file's path on rank 0 (malloc), NULL with
 * *status set on every rank after a fault (each rank's named). */
static char* parts_together(const char* pattern, int rank, int size, int max_depth, int* status) {
    char path[4096], msg[4600] = "";
    char* text = NULL;
    long long len = 0;
    int ok = 1, all, r;
    char* out = NULL;
    *status = 0;
    if (strstr(pattern, "%d") == NULL || strlen(pattern) > 4000) {
        if (rank == 0) fprintf(stderr, "ntscontact-mpi: --part takes a path with %%d (the rank): not '%s'\n", pattern);
        *status = 2;
        return NULL;
    }
    {
        const char* at = strstr(pattern, "%d");
        snprintf(path, sizeof path, "%.*s%d%s", (int)(at - pattern), pattern, rank, at + 2);
    }
    {
        FILE* f = fopen(path, "rb");
        struct stat st;
        if (f == NULL || (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode))) {
            /* (fopen opens a directory; reading it fails) */
            snprintf(msg, sizeof msg, "rank %d cannot read '%s': %s", rank, path, strerror(f == NULL ? errno : EISDIR));
            if (f != NULL) fclose(f);
            ok = 0;
        } else {
            if (fseek(f, 0, SEEK_END) == 0 && (len = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0 && len < INT_MAX &&
                (text = (char*)malloc((size_t)len + 1)) != NULL && fread(text, 1, (size_t)len, f) == (size_t)len) {
                text[len] = '\0';
            } else {
                snprintf(msg, sizeof msg, "rank %d cannot read '%s' whole%s%s", rank, path, ferror(f) ? ": " : "",
                         ferror(f) ? strerror(errno) : "");
                ok = 0;
            }
            fclose(f);
        }
    }
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (!all) { /* every failing rank says why, rank 0 first */
        for (r = 0; r < size; ++r) {
            if (r == rank && !ok) fprintf(stderr, "ntscontact-mpi: %s\n", msg);
            MPI_Barrier(MPI_COMM_WORLD);
        }
        free(text);
        *status = 2;
        return NULL;
    }
    {
        /* the texts to rank 0 */
        int n = (int)len;
        int* counts = rank == 0 ? (int*)malloc(sizeof(int) * 2u * (size_t)size) : NULL;
        char* texts = NULL;
        long long total = 0;
        MPI_Gather(&n, 1, MPI_INT, counts, 1, MPI_INT, 0, MPI_COMM_WORLD);
        if (rank == 0) {
            ok = counts != NULL;
            for (r = 0; ok && r < size; ++r) {
                counts[size + r] = (int)total;
                total += counts[r];
            }
            ok = ok && total < INT_MAX && (texts = (char*)malloc((size_t)total + 1)) != NULL;
        }
        MPI_Bcast(&ok, 1, MPI_INT, 0, MPI_COMM_WORLD);
        if (ok) MPI_Gatherv(text, n, MPI_BYTE, texts, counts, counts + size, MPI_BYTE, 0, MPI_COMM_WORLD);
        free(text);
        if (!ok) {
            if (rank == 0) fprintf(stderr, "ntscontact-mpi: out of memory gathering the parts\n");
            free(counts);
            *status = 1;
            return NULL;
        }
        if (rank == 0) {
            /* one request: part 0's document, every part's bodies in rank order */
            cJSON* whole = NULL;
            cJSON* bodies = NULL;
            for (r = 0; r < size && *status == 0; ++r) {
                /* Each part read as strictly as a request (cJSON alone would
                 * take trailing data or 010), its faults named in it. */
                char where[256], why[256];
                const cJSON* extra;
                const char* differs;
                const int blank = only_space(texts + counts[size + r], (size_t)counts[r]);
                const char* code = blank ? "empty_body" /* (as a request of no bytes, or of spaces) */
                                         : ntsj_json_check(texts + counts[size + r], (size_t)counts[r], max_depth, where,
                                                           sizeof where, why, sizeof why);
                if (blank) {
                    where[0] = '\0';
                    snprintf(why, sizeof why, "the part is empty");
                }
                cJSON* part = code == NULL ? cJSON_ParseWithLength(texts + counts[size + r], (size_t)counts[r]) : NULL;
                cJSON* pb = part != NULL ? cJSON_GetObjectItemCaseSensitive(part, "bodies") : NULL;
                if (code != NULL) {
                    fprintf(stderr, "ntscontact-mpi: %s at \"%s\" of part %d: %s\n", code, where, r, why);
                    *status = 3;
                } else if (part != NULL && (code = part_fault(part, where, sizeof where, 0, why, sizeof why)) != NULL) {
                    fprintf(stderr, "ntscontact-mpi: %s at \"%s\" of part %d: %s\n", code, where, r, why);
                    *status = strcmp(code, "out_of_memory") == 0 ? 1 : 3; /* (the CLI's internal error) */
                } else if (part == NULL) { /* (checked already: cJSON's room) */
                    fprintf(stderr, "ntscontact-mpi: out of memory reading part %d\n", r);
                    *status = 1;
                } else if (!cJSON_IsObject(part) || !cJSON_IsArray(pb)) {
                    /* in the words of the codec's decoder (decode.c) for a whole scene */
                    const int root = !cJSON_IsObject(part);
                    const cJSON* stray = NULL;
                    if (root || pb != NULL) {
                        fprintf(stderr, "ntscontact-mpi: invalid_type at \"%s\" of part %d: expected %s, got %s\n",
                                root ? "" : "/bodies", r, root ? "a scene (an object)" : "an array of bodies",
                                ntsj_json_type_name(root ? part : pb));
                    } else if ((stray = unknown_root(part)) != NULL) {
                        /* (a misspelt "bodies": named first, as the decoder does) */
                        where[0] = '\0';
                        ntsj_pointer_append_key(where, sizeof where, stray->string);
                        fprintf(stderr, "ntscontact-mpi: unknown_field at \"%s\" of part %d: unknown field\n", where,
                                r);
                    } else {
                        fprintf(stderr, "ntscontact-mpi: missing_field at \"/bodies\" of part %d: a part needs "
                                        "\"bodies\"\n", r);
                    }
                    *status = 3;
                } else if (r > 0 && (extra = beyond_bodies(part)) != NULL) {
                    const int known = strcmp(extra->string, "history") == 0 || strcmp(extra->string, "session") == 0;
                    where[0] = '\0';
                    ntsj_pointer_append_key(where, sizeof where, extra->string);
                    fprintf(stderr, "ntscontact-mpi: %s at \"%s\" of part %d: %s\n",
                            known ? "invalid_value" : "unknown_field", where, r,
                            known ? "only part 0's is read (a part after it gives bodies, and the same options)"
                                  : "unknown field (a part after the first has \"bodies\", and \"options\", "
                                    "\"version\" and \"$schema\" as part 0's)");
                    *status = 3;
                } else if (r > 0 && (differs = !same_member(whole, part, "version")   ? "version"
                                               : !same_member(whole, part, "$schema") ? "$schema"
                                                                                       : NULL) != NULL) {
                    fprintf(stderr, "ntscontact-mpi: invalid_value at \"/%s\" of part %d: part %d's %s differs from "
                                    "part 0's\n", differs, r, r, differs);
                    *status = 3;
                } else if (r == 0) {
                    whole = part;
                    bodies = pb;
                    part = NULL;
                } else {
                    if (!same_member(whole, part, "options")) {
                        fprintf(stderr, "ntscontact-mpi: invalid_value at \"/options\": part %d's options differ "
                                        "from part 0's\n", r);
                        *status = 3;
                    }
                    while (*status == 0 && cJSON_GetArraySize(pb) > 0)
                        cJSON_AddItemToArray(bodies, cJSON_DetachItemFromArray(pb, 0));
                }
                cJSON_Delete(part);
            }
            if (*status == 0) {
                /* in $TMPDIR when it is set, as temporary files are expected
                 * to be, else /tmp */
                char tmpl[4096];
                const char* dir = getenv("TMPDIR");
                int fd = -1, bad = 1, why = 0;
                FILE* f = NULL;
                if (dir == NULL || dir[0] == '\0') dir = "/tmp";
                if (snprintf(tmpl, sizeof tmpl, "%s/ntscontact-mpi-XXXXXX", dir) >= (int)sizeof tmpl)
                    snprintf(tmpl, sizeof tmpl, "/tmp/ntscontact-mpi-XXXXXX"); /* (a $TMPDIR too long) */
                on_stop_remove_assembled();
                errno = 0;
                fd = mkstemp(tmpl);
                if (fd >= 0) {
                    memcpy(g_assembled, tmpl, sizeof g_assembled);
                    g_assembled_set = 1;
                }
                f = fd >= 0 ? fdopen(fd, "wb") : NULL;
                if (f != NULL) {
                    /* closed whatever the write gave (a full disk sets the
                     * error flag; fclose then flushes what is left) */
                    json_write(f, whole);
                    bad = ferror(f) != 0;
                    why = errno;
                    if (fclose(f) != 0) {
                        bad = 1;
                        if (!why) why = errno;
                    }
                } else {
                    why = errno;
                    if (fd >= 0) close(fd);
                }
                if (bad || (out = strdup(tmpl)) == NULL) {
                    fprintf(stderr, "ntscontact-mpi: cannot write the assembled request to %s: %s\n", tmpl,
                            strerror(why ? why : ENOMEM));
                    if (fd >= 0) unlink(tmpl);
                    g_assembled_set = 0;
                    *status = 1; /* (the CLI's internal error: a write that fails, out of memory) */
                }
            }
            cJSON_Delete(whole);
            free(texts);
            free(counts);
        }
        MPI_Bcast(status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    }
    return out;
}

int main(int argc, char** argv) {
    int rank, size, status = 0, provided, k, nargs = 0;
    const char* pattern = NULL;
    char* assembled = NULL;
    char** args;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    /* --part PATTERN (ntscontact-mpi's own flag), then the CLI's */
    args = (char**)calloc((size_t)argc + 2, sizeof(char*));
    for (k = 0; args != NULL && k < argc; ++k) {
        if (strcmp(argv[k], "--part") == 0 && k + 1 < argc) pattern = argv[++k];
        else if (strncmp(argv[k], "--part=", 7) == 0) pattern = argv[k] + 7;
        else args[nargs++] = argv[k];
    }
    if (args == NULL) {
        fprintf(stderr, "ntscontact-mpi: out of memory\n");
        MPI_Finalize();
        return 1;
    }
    if (argc > 1 && strcmp(argv[argc - 1], "--part") == 0) { /* (the CLI would call it unknown) */
        if (rank == 0)
            fprintf(stderr, "ntscontact-mpi: --part needs a value: a path with %%d (the rank)\n"
                            "Try 'ntscontact-mpi --help' for more information.\n");
        free(args);
        MPI_Finalize();
        return 2;
    }
    if (pattern != NULL) {
        /* The flags first, as the CLI reads them (a bad one refused before
         * any part is read), then the parts with their --max-depth. */
        int flags[2] = {0, 0};
        if (rank == 0) {
            ntsj_config cfg = ntsj_default_config();
            args[nargs] = (char*)"the scene of --part"; /* (a name: a second scene given is named against it) */
            flags[0] = nts_cli_flags(nargs + 1, args, &cfg);
            args[nargs] = NULL;
            flags[1] = cfg.max_depth;
        }
        MPI_Bcast(flags, 2, MPI_INT, 0, MPI_COMM_WORLD);
        if (flags[0] != 0) {
            free(args);
            MPI_Finalize();
            return flags[0] < 0 ? 0 : flags[0]; /* -1: --help or --version answered */
        }
        assembled = parts_together(pattern, rank, size, flags[1], &status);
        if (status == 0 && rank == 0) args[nargs++] = assembled;
    }
    if (status != 0) {
        free(args);
        MPI_Finalize();
        return status;
    }
    if (rank == 0) {
        int cmd = JOB_STOP;
        status = nts_cli_main(nargs, args);
        MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
    } else {
        for (;;) {
            int cmd;
            nts_options opt;
            nts_frame frame;
            nts_result out;
            nts_error err;
            MPI_Bcast(&cmd, 1, MPI_INT, 0, MPI_COMM_WORLD);
            if (cmd != JOB_EVALUATE) break;
            (void)job_run(NULL, &opt, &frame, NULL, 0, &out, &err);
        }
    }
    if (assembled != NULL) {
        g_assembled_set = 0;
        unlink(assembled);
        free(assembled);
    }
    free(args);
    job_end();
    MPI_Finalize();
    return status;
}
