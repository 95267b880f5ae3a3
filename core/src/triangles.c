/* Boundary of a linear triangle mesh, as FEM codes have it: orient every triangle
 * counter-clockwise, keep the directed edges whose reverse is absent, chain them
 * into loops. Outer boundaries then run counter-clockwise and holes clockwise. */
#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

typedef struct edge_rec {
    int lo, hi;   /* undirected key */
    int from, to; /* direction in its (counter-clockwise) triangle */
    int tri;
} edge_rec;

static int edge_cmp(const void* pa, const void* pb) {
    const edge_rec* a = (const edge_rec*)pa;
    const edge_rec* b = (const edge_rec*)pb;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    if (a->tri != b->tri) return a->tri < b->tri ? -1 : 1; /* total order: qsort is not stable */
    return 0;
}

static int tri_fail(nts_error* err, int code, int tri, int corner, int node, const char* msg) {
    nts_where at = nts_at(-1, -1, -1, node);
    at.triangle = tri;
    at.corner = corner;
    return nts_error_set(err, code, at, "%s", msg);
}

void nts_boundary_free(nts_boundary* b) {
    if (b == NULL) return;
    nts_free(b->loop_nodes);
    nts_free(b->loop_start);
    b->loop_nodes = b->loop_start = NULL;
    b->loop_count = 0;
}

int nts_triangle_winding(const nts_vec2* nodes, const int v[3], double lx, double ly) {
    nts_vec2 e1, e2;
    double cr;
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) return 0;
    e1 = nts_min_image(nts_sub(nodes[v[1]], nodes[v[0]]), lx, ly);
    e2 = nts_min_image(nts_sub(nodes[v[2]], nodes[v[0]]), lx, ly);
    cr = nts_cross(e1, e2);
    /* Zero area relative to the edges' own lengths: the same verdict at any scale. */
    if (!(fabs(cr) > 64.0 * DBL_EPSILON * nts_length(e1) * nts_length(e2))) return 0;
    return cr > 0.0 ? 1 : -1;
}

int nts_boundary_from_triangles(const nts_vec2* nodes, int node_count, const int* tri, int tri_count,
                                double lx, double ly, nts_boundary* out, nts_error* err) {
    edge_rec* edges = NULL;
    int* next = NULL;  /* boundary successor of a node, -1 if none */
    int* used = NULL;
    int ne = 3 * tri_count, nb = 0, i, t, rc = NTS_OK;
    char msg[160];

    memset(out, 0, sizeof *out);
    if (tri_count > 0x0fffffff) return tri_fail(err, NTS_ELIMIT, -1, -1, -1, "too many triangles");
    edges = (edge_rec*)nts_alloc(sizeof(edge_rec) * (size_t)ne);
    next = (int*)nts_alloc(sizeof(int) * (size_t)node_count);
    used = (int*)nts_alloc(sizeof(int) * (size_t)node_count);
    if (edges == NULL || next == NULL || used == NULL) {
        rc = tri_fail(err, NTS_ENOMEM, -1, -1, -1, "out of memory");
        goto done;
    }
    for (t = 0; t < tri_count; ++t) {
        int v[3], k, winding;
        for (k = 0; k < 3; ++k) {
            v[k] = tri[3 * t + k];
            if (v[k] < 0 || v[k] >= node_count) {
                snprintf(msg, sizeof msg, "triangle %d: node index %d out of range [0, %d)", t, v[k], node_count);
                rc = tri_fail(err, NTS_EINDEX_RANGE, t, k, -1, msg);
                goto done;
            }
        }
        winding = nts_triangle_winding(nodes, v, lx, ly);
        if (winding == 0) {
            snprintf(msg, sizeof msg, "triangle %d (%d, %d, %d) has zero area", t, v[0], v[1], v[2]);
            rc = tri_fail(err, NTS_EDEGENERATE_TRIANGLE, t, -1, -1, msg);
            goto done;
        }
        if (winding < 0) { int tmp = v[1]; v[1] = v[2]; v[2] = tmp; } /* counter-clockwise */
        for (k = 0; k < 3; ++k) {
            edge_rec* e = &edges[3 * t + k];
            e->from = v[k];
            e->to = v[(k + 1) % 3];
            e->lo = e->from < e->to ? e->from : e->to;
            e->hi = e->from < e->to ? e->to : e->from;
            e->tri = t;
        }
    }
    qsort(edges, (size_t)ne, sizeof(edge_rec), edge_cmp);
    for (i = 0; i < node_count; ++i) next[i] = -1;
    for (i = 0; i < ne;) {
        int j = i;
        while (j < ne && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
        if (j - i > 2 || (j - i == 2 && edges[i].from == edges[i + 1].from)) {
            /* Three or more triangles on one edge, or two folded onto each other. */
            snprintf(msg, sizeof msg, "edge (%d, %d) is shared by %d triangles in a non-manifold way", edges[i].lo,
                     edges[i].hi, j - i);
            rc = tri_fail(err, NTS_ENONMANIFOLD, edges[j - 1].tri, -1, -1, msg);
            goto done;
        }
        if (j - i == 1) {
            int from = edges[i].from;
            if (next[from] != -1) {
                snprintf(msg, sizeof msg, "node %d is a pinch point (two boundary edges leave it)", from);
                rc = tri_fail(err, NTS_ENONMANIFOLD, edges[i].tri, -1, from, msg);
                goto done;
            }
            next[from] = edges[i].to;
            ++nb;
        }
        i = j;
    }
    if (nb == 0) {
        rc = tri_fail(err, NTS_ENO_BOUNDARY, -1, -1, -1, "triangle mesh has no boundary edge");
        goto done;
    }
    out->loop_nodes = (int*)nts_alloc(sizeof(int) * (size_t)nb);
    out->loop_start = (int*)nts_alloc(sizeof(int) * (size_t)(nb + 1));
    if (out->loop_nodes == NULL || out->loop_start == NULL) {
        rc = tri_fail(err, NTS_ENOMEM, -1, -1, -1, "out of memory");
        goto done;
    }
    /* Chain from the smallest unused node, so the loops do not depend on the
     * triangle order; the walk is bounded by the number of boundary edges. */
    for (i = 0; i < node_count; ++i) used[i] = 0;
    {
        int placed = 0;
        for (i = 0; i < node_count; ++i) {
            int v = i, steps = 0;
            if (next[i] == -1 || used[i]) continue;
            out->loop_start[out->loop_count++] = placed;
            do {
                if (used[v] || next[v] == -1 || steps > nb) {
                    snprintf(msg, sizeof msg, "boundary through node %d does not close", v);
                    rc = tri_fail(err, NTS_ENONMANIFOLD, -1, -1, v, msg);
                    goto done;
                }
                used[v] = 1;
                out->loop_nodes[placed++] = v;
                v = next[v];
                ++steps;
            } while (v != i);
        }
        out->loop_start[out->loop_count] = placed;
    }
done:
    nts_free(edges);
    nts_free(next);
    nts_free(used);
    if (rc != NTS_OK) nts_boundary_free(out);
    return rc;
}
