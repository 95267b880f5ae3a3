/* Scenes: copy, validate and normalise the caller's bodies (docs/model.md,
 * "Geometry"). Every error names the body, loop and node at fault. */
#include <float.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "checks.h"
#include "internal.h"

nts_limits nts_default_limits(void) {
    nts_limits l;
    l.max_bodies = 1000000;
    l.max_nodes_per_body = 10000000;
    l.max_nodes = 50000000;
    return l;
}

nts_scene_def nts_default_scene_def(void) {
    nts_scene_def d;
    memset(&d, 0, sizeof d);
    d.limits = nts_default_limits();
    return d;
}

/* An error at (body, loop, place in the loop, node): nts_error_set. */
#define fail(err, code, body, loop, pos, node, ...) nts_error_set(err, code, nts_at(body, loop, pos, node), __VA_ARGS__)
/* An error of body `body` (-1: of the scene) that names an option or limit. */
#define fail_naming(err, code, body, option, ...) \
    nts_error_set(err, code, nts_naming(nts_at(body, -1, -1, -1), option), __VA_ARGS__)

void nts_scene_destroy(nts_scene* s) {
    if (s == NULL) return;
    nts_free(s->pos);
    nts_free(s->body_node_start);
    nts_free(s->body_loop_start);
    nts_free(s->loop_start);
    nts_free(s->surf_node);
    nts_free(s->surf_local);
    nts_free(s->surf_prev);
    nts_free(s->surf_next);
    nts_free(s->surf_body);
    nts_free(s->loop_reversed);
    nts_free(s->body_outer);
    nts_free(s->body_role);
    nts_free(s->body_mesh);
    nts_free(s->body_alpha);
    nts_free(s->body_friction);
    nts_free(s->body_self);
    nts_free(s->surf_trib);
    nts_free(s->loop_piece);
    nts_free(s->piece_area2);
    nts_free(s->surf_flag);
    nts_free(s->steps);
    nts_free(s);
}


/* Geometry checks of one loop: degenerate segments, zero-angle spikes, zero
 * area. `nodes` holds the loop as stored; when `reversed` the input order is
 * its reversal keeping the first node (input place k is stored place
 * (n - k) mod n), so that the checks, their error messages and the signed area
 * are always those of the caller's own order. Positions come from `pos`
 * (global order), so new positions can be checked before they are taken
 * (nts_scene_update_positions). */
static int check_loop(const nts_scene* s, const nts_vec2* pos, int body, int loop, const int* nodes, int n,
                      int reversed, int node0, double* scratch, double* area2_out, nts_error* err) {
    /* scratch: 3 n doubles, the steps d_k = X_{k+1} - X_k (minimum image)
     * and their lengths, each computed once: the neighbours' step back is
     * -d_{k-1}, exactly (a difference and the minimum image are odd), so
     * every verdict below is what one would find from the positions. */
    nts_vec2* d = (nts_vec2*)(void*)scratch;
    double* len = scratch + 2 * n;
    double perim = 0.0, a2;
    int k;
    /* input place k is stored place (n - k) mod n when reversed */
#define NODE_AT(k) nodes[reversed && (k) > 0 ? n - (k) : (k)]
    for (k = 0; k < n; ++k) {
        const int next = k + 1 < n ? k + 1 : 0;
        d[k] = nts_scene_diff(s, pos[node0 + NODE_AT(next)], pos[node0 + NODE_AT(k)]);
        len[k] = nts_length(d[k]);
    }
    for (k = 0; k < n; ++k) {
        const int next = k + 1 < n ? k + 1 : 0, a = NODE_AT(k), c = NODE_AT(next);
        const double tol = nts_segment_tolerance(len[k > 0 ? k - 1 : n - 1], len[next], pos[node0 + a], pos[node0 + c]);
        if (!(len[k] > tol))
            return fail(err, NTS_EDEGENERATE_SEGMENT, body, loop, k, a,
                        "body %d loop %d: segment from node %d to node %d has length %.3g (<= %.3g: 1e-12 of its "
                        "neighbours, the resolution of its coordinates, or 1e-100)",
                        body, loop, a, c, len[k], tol);
        perim += len[k];
    }
    for (k = 0; k < n; ++k) {
        const int prev = k > 0 ? k - 1 : n - 1;
        if (nts_is_spike(d[prev], d[k], len[prev], len[k]))
            return fail(err, NTS_ESPIKE, body, loop, k, NODE_AT(k),
                        "body %d loop %d: zero-angle spike at node %d", body, loop, NODE_AT(k));
    }
    /* Twice the signed area, relative to the loop's first node (checks.h). */
    a2 = 0.0;
    {
        nts_vec2 cur = nts_v2(0.0, 0.0);
        for (k = 0; k < n; ++k) nts_shoelace_step(&cur, &a2, d[k]);
    }
#undef NODE_AT
    if (nts_zero_area(a2, perim))
        return fail(err, NTS_EZERO_AREA, body, loop, -1, -1, "body %d loop %d encloses zero area", body, loop);
    *area2_out = a2;
    return NTS_OK;
}

/* The outer loop of a mesh's piece, loop by loop in the loops' order: the
 * first of the largest |area| (twice the signed area `a2` of loop `l`, in the
 * piece's orientation by connectivity) is kept in best[head], head being the
 * piece's first loop. The piece runs the right way when that area is positive.
 * nts_scene_create and nts_scene_update_positions both decide by it. */
