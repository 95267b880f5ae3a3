/* One scene across the ranks of a communicator (ntscontact/mpi.h,
 * docs/distributed.md). An evaluation:
 *   1. the frame: what the whole scene's segments set (the median segment,
 *      exactly, by bisection of its bits; the longest; the extent), reduced
 *      across the ranks (distributed.h);
 *   2. the slabs: cuts along the longer axis at the quantiles of the surface
 *      nodes (a histogram summed across the ranks): each slab owns the slave
 *      entries whose node lies in it;
 *   3. the halo: each body goes whole to every slab its bounding box, grown
 *      by the reach, overlaps (a contact's slave lies within the reach of
 *      its master, or inside it; the corners and the deep contacts' chains
 *      need the whole loop);
 *   4. each rank evaluates its part with the whole's frame and keeps the
 *      parts (distributed.h) of the slaves it owns;
 *   5. the sums in one process's order: each contribution to a node's force
 *      goes to the node's owner with its key (deep, global slave entry,
 *      master body, place) and is added in key order; each chunk of
 *      NTS_PART_CHUNK slave entries is summed by one rank in contact order,
 *      the chunks' sums are added in chunk order, then the deep contacts'.
 * Every step that can fail ends in `agree`: the same error on every rank. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/mpi.h>

#include "mpi_internal.h"

/* ------------------------------------------------------------ bytes */


static void* bytes_room(bytes* b, size_t n) {
    size_t need = b->n + ((n + 7u) & ~(size_t)7u);
    if (b->oom) return NULL;
    if (need > b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 4096;
        char* p;
        while (cap < need) cap *= 2;
        if ((p = (char*)realloc(b->p, cap)) == NULL) {
            b->oom = 1;
            return NULL;
        }
        b->p = p;
        b->cap = cap;
    }
    {
        char* at = b->p + b->n;
        memset(at, 0, need - b->n);
        b->n = need;
        return at;
    }
}

static void bytes_put(bytes* b, const void* v, size_t n) {
    void* at = bytes_room(b, n);
    if (at != NULL && n > 0) memcpy(at, v, n);
}

/* Grow an array to hold `count` items of `size` bytes (1 on success). */
static int grow(void* pp, int* cap, long long count, size_t size) {
    void** p = (void**)pp;
    long long c;
    void* q;
    if (count <= *cap) return 1;
    if (count > INT_MAX) return 0;
    c = *cap > 0 ? *cap : 64;
    while (c < count) c *= 2;
    if (c > INT_MAX) c = INT_MAX;
    if ((q = realloc(*p, (size_t)c * size)) == NULL) return 0;
    *p = q;
    *cap = (int)c;
    return 1;
}

/* ------------------------------------------------------------ a body's bytes */

/* A body as bytes: its header, alpha and friction, nodes, reference,
 * loop_start, loop_nodes, triangles, surface (each 8-byte aligned). */
enum { H_ID, H_NODES, H_LOOPS, H_LOOPLEN, H_TRIS, H_ROLE, H_HAS_ALPHA, H_SURF, H_HAS_FRIC, H_SELF, H_COUNT };

static void body_write(bytes* b, const nts_body_def* d, int id, const nts_vec2* reference) {
    int h[H_COUNT];
    double ad[2];
    const int looplen = d->loop_count > 0 ? d->loop_start[d->loop_count] : 0;
    h[H_ID] = id;
    h[H_NODES] = d->node_count;
    h[H_LOOPS] = d->loop_count > 0 ? d->loop_count : 0;
    h[H_LOOPLEN] = looplen;
    h[H_TRIS] = d->triangles != NULL ? d->triangle_count : 0;
    h[H_ROLE] = (int)d->role;
    h[H_HAS_ALPHA] = d->has_alpha;
    h[H_SURF] = d->surface != NULL ? d->surface_count : -1;
    h[H_HAS_FRIC] = d->has_friction;
    h[H_SELF] = d->self_contact;
    ad[0] = d->alpha;
    ad[1] = d->friction;
    bytes_put(b, h, sizeof h);
    bytes_put(b, ad, sizeof ad);
    bytes_put(b, d->nodes, sizeof(nts_vec2) * (size_t)d->node_count);
    bytes_put(b, reference, sizeof(nts_vec2) * (size_t)d->node_count);
    if (h[H_LOOPS] > 0) {
        bytes_put(b, d->loop_start, sizeof(int) * (size_t)(d->loop_count + 1));
        bytes_put(b, d->loop_nodes, sizeof(int) * (size_t)looplen);
    }
    if (h[H_TRIS] > 0) bytes_put(b, d->triangles, sizeof(int) * 3u * (size_t)h[H_TRIS]);
    if (h[H_SURF] > 0) bytes_put(b, d->surface, sizeof(int) * 2u * (size_t)h[H_SURF]);
}

static size_t al8(size_t n) { return (n + 7u) & ~(size_t)7u; }

/* The body at p (pointers into p); returns the bytes it takes. */
static size_t body_read(const char* p, nts_body_def* d, int* id) {
    const int* h = (const int*)(const void*)p;
    const double* ad = (const double*)(const void*)(p + al8(sizeof(int) * H_COUNT));
    size_t at = al8(sizeof(int) * H_COUNT) + al8(2 * sizeof(double));
    memset(d, 0, sizeof *d);
    *id = h[H_ID];
    d->node_count = h[H_NODES];
    d->role = (nts_role)h[H_ROLE];
    d->has_alpha = h[H_HAS_ALPHA];
    d->alpha = ad[0];
    d->has_friction = h[H_HAS_FRIC];
    d->friction = ad[1];
    d->self_contact = h[H_SELF];
    d->nodes = (const nts_vec2*)(const void*)(p + at);
    at += al8(sizeof(nts_vec2) * (size_t)h[H_NODES]);
    d->reference = (const nts_vec2*)(const void*)(p + at);
    at += al8(sizeof(nts_vec2) * (size_t)h[H_NODES]);
    if (h[H_LOOPS] > 0) {
        d->loop_count = h[H_LOOPS];
        d->loop_start = (const int*)(const void*)(p + at);
        at += al8(sizeof(int) * (size_t)(h[H_LOOPS] + 1));
        d->loop_nodes = (const int*)(const void*)(p + at);
        at += al8(sizeof(int) * (size_t)h[H_LOOPLEN]);
    }
    if (h[H_TRIS] > 0) {
        d->triangle_count = h[H_TRIS];
        d->triangles = (const int*)(const void*)(p + at);
        at += al8(sizeof(int) * 3u * (size_t)h[H_TRIS]);
    }
    if (h[H_SURF] >= 0) {
        static const int no_pair[2] = {0, 0};
        d->surface_count = h[H_SURF];
        d->surface = h[H_SURF] > 0 ? (const int*)(const void*)(p + at) : no_pair;
        at += al8(sizeof(int) * 2u * (size_t)h[H_SURF]);
    }
    return at;
}

/* ------------------------------------------------------------ the scene */

/* One contribution to a node's force, with the key one process adds it in
 * (deep, slave entry, master body, place), to the rank that owns the node. */
typedef struct share_msg {
    int at;    /* the node among its owner's nodes */
    int entry; /* global slave entry */
    int body;  /* global master body */
    int dq;    /* deep << 2 | place in the contact (0: the slave) */
    double fx, fy;
} share_msg;

/* One contact's sums, with its key. */
typedef struct sum_msg {
    int entry, body, pad[2];
    double e, xx, yy, xy, yx, dis;
} sum_msg;

/* A chunk's sums. */
typedef struct chunk_msg {
    int chunk, pad;
    double e, xx, yy, xy, yx, dis;
} chunk_msg;

struct ntsm_scene {
    MPI_Comm comm;
    int rank, size;
    /* what this rank owns */
    int count;
    int* ids;             /* global index of each owned body */
    bytes own_bytes;      /* the owned bodies, as sent */
    size_t* own_at;       /* each one's offset in own_bytes */
    nts_body_def* own_defs;
    nts_scene* own;       /* the owned bodies alone (positions, the frame's lengths) */
    nts_context* own_ctx;
    int own_nodes;
    int* own_node_at;     /* count + 1: each owned body's first node among this rank's */
    /* the whole, by global body */
    int bodies;
    int* owner;           /* rank */
    int* local_of;        /* index among this rank's bodies, or -1 */
    long long* node_off;  /* bodies + 1 */
    long long* entry_off; /* bodies + 1 */
    int* owner_node_at;   /* each body's first node among its owner's nodes */
    int loops_reversed;
    double lx, ly;        /* the periodic box (0: open) */
    nts_frame frame;
    int frame_given;
    /* the last evaluation's part */
    bytes recv;
    nts_scene* part;
    nts_context* ctx;
    int* part_ids;        /* part body -> global */
    int part_cap_ids;
    long long* part_node; /* part node -> global node */
    int part_node_cap;
    int* node_owner;      /* part node -> its owner rank, and its place among the owner's nodes */
    int* node_at;
    int node_owner_cap, node_at_cap;
    int* entry_owned;     /* part entry -> 1 when this rank owns its slave */
    long long* entry_global;
    int entry_cap;
    nts_result part_result;
    unsigned outputs;
    /* the answer on this rank */
    nts_vec2* forces;
    double* pressure;
    int forces_cap, pressure_cap;
    /* ntsm_gather's arrays on the root */
    nts_vec2* g_forces;
    double* g_pressure;
    nts_contact* g_contacts;
    nts_contact* g_gaps;
    nts_anchor* g_anchors;
    int* g_rows;
    int* g_cols;
    double* g_vals;
    nts_summary summary;
    nts_warning warnings[NTS_WARN_COUNT_];
    int warning_count;
    ntsm_stats stats;
};

