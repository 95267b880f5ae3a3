/* The distributed scene (ntscontact/mpi.h): the bodies a rank owns, the
 * whole's tables, and the collective errors every call ends in. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* The same error on every rank: the failing rank with the lowest global body
 * (-1 first), then the lowest rank, gives its record to all. */
int ntsm_agree(ntsm_scene* m, MPI_Comm comm, int rank, int size, int rc, nts_error* err) {
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

int ntsm_fail(nts_error* err, int code, const char* msg) {
    if (err != NULL) {
        *err = nts_error_none();
        err->code = code;
        snprintf(err->message, sizeof err->message, "%s", msg);
    }
    return code;
}

/* A core error on a scene of this rank's: its body as a global index. */
void ntsm_global_body(nts_error* err, const int* ids, int count) {
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
    free(m->hist);
    nts_history_destroy(m->part_history);
    free(m->part_anchors);
    free(m->part_of);
    nts_scene_destroy(m->own);
    nts_context_destroy(m->own_ctx);
    free(m->owner);
    free(m->local_of);
    free(m->node_off);
    free(m->entry_off);
    free(m->owner_node_at);
    free(m->cut_b);
    free(m->weights);
    free(m->share);
    free(m->speed);
    free(m->to);
    free(m->build_pos);
    free(m->arrival_nodes);
    free(m->arrival_off);
    free(m->recv.p);
    {
        int k;
        for (k = 0; k < SC_COUNT; ++k) free(m->sc[k].p);
    }
    nts_scene_destroy(m->part);
    nts_context_destroy(m->ctx);
    nts_candidates_destroy(m->part_kc);
    free(m->part_ids);
    free(m->part_node);
    free(m->node_owner);
    free(m->node_at);
    free(m->part_single);
    free(m->node_single);
    free(m->ps_slot);
    free(m->entry_owned);
    free(m->owned_mask);
    free(m->entry_global);
    free(m->entry_node);
    free(m->forces);
    free(m->pressure);
    ntsm_gathered_free(m);
    free(m);
}

/* The owned bodies as a scene definition: m->own's (its box the whole's,
 * its limits the caller's but for the count of bodies, which is the
 * whole's to check). */
static nts_scene_def own_scene_def(const ntsm_scene* m) {
    nts_scene_def def = nts_default_scene_def();
    def.bodies = m->own_defs;
    def.body_count = m->count;
    def.lx = m->lx;
    def.ly = m->ly;
    def.limits = m->own_limits;
    return def;
}

/* The owned bodies' definitions, pointing into own_bytes. */
static void own_defs_point(ntsm_scene* m) {
    int k, id;
    for (k = 0; k < m->count; ++k) ntsm_body_read(m->own_bytes.p + m->own_at[k], &m->own_defs[k], &id);
}

/* One process names the body its checks meet first, in the whole's order
 * (each pass of checks over every body: coordinates before loops); a
 * rank's own scene meets its bodies in the rank's order, which the caller's
 * deal need not keep ascending. So, after a failure, a rank whose bodies
 * are not in ascending global order makes its scene again with them in
 * that order (and, with `moved`, gives it those positions: node_at is each
 * body's first row of `moved`), and names the body that one fails at, as a
 * local index in e. The error path only: O(n log n) and one scene. */
typedef struct id_at {
    int id, at; /* a body's global index, and its place on this rank */
} id_at;

static int by_global(const void* a, const void* b) {
    const int x = ((const id_at*)a)->id, y = ((const id_at*)b)->id;
    return (x > y) - (x < y);
}

int ntsm_ascending(const int* ids, int count) {
    int k;
    for (k = 1; k < count; ++k)
        if (!(ids[k - 1] < ids[k])) return 0;
    return 1;
}

int* ntsm_global_order(const int* ids, int count) {
    id_at* pairs = (id_at*)malloc(sizeof(id_at) * (size_t)(count + 1));
    int* order = (int*)malloc(sizeof(int) * (size_t)(count + 1));
    int k;
    if (pairs == NULL || order == NULL) {
        free(pairs);
        free(order);
        return NULL;
    }
    for (k = 0; k < count; ++k) {
        pairs[k].id = ids[k];
        pairs[k].at = k;
    }
    qsort(pairs, (size_t)count, sizeof(id_at), by_global);
    for (k = 0; k < count; ++k) order[k] = pairs[k].at;
    free(pairs);
    return order;
}

void ntsm_lowest_failing(const nts_scene_def* def, const int* ids, const nts_vec2* moved, const int* node_at,
                         nts_error* e) {
    const int count = def->body_count;
    int* order = NULL;
    nts_body_def* sorted = NULL;
    nts_vec2* rows = NULL;
    nts_scene* s = NULL;
    nts_error e1 = nts_error_none();
    int k, failed = 0;
    if (ntsm_ascending(ids, count) || e->code == NTS_ENOMEM) return; /* (the rank's order is the whole's) */
    order = ntsm_global_order(ids, count);
    sorted = (nts_body_def*)malloc(sizeof(nts_body_def) * (size_t)(count + 1));
    if (order == NULL || sorted == NULL) goto done; /* (the first failure stays named) */
    for (k = 0; k < count; ++k) sorted[k] = def->bodies[order[k]];
    {
        nts_scene_def d = *def;
        d.bodies = sorted;
        s = nts_scene_create(&d, &e1);
    }
    if (s == NULL) {
        failed = 1;
    } else if (moved != NULL) {
        long long n = 0, at = 0;
        for (k = 0; k < count; ++k) n += sorted[k].node_count;
        if ((rows = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)(n + 1))) == NULL) goto done;
        for (k = 0; k < count; ++k) {
            memcpy(rows + at, moved + node_at[order[k]], sizeof(nts_vec2) * (size_t)sorted[k].node_count);
            at += sorted[k].node_count;
        }
        failed = nts_scene_update_positions(s, rows, &e1) != NTS_OK;
    }
    if (failed && e1.code != NTS_ENOMEM && e1.body >= 0 && e1.body < count) {
        /* its fault as the rank's scene names it: body order[b], local */
        const int local = order[e1.body];
        int used = 0, b = -1;
        char msg[sizeof e1.message + 32];
        if (sscanf(e1.message, "body %d%n", &b, &used) == 1 && b == e1.body) {
            snprintf(msg, sizeof msg, "body %d%s", local, e1.message + used);
            memcpy(e1.message, msg, sizeof e1.message - 1);
            e1.message[sizeof e1.message - 1] = '\0';
        }
        e1.body = local;
        *e = e1;
    }