static void piece_outer(double* best, int head, int l, double a2) {
    if (l == head || fabs(a2) > fabs(best[head])) best[head] = a2;
}

/* A coordinate inside the supported range (finite, |x| <= NTS_COORD_MAX).
 * `option` is "" for a node, "reference" for a node of the reference
 * configuration (nts_body_def.reference). */
static int check_point(nts_vec2 p, int body, int node, const char* option, nts_error* err) {
    nts_where at = nts_at(body, -1, -1, node);
    const char* what = option[0] ? "reference node" : "node";
    at.option = option;
    if (!nts_is_valid_vec2(p))
        return nts_error_set(err, NTS_ENONFINITE, at, "body %d %s %d has a non-finite coordinate", body, what, node);
    if (!(fabs(p.x) <= NTS_COORD_MAX && fabs(p.y) <= NTS_COORD_MAX))
        return nts_error_set(err, NTS_EOUT_OF_RANGE, at,
                             "body %d %s %d: coordinate %.3g is beyond +-1e100, where squared lengths overflow "
                             "(rescale the scene)", body, what, node, fabs(p.x) > fabs(p.y) ? p.x : p.y);
    return NTS_OK;
}
static int check_node(nts_vec2 p, int body, int node, nts_error* err) { return check_point(p, body, node, "", err); }

/* nts_scene_create in passes. Each pass establishes what the next relies on;
 * a pass that fails has written its error and returns its code, and the
 * caller frees what was built (scene_build_free, nts_scene_destroy). */

/* The working state of one nts_scene_create: the caller's definition, the
 * boundaries extracted from triangle meshes, the totals pass 1 counts and the
 * scratch of pass 2. */
typedef struct scene_build {
    const nts_scene_def* def;
    nts_boundary* bnd;  /* per body, when given by triangles */
    int* mark;          /* per node of the body being checked: on a loop already */
    int* loop_tmp;      /* the loop being checked, in input order */
    double* steps;      /* check_loop's scratch: 3 doubles a node of the largest body */
    double* area2;      /* per loop: twice its signed area in input order */
    long long total_nodes, total_surf, total_loops;
    int max_body_nodes;
} scene_build;

static void scene_build_free(scene_build* sb) {
    int b;
    nts_free(sb->mark);
    nts_free(sb->area2);
    nts_free(sb->loop_tmp);
    nts_free(sb->steps);
    if (sb->bnd != NULL) {
        for (b = 0; b < sb->def->body_count; ++b) nts_boundary_free(&sb->bnd[b]);
        nts_free(sb->bnd);
    }
}

/* Pass 0, the scene as a whole: it has bodies, its periodic box (if any) is
 * valid and inside the supported range (docs/model.md §8), and the body
 * count is within max_bodies. Nothing of a body is read yet. */
static int check_scene_def(const nts_scene_def* def, nts_error* err) {
    if (def == NULL || def->bodies == NULL || def->body_count <= 0)
        return fail(err, NTS_EEMPTY_SCENE, -1, -1, -1, -1, "scene has no bodies");
    if (!(def->lx >= 0.0 && def->ly >= 0.0) || !nts_is_valid_double(def->lx) || !nts_is_valid_double(def->ly) ||
        ((def->lx > 0.0) != (def->ly > 0.0)))
        return fail_naming(err, NTS_EINVALID_OPTION, -1, "periodic", "periodic box needs lx > 0 and ly > 0, finite");
    if (def->lx > NTS_COORD_MAX || def->ly > NTS_COORD_MAX)
        return fail_naming(err, NTS_EOUT_OF_RANGE, -1, "periodic", "periodic box beyond 1e100 (rescale the scene)");
    if (def->limits.max_bodies > 0 && def->body_count > def->limits.max_bodies)
        return fail_naming(err, NTS_ELIMIT, -1, "max_bodies", "scene has %d bodies, more than the limit of %d bodies",
                           def->body_count, def->limits.max_bodies);
    return NTS_OK;
}

/* Pass 1 for body b: its options are valid (docs/model.md §10), its node
 * count keeps the body and the running total within the limits and 2^30
 * (so every index fits an int), and every coordinate, of its nodes and of its
 * reference, is finite and inside the supported range (§2). Adds its nodes to
 * sb->total_nodes. */