/* The same error on every rank: the failing rank with the lowest global body
 * (-1 first), then the lowest rank, gives its record to all. */
static int agree(ntsm_scene* m, MPI_Comm comm, int rank, int size, int rc, nts_error* err) {
    long long mine = LLONG_MAX, first;
    nts_error e;
    (void)m;
    if (rc != NTS_OK) mine = ((long long)(err != NULL ? err->body : -1) + 1) * size + rank;
    MPI_Allreduce(&mine, &first, 1, MPI_LONG_LONG, MPI_MIN, comm);
    if (first == LLONG_MAX) return NTS_OK;
    e = err != NULL ? *err : nts_error_none();
    if (rc != NTS_OK && e.code == 0) e.code = rc;
    MPI_Bcast(&e, (int)sizeof e, MPI_BYTE, (int)(first % size), comm);
    if (err != NULL) *err = e;
    return e.code != 0 ? e.code : NTS_EINTERNAL;
}

static int fail(nts_error* err, int code, const char* msg) {
    if (err != NULL) {
        *err = nts_error_none();
        err->code = code;
        snprintf(err->message, sizeof err->message, "%s", msg);
    }
    return code;
}

/* A core error on a scene of this rank's: its body as a global index. */
static void global_body(nts_error* err, const int* ids, int count) {
    int local, used = 0;
    if (err == NULL || err->body < 0 || err->body >= count) return;
    /* the message names the body as the core does ("body K ..."): K global too */
    if (sscanf(err->message, "body %d%n", &local, &used) == 1 && local == err->body) {
        char out[sizeof err->message + 32];
        snprintf(out, sizeof out, "body %d%s", ids[local], err->message + used);
        memcpy(err->message, out, sizeof err->message - 1);
        err->message[sizeof err->message - 1] = '\0';
    }
    err->body = ids[err->body];
}

void ntsm_scene_destroy(ntsm_scene* m) {
    if (m == NULL) return;
    free(m->ids);
    free(m->own_bytes.p);
    free(m->own_at);
    free(m->own_defs);
    free(m->own_node_at);
    nts_scene_destroy(m->own);
    nts_context_destroy(m->own_ctx);
    free(m->owner);
    free(m->local_of);
    free(m->node_off);
    free(m->entry_off);
    free(m->owner_node_at);
    free(m->recv.p);
    nts_scene_destroy(m->part);
    nts_context_destroy(m->ctx);
    free(m->part_ids);
    free(m->part_node);
    free(m->node_owner);
    free(m->node_at);
    free(m->entry_owned);
    free(m->entry_global);
    free(m->forces);
    free(m->pressure);
    free(m->g_forces);
    free(m->g_pressure);
    free(m->g_contacts);
    free(m->g_gaps);
    free(m->g_anchors);
    free(m->g_rows);
    free(m->g_cols);
    free(m->g_vals);
    free(m);
}

/* The owned bodies' definitions, pointing into own_bytes. */
static void own_defs_point(ntsm_scene* m) {
    int k, id;
    for (k = 0; k < m->count; ++k) body_read(m->own_bytes.p + m->own_at[k], &m->own_defs[k], &id);
}

