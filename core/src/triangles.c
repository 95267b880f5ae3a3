/* Boundary of a linear triangle mesh, from its connectivity alone: the
 * triangles of each connected piece are oriented consistently through their
 * shared edges (from the piece's first triangle as given), the directed edges
 * whose reverse is absent are kept and chained into loops. No position is
 * read: an interior triangle that turns over (as FIRE iterates do) changes
 * nothing here. Which way each piece runs (its outer loop counter-clockwise)
 * is the scene's decision, from its loops' signed areas (scene.c). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

typedef struct edge_rec {
    int lo, hi;   /* undirected key */
    int from, to; /* direction in its triangle as given */
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
    nts_free(b->loop_piece);
    b->loop_nodes = b->loop_start = b->loop_piece = NULL;
    b->loop_count = 0;
}

int nts_boundary_from_triangles(int node_count, const int* tri, int tri_count, nts_boundary* out, nts_error* err) {
    edge_rec* edges = NULL;
    int* nb = NULL;               /* 3 per triangle: the triangle across that edge, or -1 */
    unsigned char* same = NULL;   /* 3 per triangle: 1 when that neighbour runs the edge the same way */
    unsigned char* flip = NULL;   /* per triangle: 1 when turned over to agree with its piece */
    int* piece = NULL;            /* per triangle: its piece, -1 until reached */
    int* queue = NULL;
    int* next = NULL;             /* boundary successor of a node, -1 if none */
    int* node_piece = NULL;       /* per boundary node: the piece of its outgoing edge */
    int* piece_loop = NULL;       /* per piece: its first loop, -1 until one is chained */
    int ne = 3 * tri_count, nbd = 0, pieces = 0, i, t, rc = NTS_OK;
    char msg[192];

    memset(out, 0, sizeof *out);
    if (tri_count > 0x0fffffff) return tri_fail(err, NTS_ELIMIT, -1, -1, -1, "too many triangles");
    edges = (edge_rec*)nts_alloc(sizeof(edge_rec) * (size_t)ne);
    nb = (int*)nts_alloc(sizeof(int) * (size_t)ne);
    same = (unsigned char*)nts_alloc((size_t)ne);
    flip = (unsigned char*)nts_alloc((size_t)tri_count);
    piece = (int*)nts_alloc(sizeof(int) * (size_t)tri_count);
    queue = (int*)nts_alloc(sizeof(int) * (size_t)tri_count);
    next = (int*)nts_alloc(sizeof(int) * (size_t)node_count);
    node_piece = (int*)nts_alloc(sizeof(int) * (size_t)node_count);
    piece_loop = (int*)nts_alloc(sizeof(int) * (size_t)tri_count);
    if (!edges || !nb || !same || !flip || !piece || !queue || !next || !node_piece || !piece_loop) {
        rc = tri_fail(err, NTS_ENOMEM, -1, -1, -1, "out of memory");
        goto done;
    }
    for (t = 0; t < tri_count; ++t) {
        int v[3], k;
        for (k = 0; k < 3; ++k) {
            v[k] = tri[3 * t + k];
            if (v[k] < 0 || v[k] >= node_count) {
                snprintf(msg, sizeof msg, "triangle %d: node index %d out of range [0, %d)", t, v[k], node_count);
                rc = tri_fail(err, NTS_EINDEX_RANGE, t, k, -1, msg);
                goto done;
            }
        }
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
            snprintf(msg, sizeof msg, "triangle %d (%d, %d, %d) repeats a node: it has no edges of its own", t, v[0],
                     v[1], v[2]);
            rc = tri_fail(err, NTS_EDEGENERATE_TRIANGLE, t, -1, -1, msg);
            goto done;
        }
        for (k = 0; k < 3; ++k) {
            edge_rec* e = &edges[3 * t + k];
            e->from = v[k];
            e->to = v[(k + 1) % 3];
            e->lo = e->from < e->to ? e->from : e->to;
            e->hi = e->from < e->to ? e->to : e->from;
            e->tri = t;
            nb[3 * t + k] = -1;
            same[3 * t + k] = 0;
        }
    }
    qsort(edges, (size_t)ne, sizeof(edge_rec), edge_cmp);
    /* Each edge in one triangle (the boundary) or two (their link). */
    for (i = 0; i < ne;) {
        int j = i;
        while (j < ne && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
        if (j - i > 2) {
            snprintf(msg, sizeof msg,
                     "edge (%d, %d) is shared by %d triangles (%d, %d, %d, ...): at most two may share an edge",
                     edges[i].lo, edges[i].hi, j - i, edges[i].tri, edges[i + 1].tri, edges[i + 2].tri);
            rc = tri_fail(err, NTS_ENONMANIFOLD, edges[i + 2].tri, -1, -1, msg);
            goto done;
        }
        if (j - i == 2) {
            const edge_rec *a = &edges[i], *c = &edges[i + 1];
            int ka, kc;
            /* The corner k of a triangle whose edge this is: from = v[k]. */
            for (ka = 0; tri[3 * a->tri + ka] != a->from; ++ka) continue;
            for (kc = 0; tri[3 * c->tri + kc] != c->from; ++kc) continue;
            nb[3 * a->tri + ka] = c->tri;
            nb[3 * c->tri + kc] = a->tri;
            same[3 * a->tri + ka] = same[3 * c->tri + kc] = (unsigned char)(a->from == c->from);
        }
        i = j;
    }
    /* Orientation by connectivity: each piece from its first triangle as
     * given; two triangles that share an edge must run it opposite ways. */
    for (t = 0; t < tri_count; ++t) piece[t] = -1;
    for (t = 0; t < tri_count; ++t) {
        int head = 0, tail = 0;
        if (piece[t] != -1) continue;
        piece[t] = pieces;
        flip[t] = 0;
        queue[tail++] = t;
        while (head < tail) {
            int u = queue[head++], k;
            for (k = 0; k < 3; ++k) {
                int w = nb[3 * u + k];
                unsigned char want = (unsigned char)(flip[u] ^ same[3 * u + k]);
                if (w < 0) continue;
                if (piece[w] == -1) {
                    piece[w] = pieces;
                    flip[w] = want;
                    queue[tail++] = w;
                } else if (flip[w] != want) {
                    int a = tri[3 * u + k], c = tri[3 * u + (k + 1) % 3];
                    snprintf(msg, sizeof msg, "triangle %d cannot be oriented as its neighbours are (across edge (%d, "
                             "%d) from triangle %d): the mesh is not orientable", w, a < c ? a : c, a < c ? c : a, u);
                    rc = tri_fail(err, NTS_ENONMANIFOLD, w, -1, -1, msg);
                    goto done;
                }
            }
        }
        piece_loop[pieces++] = -1;
    }
    /* The boundary: edges in one triangle, in their triangle's orientation. */
    for (i = 0; i < node_count; ++i) next[i] = -1;
    for (t = 0; t < tri_count; ++t) {
        int k;
        for (k = 0; k < 3; ++k) {
            int from = tri[3 * t + k], to = tri[3 * t + (k + 1) % 3];
            if (nb[3 * t + k] >= 0) continue;
            if (flip[t]) { int tmp = from; from = to; to = tmp; }
            if (next[from] != -1) {
                snprintf(msg, sizeof msg, "node %d is a pinch point (two boundary edges leave it, one in triangle %d)",
                         from, t);
                rc = tri_fail(err, NTS_ENONMANIFOLD, t, -1, from, msg);
                goto done;
            }
            next[from] = to;
            node_piece[from] = piece[t];
            ++nbd;
        }
    }
    if (nbd == 0) {
        rc = tri_fail(err, NTS_ENO_BOUNDARY, -1, -1, -1, "triangle mesh has no boundary edge");
        goto done;
    }
    out->loop_nodes = (int*)nts_alloc(sizeof(int) * (size_t)nbd);
    out->loop_start = (int*)nts_alloc(sizeof(int) * (size_t)(nbd + 1));
    out->loop_piece = (int*)nts_alloc(sizeof(int) * (size_t)nbd);
    if (out->loop_nodes == NULL || out->loop_start == NULL || out->loop_piece == NULL) {
        rc = tri_fail(err, NTS_ENOMEM, -1, -1, -1, "out of memory");
        goto done;
    }
    /* Chain from the smallest unused node, so the loops do not depend on the
     * triangle order; the walk is bounded by the number of boundary edges. A
     * node once placed has its piece stored as -1 - piece. Each loop names
     * the first loop of its piece (loop_piece). */
    {
        int placed = 0;
        for (i = 0; i < node_count; ++i) {
            int v = i, steps = 0, p;
            if (next[i] == -1 || node_piece[i] < 0) continue;
            p = node_piece[i];
            if (piece_loop[p] == -1) piece_loop[p] = out->loop_count;
            out->loop_piece[out->loop_count] = piece_loop[p];
            out->loop_start[out->loop_count++] = placed;
            do {
                if (next[v] == -1 || node_piece[v] < 0 || steps > nbd) {
                    snprintf(msg, sizeof msg, "boundary through node %d does not close", v);
                    rc = tri_fail(err, NTS_ENONMANIFOLD, -1, -1, v, msg);
                    goto done;
                }
                node_piece[v] = -1 - node_piece[v]; /* used */
                out->loop_nodes[placed++] = v;
                v = next[v];
                ++steps;
            } while (v != i);
        }
        out->loop_start[out->loop_count] = placed;
    }
done:
    nts_free(edges);
    nts_free(nb);
    nts_free(same);
    nts_free(flip);
    nts_free(piece);
    nts_free(queue);
    nts_free(next);
    nts_free(node_piece);
    nts_free(piece_loop);
    if (rc != NTS_OK) nts_boundary_free(out);
    return rc;
}