static int count_body_nodes(scene_build* sb, int b, nts_error* err) {
    const nts_scene_def* def = sb->def;
    const nts_body_def* bd = &def->bodies[b];
    int i, rc;
    if (bd->node_count <= 0 || bd->nodes == NULL)
        return fail(err, NTS_ENO_NODES, b, -1, -1, -1, "body %d has no nodes", b);
    if (bd->role != NTS_ROLE_BOTH && bd->role != NTS_ROLE_MASTER && bd->role != NTS_ROLE_SLAVE)
        return fail_naming(err, NTS_EINVALID_OPTION, b, "role", "body %d: role must be both, master or slave", b);
    if (bd->has_alpha && !(bd->alpha >= 0.0 && bd->alpha <= 0.5))
        return fail_naming(err, NTS_EINVALID_OPTION, b, "alpha", "body %d: alpha must be in [0, 0.5]", b);
    if (bd->has_friction && !(bd->friction >= 0.0 && bd->friction <= 10.0))
        return fail_naming(err, NTS_EINVALID_OPTION, b, "friction", "body %d: friction must be in [0, 10]", b);
    if (bd->self_contact != 0 && bd->self_contact != 1)
        return fail_naming(err, NTS_EINVALID_OPTION, b, "self_contact", "body %d: self_contact must be 0 or 1", b);
    if (def->limits.max_nodes_per_body > 0 && bd->node_count > def->limits.max_nodes_per_body)
        return fail_naming(err, NTS_ELIMIT, b, "max_nodes_per_body",
                           "body %d has %d nodes, more than the limit of %d nodes per body", b, bd->node_count,
                           def->limits.max_nodes_per_body);
    sb->total_nodes += bd->node_count;
    if (def->limits.max_nodes > 0 && sb->total_nodes > def->limits.max_nodes)
        return fail_naming(err, NTS_ELIMIT, b, "max_nodes", "scene has more than the limit of %lld nodes",
                           def->limits.max_nodes);
    if (sb->total_nodes > 0x3fffffff) return fail(err, NTS_ELIMIT, b, -1, -1, -1, "scene has more than 2^30 nodes");
    for (i = 0; i < bd->node_count; ++i)
        if ((rc = check_node(bd->nodes[i], b, i, err)) != NTS_OK) return rc;
    for (i = 0; bd->reference != NULL && i < bd->node_count; ++i)
        if ((rc = check_point(bd->reference[i], b, i, "reference", err)) != NTS_OK) return rc;
    if (bd->node_count > sb->max_body_nodes) sb->max_body_nodes = bd->node_count;
    return NTS_OK;
}

/* Pass 1 for body b, after count_body_nodes: its loops exist, extracted from
 * its triangles when it is a mesh (docs/model.md §1: into sb->bnd[b], the
 * error naming the body), given as arrays, or implied (one loop through all
 * nodes). Adds its loops and loop places to the totals; the places are not
 * checked yet (pass 2). */
static int count_body_loops(scene_build* sb, int b, nts_error* err) {
    const nts_body_def* bd = &sb->def->bodies[b];
    if (bd->triangles != NULL && bd->triangle_count > 0) {
        int rc = nts_boundary_from_triangles(bd->node_count, bd->triangles, bd->triangle_count, &sb->bnd[b], err);
        if (rc != NTS_OK) {
            if (err != NULL) err->body = b;
            return rc;
        }
        sb->total_loops += sb->bnd[b].loop_count;
        sb->total_surf += sb->bnd[b].loop_start[sb->bnd[b].loop_count];
    } else if (bd->loop_count > 0) {
        int l;
        if (bd->loop_nodes == NULL || bd->loop_start == NULL)
            return fail(err, NTS_EINVALID_ARGUMENT, b, -1, -1, -1, "body %d: loop arrays missing", b);
        /* offsets into loop_nodes: from 0 on, never decreasing (the array's
         * end is the caller's to keep: loop_start[loop_count] entries) */
        for (l = 0; l < bd->loop_count; ++l)
            if (bd->loop_start[0] < 0 || bd->loop_start[l + 1] < bd->loop_start[l])
                return fail(err, NTS_EINVALID_ARGUMENT, b, l, -1, -1,
                            "body %d: loop_start must start at 0 or after and never decrease (loop %d: %d to %d)", b,
                            l, bd->loop_start[l], bd->loop_start[l + 1]);
        sb->total_loops += bd->loop_count;
        sb->total_surf += bd->loop_start[bd->loop_count] - bd->loop_start[0];
    } else {
        sb->total_loops += 1;
        sb->total_surf += bd->node_count;
    }
    return NTS_OK;
}

/* Pass 1: counts, limits, finiteness, boundary extraction, body by body
 * (each body's errors before the next body's), then the scene's loop places
 * within 2^30. Afterwards the totals size every array of pass 2. */
static int count_scene(scene_build* sb, nts_error* err) {
    int b, rc;
    sb->bnd = (nts_boundary*)nts_alloc(sizeof(nts_boundary) * (size_t)sb->def->body_count);
    if (sb->bnd == NULL) return fail(err, NTS_ENOMEM, -1, -1, -1, -1, "out of memory");
    memset(sb->bnd, 0, sizeof(nts_boundary) * (size_t)sb->def->body_count);
    for (b = 0; b < sb->def->body_count; ++b) {
        if ((rc = count_body_nodes(sb, b, err)) != NTS_OK) return rc;
        if ((rc = count_body_loops(sb, b, err)) != NTS_OK) return rc;
    }
    if (sb->total_surf > 0x3fffffff || sb->total_loops > 0x3fffffff)
        return fail(err, NTS_ELIMIT, -1, -1, -1, -1, "scene has more than 2^30 loop places");
    return NTS_OK;
}

/* The scene's arrays, sized by pass 1's totals, and the scratch of pass 2.
 * The scene is returned zeroed but for its counts and box, or NULL (out of
 * memory, written to err) with *out set to whatever was allocated, for
 * nts_scene_destroy to free. */
/* A scene's serial (nts_scene.serial): the process's count of scenes made,
 * taken atomically (scenes are made on any thread). */