ntsm_scene* ntsm_scene_create(MPI_Comm comm, const nts_body_def* bodies, const int* ids, int count, double lx,
                              double ly, nts_limits limits, nts_error* err) {
    ntsm_scene* m = (ntsm_scene*)calloc(1, sizeof *m);
    int rank, size, rc = NTS_OK, k, total = 0, i;
    int* counts = NULL;
    int* displs = NULL;
    int* mine = NULL;
    int* all = NULL;
    nts_error e = nts_error_none();
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    if (m == NULL || count < 0 || (count > 0 && (bodies == NULL || ids == NULL))) {
        rc = m == NULL ? fail(&e, NTS_ENOMEM, "out of memory") : fail(&e, NTS_EINVALID_ARGUMENT, "no bodies given");
    }
    if (rc == NTS_OK) {
        m->comm = comm;
        m->rank = rank;
        m->size = size;
        m->count = count;
        m->lx = lx;
        m->ly = ly;
        m->ids = (int*)malloc(sizeof(int) * (size_t)(count + 1));
        m->own_node_at = (int*)calloc((size_t)count + 1, sizeof(int));
        m->own_at = (size_t*)malloc(sizeof(size_t) * (size_t)(count + 1));
        m->own_defs = (nts_body_def*)calloc((size_t)count + 1, sizeof(nts_body_def));
        if (m->ids == NULL || m->own_at == NULL || m->own_defs == NULL || m->own_node_at == NULL) rc = fail(&e, NTS_ENOMEM, "out of memory");
    }
    for (k = 0; k < count && rc == NTS_OK; ++k) {
        if (bodies[k].nodes == NULL || bodies[k].node_count < 0) {
            rc = fail(&e, NTS_EINVALID_ARGUMENT, "a body has no nodes array");
            e.body = ids[k];
            break;
        }
        m->ids[k] = ids[k];
        m->own_at[k] = m->own_bytes.n;
        /* no reference given: the first positions are it, wherever the body goes */
        body_write(&m->own_bytes, &bodies[k], ids[k], bodies[k].reference ? bodies[k].reference : bodies[k].nodes);
    }
    if (rc == NTS_OK && m->own_bytes.oom) rc = fail(&e, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK) {
        nts_scene_def def = nts_default_scene_def();
        own_defs_point(m);
        def.bodies = m->own_defs;
        def.body_count = count;
        def.lx = lx;
        def.ly = ly;
        def.limits = limits;
        def.limits.max_bodies = INT_MAX;
        if (count > 0) {
            m->own = nts_scene_create(&def, &e);
            if (m->own == NULL) {
                rc = e.code != 0 ? e.code : NTS_ENOMEM;
                global_body(&e, m->ids, count);
            }
        }
        m->own_ctx = nts_context_create();
        m->ctx = nts_context_create();
        if (rc == NTS_OK && (m->own_ctx == NULL || m->ctx == NULL)) rc = fail(&e, NTS_ENOMEM, "out of memory");
    }
    if (agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;

    /* The whole: every body's owner, nodes and surface entries. */
    counts = (int*)malloc(sizeof(int) * (size_t)size);
    displs = (int*)malloc(sizeof(int) * (size_t)(size + 1));
    mine = (int*)malloc(sizeof(int) * 3u * (size_t)(count + 1));
    rc = counts && displs && mine ? NTS_OK : fail(&e, NTS_ENOMEM, "out of memory");
    if (agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    for (k = 0; k < count; ++k) {
        mine[3 * k] = m->ids[k];
        mine[3 * k + 1] = m->own_defs[k].node_count;
        mine[3 * k + 2] = nts_scene_body_entry_start(m->own, k + 1) - nts_scene_body_entry_start(m->own, k);
        m->own_nodes += m->own_defs[k].node_count;
        m->own_node_at[k + 1] = m->own_nodes;
    }
    k = 3 * count;
    MPI_Allgather(&k, 1, MPI_INT, counts, 1, MPI_INT, comm);
    for (i = 0, displs[0] = 0; i < size; ++i) displs[i + 1] = displs[i] + counts[i];
    total = displs[size] / 3;
    all = (int*)malloc(sizeof(int) * 3u * (size_t)(total + 1));
    m->bodies = total;
    m->owner = (int*)malloc(sizeof(int) * (size_t)(total + 1));
    m->local_of = (int*)malloc(sizeof(int) * (size_t)(total + 1));
    m->node_off = (long long*)malloc(sizeof(long long) * (size_t)(total + 1));
    m->entry_off = (long long*)malloc(sizeof(long long) * (size_t)(total + 1));
    m->owner_node_at = (int*)malloc(sizeof(int) * (size_t)(total + 1));
    rc = all && m->owner && m->local_of && m->node_off && m->entry_off && m->owner_node_at ? NTS_OK : fail(&e, NTS_ENOMEM, "out of memory");
    if (agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    MPI_Allgatherv(mine, 3 * count, MPI_INT, all, counts, displs, MPI_INT, comm);
    for (i = 0; i < total; ++i) m->owner[i] = -1;
    for (i = 0; i < size && rc == NTS_OK; ++i) {
        int j, at = 0;
        for (j = displs[i] / 3; j < displs[i + 1] / 3; ++j) {
            const int id = all[3 * j];
            if (id < 0 || id >= total || m->owner[id] >= 0) {
                rc = fail(&e, NTS_EINVALID_ARGUMENT,
                          "the ranks' body indices must be 0 .. B-1, each on exactly one rank");
                e.body = id >= 0 && id < total ? id : -1;
                break;
            }
            m->owner[id] = i;
            m->owner_node_at[id] = at;
            at += all[3 * j + 1];
            m->node_off[id + 1] = all[3 * j + 1];
            m->entry_off[id + 1] = all[3 * j + 2];
        }
    }
    if (rc == NTS_OK) {
        m->node_off[0] = m->entry_off[0] = 0;
        for (i = 0; i < total; ++i) {
            m->node_off[i + 1] += m->node_off[i];
            m->entry_off[i + 1] += m->entry_off[i];
            m->local_of[i] = -1;
        }
        for (k = 0; k < count; ++k) m->local_of[m->ids[k]] = k;
        if (total == 0) rc = fail(&e, NTS_EEMPTY_SCENE, "scene has no bodies");
        else if (total > limits.max_bodies) rc = fail(&e, NTS_ELIMIT, "more bodies than the limit max_bodies");
        else if (m->node_off[total] > limits.max_nodes) rc = fail(&e, NTS_ELIMIT, "more nodes than the limit max_nodes");
        else if (m->entry_off[total] > INT_MAX / 2) rc = fail(&e, NTS_ELIMIT, "too many surface nodes");
        if (rc == NTS_ELIMIT) snprintf(e.option, sizeof e.option, "%s", total > limits.max_bodies ? "max_bodies" : "max_nodes");
    }
    if (agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    k = m->own != NULL ? nts_scene_loops_reversed(m->own) : 0;
    MPI_Allreduce(&k, &m->loops_reversed, 1, MPI_INT, MPI_SUM, comm);
    free(counts);
    free(displs);
    free(mine);
    free(all);
    if (err != NULL) *err = nts_error_none();
    return m;
failed:
    free(counts);
    free(displs);
    free(mine);
    free(all);
    ntsm_scene_destroy(m);
    if (err != NULL) *err = e;
    return NULL;
}

int ntsm_scene_update_positions(ntsm_scene* m, const nts_vec2* positions, nts_error* err) {
    nts_error e = nts_error_none();
    int rc = NTS_OK, k, at = 0;
    if (m->own != NULL && (rc = nts_scene_update_positions(m->own, positions, &e)) != NTS_OK)
        global_body(&e, m->ids, m->count);
    if (rc == NTS_OK)
        for (k = 0; k < m->count; ++k) {
            memcpy((void*)(uintptr_t)m->own_defs[k].nodes, positions + at,
                   sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
            at += m->own_defs[k].node_count;
        }
    rc = agree(m, m->comm, m->rank, m->size, rc, &e);
    if (err != NULL) *err = rc == NTS_OK ? nts_error_none() : e;
    return rc;
}

void ntsm_scene_set_frame(ntsm_scene* m, const nts_frame* frame) {
    m->frame_given = frame != NULL;
    if (frame != NULL) m->frame = *frame;
}

/* ------------------------------------------------------------ the frame */

static uint64_t bits_of(double v) {
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

static double double_of(uint64_t u) {
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* The k-th smallest (0-based) of every rank's values v[0..n), exactly: the
 * values are positive doubles, ordered as their bits, so eight rounds each
 * fix the next byte of the answer's bits, from a histogram of that byte
 * among the values that agree with the bytes found so far, summed across
 * the ranks (v is reordered: those candidates are kept in front). */
static double kth_across(MPI_Comm comm, double* v, int n, long long k) {
    uint64_t prefix = 0;
    long long h[256], sum[256];
    int round, live = n, i, c;
    for (round = 0; round < 8; ++round) {
        const int shift = 56 - 8 * round;
        memset(h, 0, sizeof h);
        for (i = 0; i < live; ++i) h[(bits_of(v[i]) >> shift) & 255u]++;
        MPI_Allreduce(h, sum, 256, MPI_LONG_LONG, MPI_SUM, comm);
        for (c = 0; c < 255 && k >= sum[c]; ++c) k -= sum[c];
        prefix |= (uint64_t)c << shift;
        { /* keep the candidates that share the bytes so far */
            int kept = 0;
            const uint64_t mask = ~(uint64_t)0 << shift;
            for (i = 0; i < live; ++i)
                if ((bits_of(v[i]) & mask) == prefix) v[kept++] = v[i];
            live = kept;
        }
    }
    return double_of(prefix);
}

/* The whole scene's frame: its segments' extremes reduced, and the median
 * (the k-th smallest of every rank's lengths, exactly: the lengths are
 * positive doubles, ordered as their bits, so at most 64 rounds of counting
 * find it). */
static int frame_find(ntsm_scene* m, const nts_options* opt, nts_frame* f, nts_error* err) {
    const int n = m->own != NULL ? nts_scene_surface_node_count(m->own) : 0;
    double* len = (double*)malloc(sizeof(double) * (size_t)(n + 1));
    double ext[6], red[6];
    int rc = len ? NTS_OK : fail(err, NTS_ENOMEM, "out of memory");
    nts_frame mine;
    memset(&mine, 0, sizeof mine);
    if (rc == NTS_OK && n > 0 && (rc = nts_scene_frame(m->own_ctx, m->own, opt, &mine, len, err)) != NTS_OK)
        global_body(err, m->ids, m->count);
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, err)) != NTS_OK) {
        free(len);
        return rc;
    }
    if (n == 0) {
        mine.xmin = mine.ymin = HUGE_VAL;
        mine.xmax = mine.ymax = -HUGE_VAL;
    }
    ext[0] = mine.lmax;
    ext[1] = mine.coord_max;
    ext[2] = -mine.xmin;
    ext[3] = mine.xmax;
    ext[4] = -mine.ymin;
    ext[5] = mine.ymax;
    MPI_Allreduce(ext, red, 6, MPI_DOUBLE, MPI_MAX, m->comm);
    memset(f, 0, sizeof *f);
    f->lmax = red[0];
    f->coord_max = red[1];
    f->xmin = -red[2];
    f->xmax = red[3];
    f->ymin = -red[4];
    f->ymax = red[5];
    f->cell_size = -1.0;
    f->surface_nodes = (int)m->entry_off[m->bodies];
    if (opt->search_radius < 0.0 && f->surface_nodes > 0)
        f->median = kth_across(m->comm, len, n, (long long)(f->surface_nodes - 1) / 2);
    free(len);
    return NTS_OK;
}

/* ------------------------------------------------------------ the slabs */

enum { BINS = 4096 };

typedef struct slabs {
    int axis;        /* 0: x, 1: y */
    double period;   /* the box along the axis, or 0 */
    double lo, hi;
    double* cut;     /* size + 1: slab r is [cut[r], cut[r + 1]) */
} slabs;

static double axis_of(const slabs* sl, nts_vec2 p) {
    double c = sl->axis == 0 ? p.x : p.y;
    if (sl->period > 0.0) {
        c -= sl->period * floor(c / sl->period);
        if (!(c < sl->period)) c = 0.0; /* a round-off at the top */
    }
    return c;
}

static int slab_of(const slabs* sl, int size, double c) {
    int lo = 0, hi = size - 1; /* the last r with cut[r] <= c */
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (sl->cut[mid] <= c) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

static int bin_of(const slabs* sl, double c) {
    const double w = sl->hi - sl->lo;
    double q;
    if (!(w > 0.0)) return 0;
    q = (c - sl->lo) / w * BINS;
    return q <= 0.0 ? 0 : (q >= BINS - 1 ? BINS - 1 : (int)q);
}

/* The cuts: at the quantiles of the surface nodes along the longer axis. */
static int slabs_make(ntsm_scene* m, const nts_frame* f, double lx, double ly, slabs* sl) {
    long long* h = (long long*)calloc(2 * BINS, sizeof(long long));
    const nts_vec2* pos = m->own ? nts_scene_positions(m->own) : NULL;
    const long long total = m->entry_off[m->bodies];
    long long acc = 0;
    int b, k, r;
    if (h == NULL || (sl->cut = (double*)malloc(sizeof(double) * (size_t)(m->size + 1))) == NULL) {
        free(h);
        return NTS_ENOMEM;
    }
    if (lx > 0.0) {
        sl->axis = lx >= ly ? 0 : 1;
        sl->period = sl->axis == 0 ? lx : ly;
        sl->lo = 0.0;
        sl->hi = sl->period;
    } else {
        sl->axis = f->xmax - f->xmin >= f->ymax - f->ymin ? 0 : 1;
        sl->period = 0.0;
        sl->lo = sl->axis == 0 ? f->xmin : f->ymin;
        sl->hi = sl->axis == 0 ? f->xmax : f->ymax;
    }
    for (b = 0; b < m->count; ++b) {
        const int e0 = nts_scene_body_entry_start(m->own, b), e1 = nts_scene_body_entry_start(m->own, b + 1);
        const int n0 = nts_scene_body_node_offset(m->own, b);
        for (k = e0; k < e1; ++k) {
            int body, node;
            nts_scene_entry(m->own, k, &body, &node);
            h[bin_of(sl, axis_of(sl, pos[n0 + node]))]++;
        }
    }
    MPI_Allreduce(h, h + BINS, BINS, MPI_LONG_LONG, MPI_SUM, m->comm);
    sl->cut[0] = -HUGE_VAL;
    sl->cut[m->size] = HUGE_VAL;
    for (r = 1, b = 0; r < m->size; ++r) {
        const long long target = total * r / m->size;
        while (b < BINS && acc + h[BINS + b] < target) acc += h[BINS + b++];
        /* the slab boundary at the end of bin b (the bins' edges, exactly the
         * same on every rank) */
        sl->cut[r] = b >= BINS ? HUGE_VAL : sl->lo + (sl->hi - sl->lo) * (double)(b + 1) / BINS;
        if (sl->cut[r] < sl->cut[r - 1]) sl->cut[r] = sl->cut[r - 1];
    }
    free(h);
    return NTS_OK;
}

/* Whether [a, b] (along the axis, maybe past the box) meets slab r. */
static int meets(const slabs* sl, int r, double a, double b) {
    int k;
    if (sl->period <= 0.0) return b >= sl->cut[r] && a < sl->cut[r + 1];
    if (b - a >= sl->period) return 1;
    {
        const double s0 = sl->cut[r] < 0.0 ? 0.0 : sl->cut[r];
        const double s1 = sl->cut[r + 1] > sl->period ? sl->period : sl->cut[r + 1];
        const double shift = sl->period * floor(a / sl->period);
        for (k = -1; k <= 2; ++k) {
            const double o = shift + k * sl->period;
            if (b >= s0 + o && a < s1 + o) return 1;
        }
    }
    return 0;
}

/* ------------------------------------------------------------ sorting keys */

/* One process's order of a node's contributions: the chunks' (by slave
 * entry, master body, place), then the deep contacts' (scatter.c). */
static int cmp_share(const share_msg* a, const share_msg* b) {
    if ((a->dq >> 2) != (b->dq >> 2)) return (a->dq >> 2) - (b->dq >> 2);
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    if (a->body != b->body) return a->body < b->body ? -1 : 1;
    return (a->dq & 3) - (b->dq & 3);
}

static int cmp_sum(const void* pa, const void* pb) {
    const sum_msg* a = (const sum_msg*)pa;
    const sum_msg* b = (const sum_msg*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

/* v[0..n) in (entry, body) order: a counting sort by entry (the entries a
 * chunk home receives span its chunks), then each entry's few by body. */
static int sort_sums(sum_msg* v, int n) {
    int lo = v[0].entry, hi = v[0].entry, k, j, e;
    int* start;
    sum_msg* out;
    for (k = 1; k < n; ++k) {
        if (v[k].entry < lo) lo = v[k].entry;
        if (v[k].entry > hi) hi = v[k].entry;
    }
    start = (int*)calloc((size_t)(hi - lo) + 2, sizeof(int));
    out = (sum_msg*)malloc(sizeof(sum_msg) * (size_t)n);
    if (start == NULL || out == NULL) {
        free(start);
        free(out);
        return NTS_ENOMEM;
    }
    for (k = 0; k < n; ++k) start[v[k].entry - lo + 1]++;
    for (e = 0; e <= hi - lo; ++e) start[e + 1] += start[e];
    for (k = 0; k < n; ++k) out[start[v[k].entry - lo]++] = v[k];
    for (k = 1; k < n; ++k) /* insertion sort: only a slave's few contacts are out of order */
        for (j = k; j > 0 && cmp_sum(&out[j - 1], &out[j]) > 0; --j) {
            const sum_msg t = out[j];
            out[j] = out[j - 1];
            out[j - 1] = t;
        }
    memcpy(v, out, sizeof(sum_msg) * (size_t)n);
    free(start);
    free(out);
    return NTS_OK;
}

static int cmp_chunk(const void* pa, const void* pb) {
    const chunk_msg* a = (const chunk_msg*)pa;
    const chunk_msg* b = (const chunk_msg*)pb;
    return (a->chunk > b->chunk) - (a->chunk < b->chunk);
}

/* All-to-all of records of `size` bytes, send[] grouped by destination with
 * counts[r]; returns the received records (malloc) and their count. */
static void* exchange(ntsm_scene* m, const void* send, const int* counts, size_t size, int* got) {
    int* sc = (int*)malloc(sizeof(int) * 4u * (size_t)m->size);
    int *sd, *rc_, *rd, r, total = 0;
    void* out = NULL;
    long long sent = 0, recvd = 0;
    if (sc == NULL) return NULL;
    sd = sc + m->size;
    rc_ = sd + m->size;
    rd = rc_ + m->size;
    for (r = 0; r < m->size; ++r) {
        sc[r] = (int)(counts[r] * size);
        sd[r] = r == 0 ? 0 : sd[r - 1] + sc[r - 1];
        if (r != m->rank) sent += sc[r];
    }
    MPI_Alltoall(sc, 1, MPI_INT, rc_, 1, MPI_INT, m->comm);
    for (r = 0; r < m->size; ++r) {
        rd[r] = r == 0 ? 0 : rd[r - 1] + rc_[r - 1];
        if (r != m->rank) recvd += rc_[r];
    }
    total = rd[m->size - 1] + rc_[m->size - 1];
    out = malloc((size_t)total + 8);
    if (out != NULL) MPI_Alltoallv(send, sc, sd, MPI_BYTE, out, rc_, rd, MPI_BYTE, m->comm);
    m->stats.bytes_sent += sent;
    m->stats.bytes_received += recvd;
    *got = (int)((size_t)total / size);
    free(sc);
    return out;
}

/* ------------------------------------------------------------ evaluate */

static double now(void) { return MPI_Wtime(); }



typedef struct part_body {
    int id;
    size_t at;
} part_body;

static int cmp_part_body(const void* pa, const void* pb) {
    const part_body* a = (const part_body*)pa;
    const part_body* b = (const part_body*)pb;
    return (a->id > b->id) - (a->id < b->id);
}

/* Send each owned body to every slab it reaches; build this rank's part. */
static int part_build(ntsm_scene* m, const slabs* sl, double halo, double lx, double ly, nts_error* err) {
    const int P = m->size;
    int* counts = (int*)calloc((size_t)P, sizeof(int));
    size_t* sizes = (size_t*)calloc((size_t)P, sizeof(size_t));
    unsigned char* to = (unsigned char*)calloc((size_t)m->count * (size_t)P + 1, 1);
    int* sc = (int*)calloc(4u * (size_t)P, sizeof(int));
    char* send = NULL;
    part_body* pb = NULL;
    nts_body_def* defs = NULL;
    int k, r, got = 0, rc = NTS_OK;
    size_t at, total = 0;
    if (!counts || !sizes || !to || !sc) rc = fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < m->count && rc == NTS_OK; ++k) {
        const nts_body_def* d = &m->own_defs[k];
        const size_t bytes_k = (k + 1 < m->count ? m->own_at[k + 1] : m->own_bytes.n) - m->own_at[k];
        double a = HUGE_VAL, b = -HUGE_VAL;
        int i;
        for (i = 0; i < d->node_count; ++i) {
            const double c = sl->axis == 0 ? d->nodes[i].x : d->nodes[i].y;
            if (c < a) a = c;
            if (c > b) b = c;
        }
        for (r = 0; r < P; ++r)
            if (d->node_count > 0 && meets(sl, r, a - halo, b + halo)) {
                to[(size_t)k * P + r] = 1;
                sizes[r] += bytes_k;
                total += bytes_k;
            }
    }
    for (r = 0; r < P && rc == NTS_OK; ++r)
        if (sizes[r] > INT_MAX) rc = fail(err, NTS_ELIMIT, "more than 2 GiB of bodies for one rank");
    if (rc == NTS_OK && (send = (char*)malloc(total + 8)) == NULL) rc = fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    for (r = 0, at = 0; r < P; ++r) {
        sc[r] = (int)sizes[r];
        sc[P + r] = (int)at;
        for (k = 0; k < m->count; ++k)
            if (to[(size_t)k * P + r]) {
                const size_t bytes_k = (k + 1 < m->count ? m->own_at[k + 1] : m->own_bytes.n) - m->own_at[k];
                memcpy(send + at, m->own_bytes.p + m->own_at[k], bytes_k);
                at += bytes_k;
            }
    }
    MPI_Alltoall(sc, 1, MPI_INT, sc + 2 * P, 1, MPI_INT, m->comm);
    for (r = 0, at = 0; r < P; ++r) {
        sc[3 * P + r] = (int)at;
        at += (size_t)sc[2 * P + r];
        if (r != m->rank) {
            m->stats.bytes_sent += sc[r];
            m->stats.bytes_received += sc[2 * P + r];
        }
    }
    free(m->recv.p);
    memset(&m->recv, 0, sizeof m->recv);
    rc = at < INT_MAX && bytes_room(&m->recv, at + 8) != NULL ? NTS_OK : fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    MPI_Alltoallv(send, sc, sc + P, MPI_BYTE, m->recv.p, sc + 2 * P, sc + 3 * P, MPI_BYTE, m->comm);
    /* The bodies received, by global index (one process's order). */
    {
        size_t p = 0;
        int cap = 0, id;
        nts_body_def d;
        while (p < at && rc == NTS_OK) {
            if (!grow(&pb, &cap, got + 1, sizeof(part_body))) rc = fail(err, NTS_ENOMEM, "out of memory");
            else {
                pb[got].at = p;
                p += body_read(m->recv.p + p, &d, &id);
                pb[got++].id = id;
            }
        }
    }
    if (rc == NTS_OK && got > 1) qsort(pb, (size_t)got, sizeof(part_body), cmp_part_body);
    if (rc == NTS_OK && (defs = (nts_body_def*)calloc((size_t)got + 1, sizeof(nts_body_def))) == NULL)
        rc = fail(err, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK && !grow(&m->part_ids, &m->part_cap_ids, got + 1, sizeof(int)))
        rc = fail(err, NTS_ENOMEM, "out of memory");
    for (k = 0; k < got && rc == NTS_OK; ++k) body_read(m->recv.p + pb[k].at, &defs[k], &m->part_ids[k]);
    nts_scene_destroy(m->part);
    m->part = NULL;
    if (rc == NTS_OK && got > 0) {
        nts_scene_def def = nts_default_scene_def();
        def.bodies = defs;
        def.body_count = got;
        def.lx = lx;
        def.ly = ly;
        def.limits.max_bodies = INT_MAX;
        def.limits.max_nodes_per_body = INT_MAX;
        def.limits.max_nodes = LLONG_MAX;
        if ((m->part = nts_scene_create(&def, err)) == NULL) {
            rc = err != NULL && err->code != 0 ? err->code : NTS_ENOMEM;
            global_body(err, m->part_ids, got);
        }
    }
    m->stats.part_bodies = got;
    rc = agree(m, m->comm, m->rank, P, rc, err);
done:
    free(counts);
    free(sizes);
    free(to);
    free(sc);
    free(send);
    free(pb);
    free(defs);
    return rc;
}

/* The part's entries: whether this rank owns each one's slave, and its
 * global index; the part's nodes' global indices. */
static int part_maps(ntsm_scene* m, const slabs* sl) {
    const int nb = m->part ? nts_scene_body_count(m->part) : 0;
    const int ne = m->part ? nts_scene_surface_node_count(m->part) : 0;
    const int nn = m->part ? nts_scene_node_count(m->part) : 0;
    const nts_vec2* pos = m->part ? nts_scene_positions(m->part) : NULL;
    int b, e, owned = 0;
    if (!grow(&m->entry_owned, &m->entry_cap, ne + 1, sizeof(int))) return NTS_ENOMEM;
    {
        int cap = m->entry_cap - 1;
        if (!grow(&m->entry_global, &cap, m->entry_cap, sizeof(long long))) return NTS_ENOMEM;
    }
    if (!grow(&m->part_node, &m->part_node_cap, nn + 1, sizeof(long long)) ||
        !grow(&m->node_owner, &m->node_owner_cap, nn + 1, sizeof(int)) ||
        !grow(&m->node_at, &m->node_at_cap, nn + 1, sizeof(int)))
        return NTS_ENOMEM;
    for (b = 0; b < nb; ++b) {
        const int id = m->part_ids[b], n0 = nts_scene_body_node_offset(m->part, b);
        const int e0 = nts_scene_body_entry_start(m->part, b), e1 = nts_scene_body_entry_start(m->part, b + 1);
        int i;
        for (i = 0; i < nts_scene_body_node_count(m->part, b); ++i) {
            m->part_node[n0 + i] = m->node_off[id] + i;
            m->node_owner[n0 + i] = m->owner[id];
            m->node_at[n0 + i] = m->owner_node_at[id] + i;
        }
        for (e = e0; e < e1; ++e) {
            int body, node;
            nts_scene_entry(m->part, e, &body, &node);
            m->entry_global[e] = m->entry_off[id] + (e - e0);
            m->entry_owned[e] = slab_of(sl, m->size, axis_of(sl, pos[n0 + node])) == m->rank;
            owned += m->entry_owned[e];
        }
    }
    m->stats.owned_slaves = owned;
    m->stats.part_entries = ne;
    return NTS_OK;
}

/* This rank's answer: the shares summed at the nodes' owners, the chunks'
 * sums, the counts. */
static int sums(ntsm_scene* m, const nts_options* opt, nts_error* err) {
    const int P = m->size;
    const long long N = m->entry_off[m->bodies];
    const int nchunk = (int)((N + NTS_PART_CHUNK - 1) / NTS_PART_CHUNK);
    int np = 0, ng = 0, k, q, r, got = 0, rc = NTS_OK;
    const nts_part* parts = m->part ? nts_context_parts(m->ctx, &np) : NULL;
    const int* gap_entries = m->part ? nts_context_gap_entries(m->ctx, &ng) : NULL;
    int* counts = (int*)calloc(2u * (size_t)P, sizeof(int));
    int* fill = counts ? counts + P : NULL;
    share_msg* sh = NULL;
    sum_msg* sm = NULL;
    sum_msg* deep_mine = NULL;
    int n_sh = 0, n_sm = 0, n_deep = 0;
    share_msg* rs = NULL;
    sum_msg* rsum = NULL;
    chunk_msg* ch = NULL;
    chunk_msg* all_ch = NULL;
    sum_msg* all_deep = NULL;
    long long cnt[8], tot[8];
    double maxpen = 0.0, gmax = 0.0;
    const int want_forces = (m->outputs & NTS_OUT_FORCES) != 0u;
    if (counts == NULL) return fail(err, NTS_ENOMEM, "out of memory");
    memset(cnt, 0, sizeof cnt);

    /* The shares, grouped by the rank that owns each node. */
    for (k = 0; k < np && want_forces; ++k) {
        if (!m->entry_owned[parts[k].entry]) continue;
        for (q = 0; q < 4 && parts[k].nodes[q] >= 0; ++q) counts[m->node_owner[parts[k].nodes[q]]]++;
    }
    for (r = 0, n_sh = 0; r < P; ++r) {
        fill[r] = n_sh;
        n_sh += counts[r];
    }
    if ((sh = (share_msg*)malloc(sizeof(share_msg) * (size_t)(n_sh + 1))) == NULL) rc = NTS_ENOMEM;
    if (rc == NTS_OK && (sm = (sum_msg*)malloc(sizeof(sum_msg) * (size_t)(np + 1))) == NULL) rc = NTS_ENOMEM;
    if (rc == NTS_OK && (deep_mine = (sum_msg*)malloc(sizeof(sum_msg) * (size_t)(np + 1))) == NULL) rc = NTS_ENOMEM;
    if ((rc = agree(m, m->comm, m->rank, P, rc == NTS_OK ? rc : fail(err, rc, "out of memory"), err)) != NTS_OK)
        goto done;
    for (k = 0; k < np; ++k) {
        const nts_part* p = &parts[k];
        const int gb = m->part_ids[p->master_body];
        const int ge = (int)m->entry_global[p->entry];
        sum_msg s;
        if (!m->entry_owned[p->entry]) continue;
        for (q = 0; q < 4 && p->nodes[q] >= 0 && want_forces; ++q) {
            share_msg* o = &sh[fill[m->node_owner[p->nodes[q]]]++];
            o->at = m->node_at[p->nodes[q]];
            o->entry = ge;
            o->body = gb;
            o->dq = p->deep << 2 | q;
            o->fx = p->force[q].x;
            o->fy = p->force[q].y;
        }
        memset(&s, 0, sizeof s);
        s.entry = ge;
        s.body = gb;
        s.e = p->energy;
        s.xx = p->virial.xx;
        s.yy = p->virial.yy;
        s.xy = p->virial.xy;
        s.yx = p->virial.yx;
        s.dis = p->dissipation;
        if (p->deep) deep_mine[n_deep++] = s;
        else sm[n_sm++] = s;
        cnt[0]++;                       /* contacts */
        cnt[2] += p->deep;              /* deep */
        cnt[3] += p->state == NTS_STICK;
        cnt[4] += p->state == NTS_SLIP;
        if (p->penetration > maxpen) maxpen = p->penetration;
    }
    for (k = 0; k < ng; ++k) cnt[1] += m->entry_owned[gap_entries[k]];
    {
        int nw, w;
        const int* we;
        we = m->part ? nts_context_warning_entries(m->ctx, NTS_WARN_PENETRATION_BEYOND_RADIUS, &nw) : NULL;
        for (w = 0; we && w < nw; ++w) cnt[5] += m->entry_owned[we[w]];
        we = m->part ? nts_context_warning_entries(m->ctx, NTS_WARN_PENETRATION_BEYOND_REACH, &nw) : NULL;
        for (w = 0; we && w < nw; ++w) cnt[6] += m->entry_owned[we[w]];
    }
    MPI_Allreduce(cnt, tot, 8, MPI_LONG_LONG, MPI_SUM, m->comm);
    MPI_Allreduce(&maxpen, &gmax, 1, MPI_DOUBLE, MPI_MAX, m->comm);

    /* Each node's forces at its owner, in one process's order. */
    rs = (share_msg*)exchange(m, sh, counts, sizeof(share_msg), &got);
    rc = rs != NULL ? NTS_OK : fail(err, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK && (m->outputs & NTS_OUT_FORCES) &&
        !grow(&m->forces, &m->forces_cap, m->own_nodes + 1, sizeof(nts_vec2)))
        rc = fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    if (want_forces) {
        /* by node (a counting sort), then each node's few by key */
        int bad = 0, any_bad = 0, i, j;
        int* start = (int*)calloc((size_t)m->own_nodes + 2, sizeof(int));
        int* order = (int*)malloc(sizeof(int) * (size_t)(got + 1));
        if (start == NULL || order == NULL) {
            free(start);
            free(order);
            rc = fail(err, NTS_ENOMEM, "out of memory");
            goto done;
        }
        for (k = 0; k < got; ++k) start[rs[k].at + 1]++;
        for (i = 0; i < m->own_nodes; ++i) start[i + 1] += start[i];
        for (k = 0; k < got; ++k) order[start[rs[k].at]++] = k;
        for (i = m->own_nodes; i > 0; --i) start[i] = start[i - 1];
        start[0] = 0;
        for (i = 0; i < m->own_nodes; ++i) {
            nts_vec2 f = {0.0, 0.0};
            for (j = start[i] + 1; j < start[i + 1]; ++j) { /* insertion sort by key */
                const int x = order[j];
                int t = j;
                while (t > start[i] && cmp_share(&rs[order[t - 1]], &rs[x]) > 0) {
                    order[t] = order[t - 1];
                    --t;
                }
                order[t] = x;
            }
            for (j = start[i]; j < start[i + 1]; ++j) {
                f.x = f.x + rs[order[j]].fx;
                f.y = f.y + rs[order[j]].fy;
            }
            m->forces[i] = f;
        }
        free(start);
        free(order);
        for (k = 0; k < m->own_nodes; ++k) bad |= !isfinite(m->forces[k].x) || !isfinite(m->forces[k].y);
        MPI_Allreduce(&bad, &any_bad, 1, MPI_INT, MPI_MAX, m->comm);
        if (any_bad) {
            rc = fail(err, NTS_ENONFINITE, "the result overflows a double (penalty or coordinates too large)");
            snprintf(err->option, sizeof err->option, "penalty");
            goto done;
        }
    }

    /* Each chunk summed by one rank in contact order, the chunks in order,
     * then the deep contacts (scatter.c's order). */
    memset(counts, 0, sizeof(int) * (size_t)P);
    for (k = 0; k < n_sm; ++k) counts[(int)((long long)(sm[k].entry / NTS_PART_CHUNK) * P / nchunk)]++;
    {
        sum_msg* sorted = (sum_msg*)malloc(sizeof(sum_msg) * (size_t)(n_sm + 1));
        int* at = (int*)calloc((size_t)P, sizeof(int));
        if (sorted == NULL || at == NULL) {
            free(sorted);
            free(at);
            rc = fail(err, NTS_ENOMEM, "out of memory");
        } else {
            for (r = 1; r < P; ++r) at[r] = at[r - 1] + counts[r - 1];
            for (k = 0; k < n_sm; ++k) sorted[at[(int)((long long)(sm[k].entry / NTS_PART_CHUNK) * P / nchunk)]++] = sm[k];
            free(at);
            rsum = (sum_msg*)exchange(m, sorted, counts, sizeof(sum_msg), &got);
            free(sorted);
            if (rsum == NULL) rc = fail(err, NTS_ENOMEM, "out of memory");
        }
    }
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    if (got > 1 && sort_sums(rsum, got) != NTS_OK) rc = fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    ch = (chunk_msg*)calloc((size_t)got + 1, sizeof(chunk_msg));
    rc = ch ? NTS_OK : fail(err, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) goto done;
    {
        int nc = 0;
        for (k = 0; k < got; ++k) {
            const int c = rsum[k].entry / NTS_PART_CHUNK;
            if (nc == 0 || ch[nc - 1].chunk != c) {
                memset(&ch[nc], 0, sizeof ch[nc]);
                ch[nc++].chunk = c;
            }
            ch[nc - 1].e += rsum[k].e;
            ch[nc - 1].xx += rsum[k].xx;
            ch[nc - 1].yy += rsum[k].yy;
            ch[nc - 1].xy += rsum[k].xy;
            ch[nc - 1].yx += rsum[k].yx;
            ch[nc - 1].dis += rsum[k].dis;
        }
        /* every rank gets every chunk's sums, and every deep contact's */
        {
            int* cc = (int*)malloc(sizeof(int) * 2u * (size_t)(P + 1));
            int total_c = 0, total_d = 0;
            double energy = 0.0, xx = 0.0, yy = 0.0, xy = 0.0, yx = 0.0, dis = 0.0;
            double de = 0.0, dxx = 0.0, dyy = 0.0, dxy = 0.0, dyx = 0.0, ddis = 0.0;
            int mine_bytes = (int)(nc * sizeof(chunk_msg));
            if (cc == NULL) {
                rc = fail(err, NTS_ENOMEM, "out of memory");
            }
            if ((rc = agree(m, m->comm, m->rank, P, rc, err)) != NTS_OK) {
                free(cc);
                goto done;
            }
            MPI_Allgather(&mine_bytes, 1, MPI_INT, cc, 1, MPI_INT, m->comm);
            for (r = 0, cc[P] = 0; r < P; ++r) total_c += cc[r];
            {
                int* dd = (int*)malloc(sizeof(int) * (size_t)P);
                int* disp = (int*)malloc(sizeof(int) * (size_t)P);
                all_ch = (chunk_msg*)malloc((size_t)total_c + sizeof(chunk_msg));
                for (r = 0; disp && r < P; ++r) disp[r] = r == 0 ? 0 : disp[r - 1] + cc[r - 1];
                if (dd && disp && all_ch)
                    MPI_Allgatherv(ch, mine_bytes, MPI_BYTE, all_ch, cc, disp, MPI_BYTE, m->comm);
                mine_bytes = (int)(n_deep * sizeof(sum_msg));
                MPI_Allgather(&mine_bytes, 1, MPI_INT, dd, 1, MPI_INT, m->comm);
                for (r = 0; r < P; ++r) {
                    disp[r] = r == 0 ? 0 : disp[r - 1] + dd[r - 1];
                    total_d += dd[r];
                }
                all_deep = (sum_msg*)malloc((size_t)total_d + sizeof(sum_msg));
                if (all_deep) MPI_Allgatherv(deep_mine, mine_bytes, MPI_BYTE, all_deep, dd, disp, MPI_BYTE, m->comm);
                free(dd);
                free(disp);
            }
            free(cc);
            total_c /= (int)sizeof(chunk_msg);
            total_d /= (int)sizeof(sum_msg);
            if (total_c > 1) qsort(all_ch, (size_t)total_c, sizeof(chunk_msg), cmp_chunk);
            if (total_d > 1) qsort(all_deep, (size_t)total_d, sizeof(sum_msg), cmp_sum);
            for (k = 0; k < total_c; ++k) {
                energy += all_ch[k].e;
                xx += all_ch[k].xx;
                yy += all_ch[k].yy;
                xy += all_ch[k].xy;
                yx += all_ch[k].yx;
                dis += all_ch[k].dis;
            }
            for (k = 0; k < total_d; ++k) {
                de += all_deep[k].e;
                dxx += all_deep[k].xx;
                dyy += all_deep[k].yy;
                dxy += all_deep[k].xy;
                dyx += all_deep[k].yx;
                ddis += all_deep[k].dis;
            }
            m->summary.energy = energy + de;
            m->summary.virial.xx = xx + dxx;
            m->summary.virial.yy = yy + dyy;
            m->summary.virial.xy = xy + dxy;
            m->summary.virial.yx = yx + dyx;
            m->summary.dissipation = dis + ddis;
        }
    }
    m->summary.bodies = m->bodies;
    m->summary.surface_nodes = (int)N;
    m->summary.contacts = (int)tot[0];
    m->summary.gaps = (int)tot[1];
    m->summary.deep_contacts = (int)tot[2];
    m->summary.sticking = (int)tot[3];
    m->summary.slipping = (int)tot[4];
    m->summary.max_penetration = gmax;
    m->summary.loops_reversed = m->loops_reversed;
    m->warning_count = 0;
    if (tot[5] > 0) {
        m->warnings[m->warning_count].code = NTS_WARN_PENETRATION_BEYOND_RADIUS;
        m->warnings[m->warning_count++].count = tot[5];
    }
    if (tot[6] > 0) {
        m->warnings[m->warning_count].code = NTS_WARN_PENETRATION_BEYOND_REACH;
        m->warnings[m->warning_count++].count = tot[6];
    }
    {
        const nts_summary* s = &m->summary;
        if (!isfinite(s->energy) || !isfinite(s->virial.xx) || !isfinite(s->virial.yy) || !isfinite(s->virial.xy) ||
            !isfinite(s->virial.yx) || !isfinite(s->dissipation)) {
            rc = fail(err, NTS_ENONFINITE, "the result overflows a double (penalty or coordinates too large)");
            snprintf(err->option, sizeof err->option, "penalty");
        }
    }
    (void)opt;
done:
    free(counts);
    free(sh);
    free(sm);
    free(deep_mine);
    free(rs);
    free(rsum);
    free(ch);
    free(all_ch);
    free(all_deep);
    return rc;
}

int ntsm_evaluate(ntsm_scene* m, const nts_options* opt, ntsm_result* out, nts_error* err) {
    nts_error e = nts_error_none();
    nts_frame f;
    slabs sl;
    nts_options po;
    double t0 = now(), t1, halo, r;
    int rc = NTS_OK;
    memset(&sl, 0, sizeof sl);
    memset(out, 0, sizeof *out);
    memset(&m->stats, 0, sizeof m->stats);
    memset(&m->part_result, 0, sizeof m->part_result);
    memset(&m->summary, 0, sizeof m->summary);
    if (opt == NULL) rc = fail(&e, NTS_EINVALID_ARGUMENT, "null options");
    else if (opt->history != NULL || opt->candidates != NULL || opt->cancel != NULL)
        rc = fail(&e, NTS_EINVALID_ARGUMENT,
                  "a distributed evaluation takes no friction history, kept candidate list or cancel callback yet");
    else rc = nts_options_validate(opt, &e);
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    m->outputs = opt->outputs;

    /* 1. The frame; 2. the slabs; 3. the halo: a slave's contacts are on
     * masters within the reach (r, and each feature within (1 + ext) L_max
     * of its master node) or around it (deep): twice that, and the bodies
     * that contain it (their boxes hold it). */
    if (m->frame_given) f = m->frame;
    else if ((rc = frame_find(m, opt, &f, &e)) != NTS_OK) goto out;
    rc = slabs_make(m, &f, m->lx, m->ly, &sl) == NTS_OK ? NTS_OK : fail(&e, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    r = opt->search_radius >= 0.0 ? opt->search_radius : f.median;
    halo = 2.0 * (r + (1.0 + opt->surface_extension) * f.lmax) * (1.0 + 1e-9) +
           1e-9 * (f.coord_max + m->lx + m->ly);
    t1 = now();
    m->stats.seconds[0] = t1 - t0;
    t0 = t1;
    if ((rc = part_build(m, &sl, halo, m->lx, m->ly, &e)) != NTS_OK) goto out;
    rc = part_maps(m, &sl) == NTS_OK ? NTS_OK : fail(&e, NTS_ENOMEM, "out of memory");
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    t1 = now();
    m->stats.seconds[1] = t1 - t0;
    t0 = t1;

    /* 4. The part, with the whole's frame; its parts. */
    po = *opt;
    po.outputs &= ~(unsigned)NTS_OUT_FORCES; /* the parts carry them */
    nts_context_set_frame(m->ctx, &f);
    nts_context_set_parts(m->ctx, 1);
    if (m->part != NULL && (rc = nts_evaluate(m->ctx, m->part, &po, &m->part_result, &e)) != NTS_OK)
        global_body(&e, m->part_ids, nts_scene_body_count(m->part));
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    t1 = now();
    m->stats.seconds[2] = t1 - t0;
    t0 = t1;

    /* 5. The sums. */
    rc = sums(m, opt, &e);
    if ((rc = agree(m, m->comm, m->rank, m->size, rc, &e)) != NTS_OK) goto out;
    m->summary.search_radius = r;
    m->summary.cell_size = opt->search == NTS_SEARCH_CELLS
                               ? (f.cell_size >= 0.0 ? f.cell_size : m->part_result.summary.cell_size)
                               : 0.0;
    m->stats.seconds[3] = now() - t0;
    out->summary = m->summary;
    memcpy(out->warnings, m->warnings, sizeof out->warnings);
    out->warning_count = m->warning_count;
    out->forces = (opt->outputs & NTS_OUT_FORCES) ? m->forces : NULL;
    out->pressure = NULL;
    out->node_count = m->own_nodes;
    out->stats = m->stats;
out:
    free(sl.cut);
    if (err != NULL) *err = rc == NTS_OK ? nts_error_none() : e;
    return rc;
}

/* ------------------------------------------------------------ gather */

/* Every rank's bytes, one after the other on root (malloc; NULL elsewhere). */
static char* gather_bytes(ntsm_scene* m, int root, const void* mine, size_t n, size_t* total, int* ok) {
    int mine_n = (int)n, r;
    int* cc = (int*)malloc(sizeof(int) * 2u * (size_t)m->size);
    char* all = NULL;
    long long t = 0;
    *total = 0;
    if (cc == NULL || n > INT_MAX) {
        free(cc);
        *ok = 0;
        return NULL;
    }
    MPI_Gather(&mine_n, 1, MPI_INT, cc, 1, MPI_INT, root, m->comm);
    if (m->rank == root) {
        for (r = 0; r < m->size; ++r) {
            cc[m->size + r] = (int)t;
            t += cc[r];
        }
        if (t > INT_MAX || (all = (char*)malloc((size_t)t + 8)) == NULL) *ok = 0;
    }
    MPI_Bcast(ok, 1, MPI_INT, root, m->comm);
    if (*ok) MPI_Gatherv(mine, mine_n, MPI_BYTE, all, cc, cc + m->size, MPI_BYTE, root, m->comm);
    *total = (size_t)t;
    free(cc);
    return all;
}

typedef struct keyed_contact {
    int entry, body;
    nts_contact c;
} keyed_contact;

typedef struct keyed_anchor {
    int entry, body;
    nts_anchor a;
} keyed_anchor;

typedef struct keyed_triplet {
    int entry, body, seq, row, col, pad;
    double v;
} keyed_triplet;

static int cmp_keyed_contact(const void* pa, const void* pb) {
    const keyed_contact* a = (const keyed_contact*)pa;
    const keyed_contact* b = (const keyed_contact*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

static int cmp_keyed_anchor(const void* pa, const void* pb) {
    const keyed_anchor* a = (const keyed_anchor*)pa;
    const keyed_anchor* b = (const keyed_anchor*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    return (a->body > b->body) - (a->body < b->body);
}

static int cmp_keyed_triplet(const void* pa, const void* pb) {
    const keyed_triplet* a = (const keyed_triplet*)pa;
    const keyed_triplet* b = (const keyed_triplet*)pb;
    if (a->entry != b->entry) return a->entry < b->entry ? -1 : 1;
    if (a->body != b->body) return a->body < b->body ? -1 : 1;
    return (a->seq > b->seq) - (a->seq < b->seq);
}

static nts_contact contact_global(const ntsm_scene* m, nts_contact c) {
    c.slave_body = m->part_ids[c.slave_body];
    c.master_body = m->part_ids[c.master_body];
    return c;
}

int ntsm_gather(ntsm_scene* m, int root, nts_result* out, nts_error* err) {
    const long long nodes = m->node_off[m->bodies];
    const nts_result* pr = &m->part_result;
    int np = 0, ng = 0, k, ok = 1, rc = NTS_OK;
    const nts_part* parts = m->part ? nts_context_parts(m->ctx, &np) : NULL;
    const int* gap_entries = m->part ? nts_context_gap_entries(m->ctx, &ng) : NULL;
    bytes b;
    char* all;
    size_t total;
    nts_error e = nts_error_none();
    memset(out, 0, sizeof *out);
    memset(&b, 0, sizeof b);
    free(m->g_forces);
    free(m->g_pressure);
    free(m->g_contacts);
    free(m->g_gaps);
    free(m->g_anchors);
    free(m->g_rows);
    free(m->g_cols);
    free(m->g_vals);
    m->g_forces = NULL;
    m->g_pressure = NULL;
    m->g_contacts = m->g_gaps = NULL;
    m->g_anchors = NULL;
    m->g_rows = m->g_cols = NULL;
    m->g_vals = NULL;
    if (m->rank == root) {
        out->summary = m->summary;
        out->warnings = m->warning_count > 0 ? m->warnings : NULL;
        out->warning_count = m->warning_count;
    }

    /* The forces: each rank's bodies (index, then its nodes' forces). */
    if (m->outputs & NTS_OUT_FORCES) {
        int at = 0;
        for (k = 0; k < m->count; ++k) {
            long long head[2];
            head[0] = m->ids[k];
            head[1] = m->own_defs[k].node_count;
            bytes_put(&b, head, sizeof head);
            bytes_put(&b, m->forces + at, sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
            at += m->own_defs[k].node_count;
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            size_t p = 0;
            if ((m->g_forces = (nts_vec2*)calloc((size_t)nodes + 1, sizeof(nts_vec2))) == NULL) ok = 0;
            while (ok && p < total) {
                const long long* head = (const long long*)(const void*)(all + p);
                p += 2 * sizeof(long long);
                memcpy(m->g_forces + m->node_off[head[0]], all + p, sizeof(nts_vec2) * (size_t)head[1]);
                p += al8(sizeof(nts_vec2) * (size_t)head[1]);
            }
            out->forces = m->g_forces;
        }
        free(all);
        b.n = 0;
        if (!ok) goto oom;
    }

    /* The pressure: each owned slave's node, from the part that owns it. */
    if (m->outputs & NTS_OUT_PRESSURE) {
        const int ne = m->part ? nts_scene_surface_node_count(m->part) : 0;
        for (k = 0; k < ne; ++k)
            if (m->entry_owned[k]) {
                int body, node;
                long long g;
                double v[2];
                nts_scene_entry(m->part, k, &body, &node);
                g = m->node_off[m->part_ids[body]] + node;
                memcpy(&v[0], &g, sizeof g);
                v[1] = pr->pressure[nts_scene_body_node_offset(m->part, body) + node];
                bytes_put(&b, v, sizeof v);
            }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            size_t p;
            if ((m->g_pressure = (double*)calloc((size_t)nodes + 1, sizeof(double))) == NULL) ok = 0;
            for (p = 0; ok && p < total; p += 2 * sizeof(double)) {
                long long g;
                memcpy(&g, all + p, sizeof g);
                memcpy(&m->g_pressure[g], all + p + sizeof(double), sizeof(double));
            }
            out->pressure = m->g_pressure;
        }
        free(all);
        b.n = 0;
        if (!ok) goto oom;
    }

    /* The contacts and the anchors (contact order: parts' order). */
    {
        const int want_c = (m->outputs & NTS_OUT_CONTACTS) != 0 && pr->contacts != NULL;
        const int want_a = pr->anchors != NULL;
        int pass;
        for (pass = 0; pass < 2; ++pass) {
            size_t one = pass == 0 ? sizeof(keyed_contact) : sizeof(keyed_anchor);
            int any = pass == 0 ? (m->outputs & NTS_OUT_CONTACTS) != 0 : 1, has;
            MPI_Allreduce(pass == 0 ? &want_c : &want_a, &has, 1, MPI_INT, MPI_MAX, m->comm);
            if (!any || !has) continue;
            for (k = 0; k < np; ++k) {
                if (!m->entry_owned[parts[k].entry]) continue;
                if (pass == 0 && want_c) {
                    keyed_contact kc;
                    kc.entry = (int)m->entry_global[parts[k].entry];
                    kc.body = m->part_ids[parts[k].master_body];
                    kc.c = contact_global(m, pr->contacts[k]);
                    bytes_put(&b, &kc, sizeof kc);
                } else if (pass == 1 && want_a) {
                    keyed_anchor ka;
                    ka.entry = (int)m->entry_global[parts[k].entry];
                    ka.body = m->part_ids[parts[k].master_body];
                    ka.a = pr->anchors[k];
                    ka.a.slave_body = m->part_ids[ka.a.slave_body];
                    ka.a.master_body = m->part_ids[ka.a.master_body];
                    bytes_put(&b, &ka, sizeof ka);
                }
            }
            ok = !b.oom;
            all = gather_bytes(m, root, b.p, b.n, &total, &ok);
            if (ok && m->rank == root) {
                const int n = (int)(total / al8(one));
                if (pass == 0) {
                    keyed_contact* kc = (keyed_contact*)(void*)all;
                    if (n > 1) qsort(kc, (size_t)n, sizeof(keyed_contact), cmp_keyed_contact);
                    if ((m->g_contacts = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(n + 1))) == NULL) ok = 0;
                    for (k = 0; ok && k < n; ++k) m->g_contacts[k] = kc[k].c;
                    out->contacts = m->g_contacts;
                    out->contact_count = n;
                } else {
                    keyed_anchor* ka = (keyed_anchor*)(void*)all;
                    if (n > 1) qsort(ka, (size_t)n, sizeof(keyed_anchor), cmp_keyed_anchor);
                    if ((m->g_anchors = (nts_anchor*)malloc(sizeof(nts_anchor) * (size_t)(n + 1))) == NULL) ok = 0;
                    for (k = 0; ok && k < n; ++k) m->g_anchors[k] = ka[k].a;
                    out->anchors = m->g_anchors;
                    out->anchor_count = n;
                }
            }
            free(all);
            b.n = 0;
            if (!ok) goto oom;
        }
    }

    /* The gaps. */
    if (m->outputs & NTS_OUT_GAPS) {
        for (k = 0; k < ng; ++k) {
            keyed_contact kc;
            if (!m->entry_owned[gap_entries[k]]) continue;
            kc.c = contact_global(m, pr->gaps[k]);
            kc.entry = (int)m->entry_global[gap_entries[k]];
            kc.body = kc.c.master_body;
            bytes_put(&b, &kc, sizeof kc);
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            const int n = (int)(total / al8(sizeof(keyed_contact)));
            keyed_contact* kc = (keyed_contact*)(void*)all;
            if (n > 1) qsort(kc, (size_t)n, sizeof(keyed_contact), cmp_keyed_contact);
            if ((m->g_gaps = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(n + 1))) == NULL) ok = 0;
            for (k = 0; ok && k < n; ++k) m->g_gaps[k] = kc[k].c;
            out->gaps = m->g_gaps;
            out->gap_count = n;
        }
        free(all);
        b.n = 0;
        if (!ok) goto oom;
    }

    /* The tangent: each active contact's block in contact order. */
    if (m->outputs & NTS_OUT_STIFFNESS) {
        for (k = 0; k < np; ++k) {
            int t;
            if (!m->entry_owned[parts[k].entry]) continue;
            for (t = 0; t < parts[k].stiff_count; ++t) {
                const int at = parts[k].stiff_at + t;
                const int row = pr->stiffness.rows[at], col = pr->stiffness.cols[at];
                keyed_triplet kt;
                kt.entry = (int)m->entry_global[parts[k].entry];
                kt.body = m->part_ids[parts[k].master_body];
                kt.seq = t;
                kt.row = (int)(2 * m->part_node[row / 2] + row % 2);
                kt.col = (int)(2 * m->part_node[col / 2] + col % 2);
                kt.pad = 0;
                kt.v = pr->stiffness.values[at];
                bytes_put(&b, &kt, sizeof kt);
            }
        }
        ok = !b.oom;
        all = gather_bytes(m, root, b.p, b.n, &total, &ok);
        if (ok && m->rank == root) {
            const int n = (int)(total / sizeof(keyed_triplet));
            keyed_triplet* kt = (keyed_triplet*)(void*)all;
            if (n > 1) qsort(kt, (size_t)n, sizeof(keyed_triplet), cmp_keyed_triplet);
            m->g_rows = (int*)malloc(sizeof(int) * (size_t)(n + 1));
            m->g_cols = (int*)malloc(sizeof(int) * (size_t)(n + 1));
            m->g_vals = (double*)malloc(sizeof(double) * (size_t)(n + 1));
            if (!m->g_rows || !m->g_cols || !m->g_vals) ok = 0;
            for (k = 0; ok && k < n; ++k) {
                m->g_rows[k] = kt[k].row;
                m->g_cols[k] = kt[k].col;
                m->g_vals[k] = kt[k].v;
            }
            out->stiffness.rows = m->g_rows;
            out->stiffness.cols = m->g_cols;
            out->stiffness.values = m->g_vals;
            out->stiffness.count = n;
        }
        free(all);
        b.n = 0;
        if (!ok) goto oom;
    }
    if (m->rank == root) out->stiffness.size = (int)(2 * nodes);
    free(b.p);
    rc = agree(m, m->comm, m->rank, m->size, NTS_OK, &e);
    if (err != NULL) *err = e;
    return rc;
oom:
    free(b.p);
    rc = fail(&e, NTS_ENOMEM, "out of memory");
    rc = agree(m, m->comm, m->rank, m->size, rc, &e);
    if (err != NULL) *err = e;
    return rc;
}

/* ------------------------------------------------------------ the CLI's deal */

int ntsm_deal_bodies(MPI_Comm comm, int root, const nts_body_def* bodies, int body_count, ntsm_dealt* out) {
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
                body_write(&blk, &bodies[b], b, bodies[b].reference ? bodies[b].reference : bodies[b].nodes);
                acc += bodies[b++].node_count;
            }
            head[0] = b - first;
            head[1] = (long long)blk.n;
            if (blk.oom || blk.n > INT_MAX) ok = 0;
            if (r == root) {
                out->count = b - first;
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
        if (bytes_room(&out->data, (size_t)head[1] + 8) == NULL) ok = 0;
        out->data.n = (size_t)head[1];
        if (head[1] > 0) MPI_Recv(out->data.p, (int)head[1], MPI_BYTE, root, 72, comm, MPI_STATUS_IGNORE);
    }
    out->defs = (nts_body_def*)calloc((size_t)out->count + 1, sizeof(nts_body_def));
    out->ids = (int*)calloc((size_t)out->count + 1, sizeof(int));
    if (out->defs == NULL || out->ids == NULL) ok = 0;
    if (ok) {
        size_t p = 0;
        for (k = 0; k < out->count; ++k) p += body_read(out->data.p + p, &out->defs[k], &out->ids[k]);
    }
    {
        int all_ok;
        MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, comm);
        return all_ok ? NTS_OK : NTS_ENOMEM;
    }
}

void ntsm_dealt_free(ntsm_dealt* d) {
    free(d->data.p);
    free(d->defs);
    free(d->ids);
    memset(d, 0, sizeof *d);
}