done:
    nts_scene_destroy(s);
    free(rows);
    free(sorted);
    free(order);
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
    if (m == NULL || count < 0 || count > INT_MAX / 4 || (count > 0 && (bodies == NULL || ids == NULL))) {
        rc = m == NULL            ? ntsm_fail(&e, NTS_ENOMEM, "out of memory")
             : count > INT_MAX / 4 ? ntsm_fail(&e, NTS_ELIMIT, "more than 2^29 bodies on one rank")
                                   : ntsm_fail(&e, NTS_EINVALID_ARGUMENT, "no bodies given");
    }
    if (rc == NTS_OK) {
        m->comm = comm;
        m->rank = rank;
        m->size = size;
        m->count = count;
        m->lx = lx;
        m->ly = ly;
        m->skin = -1.0;
        m->ids = (int*)malloc(sizeof(int) * (size_t)(count + 1));
        m->own_node_at = (int*)calloc((size_t)count + 1, sizeof(int));
        m->own_at = (size_t*)malloc(sizeof(size_t) * (size_t)(count + 1));
        m->own_defs = (nts_body_def*)calloc((size_t)count + 1, sizeof(nts_body_def));
        if (m->ids == NULL || m->own_at == NULL || m->own_defs == NULL || m->own_node_at == NULL) rc = ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    }
    for (k = 0; k < count && rc == NTS_OK; ++k) {
        const nts_body_def* d = &bodies[k];
        const char* bad = (d->nodes == NULL && d->node_count != 0) || d->node_count < 0 ? "no nodes array"
                          : d->loop_count < 0 || (d->loop_count > 0 && (d->loop_start == NULL || d->loop_nodes == NULL ||
                                                                        d->loop_start[d->loop_count] < 0))
                              ? "a loop count without its arrays"
                          : d->triangle_count < 0 || (d->triangle_count > 0 && d->triangles == NULL)
                              ? "a triangle count without its array"
                          : d->surface != NULL && d->surface_count < 0 ? "a negative surface count"
                                                                        : NULL;
        if (bad != NULL) {
            rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT, bad);
            e.body = ids[k];
            break;
        }
        m->ids[k] = ids[k];
        m->own_at[k] = m->own_bytes.n;
        /* no reference given: the first positions are it, wherever the body goes */
        ntsm_body_write(&m->own_bytes, &bodies[k], ids[k], bodies[k].reference ? bodies[k].reference : bodies[k].nodes);
    }
    if (rc == NTS_OK && m->own_bytes.oom) rc = ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    if (rc == NTS_OK) {
        nts_scene_def def;
        own_defs_point(m);
        m->own_limits = limits;
        m->own_limits.max_bodies = INT_MAX;
        def = own_scene_def(m);
        if (count > 0) {
            m->own = nts_scene_create(&def, &e);
            if (m->own == NULL) {
                rc = e.code != 0 ? e.code : NTS_ENOMEM;
                if (e.body >= 0 && e.body < count && rc != NTS_ENOMEM) ntsm_lowest_failing(&def, m->ids, NULL, NULL, &e);
                ntsm_global_body(&e, m->ids, count);
            }
        }
        m->own_ctx = nts_context_create();
        m->ctx = nts_context_create();
        m->part_kc = nts_candidates_create(-1.0); /* (NULL: none, the same bits) */
        if (rc == NTS_OK && (m->own_ctx == NULL || m->ctx == NULL)) rc = ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    }
    if (ntsm_agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    {
        /* One box for the whole: a rank's own would silently give its
         * slaves other minimum images (or none) than one process does. */
        double box[2];
        box[0] = lx;
        box[1] = ly;
        MPI_Bcast(box, 2, MPI_DOUBLE, 0, comm);
        if (!(box[0] == lx && box[1] == ly)) {
            rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT, "the ranks' periodic boxes differ: lx and ly must be the same on "
                                                      "every rank (0 and 0: no box)");
            snprintf(e.option, sizeof e.option, "%s", "periodic");
        }
        if (ntsm_agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    }

    /* The whole: every body's owner, nodes and surface entries. */
    counts = (int*)malloc(sizeof(int) * (size_t)size);
    displs = (int*)malloc(sizeof(int) * (size_t)(size + 1));
    mine = (int*)malloc(sizeof(int) * 3u * (size_t)(count + 1));
    rc = counts && displs && mine ? NTS_OK : ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    if (ntsm_agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
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
    rc = all && m->owner && m->local_of && m->node_off && m->entry_off && m->owner_node_at ? NTS_OK : ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    if (ntsm_agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
    MPI_Allgatherv(mine, 3 * count, MPI_INT, all, counts, displs, MPI_INT, comm);
    for (i = 0; i < total; ++i) m->owner[i] = -1;
    for (i = 0; i < size && rc == NTS_OK; ++i) {
        int j, at = 0;
        for (j = displs[i] / 3; j < displs[i + 1] / 3; ++j) {
            const int id = all[3 * j];
            if (id < 0 || id >= total || m->owner[id] >= 0) {
                rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT,
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
        if (total == 0) rc = ntsm_fail(&e, NTS_EEMPTY_SCENE, "scene has no bodies");
        else if (total > limits.max_bodies) rc = ntsm_fail(&e, NTS_ELIMIT, "more bodies than the limit max_bodies");
        else if (m->node_off[total] > limits.max_nodes) rc = ntsm_fail(&e, NTS_ELIMIT, "more nodes than the limit max_nodes");
        else if (m->entry_off[total] > INT_MAX / 2) rc = ntsm_fail(&e, NTS_ELIMIT, "more than 2^30 surface nodes");
        if (rc == NTS_ELIMIT && m->entry_off[total] <= INT_MAX / 2)
            snprintf(e.option, sizeof e.option, "%s", total > limits.max_bodies ? "max_bodies" : "max_nodes");
    }
    if (ntsm_agree(m, comm, rank, size, rc, &e) != NTS_OK) goto failed;
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
    nts_vec2* old = (nts_vec2*)ntsm_scratch(&m->sc[SC_OLD_POS], sizeof(nts_vec2) * ((size_t)m->own_nodes + 1));
    int rc = NTS_OK, mine, k, at = 0;
    if (old == NULL) {
        rc = ntsm_fail(&e, NTS_ENOMEM, "out of memory");
    } else if (m->own != NULL && positions == NULL) {
        rc = ntsm_fail(&e, NTS_EINVALID_ARGUMENT, "no positions");
    } else if (m->own != NULL) {
        /* the positions before, should another rank's be refused */
        for (k = 0; k < m->count; ++k) {
            memcpy(old + at, m->own_defs[k].nodes, sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
            at += m->own_defs[k].node_count;
        }
        if ((rc = nts_scene_update_positions(m->own, positions, &e)) != NTS_OK) {
            if (e.body >= 0 && e.body < m->count && rc != NTS_ENOMEM) {
                /* (the own definitions still hold the positions before) */
                const nts_scene_def def = own_scene_def(m);
                ntsm_lowest_failing(&def, m->ids, positions, m->own_node_at, &e);
            }
            ntsm_global_body(&e, m->ids, m->count);
        }
    }
    mine = rc;
    rc = ntsm_agree(m, m->comm, m->rank, m->size, rc, &e);
    if (rc != NTS_OK) {
        /* all or nothing: every rank keeps the positions it had */
        if (mine == NTS_OK && m->own != NULL) nts_scene_update_positions(m->own, old, NULL);
    } else {
        for (k = 0, at = 0; k < m->count; ++k) {
            memcpy((void*)(uintptr_t)m->own_defs[k].nodes, positions + at,
                   sizeof(nts_vec2) * (size_t)m->own_defs[k].node_count);
            at += m->own_defs[k].node_count;
        }
        m->frame_given = 0; /* a given frame was for the positions before */
    }
    if (err != NULL) *err = rc == NTS_OK ? nts_error_none() : e;
    return rc;
}

int ntsm_scene_set_history(ntsm_scene* m, const nts_anchor* anchors, int count) {
    nts_anchor* copy = NULL;
    if (anchors != NULL && count > 0) {
        if ((copy = (nts_anchor*)malloc(sizeof(nts_anchor) * (size_t)count)) == NULL) return NTS_ENOMEM;
        memcpy(copy, anchors, sizeof(nts_anchor) * (size_t)count);
    }
    free(m->hist);
    m->hist = copy;
    m->hist_count = copy != NULL ? count : 0;
    return NTS_OK;
}

void ntsm_scene_set_skin(ntsm_scene* m, double skin) {
    m->skin = skin;
    m->built = 0;
    /* parts made every evaluation keep no candidate list: its memory given
     * back (without one, an evaluation searches the cells: the same bits) */
    nts_candidates_destroy(m->part_kc);
    m->part_kc = skin != 0.0 ? nts_candidates_create(-1.0) : NULL;
}

int ntsm_scene_set_weights(ntsm_scene* m, const double* weights) {
    int r;
    free(m->weights);
    m->weights = NULL;
    m->share_on = 0; /* equal shares until the next evaluation says otherwise */
    m->lost = 0.0;
    if (m->speed != NULL) memset(m->speed, 0, sizeof(double) * (size_t)m->size); /* (measured anew) */
    m->built = 0;    /* the next evaluation cuts the slabs anew */
    if (weights == NULL) return NTS_OK;
    if ((m->weights = (double*)malloc(sizeof(double) * (size_t)m->size)) == NULL) return NTS_ENOMEM;
    for (r = 0; r < m->size; ++r) m->weights[r] = weights[r];
    return NTS_OK;
}

void ntsm_scene_set_frame(ntsm_scene* m, const nts_frame* frame) {
    m->frame_given = frame != NULL;
    if (frame != NULL) m->frame = *frame;
}