static unsigned long long next_serial(void) {
    static unsigned long long count = 0;
#if defined(__GNUC__)
    return __atomic_add_fetch(&count, 1ULL, __ATOMIC_RELAXED);
#else
    return ++count;
#endif
}

static int alloc_scene(scene_build* sb, nts_scene** out, nts_error* err) {
    const nts_scene_def* def = sb->def;
    size_t nodes = (size_t)sb->total_nodes, surf = (size_t)sb->total_surf, loops = (size_t)sb->total_loops;
    size_t bodies = (size_t)def->body_count, scratch = (size_t)sb->max_body_nodes;
    nts_scene* s = (nts_scene*)nts_alloc(sizeof *s);
    *out = s;
    if (s == NULL) return fail(err, NTS_ENOMEM, -1, -1, -1, -1, "out of memory");
    memset(s, 0, sizeof *s);
    s->serial = next_serial();
    s->body_count = def->body_count;
    s->node_count = (int)sb->total_nodes;
    s->surface_count = (int)sb->total_surf;
    s->loop_total = (int)sb->total_loops;
    s->lx = def->lx;
    s->ly = def->ly;
    s->pos = (nts_vec2*)nts_alloc(sizeof(nts_vec2) * nodes);
    s->body_node_start = (int*)nts_alloc(sizeof(int) * (bodies + 1));
    s->body_loop_start = (int*)nts_alloc(sizeof(int) * (bodies + 1));
    s->loop_start = (int*)nts_alloc(sizeof(int) * (loops + 1));
    s->surf_node = (int*)nts_alloc(sizeof(int) * surf);
    s->surf_local = (int*)nts_alloc(sizeof(int) * surf);
    s->surf_prev = (int*)nts_alloc(sizeof(int) * surf);
    s->surf_next = (int*)nts_alloc(sizeof(int) * surf);
    s->surf_body = (int*)nts_alloc(sizeof(int) * surf);
    s->loop_reversed = (unsigned char*)nts_alloc(loops);
    s->body_outer = (int*)nts_alloc(sizeof(int) * bodies);
    s->body_role = (unsigned char*)nts_alloc(bodies);
    s->body_mesh = (unsigned char*)nts_alloc(bodies);
    s->body_alpha = (double*)nts_alloc(sizeof(double) * bodies);
    s->body_friction = (double*)nts_alloc(sizeof(double) * bodies);
    s->body_self = (unsigned char*)nts_alloc(bodies);
    s->surf_trib = (double*)nts_alloc(sizeof(double) * surf);
    s->loop_piece = (int*)nts_alloc(sizeof(int) * loops);
    s->piece_area2 = (double*)nts_alloc(sizeof(double) * loops);
    sb->mark = (int*)nts_alloc(sizeof(int) * scratch);
    sb->area2 = (double*)nts_alloc(sizeof(double) * (loops + 1));
    sb->loop_tmp = (int*)nts_alloc(sizeof(int) * scratch);
    sb->steps = (double*)nts_alloc(3 * sizeof(double) * scratch);
    if (!s->pos || !s->body_node_start || !s->body_loop_start || !s->loop_start || !s->surf_node ||
        !s->surf_local || !s->surf_prev || !s->surf_next || !s->surf_body || !s->loop_reversed || !s->body_outer ||
        !s->body_role || !s->body_mesh || !s->body_alpha || !s->body_friction || !s->body_self || !s->surf_trib || !s->loop_piece || !s->piece_area2 ||
        !sb->mark || !sb->area2 || !sb->loop_tmp || !sb->steps)
        return fail(err, NTS_ENOMEM, -1, -1, -1, -1, "out of memory");
    return NTS_OK;
}

/* Pass 2 for body b, whose nodes start at s->body_node_start[b] and loops at
 * s->body_loop_start[b]: its positions are copied, each loop has at least 3
 * places, indices in range and no node twice in the body (docs/model.md §1),
 * and passes check_loop (§2) in the caller's order. Its loops are stored in
 * input order (surf_local, surf_body, loop_start, sb->area2), its outer loop
 * (the largest |area|, the first of equals) in body_outer, and the ends of
 * its ranges in body_node_start[b + 1], body_loop_start[b + 1] and the
 * loop_start after its last loop (the next body starts there). */
