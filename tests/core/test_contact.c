/* Contact suite: outputs on demand, determinism, allocation-free reuse,
 * periodic wrap, forces aligned with the input nodes. */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

static long g_allocs;
static void* counting_alloc(size_t n, void* u) { (void)u; ++g_allocs; return malloc(n); }
static void counting_free(void* p, void* u) { (void)u; free(p); }

static nts_scene* two_disks(int n, double overlap) {
    static test_body b[2];
    make_polygon(&b[0], n, 1.0, nts_v2(0, 0), 0.0);
    make_polygon(&b[1], n, 1.0, nts_v2(2.0 - overlap, 0.0), 3.14159265358979 / n);
    return make_scene(b, 2, 0, 0);
}

static void test_outputs_only_when_asked(void) {
    nts_scene* s = two_disks(32, 0.05);
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx = nts_context_create();
    nts_error err;
    o.penalty = 100.0;
    o.outputs = NTS_OUT_ENERGY;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT(r.forces == NULL);
    CU_ASSERT(r.contacts == NULL && r.contact_count == 0);
    CU_ASSERT(r.gaps == NULL && r.gap_count == 0);
    CU_ASSERT(r.summary.contacts > 0);
    CU_ASSERT(r.summary.energy > 0.0);
    ASSERT_NEAR(r.summary.virial.xx, 0.0, 0.0); /* virial not asked: not computed */
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT(r.forces != NULL);
    ASSERT_INT_EQ(r.contact_count, r.summary.contacts);
    CU_ASSERT(r.gap_count >= r.contact_count);
    CU_ASSERT(r.summary.virial.xx > 0.0);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

static void test_bitwise_deterministic_and_allocation_free(void) {
    test_packing p = make_packing(64, 32, 1.0, 1.95, 1, 7);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_options o = nts_default_options();
    nts_result r1, r2;
    nts_context* ctx = nts_context_create();
    nts_context* ctx2 = nts_context_create();
    nts_vec2* f1;
    nts_contact* c1;
    nts_error err;
    int n, nc, b;
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_ALL;
    o.penalty = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r1, &err) == 0);
    n = nts_scene_node_count(s);
    nc = r1.contact_count;
    CU_ASSERT(nc > 50);
    f1 = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    c1 = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)nc);
    memcpy(f1, r1.forces, sizeof(nts_vec2) * (size_t)n);
    memcpy(c1, r1.contacts, sizeof(nts_contact) * (size_t)nc);
    /* Same input, fresh context: bitwise the same. */
    CU_ASSERT_FATAL(nts_evaluate(ctx2, s, &o, &r2, &err) == 0);
    CU_ASSERT(memcmp(f1, r2.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    ASSERT_INT_EQ(r2.contact_count, nc);
    CU_ASSERT(memcmp(c1, r2.contacts, sizeof(nts_contact) * (size_t)nc) == 0);
    CU_ASSERT(memcmp(&r1.summary, &r2.summary, sizeof r1.summary) == 0);
    /* New positions on the same topology (a small shift of every body), reused
     * context: no allocation at all once the buffers have grown. */
    for (b = 0; b < p.count; ++b) {
        int k;
        for (k = 0; k < p.bodies[b].node_count; ++k)
            p.bodies[b].nodes[k] = nts_add(p.bodies[b].nodes[k], nts_v2(1e-4 * (b % 3), -1e-4 * (b % 2)));
        CU_ASSERT(nts_scene_set_positions(s, b, p.bodies[b].nodes, &err) == 0);
    }
    nts_set_allocator(counting_alloc, counting_free, NULL);
    g_allocs = 0;
    CU_ASSERT(nts_evaluate(ctx, s, &o, &r1, &err) == 0);
    CU_ASSERT(nts_evaluate(ctx, s, &o, &r1, &err) == 0);
    nts_set_allocator(NULL, NULL, NULL);
    if (g_allocs != 0) fprintf(stderr, "\n  %ld allocations on re-evaluation\n", g_allocs);
    ASSERT_INT_EQ(g_allocs, 0);
    free(f1);
    free(c1);
    nts_context_destroy(ctx);
    nts_context_destroy(ctx2);
    nts_scene_destroy(s);
    free_packing(&p);
}

static void test_periodic_contact_across_the_boundary(void) {
    /* Two disks touching across x = 0 of a periodic box: the same contacts as the
     * same disks placed side by side in the open, shifted. */
    test_body b[2], c[2];
    nts_scene *sp, *so;
    nts_options o = nts_default_options();
    nts_result rp, ro;
    nts_context *cp, *co;
    int i;
    make_polygon(&b[0], 24, 1.0, nts_v2(0.95, 5.0), 0.0);
    make_polygon(&b[1], 24, 1.0, nts_v2(9.05, 5.0), 0.1); /* wraps: centre at -0.95 */
    make_polygon(&c[0], 24, 1.0, nts_v2(0.95, 5.0), 0.0);
    make_polygon(&c[1], 24, 1.0, nts_v2(-0.95, 5.0), 0.1);
    sp = make_scene(b, 2, 10.0, 10.0);
    so = make_scene(c, 2, 0, 0);
    CU_ASSERT_FATAL(sp != NULL && so != NULL);
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(eval_scene(sp, &o, &rp, &cp) == 0);
    CU_ASSERT_FATAL(eval_scene(so, &o, &ro, &co) == 0);
    CU_ASSERT(rp.contact_count > 0);
    ASSERT_INT_EQ(rp.contact_count, ro.contact_count);
    ASSERT_NEAR(rp.summary.energy, ro.summary.energy, 1e-12 * ro.summary.energy);
    for (i = 0; i < nts_scene_node_count(so); ++i) {
        ASSERT_NEAR(rp.forces[i].x, ro.forces[i].x, 1e-12);
        ASSERT_NEAR(rp.forces[i].y, ro.forces[i].y, 1e-12);
    }
    ASSERT_NEAR(rp.summary.virial.xx, ro.summary.virial.xx, 1e-12);
    nts_context_destroy(cp);
    nts_context_destroy(co);
    nts_scene_destroy(sp);
    nts_scene_destroy(so);
}

static void test_box_too_small_is_an_error(void) {
    test_body b[2];
    nts_scene* s;
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx;
    make_polygon(&b[0], 8, 1.0, nts_v2(1, 1), 0.0);
    make_polygon(&b[1], 8, 1.0, nts_v2(2.5, 1), 0.0);
    s = make_scene(b, 2, 3.0, 3.0);
    CU_ASSERT_FATAL(s != NULL);
    o.search_radius = 1.0;
    CU_ASSERT(eval_scene(s, &o, &r, &ctx) == NTS_EBOX_TOO_SMALL);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

/* A triangle mesh (nodes, triangles) and a polygon `disk`: the scene. */
static nts_scene* mesh_and_disk(const nts_vec2* nodes, int node_count, const int* tri, int triangle_count,
                                const test_body* disk) {
    nts_body_def defs[2];
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    memset(defs, 0, sizeof defs);
    defs[0].nodes = nodes;
    defs[0].node_count = node_count;
    defs[0].triangles = tri;
    defs[0].triangle_count = triangle_count;
    defs[1].nodes = disk->nodes;
    defs[1].node_count = disk->node_count;
    def.bodies = defs;
    def.body_count = 2;
    return nts_scene_create(&def, &err);
}

/* A g x g grid mesh of the square [0, 2]^2 (grid: g^2 nodes, tri: 6 (g -
 * 1)^2 indices) and a 24-gon pressed into its top edge (*disk): the scene. */
static nts_scene* grid_and_disk(int g, nts_vec2* grid, int* tri, test_body* disk) {
    int i, j, t = 0;
    for (j = 0; j < g; ++j)
        for (i = 0; i < g; ++i) grid[j * g + i] = nts_v2(2.0 * i / (g - 1), 2.0 * j / (g - 1));
    for (j = 0; j + 1 < g; ++j)
        for (i = 0; i + 1 < g; ++i) {
            const int a = j * g + i;
            tri[t++] = a, tri[t++] = a + 1, tri[t++] = a + g + 1;
            tri[t++] = a, tri[t++] = a + g + 1, tri[t++] = a + g;
        }
    make_polygon(disk, 24, 0.5, nts_v2(0.9, 2.45), 0.05);
    return mesh_and_disk(grid, g * g, tri, t / 3, disk);
}

static void test_interior_nodes_get_zero_force(void) {
    /* A triangle-mesh body (square with a centre node) pressed by a disk: the
     * interior node's force is exactly zero, forces align with the input nodes. */
    nts_vec2 pts[5] = {{0, 0}, {2, 0}, {1, 1}, {2, 2}, {0, 2}};
    int tri[12] = {0, 1, 2, 1, 3, 2, 3, 4, 2, 4, 0, 2};
    test_body disk;
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx;
    nts_scene* s;
    double fx = 0, fy = 0;
    int i;
    make_polygon(&disk, 16, 0.5, nts_v2(1.0, 2.45), 0.05);
    s = mesh_and_disk(pts, 5, tri, 4, &disk);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT_FATAL(eval_scene(s, &o, &r, &ctx) == 0);
    CU_ASSERT(r.summary.contacts > 0);
    ASSERT_NEAR(r.forces[2].x, 0.0, 0.0);
    ASSERT_NEAR(r.forces[2].y, 0.0, 0.0);
    CU_ASSERT(r.forces[3].y < 0.0 || r.forces[4].y < 0.0); /* the top corners are pushed down */
    for (i = 0; i < nts_scene_node_count(s); ++i) {
        fx += r.forces[i].x;
        fy += r.forces[i].y;
    }
    ASSERT_NEAR(fx, 0.0, 1e-14);
    ASSERT_NEAR(fy, 0.0, 1e-14);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

/* A mesh whose nodes are mostly inside (a 12 x 12 grid of nodes, 44 of 144
 * on its boundary) pressed by a disk: a context that evaluated it last
 * clears only the surface nodes' forces (the interior ones still hold
 * zero). Every evaluation, on a context that has seen other scenes (a
 * larger one with forces on most of its nodes, on one thread and on two;
 * the same mesh on two threads; a trim) or this one at other positions,
 * gives a fresh context's forces bit for bit, interior zeros included. */
static void test_mesh_forces_on_a_context_used_before(void) {
    enum { G = 12 };
    nts_vec2 grid[G * G];
    int tri[6 * (G - 1) * (G - 1)];
    test_body disk, other[2];
    nts_options o = nts_default_options();
    nts_context* ctx = nts_context_create();
    nts_scene *s, *big;
    nts_error err;
    nts_result r, want;
    int i, k, n;
    s = grid_and_disk(G, grid, tri, &disk);
    CU_ASSERT_FATAL(s != NULL);
    n = nts_scene_node_count(s);
    CU_ASSERT_FATAL(2 * nts_scene_surface_node_count(s) <= n);
    /* two disks pressed deep into each other: forces on most of their nodes */
    make_polygon(&other[0], 200, 1.0, nts_v2(0, 0), 0.0);
    make_polygon(&other[1], 200, 1.0, nts_v2(0.6, 0), 0.1);
    big = make_scene(other, 2, 0, 0);
    CU_ASSERT_FATAL(big != NULL);
    o.penalty = 10.0;
    for (k = 0; k < 8; ++k) {
        nts_context* fresh = nts_context_create();
        nts_vec2 pos[G * G + 24];
        /* the disk a little lower each time, the mesh as it is */
        memcpy(pos, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
        for (i = G * G; i < n; ++i) pos[i].y -= 0.01 * k;
        CU_ASSERT_FATAL(nts_scene_update_positions(s, pos, &err) == 0);
        o.threads = k == 6 ? 2 : 1;
        if (k == 3 || k == 6) { /* another scene between, on one thread or two */
            int nonzero = 0;
            CU_ASSERT_FATAL(nts_evaluate(ctx, big, &o, &r, &err) == 0);
            for (i = 0; i < n; ++i) nonzero += r.forces[i].x != 0.0 || r.forces[i].y != 0.0;
            CU_ASSERT(nonzero > n / 2); /* where the mesh's interior forces lie */
            o.threads = 1;
        }
        if (k == 4) {
            o.threads = 2;
            CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
            o.threads = 1;
        }
        if (k == 5) nts_context_trim(ctx);
        CU_ASSERT_FATAL(nts_evaluate(fresh, s, &o, &want, &err) == 0);
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
        CU_ASSERT(want.summary.contacts > 0);
        CU_ASSERT(memcmp(r.forces, want.forces, sizeof(nts_vec2) * (size_t)n) == 0);
        for (i = 0; i < n; ++i)
            if (i % G != 0 && i % G != G - 1 && i / G != 0 && i / G != G - 1 && i < G * G)
                CU_ASSERT(r.forces[i].x == 0.0 && r.forces[i].y == 0.0);
        nts_context_destroy(fresh);
    }
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    nts_scene_destroy(big);
}

/* nts_evaluate_surface_positions reads and takes the loops' nodes alone: an
 * 8 x 8 grid mesh (36 of its 64 nodes inside) pressed by a disk, stepped on
 * one scene with the interior entries NaN, answers as nts_evaluate_positions
 * on a second scene given its stored positions with the loops' nodes
 * replaced, bit for bit, and the first scene keeps its interior nodes where
 * they were (a step of every node moves them, on both). Refused positions (a
 * NaN on a loop, a segment of length zero, the mesh mirrored) give the
 * update's error, the same fields, and leave the scene as it was. */
static void test_surface_positions_are_the_whole_step(void) {
    enum { G = 8 };
    nts_vec2 grid[G * G], part[G * G + 24], whole[G * G + 24], before[G * G + 24];
    int tri[6 * (G - 1) * (G - 1)];
    unsigned char on[G * G + 24];
    test_body disk;
    nts_options o = nts_default_options();
    nts_context *ca = nts_context_create(), *cb = nts_context_create();
    nts_scene *sa, *sb;
    nts_error ea, eb;
    nts_result ra, rb;
    int i, j, k, n, b, l, inside = 0, active = 0;
    test_rng rng = {5};
    sa = grid_and_disk(G, grid, tri, &disk);
    sb = grid_and_disk(G, grid, tri, &disk);
    CU_ASSERT_FATAL(sa != NULL && sb != NULL && ca != NULL && cb != NULL);
    n = nts_scene_node_count(sa);
    memset(on, 0, sizeof on);
    for (b = 0; b < 2; ++b)
        for (l = 0; l < nts_scene_body_loop_count(sa, b); ++l) {
            const int* idx;
            const int len = nts_scene_body_loop(sa, b, l, &idx);
            for (i = 0; i < len; ++i) on[nts_scene_body_node_offset(sa, b) + idx[i]] = 1;
        }
    for (i = 0; i < n; ++i) inside += !on[i];
    CU_ASSERT_FATAL(inside == (G - 2) * (G - 2));
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_STIFFNESS;
    for (k = 0; k < 8; ++k) {
        for (i = 0; i < n; ++i) {
            const nts_vec2 p = nts_scene_positions(sa)[i];
            whole[i] = nts_v2(p.x + 0.01 * (rng_uniform(&rng) - 0.5), p.y + 0.01 * (rng_uniform(&rng) - 0.5) -
                                                                          (i >= G * G ? 0.005 : 0.0));
        }
        if (k == 3) { /* every node moved, the interior too: on both */
            CU_ASSERT_FATAL(nts_evaluate_positions(ca, sa, whole, &o, &ra, &ea) == 0);
            CU_ASSERT_FATAL(nts_evaluate_positions(cb, sb, whole, &o, &rb, &eb) == 0);
        } else {
            for (i = 0; i < n; ++i) part[i] = on[i] ? whole[i] : nts_v2(NAN, NAN);
            for (i = 0; i < n; ++i)
                if (!on[i]) whole[i] = nts_scene_positions(sb)[i];
            CU_ASSERT_FATAL(nts_evaluate_surface_positions(ca, sa, part, &o, &ra, &ea) == 0);
            CU_ASSERT_FATAL(nts_evaluate_positions(cb, sb, whole, &o, &rb, &eb) == 0);
        }
        CU_ASSERT(memcmp(nts_scene_positions(sa), nts_scene_positions(sb), sizeof(nts_vec2) * (size_t)n) == 0);
        CU_ASSERT(memcmp(ra.forces, rb.forces, sizeof(nts_vec2) * (size_t)n) == 0);
        CU_ASSERT(memcmp(&ra.summary.energy, &rb.summary.energy, sizeof(double)) == 0);
        CU_ASSERT(memcmp(&ra.summary.virial, &rb.summary.virial, sizeof ra.summary.virial) == 0);
        CU_ASSERT(ra.stiffness.count == rb.stiffness.count);
        if (ra.stiffness.count == rb.stiffness.count && ra.stiffness.count > 0)
            CU_ASSERT(memcmp(ra.stiffness.values, rb.stiffness.values, sizeof(double) * (size_t)ra.stiffness.count) == 0);
        active += ra.summary.contacts;
    }
    CU_ASSERT(active > 0);
    /* refused: a NaN on a loop, two consecutive loop nodes at one place, the mesh mirrored */
    memcpy(before, nts_scene_positions(sa), sizeof(nts_vec2) * (size_t)n);
    for (k = 0; k < 3; ++k) {
        for (i = 0; i < n; ++i) part[i] = on[i] ? before[i] : nts_v2(NAN, NAN);
        if (k == 0) part[G - 1].y = NAN;
        if (k == 1) part[2] = part[1];
        if (k == 2)
            for (i = 0; i < G * G; ++i) part[i].x = on[i] ? 2.0 - part[i].x : part[i].x;
        for (i = 0; i < n; ++i) whole[i] = on[i] ? part[i] : before[i];
        ra = rb;
        j = nts_evaluate_surface_positions(ca, sa, part, &o, &ra, &ea);
        CU_ASSERT(j != 0 && j == nts_scene_update_positions(sb, whole, &eb));
        CU_ASSERT(ea.code == eb.code && ea.body == eb.body && ea.loop == eb.loop && ea.loop_pos == eb.loop_pos &&
                  ea.node == eb.node && strcmp(ea.message, eb.message) == 0);
        CU_ASSERT(memcmp(nts_scene_positions(sa), before, sizeof(nts_vec2) * (size_t)n) == 0);
        CU_ASSERT(memcmp(&ra, &rb, sizeof ra) == 0); /* the result left as it was */
    }
    nts_context_destroy(ca);
    nts_context_destroy(cb);
    nts_scene_destroy(sa);
    nts_scene_destroy(sb);
}

static void test_overflow_is_an_error_not_nan(void) {
    /* Finite input whose energy overflows (gaps ~1e88, eps g^2 ~1e376): an
     * error naming the penalty, never Inf or NaN out of the library. */
    test_body b[2];
    nts_scene* s;
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx = nts_context_create();
    nts_error err;
    make_polygon(&b[0], 32, 1e90, nts_v2(0, 0), 0.0);
    make_polygon(&b[1], 32, 1e90, nts_v2(1.95e90, 0.0), 0.1);
    s = make_scene(b, 2, 0, 0);
    CU_ASSERT_FATAL(s != NULL);
    o.penalty = 1e200;
    o.outputs = NTS_OUT_ALL;
    ASSERT_INT_EQ(nts_evaluate(ctx, s, &o, &r, &err), NTS_ENONFINITE);
    CU_ASSERT(strcmp(err.option, "penalty") == 0);
    o.penalty = 1e-20; /* same scene, representable result: fine */
    ASSERT_INT_EQ(nts_evaluate(ctx, s, &o, &r, &err), 0);
    CU_ASSERT(isfinite(r.summary.energy) && r.summary.energy > 0.0);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
}

/* Forces that overflow while the energy does not: a long master's end node
 * (node 3) pushed by the four nodes of a square 0.5 to 1 deep (its share of
 * each force 0.97-0.98 at alpha 0), the penalty P such that their sum
 * exceeds the largest double (about 2.9 P) while the energy (1.25 P) and
 * each slave's own force (at most P) do not; then a small polygon's twelve
 * shallow contacts on the master's bottom edge, before or after the square's
 * in slave order (the search's own path adds a force when eight more have
 * come, or at the end). An error naming the penalty on every path that
 * sums forces: the search's own (one thread), the force shares (two
 * threads) and the records (contacts asked for), each with the radius
 * given (the square found by the search: the chunks' adds) and the default
 * (found by the deep contacts' growth: their own adds); at a tenth of the
 * penalty every value is finite, and ten times only node 3's force is not. */
static void test_force_overflow_is_an_error(void) {
    test_body b[3], t;
    nts_scene* scenes[2];
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx = nts_context_create();
    nts_error err;
    static const nts_vec2 master[4] = {{0.0, 0.0}, {100.0, 0.0}, {100.0, 10.0}, {0.0, 10.0}};
    static const nts_vec2 square[4] = {{2.0, 9.0}, {3.0, 9.0}, {3.0, 9.5}, {2.0, 9.5}};
    static const unsigned paths[7] = {0u, 0u, 0u, 0u, NTS_OUT_CONTACTS, 0u, NTS_OUT_CONTACTS};
    static const int threads[7] = {1, 1, 1, 2, 1, 2, 1};
    static const double radius[7] = {2.0, 2.0, -1.0, -1.0, -1.0, 2.0, 2.0};
    static const int order[7] = {0, 1, 0, 0, 0, 0, 0}; /* the square before the polygon, or after */
    int k, i, n;
    memset(b, 0, sizeof b);
    for (i = 0; i < 4; ++i) {
        b[0].nodes[i] = master[i];
        b[1].nodes[i] = square[i];
    }
    b[0].node_count = b[1].node_count = 4;
    make_polygon(&b[2], 12, 0.05, nts_v2(50.0, 0.06), 0.0);
    scenes[0] = make_scene(b, 3, 0, 0);
    t = b[1];
    b[1] = b[2];
    b[2] = t;
    scenes[1] = make_scene(b, 3, 0, 0);
    CU_ASSERT_FATAL(scenes[0] != NULL && scenes[1] != NULL);
    n = nts_scene_node_count(scenes[0]);
    o.alpha = 0.0;
    for (k = 0; k < 7; ++k) {
        nts_scene* s = scenes[order[k]];
        double fmax = 0.0;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | paths[k];
        o.threads = threads[k];
        o.search_radius = radius[k];
        o.penalty = 1e307;
        ASSERT_INT_EQ(nts_evaluate(ctx, s, &o, &r, &err), 0);
        ASSERT_INT_EQ(r.summary.contacts, 16);
        for (i = 0; i < n; ++i) fmax = fabs(r.forces[i].y) > fmax ? fabs(r.forces[i].y) : fmax;
        CU_ASSERT(fabs(r.forces[3].y) == fmax && 10.0 * fmax > DBL_MAX);
        for (i = 0; i < n; ++i)
            if (i != 3) CU_ASSERT(10.0 * fabs(r.forces[i].x) < DBL_MAX && 10.0 * fabs(r.forces[i].y) < DBL_MAX);
        CU_ASSERT(r.summary.energy > 0.0 && 10.0 * r.summary.energy < DBL_MAX);
        o.penalty = 1e308;
        ASSERT_INT_EQ(nts_evaluate(ctx, s, &o, &r, &err), NTS_ENONFINITE);
        CU_ASSERT(strcmp(err.option, "penalty") == 0);
    }
    nts_context_destroy(ctx);
    nts_scene_destroy(scenes[0]);
    nts_scene_destroy(scenes[1]);
}

/* A context trimmed after a large evaluation holds no more than a new one,
 * and evaluates again to the same bits (a session gives back what one step
 * with gaps on a wide radius grew: server/src/sessions.c). */
static void test_trim_gives_back_and_keeps_results(void) {
    test_packing p = make_packing(36, 24, 1.0, 1.95, 0, 3);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_options o = nts_default_options();
    nts_result r;
    nts_context* ctx = nts_context_create();
    nts_context* fresh = nts_context_create();
    nts_vec2* f1;
    nts_summary s1;
    size_t created = nts_context_memory_bytes(ctx), small, wide;
    nts_error err;
    int n;
    CU_ASSERT_FATAL(s != NULL);
    n = nts_scene_node_count(s);
    o.penalty = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    small = nts_context_memory_bytes(ctx);
    f1 = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    memcpy(f1, r.forces, sizeof(nts_vec2) * (size_t)n);
    s1 = r.summary;
    o.outputs = NTS_OUT_ALL;
    o.search_radius = 4.0; /* the closest points on every neighbour and theirs */
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    wide = nts_context_memory_bytes(ctx);
    CU_ASSERT(wide > 4 * small);
    nts_context_trim(ctx);
    ASSERT_INT_EQ((long long)nts_context_memory_bytes(ctx), (long long)created);
    ASSERT_INT_EQ((long long)nts_context_memory_bytes(fresh), (long long)created);
    o = nts_default_options();
    o.penalty = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT(memcmp(f1, r.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    CU_ASSERT(memcmp(&s1, &r.summary, sizeof s1) == 0);
    ASSERT_INT_EQ((long long)nts_context_memory_bytes(ctx), (long long)small);
    nts_context_trim(NULL); /* like nts_context_destroy(NULL) */
    free(f1);
    nts_context_destroy(ctx);
    nts_context_destroy(fresh);
    nts_scene_destroy(s);
    free_packing(&p);
}

void register_contact_suite(void) {
    CU_pSuite s = CU_add_suite("contact", NULL, NULL);
    ADD_TEST(s, test_outputs_only_when_asked);
    ADD_TEST(s, test_bitwise_deterministic_and_allocation_free);
    ADD_TEST(s, test_periodic_contact_across_the_boundary);
    ADD_TEST(s, test_box_too_small_is_an_error);
    ADD_TEST(s, test_force_overflow_is_an_error);
    ADD_TEST(s, test_mesh_forces_on_a_context_used_before);
    ADD_TEST(s, test_surface_positions_are_the_whole_step);
    ADD_TEST(s, test_interior_nodes_get_zero_force);
    ADD_TEST(s, test_overflow_is_an_error_not_nan);
    ADD_TEST(s, test_trim_gives_back_and_keeps_results);
}