static int copy_body(scene_build* sb, nts_scene* s, int b, nts_error* err) {
    const nts_body_def* bd = &sb->def->bodies[b];
    const nts_boundary* bnd = &sb->bnd[b];
    const int* ln = NULL;
    const int* ls = NULL;
    int node_off = s->body_node_start[b], loop_i = s->body_loop_start[b], surf = s->loop_start[loop_i];
    int nl = 1, l, i, implicit = 0, outer = -1, rc;
    double outer_abs = -1.0;
    memcpy(s->pos + node_off, bd->nodes, sizeof(nts_vec2) * (size_t)bd->node_count);
    if (bnd->loop_nodes != NULL) {
        ln = bnd->loop_nodes; ls = bnd->loop_start; nl = bnd->loop_count;
    } else if (bd->loop_count > 0) {
        ln = bd->loop_nodes; ls = bd->loop_start; nl = bd->loop_count;
    } else {
        implicit = 1;
    }
    for (i = 0; i < bd->node_count; ++i) sb->mark[i] = 0;
    for (l = 0; l < nl; ++l) {
        int n = implicit ? bd->node_count : ls[l + 1] - ls[l];
        int k;
        if (n < 3)
            return fail(err, NTS_ELOOP_TOO_SHORT, b, implicit ? -1 : l, -1, -1,
                        "body %d loop %d has %d nodes (at least 3 needed)", b, l, n);
        for (k = 0; k < n; ++k) {
            int v = implicit ? k : ln[ls[l] + k];
            if (v < 0 || v >= bd->node_count)
                return fail(err, NTS_EINDEX_RANGE, b, l, k, -1,
                            "body %d loop %d place %d: node index %d out of range [0, %d)", b, l, k, v,
                            bd->node_count);
            if (sb->mark[v] != 0)
                return fail(err, NTS_ENODE_REUSED, b, l, k, v,
                            "body %d loop %d place %d: node %d is already on a loop", b, l, k, v);
            sb->mark[v] = 1;
            sb->loop_tmp[k] = v;
        }
        rc = check_loop(s, s->pos, b, l, sb->loop_tmp, n, 0, node_off, sb->steps, &sb->area2[loop_i], err);
        if (rc != NTS_OK) {
            /* an implied loop is the body itself: the error names no loop */
            if (implicit && err != NULL) err->loop = err->loop_pos = -1;
            return rc;
        }
        if (fabs(sb->area2[loop_i]) > outer_abs) { outer_abs = fabs(sb->area2[loop_i]); outer = loop_i; }
        s->loop_start[loop_i] = surf;
        for (k = 0; k < n; ++k) {
            s->surf_local[surf + k] = sb->loop_tmp[k];
            s->surf_body[surf + k] = b;
        }
        surf += n;
        ++loop_i;
    }
    s->body_outer[b] = outer;
    s->body_node_start[b + 1] = node_off + bd->node_count;
    s->body_loop_start[b + 1] = loop_i;
    s->loop_start[loop_i] = surf;
    return NTS_OK;
}

/* Pass 2 for body b, after copy_body: its options are stored, and its loops
 * are oriented (docs/model.md §2): the loop with the largest |area| is the
 * outer one and runs counter-clockwise; holes run clockwise. A loop the wrong
 * way is reversed keeping its first node. A triangle mesh's loops come
 * oriented by its connectivity, piece by piece: each piece is turned over as
 * a whole when its own outer loop (the largest |area| of the piece) runs
 * clockwise, so each piece of a mesh in several pieces keeps its own outer
 * loop counter-clockwise and its holes clockwise (not counted in
 * loops_reversed: a mesh gives no loops). Then each place knows its global
 * node and its neighbours on the loop (surf_node, surf_prev, surf_next). */
static void orient_body(const scene_build* sb, nts_scene* s, int b) {
    const nts_body_def* bd = &sb->def->bodies[b];
    int l0 = s->body_loop_start[b], l1 = s->body_loop_start[b + 1], node_off = s->body_node_start[b], l;
    s->body_mesh[b] = (unsigned char)(sb->bnd[b].loop_nodes != NULL);
    s->body_role[b] = (unsigned char)bd->role;
    s->body_alpha[b] = bd->has_alpha ? bd->alpha : -1.0;
    s->body_friction[b] = bd->has_friction ? bd->friction : -1.0;
    s->body_self[b] = (unsigned char)(bd->self_contact != 0);
    s->self_bodies += bd->self_contact != 0;
    for (l = l0; l < l1; ++l) {
        s->loop_piece[l] = s->body_mesh[b] ? l0 + sb->bnd[b].loop_piece[l - l0] : -1;
        if (s->body_mesh[b]) piece_outer(s->piece_area2, s->loop_piece[l], l, sb->area2[l]);
    }
    for (l = l0; l < l1; ++l) {
        int first = s->loop_start[l], n = s->loop_start[l + 1] - first, k;
        if (s->body_mesh[b])
            s->loop_reversed[l] = (unsigned char)(s->piece_area2[s->loop_piece[l]] < 0.0);
        else
            s->loop_reversed[l] = (unsigned char)((sb->area2[l] > 0.0) != (l == s->body_outer[b]));
        if (s->loop_reversed[l]) {
            for (k = 1; k < n - k; ++k) {
                int t = s->surf_local[first + k];
                s->surf_local[first + k] = s->surf_local[first + n - k];
                s->surf_local[first + n - k] = t;
            }
            if (!s->body_mesh[b]) ++s->loops_reversed;
        }
        for (k = 0; k < n; ++k) {
            s->surf_node[first + k] = node_off + s->surf_local[first + k];
            s->surf_prev[first + k] = first + (k + n - 1) % n;
            s->surf_next[first + k] = first + (k + 1) % n;
        }
    }
}

/* An error of pair k of body b's surface (err->option "surface", err->item
 * k; `place` 0 or 1 names one of its node indices, -1 the pair). */
static int fail_surface(nts_error* err, int code, int b, int k, int place, const char* fmt, int x, int y) {
    nts_where at = nts_naming(nts_at(b, -1, -1, -1), "surface");
    at.item = k;
    at.corner = place;
    return nts_error_set(err, code, at, fmt, b, k, x, y);
}

/* Pass 3, on the stored loops: the contact surfaces (docs/model.md §13).
 * Each pair of a body's surface names one segment of its loops, either
 * direction (the loops may have been reversed: a pair is a segment whatever
 * its order), each segment once; the flags of every entry follow from its
 * two segments and the next one's. A body without a surface has every
 * segment on. No body with a surface: no flags at all (nothing reads them).
 * `entry_of`: scratch of max_body_nodes ints. */
static int mark_surfaces(const nts_scene_def* def, nts_scene* s, int* entry_of, nts_error* err) {
    int b, e, k, any = 0;
    for (b = 0; b < def->body_count; ++b) any |= def->bodies[b].surface != NULL;
    if (!any) return NTS_OK;
    if ((s->surf_flag = (unsigned char*)nts_alloc((size_t)s->surface_count + 1)) == NULL)
        return fail(err, NTS_ENOMEM, -1, -1, -1, -1, "out of memory");
    for (b = 0; b < def->body_count; ++b) {
        const nts_body_def* bd = &def->bodies[b];
        const int e0 = s->loop_start[s->body_loop_start[b]], e1 = s->loop_start[s->body_loop_start[b + 1]];
        if (bd->surface == NULL) {
            memset(s->surf_flag + e0, NTS_SF_SEG, (size_t)(e1 - e0));
            continue;
        }
        memset(s->surf_flag + e0, 0, (size_t)(e1 - e0));
        if (bd->surface_count < 0)
            return fail_naming(err, NTS_EINVALID_ARGUMENT, b, "surface", "body %d: surface_count is negative", b);
        for (k = 0; k < bd->node_count; ++k) entry_of[k] = -1;
        for (e = e0; e < e1; ++e) entry_of[s->surf_local[e]] = e;
        for (k = 0; k < bd->surface_count; ++k) {
            const int i = bd->surface[2 * k], j = bd->surface[2 * k + 1];
            int seg = -1, place;
            for (place = 0; place < 2; ++place) {
                const int v = bd->surface[2 * k + place];
                if (v < 0 || v >= bd->node_count)
                    return fail_surface(err, NTS_EINDEX_RANGE, b, k, place,
                                        "body %d surface pair %d: node index %d out of range [0, %d)", v,
                                        bd->node_count);
            }
            e = entry_of[i];
            if (e >= 0 && i != j) {
                if (s->surf_local[s->surf_next[e]] == j) seg = e;
                else if (s->surf_local[s->surf_prev[e]] == j) seg = s->surf_prev[e];
            }
            if (seg < 0)
                return fail_surface(err, NTS_EINVALID_SURFACE, b, k, -1,
                                    "body %d surface pair %d: nodes %d and %d are not the ends of a segment of its "
                                    "boundary", i, j);
            if (s->surf_flag[seg] & NTS_SF_SEG)
                return fail_surface(err, NTS_EINVALID_SURFACE, b, k, -1,
                                    "body %d surface pair %d: the segment from node %d to node %d is on the surface "
                                    "already (each segment once)", s->surf_local[seg], s->surf_local[s->surf_next[seg]]);
            s->surf_flag[seg] |= NTS_SF_SEG;
        }
    }
    for (e = 0; e < s->surface_count; ++e) {
        if (s->surf_flag[s->surf_prev[e]] & NTS_SF_SEG) s->surf_flag[e] |= NTS_SF_PREV;
        if (s->surf_flag[s->surf_next[e]] & NTS_SF_SEG) s->surf_flag[e] |= NTS_SF_NEXT;
        if ((s->surf_flag[e] & NTS_SF_SEG) && (s->surf_flag[e] & (NTS_SF_PREV | NTS_SF_NEXT)) != (NTS_SF_PREV | NTS_SF_NEXT))
            ++s->surf_ends;
    }
    return NTS_OK;
}

/* Pass 4, on the stored loops: tributary lengths in each body's reference
 * configuration (the nodes as given unless nts_body_def.reference says
 * otherwise; docs/model.md §10): half of the two segments at each node that
 * are on the contact surface (§13), which must not both be 0 on a node of
 * the surface. A loop stored reversed has the same two segments at each
 * node, so the same lengths, bit for bit. */
static int tributary_lengths(const nts_scene_def* def, nts_scene* s, nts_error* err) {
    int e;
    for (e = 0; e < s->surface_count; ++e) {
        const nts_body_def* bd = &def->bodies[s->surf_body[e]];
        const nts_vec2* ref = bd->reference != NULL ? bd->reference : bd->nodes;
        const unsigned f = s->surf_flag != NULL ? s->surf_flag[e] : (unsigned)NTS_SF_ALL;
        nts_vec2 x = ref[s->surf_local[e]];
        double lp = nts_length(nts_scene_diff(s, x, ref[s->surf_local[s->surf_prev[e]]]));
        double lq = nts_length(nts_scene_diff(s, ref[s->surf_local[s->surf_next[e]]], x));
        if (!(f & NTS_SF_PREV)) lp = 0.0;
        if (!(f & NTS_SF_SEG)) lq = 0.0;
        s->surf_trib[e] = 0.5 * (lp + lq);
        if ((f & NTS_SF_NODE) && !(s->surf_trib[e] > 0.0)) {
            nts_where at = nts_at(s->surf_body[e], -1, -1, s->surf_local[e]);
            at.option = "reference";
            return nts_error_set(err, NTS_EDEGENERATE_SEGMENT, at,
                                 "body %d node %d: both of its segments have length 0 in the reference "
                                 "configuration (no tributary length)", s->surf_body[e], s->surf_local[e]);
        }
    }
    return NTS_OK;
}

nts_scene* nts_scene_create(const nts_scene_def* def, nts_error* err) {
    scene_build sb;
    nts_scene* s = NULL;
    int b, rc;

    if (err != NULL) *err = nts_error_none();
    if (check_scene_def(def, err) != NTS_OK) return NULL;
    memset(&sb, 0, sizeof sb);
    sb.def = def;
    rc = count_scene(&sb, err);
    if (rc == NTS_OK) rc = alloc_scene(&sb, &s, err);
    if (rc == NTS_OK) {
        /* Body by body: each body is checked and oriented before the next is
         * read, so the first error is the first body's at fault. */
        s->body_node_start[0] = s->body_loop_start[0] = s->loop_start[0] = 0;
        for (b = 0; b < def->body_count && rc == NTS_OK; ++b)
            if ((rc = copy_body(&sb, s, b, err)) == NTS_OK) orient_body(&sb, s, b);
    }
    if (rc == NTS_OK) {
        assert(s->loop_start[s->loop_total] == s->surface_count &&
               s->body_loop_start[def->body_count] == s->loop_total &&
               s->body_node_start[def->body_count] == s->node_count);
        rc = mark_surfaces(def, s, sb.mark, err);
        if (rc == NTS_OK) rc = tributary_lengths(def, s, err);
    }
    if (rc == NTS_OK) {
        /* nts_scene_update_positions' scratch, for the longest loop */
        int l, longest = 0;
        for (l = 0; l < s->loop_total; ++l)
            if (s->loop_start[l + 1] - s->loop_start[l] > longest) longest = s->loop_start[l + 1] - s->loop_start[l];
        s->longest_loop = longest;
        s->steps = (double*)nts_alloc(3 * sizeof(double) * (size_t)(longest > 0 ? longest : 1));
        if (s->steps == NULL) rc = fail(err, NTS_ENOMEM, -1, -1, -1, -1, "out of memory");
    }
    scene_build_free(&sb);
    if (rc != NTS_OK) {
        nts_scene_destroy(s);
        return NULL;
    }
    return s;
}

int nts_scene_set_positions(nts_scene* s, int body, const nts_vec2* nodes, nts_error* err) {
    int i, n, off;
    if (err != NULL) *err = nts_error_none();
    if (s == NULL || nodes == NULL || body < 0 || body >= s->body_count)
        return fail(err, NTS_EINVALID_ARGUMENT, body, -1, -1, -1, "no such body %d", body);
    off = s->body_node_start[body];
    n = s->body_node_start[body + 1] - off;
    for (i = 0; i < n; ++i) {
        int rc = check_node(nodes[i], body, i, err); /* the rule of nts_scene_create and updates */
        if (rc != NTS_OK) return rc;
    }
    memmove(s->pos + off, nodes, sizeof(nts_vec2) * (size_t)n); /* (nodes may be the scene's own) */
    return NTS_OK;
}

/* The verdicts of nts_scene_update_positions on a loop's signed area (twice
 * it, in the caller's order): nts_scene_create would store loop l of body b
 * the other way round (the outer loop counter-clockwise, holes clockwise). */
static int loop_turned(const nts_scene* s, int b, int l, double a2) {
    return ((a2 > 0.0) != (l == s->body_outer[b])) != (s->loop_reversed[l] != 0);
}
/* A mesh's piece headed by loop l would be turned the other way (by the sign
 * of its outer loop, piece_outer's). */
static int piece_turned(const nts_scene* s, int l) {
    return s->loop_piece[l] == l && (s->piece_area2[l] < 0.0) != (s->loop_reversed[l] != 0);
}

int nts_scene_keeps_shape(nts_scene* s, const double* area_perim) {
    int b, l;
    for (b = 0; b < s->body_count; ++b) {
        const int l0 = s->body_loop_start[b], l1 = s->body_loop_start[b + 1];
        double outer_abs = -1.0;
        int outer = -1;
        for (l = l0; l < l1; ++l) {
            const double a2 = area_perim[2 * l];
            if (nts_zero_area(a2, area_perim[2 * l + 1])) return 0;
            if (s->body_mesh[b]) {
                piece_outer(s->piece_area2, s->loop_piece[l], l, a2);
                continue;
            }
            if (fabs(a2) > outer_abs) {
                outer_abs = fabs(a2);
                outer = l;
            }
            if (loop_turned(s, b, l, a2)) return 0;
        }
        if (s->body_mesh[b]) {
            for (l = l0; l < l1; ++l)
                if (piece_turned(s, l)) return 0;
        } else if (outer != s->body_outer[b]) {
            return 0;
        }
    }
    return 1;
}

int nts_scene_interior_in_range(const nts_scene* s, const nts_vec2* pos) {
    int b, i, ok = 1;
    for (b = 0; b < s->body_count; ++b) {
        const int n0 = s->body_node_start[b], n1 = s->body_node_start[b + 1];
        if (nts_body_all_on_loops(s, b)) continue; /* (the segment pass judges them) */
        /* check_point's verdict without a branch a node: a NaN fails both tests */
        for (i = n0; i < n1; ++i) ok &= (fabs(pos[i].x) <= NTS_COORD_MAX) & (fabs(pos[i].y) <= NTS_COORD_MAX);
    }
    return ok;
}

int nts_scene_update_positions(nts_scene* s, const nts_vec2* pos, nts_error* err) {
    int b, i, rc;
    if (err != NULL) *err = nts_error_none();
    if (s == NULL || pos == NULL) return fail(err, NTS_EINVALID_ARGUMENT, -1, -1, -1, -1, "null argument");
    /* The checks of nts_scene_create, in its order, on the new positions: the
     * coordinates, then each loop's geometry and orientation verdict. A
     * mesh's triangles are not read: its boundary follows from its
     * connectivity, and an interior triangle turned over changes no contact. */
    for (b = 0; b < s->body_count; ++b) {
        int off = s->body_node_start[b], n = s->body_node_start[b + 1] - off;
        for (i = 0; i < n; ++i)
            if ((rc = check_node(pos[off + i], b, i, err)) != NTS_OK) return rc;
    }
    for (b = 0; b < s->body_count; ++b) {
        int l0 = s->body_loop_start[b], l1 = s->body_loop_start[b + 1], l, outer = -1;
        double outer_abs = -1.0, a2;
        for (l = l0; l < l1; ++l) {
            int first = s->loop_start[l], n = s->loop_start[l + 1] - first;
            rc = check_loop(s, pos, b, l - l0, s->surf_local + first, n, s->loop_reversed[l], s->body_node_start[b],
                            s->steps, &a2, err);
            if (rc != NTS_OK) return rc;
            if (s->body_mesh[b]) {
                /* a2 is in the piece's orientation by connectivity, as at creation */
                piece_outer(s->piece_area2, s->loop_piece[l], l, a2);
                continue;
            }
            if (fabs(a2) > outer_abs) { outer_abs = fabs(a2); outer = l; }
            /* nts_scene_create reverses a loop whose sign disagrees with its role
             * (the outer loop counter-clockwise, holes clockwise): the stored order
             * is still the one it would give while each verdict is unchanged. */
            if (loop_turned(s, b, l, a2))
                return fail(err, NTS_ERESHAPED, b, l - l0, -1, -1,
                            "body %d loop %d turned over; create the scene anew", b, l - l0);
        }
        if (s->body_mesh[b]) {
            /* Each piece stays turned the way nts_scene_create turned it: by
             * the sign of its outer loop, the largest |area| of the piece. */
            for (l = l0; l < l1; ++l)
                if (piece_turned(s, l))
                    return fail(err, NTS_ERESHAPED, b, l - l0, -1, -1,
                                "body %d: the piece of its mesh with loop %d turned over (its outer loop changed "
                                "direction); create the scene anew", b, l - l0);
        } else if (outer != s->body_outer[b]) {
            return fail(err, NTS_ERESHAPED, b, -1, -1, -1,
                        "body %d: another loop became the outer one; create the scene anew", b);
        }
    }
    memmove(s->pos, pos, sizeof(nts_vec2) * (size_t)s->node_count); /* (pos may be the scene's own) */
    return NTS_OK;
}

size_t nts_scene_memory_bytes(const nts_scene* s) {
    if (s == NULL) return 0;
    return sizeof *s + (size_t)s->node_count * sizeof(nts_vec2) +
           (size_t)s->surface_count * (5 * sizeof(int) + sizeof(double)) +
           (size_t)(s->loop_total + 1) * sizeof(int) + (size_t)s->loop_total * (1 + sizeof(int) + sizeof(double)) +
           (size_t)(s->body_count + 1) * (3 * sizeof(int) + 2 + 2 * sizeof(double)) +
           (s->surf_flag != NULL ? (size_t)s->surface_count + 1 : 0) + 3 * sizeof(double) * (size_t)s->longest_loop;
}

int nts_scene_body_count(const nts_scene* s) { return s->body_count; }
int nts_scene_node_count(const nts_scene* s) { return s->node_count; }
int nts_scene_surface_node_count(const nts_scene* s) { return s->surface_count; }
int nts_scene_body_node_offset(const nts_scene* s, int body) { return s->body_node_start[body]; }
int nts_scene_body_node_count(const nts_scene* s, int body) {
    return s->body_node_start[body + 1] - s->body_node_start[body];
}
int nts_scene_body_loop_count(const nts_scene* s, int body) {
    return s->body_loop_start[body + 1] - s->body_loop_start[body];
}
int nts_scene_body_loop(const nts_scene* s, int body, int loop, const int** out) {
    int l = s->body_loop_start[body] + loop;
    if (out != NULL) *out = s->surf_local + s->loop_start[l];
    return s->loop_start[l + 1] - s->loop_start[l];
}
int nts_scene_loops_reversed(const nts_scene* s) { return s->loops_reversed; }
int nts_scene_on_surface(const nts_scene* s, int body, int loop, int k) {
    return nts_on_surface(s, s->loop_start[s->body_loop_start[body] + loop] + k);
}
int nts_scene_has_surfaces(const nts_scene* s) { return s->surf_flag != NULL; }
const nts_vec2* nts_scene_positions(const nts_scene* s) { return s->pos; }
