/* Update suite: nts_scene_update_positions takes new positions only when
 * creating the scene anew from them would give the very same scene, so an
 * evaluation after an update equals, bit for bit, one on a fresh scene. */
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

/* All positions of test bodies in global order (caller frees). */
static nts_vec2* gather(const test_body* bodies, int count, int* n_out) {
    int b, n = 0, k = 0;
    nts_vec2* p;
    for (b = 0; b < count; ++b) n += bodies[b].node_count;
    p = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    for (b = 0; b < count; ++b) {
        memcpy(p + k, bodies[b].nodes, sizeof(nts_vec2) * (size_t)bodies[b].node_count);
        k += bodies[b].node_count;
    }
    *n_out = n;
    return p;
}

/* Forces and summary of an evaluation on `updated` equal those on a scene made
 * fresh from `bodies`, bit for bit. */
static void assert_same_as_fresh(const nts_scene* updated, const test_body* bodies, int count, double lx, double ly) {
    nts_scene* fresh = make_scene(bodies, count, lx, ly);
    nts_options opt = nts_default_options();
    nts_context *c1 = nts_context_create(), *c2 = nts_context_create();
    nts_result r1, r2;
    nts_error err;
    CU_ASSERT_FATAL(fresh != NULL);
    opt.outputs = NTS_OUT_ALL;
    ASSERT_INT_EQ(nts_evaluate(c1, updated, &opt, &r1, &err), 0);
    ASSERT_INT_EQ(nts_evaluate(c2, fresh, &opt, &r2, &err), 0);
    ASSERT_INT_EQ(nts_scene_loops_reversed(updated), nts_scene_loops_reversed(fresh));
    ASSERT_INT_EQ(r1.summary.contacts, r2.summary.contacts);
    ASSERT_INT_EQ(r1.gap_count, r2.gap_count);
    CU_ASSERT(memcmp(&r1.summary.energy, &r2.summary.energy, sizeof(double)) == 0);
    CU_ASSERT(memcmp(&r1.summary.virial, &r2.summary.virial, sizeof(nts_virial)) == 0);
    CU_ASSERT(memcmp(r1.forces, r2.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(fresh)) == 0);
    if (r1.gap_count == r2.gap_count && r1.gap_count > 0)
        CU_ASSERT(memcmp(r1.gaps, r2.gaps, sizeof(nts_contact) * (size_t)r1.gap_count) == 0);
    nts_context_destroy(c1);
    nts_context_destroy(c2);
    nts_scene_destroy(fresh);
}

static void check_random_moves(int periodic) {
    test_packing p = make_packing(16, 24, 1.0, 1.9, periodic, 7);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    test_rng rng = {12345};
    int step, n, b, k;
    CU_ASSERT_FATAL(s != NULL);
    for (step = 0; step < 5; ++step) {
        nts_vec2* pos;
        nts_error err;
        for (b = 0; b < p.count; ++b) {
            /* A rigid shift of each body plus a small jitter of its nodes. */
            double dx = 0.05 * (rng_uniform(&rng) - 0.5), dy = 0.05 * (rng_uniform(&rng) - 0.5);
            for (k = 0; k < p.bodies[b].node_count; ++k) {
                p.bodies[b].nodes[k].x += dx + 0.01 * (rng_uniform(&rng) - 0.5);
                p.bodies[b].nodes[k].y += dy + 0.01 * (rng_uniform(&rng) - 0.5);
            }
        }
        pos = gather(p.bodies, p.count, &n);
        ASSERT_INT_EQ(n, nts_scene_node_count(s));
        ASSERT_INT_EQ(update_both(s, pos, &err), 0);
        CU_ASSERT(memcmp(nts_scene_positions(s), pos, sizeof(nts_vec2) * (size_t)n) == 0);
        assert_same_as_fresh(s, p.bodies, p.count, p.lx, p.ly);
        free(pos);
    }
    nts_scene_destroy(s);
    free_packing(&p);
}

static void test_random_moves_open(void) { check_random_moves(0); }
static void test_random_moves_periodic(void) { check_random_moves(1); }

/* Outer loop given clockwise and a hole counter-clockwise (both reversed by the
 * scene): moves that keep the orientations are taken; mirroring is refused. */
static void test_orientation_kept_or_refused(void) {
    test_body b[2];
    nts_scene* s;
    nts_vec2 pos[12], before[12];
    nts_error err;
    int i;
    memset(b, 0, sizeof b);
    /* body 0: square 0..4 clockwise, hole 1..3 counter-clockwise */
    {
        nts_vec2 pts[8] = {{0, 0}, {0, 4}, {4, 4}, {4, 0}, {1, 1}, {3, 1}, {3, 3}, {1, 3}};
        memcpy(b[0].nodes, pts, sizeof pts);
        b[0].node_count = 8;
        for (i = 0; i < 8; ++i) b[0].loop_nodes[i] = i;
        b[0].loop_start[0] = 0; b[0].loop_start[1] = 4; b[0].loop_start[2] = 8;
        b[0].loop_count = 2;
    }
    make_polygon(&b[1], 4, 0.8, nts_v2(2.0, 2.0), 0.3); /* inside the hole, touching nothing */
    s = make_scene(b, 2, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_loops_reversed(s), 2);

    b[0].nodes[5].x += 0.2; /* a small move of a hole node */
    b[1].nodes[0].x += 0.9; /* the square pokes into the hole's edge: a contact */
    for (i = 0; i < 8; ++i) pos[i] = b[0].nodes[i];
    for (i = 0; i < 4; ++i) pos[8 + i] = b[1].nodes[i];
    ASSERT_INT_EQ(update_both(s, pos, &err), 0);
    assert_same_as_fresh(s, b, 2, 0.0, 0.0);

    /* Mirror body 1 (x -> 4 - x): its loop turns clockwise. */
    memcpy(before, nts_scene_positions(s), sizeof before);
    for (i = 8; i < 12; ++i) pos[i].x = 4.0 - pos[i].x;
    ASSERT_INT_EQ(update_both(s, pos, &err), NTS_ERESHAPED);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.loop, 0);
    CU_ASSERT(memcmp(nts_scene_positions(s), before, sizeof before) == 0); /* unchanged */

    /* The hole grows larger than the outer loop: another loop is the outer one. */
    for (i = 0; i < 12; ++i) pos[i] = before[i];
    for (i = 4; i < 8; ++i) pos[i] = nts_v2(2.0 + 5.0 * (pos[i].x - 2.0), 2.0 + 5.0 * (pos[i].y - 2.0));
    ASSERT_INT_EQ(update_both(s, pos, &err), NTS_ERESHAPED);
    ASSERT_INT_EQ(err.body, 0);

    /* The checks of creation, with its codes. */
    for (i = 0; i < 12; ++i) pos[i] = before[i];
    pos[1] = pos[0];
    ASSERT_INT_EQ(update_both(s, pos, &err), NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 0);
    pos[1] = before[1];
    pos[10].y = NAN;
    ASSERT_INT_EQ(update_both(s, pos, &err), NTS_ENONFINITE);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.node, 2);
    CU_ASSERT(memcmp(nts_scene_positions(s), before, sizeof before) == 0);
    ASSERT_INT_EQ(update_both(s, NULL, &err), NTS_EINVALID_ARGUMENT);
    nts_scene_destroy(s);
}

/* A 5 x 5 grid mesh of the unit square (32 triangles, diagonals from each
 * cell's lower left), side `h`, and a disk of 24 nodes pressed into its
 * bottom edge: nodes 0..24 the grid, 25..48 the disk. */
enum { GRID_NODES = 25, GRID_TRIS = 32, DISK_NODES = 24, ALL_NODES = GRID_NODES + DISK_NODES };
static void grid_and_disk(nts_vec2* pos, int* tri) {
    test_body disk;
    int i, j, t = 0;
    for (j = 0; j < 5; ++j)
        for (i = 0; i < 5; ++i) pos[5 * j + i] = nts_v2(0.25 * i, 0.25 * j);
    for (j = 0; j < 4; ++j)
        for (i = 0; i < 4; ++i) {
            int v = 5 * j + i;
            tri[3 * t] = v; tri[3 * t + 1] = v + 1; tri[3 * t + 2] = v + 6; ++t;
            tri[3 * t] = v; tri[3 * t + 1] = v + 6; tri[3 * t + 2] = v + 5; ++t;
        }
    make_polygon(&disk, DISK_NODES, 0.3, nts_v2(0.55, -0.29), 0.1);
    for (i = 0; i < DISK_NODES; ++i) pos[GRID_NODES + i] = disk.nodes[i];
}

static nts_scene* grid_scene(const nts_vec2* pos, const int* tri, nts_error* err) {
    nts_body_def bd[2];
    nts_scene_def def = nts_default_scene_def();
    memset(bd, 0, sizeof bd);
    bd[0].nodes = pos;
    bd[0].node_count = GRID_NODES;
    bd[0].triangles = tri;
    bd[0].triangle_count = GRID_TRIS;
    bd[1].nodes = pos + GRID_NODES;
    bd[1].node_count = DISK_NODES;
    def.bodies = bd;
    def.body_count = 2;
    return nts_scene_create(&def, err);
}

/* Forces, energy and contacts of two evaluations agree bit for bit. */
static void assert_same_contacts(const nts_scene* s1, const nts_scene* s2) {
    nts_options opt = nts_default_options();
    nts_context *c1 = nts_context_create(), *c2 = nts_context_create();
    nts_result r1, r2;
    nts_error err;
    opt.penalty = 100.0;
    opt.outputs = NTS_OUT_ALL;
    ASSERT_INT_EQ(nts_evaluate(c1, s1, &opt, &r1, &err), 0);
    ASSERT_INT_EQ(nts_evaluate(c2, s2, &opt, &r2, &err), 0);
    CU_ASSERT(r1.contact_count > 0);
    ASSERT_INT_EQ(r1.contact_count, r2.contact_count);
    ASSERT_INT_EQ(r1.gap_count, r2.gap_count);
    ASSERT_INT_EQ(r1.stiffness.count, r2.stiffness.count);
    CU_ASSERT(memcmp(&r1.summary.energy, &r2.summary.energy, sizeof(double)) == 0);
    CU_ASSERT(memcmp(&r1.summary.virial, &r2.summary.virial, sizeof(nts_virial)) == 0);
    CU_ASSERT(memcmp(r1.forces, r2.forces, sizeof(nts_vec2) * ALL_NODES) == 0);
    if (r1.contact_count == r2.contact_count && r1.contact_count > 0)
        CU_ASSERT(memcmp(r1.contacts, r2.contacts, sizeof(nts_contact) * (size_t)r1.contact_count) == 0);
    if (r1.stiffness.count == r2.stiffness.count && r1.stiffness.count > 0)
        CU_ASSERT(memcmp(r1.stiffness.values, r2.stiffness.values, sizeof(double) * (size_t)r1.stiffness.count) == 0);
    nts_context_destroy(c1);
    nts_context_destroy(c2);
}

/* Contact depends on a mesh's boundary only (issue 22 §5): an interior
 * triangle turned over, as a FIRE iterate turns one, is taken at creation
 * and by an update, and gives the very contacts of the mesh un-turned, whose
 * boundary is the same. It used to be refused (non_manifold_mesh at creation,
 * NTS_ERESHAPED then non_manifold_mesh in a session). */
static void test_interior_triangle_turned_over(void) {
    nts_vec2 pos[ALL_NODES], turned[ALL_NODES], flat[ALL_NODES];
    int tri[3 * GRID_TRIS], i;
    nts_scene *s, *fresh;
    nts_error err;
    grid_and_disk(pos, tri);
    s = grid_scene(pos, tri, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_surface_node_count(s), 16 + DISK_NODES);
    /* Node 12 (0.5, 0.5) just beyond the edge (13, 18) of its hexagon of
     * neighbours: triangle 20 (12, 13, 18) turns over, and only it. */
    memcpy(turned, pos, sizeof pos);
    turned[12] = nts_v2(0.775, 0.625);
    for (i = 0; i < GRID_TRIS; ++i) {
        const int* v = tri + 3 * i;
        double cr = nts_cross(nts_sub(turned[v[1]], turned[v[0]]), nts_sub(turned[v[2]], turned[v[0]]));
        CU_ASSERT(i == 20 ? cr < 0.0 : cr > 0.0);
    }
    fresh = grid_scene(turned, tri, &err);
    CU_ASSERT_FATAL(fresh != NULL);
    assert_same_contacts(fresh, s);
    ASSERT_INT_EQ(update_both(s, turned, &err), 0);
    CU_ASSERT(memcmp(nts_scene_positions(s), turned, sizeof turned) == 0);
    assert_same_contacts(s, fresh);
    nts_scene_destroy(fresh);
    /* Exactly on the edge: triangle 20 has zero area. Taken too. */
    memcpy(flat, pos, sizeof pos);
    flat[12] = nts_v2(0.75, 0.625);
    fresh = grid_scene(flat, tri, &err);
    CU_ASSERT_FATAL(fresh != NULL);
    ASSERT_INT_EQ(update_both(s, flat, &err), 0);
    assert_same_contacts(s, fresh);
    nts_scene_destroy(fresh);
    nts_scene_destroy(s);
}

/* What a mesh's boundary needs is still checked: a boundary segment of zero
 * length (named by its node), and the mesh mirrored (its outer loop turns
 * clockwise: a new scene, with that loop counter-clockwise again). */
static void test_mesh_boundary_verdicts(void) {
    nts_vec2 pos[ALL_NODES], moved[ALL_NODES], before[ALL_NODES];
    int tri[3 * GRID_TRIS], i;
    nts_scene *s, *fresh;
    const int* l;
    double a2 = 0.0;
    int n;
    nts_error err;
    grid_and_disk(pos, tri);
    s = grid_scene(pos, tri, &err);
    CU_ASSERT_FATAL(s != NULL);
    memcpy(before, pos, sizeof pos);
    memcpy(moved, pos, sizeof pos);
    moved[3] = moved[4]; /* boundary nodes 3 and 4 on one spot */
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 0);
    CU_ASSERT(err.node == 3 || err.node == 4);
    CU_ASSERT(strstr(err.message, "node 3") != NULL);
    CU_ASSERT(grid_scene(moved, tri, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_EDEGENERATE_SEGMENT);
    CU_ASSERT(memcmp(nts_scene_positions(s), before, sizeof before) == 0);
    /* The grid mirrored about x = 1.5, far from the disk. */
    memcpy(moved, pos, sizeof pos);
    for (i = 0; i < GRID_NODES; ++i) moved[i].x = 3.0 - moved[i].x;
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_ERESHAPED);
    ASSERT_INT_EQ(err.body, 0);
    ASSERT_INT_EQ(err.loop, 0);
    CU_ASSERT(memcmp(nts_scene_positions(s), before, sizeof before) == 0);
    fresh = grid_scene(moved, tri, &err);
    CU_ASSERT_FATAL(fresh != NULL);
    ASSERT_INT_EQ(nts_scene_loops_reversed(fresh), 0);
    n = nts_scene_body_loop(fresh, 0, 0, &l);
    ASSERT_INT_EQ(n, 16);
    for (i = 0; i < n; ++i) a2 += nts_cross(moved[l[i]], moved[l[(i + 1) % n]]);
    ASSERT_NEAR(a2, 2.0, 1e-12); /* twice the area, counter-clockwise */
    CU_ASSERT(l[0] == 0);        /* the same first node, the other way round */
    {
        const int* l0;
        nts_scene_body_loop(s, 0, 0, &l0);
        for (i = 1; i < n; ++i) ASSERT_INT_EQ(l[i], l0[n - i]);
    }
    ASSERT_INT_EQ(update_both(fresh, moved, &err), 0);
    nts_scene_destroy(fresh);
    nts_scene_destroy(s);
}

/* Energy and forces of one evaluation, for comparisons across scenes. */
typedef struct snapshot {
    double energy;
    int contacts;
    nts_vec2 forces[64];
    double penalty[64]; /* of each active contact */
} snapshot;

static snapshot snap(const nts_scene* s) {
    snapshot z;
    nts_options o = nts_default_options();
    nts_context* c = nts_context_create();
    nts_result r;
    nts_error err;
    int i;
    memset(&z, 0, sizeof z);
    o.penalty = 100.0;
    o.search_radius = 0.3;
    o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_scene_node_count(s) <= 64 && r.contact_count <= 64);
    z.energy = r.summary.energy;
    z.contacts = r.contact_count;
    memcpy(z.forces, r.forces, sizeof(nts_vec2) * (size_t)nts_scene_node_count(s));
    for (i = 0; i < r.contact_count; ++i) z.penalty[i] = r.contacts[i].penalty;
    nts_context_destroy(c);
    return z;
}

/* A scene from `pos` (three loop bodies of 24, 20 and 12 nodes, global
 * order), with each body's reference configuration taken from `ref` (NULL:
 * the nodes themselves). */
static nts_scene* three_bodies(const nts_vec2* pos, const nts_vec2* ref, nts_error* err) {
    static const int counts[3] = {24, 20, 12};
    nts_body_def bd[3];
    nts_scene_def def = nts_default_scene_def();
    int b, off = 0;
    memset(bd, 0, sizeof bd);
    for (b = 0; b < 3; ++b) {
        bd[b].nodes = pos + off;
        bd[b].node_count = counts[b];
        bd[b].reference = ref != NULL ? ref + off : NULL;
        off += counts[b];
    }
    def.bodies = bd;
    def.body_count = 3;
    return nts_scene_create(&def, err);
}

/* Sessions must not depend on their history (issue 22 §4). With penalty per
 * length, a scene created anew after NTS_ERESHAPED (a far body mirrored) used
 * to measure every body's tributary lengths at the deformed positions: the
 * same positions gave another energy before and after such a step. Created
 * anew with the first positions as its reference, it gives the same bits. */
static void test_reference_survives_a_rebuild(void) {
    test_body t[3];
    nts_vec2 x0[56], p[56], q[56];
    nts_scene *s, *again, *back, *plain;
    snapshot first, mirrored, returned, remeasured;
    nts_error err;
    int i;
    make_polygon(&t[0], 24, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&t[1], 20, 1.0, nts_v2(1.9, 0.05), 0.1);
    make_polygon(&t[2], 12, 0.5, nts_v2(10.0, 0.0), 0.0);
    for (i = 0; i < 24; ++i) x0[i] = t[0].nodes[i];
    for (i = 0; i < 20; ++i) x0[24 + i] = t[1].nodes[i];
    for (i = 0; i < 12; ++i) x0[44 + i] = t[2].nodes[i];
    /* p: body 0 stretched 1.5 times (its segments change length), body 1
     * pressed into it, body 2 untouched; q: p with body 2 mirrored. */
    for (i = 0; i < 56; ++i) p[i] = x0[i];
    for (i = 0; i < 24; ++i) p[i] = nts_v2(1.5 * x0[i].x, 1.5 * x0[i].y);
    for (i = 24; i < 44; ++i) p[i].x += 0.55;
    for (i = 0; i < 56; ++i) q[i] = p[i];
    for (i = 44; i < 56; ++i) q[i].x = 20.0 - q[i].x;

    s = three_bodies(x0, NULL, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(update_both(s, p, &err), 0);
    first = snap(s);
    CU_ASSERT_FATAL(first.contacts > 0);

    /* The mirrored body needs a new scene; with the first positions as the
     * reference it gives the same bits (body 2 touches nothing). */
    ASSERT_INT_EQ(update_both(s, q, &err), NTS_ERESHAPED);
    ASSERT_INT_EQ(err.body, 2);
    again = three_bodies(q, x0, &err);
    CU_ASSERT_FATAL(again != NULL);
    ASSERT_INT_EQ(nts_scene_loops_reversed(again), 1);
    mirrored = snap(again);
    ASSERT_INT_EQ(mirrored.contacts, first.contacts);
    CU_ASSERT(memcmp(&mirrored.energy, &first.energy, sizeof(double)) == 0);
    CU_ASSERT(memcmp(mirrored.penalty, first.penalty, sizeof first.penalty) == 0);
    CU_ASSERT(memcmp(mirrored.forces, first.forces, 44 * sizeof(nts_vec2)) == 0);

    /* Back to p: body 2 turns over again, a new scene again, the same bits. */
    ASSERT_INT_EQ(update_both(again, p, &err), NTS_ERESHAPED);
    back = three_bodies(p, x0, &err);
    CU_ASSERT_FATAL(back != NULL);
    returned = snap(back);
    ASSERT_INT_EQ(returned.contacts, first.contacts);
    CU_ASSERT(memcmp(&returned.energy, &first.energy, sizeof(double)) == 0);
    CU_ASSERT(memcmp(returned.penalty, first.penalty, sizeof first.penalty) == 0);
    CU_ASSERT(memcmp(returned.forces, first.forces, sizeof first.forces) == 0);

    /* What the reference prevents: measured at p, body 0's tributary lengths
     * are 1.5 times longer, and so is its share of the energy. */
    plain = three_bodies(p, NULL, &err);
    CU_ASSERT_FATAL(plain != NULL);
    remeasured = snap(plain);
    ASSERT_INT_EQ(remeasured.contacts, first.contacts);
    CU_ASSERT(remeasured.energy > 1.05 * first.energy);

    nts_scene_destroy(s);
    nts_scene_destroy(again);
    nts_scene_destroy(back);
    nts_scene_destroy(plain);
}

/* A reference configuration is checked as nodes are, and the error names the
 * body, the node and "reference". */
static void test_reference_errors_name_the_node(void) {
    test_body t[3];
    nts_vec2 x0[56], ref[56];
    nts_error err;
    int i;
    make_polygon(&t[0], 24, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&t[1], 20, 1.0, nts_v2(1.9, 0.05), 0.1);
    make_polygon(&t[2], 12, 0.5, nts_v2(10.0, 0.0), 0.0);
    for (i = 0; i < 24; ++i) x0[i] = t[0].nodes[i];
    for (i = 0; i < 20; ++i) x0[24 + i] = t[1].nodes[i];
    for (i = 0; i < 12; ++i) x0[44 + i] = t[2].nodes[i];
    memcpy(ref, x0, sizeof ref);
    ref[24 + 7].y = NAN;
    CU_ASSERT(three_bodies(x0, ref, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_ENONFINITE);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.node, 7);
    CU_ASSERT(strcmp(err.option, "reference") == 0);
    CU_ASSERT(strstr(err.message, "reference node 7") != NULL);
    ref[24 + 7] = nts_v2(2e100, 0.0);
    CU_ASSERT(three_bodies(x0, ref, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.node, 7);
    CU_ASSERT(strcmp(err.option, "reference") == 0);
    /* Node 3 of body 2 where both its neighbours are: no tributary length. */
    memcpy(ref, x0, sizeof ref);
    ref[44 + 2] = ref[44 + 3];
    ref[44 + 4] = ref[44 + 3];
    CU_ASSERT(three_bodies(x0, ref, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 2);
    ASSERT_INT_EQ(err.node, 3);
    CU_ASSERT(strcmp(err.option, "reference") == 0);
    /* Its neighbours keep half of their other segment: accepted. */
    ref[44 + 4] = x0[44 + 4];
    {
        nts_scene* s = three_bodies(x0, ref, &err);
        CU_ASSERT(s != NULL);
        nts_scene_destroy(s);
    }
}

/* The positions of a packing with one node (or body) of body j moved by
 * `kind` at parameter h: 0 node 1 toward node 2 (the segment's length h
 * times its own: degenerate below 1e-12 of its neighbours), 1 node 3 folded
 * back past node 4 toward node 2's side at an angle h (a zero-angle spike at
 * h = 0), 2 the body flattened to h times its height (zero area, spikes at
 * its ends). */
static void threshold_move(const nts_vec2* x0, nts_vec2* x, int n, int off, int m, int kind, double h) {
    int k;
    memcpy(x, x0, sizeof(nts_vec2) * (size_t)n);
    if (kind == 0) {
        x[off + 1] = nts_add(x0[off + 2], nts_scale(h, nts_sub(x0[off + 1], x0[off + 2])));
    } else if (kind == 1) {
        const nts_vec2 d = nts_sub(x0[off + 4], x0[off + 2]);
        x[off + 3] = nts_add(x0[off + 4], nts_add(nts_scale(0.5, d), nts_scale(h, nts_v2(-d.y, d.x))));
    } else {
        double cy = 0.0;
        for (k = 0; k < m; ++k) cy += x0[off + k].y / m;
        for (k = 0; k < m; ++k) x[off + k].y = cy + h * (x0[off + k].y - cy);
    }
}

/* nts_evaluate_positions checks new positions in the evaluation's segment
 * pass, loop piece by loop piece within each slice: each loop's lengths as
 * the pass computes them (the neighbour before a piece, across a slice's
 * edge or a loop's last entry before its first, computed again), its area
 * summed there when the loop lies within one of the pass's 64 slices and is
 * stored as given, or after the pass otherwise, the degenerate verdicts from
 * the lengths' extremes unless the shortest is below the largest tolerance.
 * At each check's threshold (found by bisection on the update's own verdict,
 * to adjacent doubles) it decides as the update does, with the same error
 * (update_both), for the bodies `bodies` of a packing of `count` 12-node
 * bodies, every other one given clockwise (stored reversed) when `reversed`,
 * all of it moved by `shift` (where the coordinates' resolution, not the
 * neighbours, sets the degenerate tolerance). */
static void thresholds_on(int count, int periodic, int reversed, double shift, const int* bodies, int nb) {
    test_packing p = make_packing(count, 12, 1.0, 2.6, periodic, 31 + (unsigned)periodic);
    nts_scene* s;
    nts_vec2 *x0, *x;
    int n, b, k, jj, kind;
    for (b = 0; b < p.count; ++b)
        for (k = 0; k < p.bodies[b].node_count; ++k) p.bodies[b].nodes[k] = nts_add(p.bodies[b].nodes[k], nts_v2(shift, shift));
    if (reversed)
        for (b = 0; b < p.count; b += 2) /* every other body clockwise */
            for (k = 1; k < p.bodies[b].node_count - k; ++k) {
                const nts_vec2 t = p.bodies[b].nodes[k];
                p.bodies[b].nodes[k] = p.bodies[b].nodes[p.bodies[b].node_count - k];
                p.bodies[b].nodes[p.bodies[b].node_count - k] = t;
            }
    s = make_scene(p.bodies, p.count, p.lx, p.ly);
    CU_ASSERT_FATAL(s != NULL);
    if (reversed) ASSERT_INT_EQ(nts_scene_loops_reversed(s), (count + 1) / 2);
    n = nts_scene_node_count(s);
    x0 = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    x = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    memcpy(x0, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    for (jj = 0; jj < nb; ++jj)
        for (kind = 0; kind < 3; ++kind) {
            const int j = bodies[jj], off = nts_scene_body_node_offset(s, j);
            const int m = nts_scene_body_node_count(s, j);
            double lo = 0.0, hi = 1.0; /* rejected at lo, accepted at hi */
            nts_error err;
            int it, d, rc;
            threshold_move(x0, x, n, off, m, kind, hi);
            ASSERT_INT_EQ(nts_scene_update_positions(s, x, &err), NTS_OK);
            threshold_move(x0, x, n, off, m, kind, lo);
            if (nts_scene_update_positions(s, x, &err) == NTS_OK) {
                /* only where the coordinates' round-off (1e6 times eps)
                 * already turns the folded node off the line: no spike */
                CU_ASSERT(shift != 0.0 && kind == 1);
                continue;
            }
            for (it = 0; it < 200 && nextafter(lo, hi) < hi; ++it) { /* ~100 halvings */
                const double mid = lo + (hi - lo) / 2;
                threshold_move(x0, x, n, off, m, kind, mid);
                if (nts_scene_update_positions(s, x, &err) == NTS_OK) hi = mid;
                else lo = mid;
            }
            CU_ASSERT(nextafter(lo, hi) == hi);
            /* both sides of the threshold, and a few doubles on either side */
            for (d = 0; d < 2; ++d) {
                double h = d == 0 ? lo : hi;
                for (k = 0; k < 3; ++k) {
                    threshold_move(x0, x, n, off, m, kind, h);
                    rc = update_both(s, x, &err);
                    CU_ASSERT(d == 0 ? rc != NTS_OK : rc == NTS_OK);
                    h = d == 0 ? nextafter(h, -1.0) : nextafter(h, 2.0);
                }
            }
            ASSERT_INT_EQ(update_both(s, x0, &err), NTS_OK);
        }
    {
        /* the coordinates' range: the next double past 1e100 out, a NaN and an infinity out */
        nts_error err;
        memcpy(x, x0, sizeof(nts_vec2) * (size_t)n);
        x[n - 1].x = nextafter(1e100, HUGE_VAL);
        ASSERT_INT_EQ(update_both(s, x, &err), NTS_EOUT_OF_RANGE);
        x[n - 1].x = NAN;
        ASSERT_INT_EQ(update_both(s, x, &err), NTS_ENONFINITE);
        x[n - 1].x = -HUGE_VAL;
        ASSERT_INT_EQ(update_both(s, x, &err), NTS_ENONFINITE);
    }
    free(x0);
    free(x);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* 144 bodies (1728 entries, slices of 27): bodies 0, 1 and 143 inside a
 * slice, 2 across one (entries 24-35, the edge at 27: reversed when the
 * even ones are), 7 across one (84-95, the edge at 81, always as given), 37
 * and 90 inside; at the origin and moved by 1e6, open and periodic. */
static void test_fused_checks_at_thresholds(void) {
    static const int bodies[] = {0, 2, 7, 37, 90, 143};
    int periodic, reversed, shifted;
    for (periodic = 0; periodic < 2; ++periodic)
        for (reversed = 0; reversed < 2; ++reversed)
            for (shifted = 0; shifted < 2; ++shifted)
                thresholds_on(144, periodic, reversed, shifted ? 1e6 : 0.0, bodies, 6);
}

/* 1600 bodies (19200 entries, slices of 300): body 21 (entries 252-263)
 * inside a slice (its first node's spike verdict taken at its end), body 24
 * (288-299) at a slice's end, body 25 (300-311) at the next one's start. */
static void test_fused_checks_at_slice_edges(void) {
    static const int bodies[] = {21, 24, 25};
    thresholds_on(1600, 0, 1, 0.0, bodies, 3);
    thresholds_on(1600, 1, 0, 0.0, bodies, 3);
}

/* What stops the evaluation before the positions are judged (an option out
 * of range, a null context) gives what the two calls give, in their order:
 * the positions taken, then the evaluation's error; refused positions the
 * update's error, the scene and the result as they were. */
static void test_fused_stops_before_the_checks(void) {
    test_packing p = make_packing(16, 24, 1.0, 1.9, 0, 5);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* ctx = nts_context_create();
    nts_options opt = nts_default_options();
    nts_result r;
    nts_error err;
    nts_vec2* x;
    int n;
    CU_ASSERT_FATAL(s != NULL && ctx != NULL);
    n = nts_scene_node_count(s);
    x = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    memcpy(x, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    x[3].x += 1e-3;
    opt.penalty = -1.0;
    ASSERT_INT_EQ(nts_evaluate_positions(ctx, s, x, &opt, &r, &err), NTS_EINVALID_OPTION);
    CU_ASSERT(memcmp(nts_scene_positions(s), x, sizeof(nts_vec2) * (size_t)n) == 0); /* taken, as the update takes them */
    x[3].x += 1e-3;
    ASSERT_INT_EQ(nts_evaluate_positions(NULL, s, x, &opt, &r, &err), NTS_EINVALID_ARGUMENT);
    CU_ASSERT(memcmp(nts_scene_positions(s), x, sizeof(nts_vec2) * (size_t)n) == 0);
    opt = nts_default_options();
    ASSERT_INT_EQ(nts_evaluate_positions(ctx, s, x, &opt, &r, &err), NTS_OK);
    {
        const nts_result before = r;
        x[5].y = NAN; /* refused: the update's error, the result as it was */
        opt.penalty = -1.0;
        ASSERT_INT_EQ(nts_evaluate_positions(ctx, s, x, &opt, &r, &err), NTS_ENONFINITE);
        opt = nts_default_options();
        ASSERT_INT_EQ(nts_evaluate_positions(ctx, s, x, &opt, &r, &err), NTS_ENONFINITE);
        ASSERT_INT_EQ(err.node, 5 - nts_scene_body_node_offset(s, err.body));
        CU_ASSERT(memcmp(&before, &r, sizeof r) == 0);
    }
    free(x);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* The coordinates' range where nothing else refuses the positions: a node
 * inside a mesh (on no loop: the segment pass never reads it) given a NaN or
 * a coordinate past 1e100, and a whole body scaled to 1.2e100 (its segments
 * long enough to be neither degenerate nor out of range). The same errors
 * from nts_evaluate_positions as from the update (update_both). */
static void test_fused_range_off_the_loops(void) {
    nts_vec2 pos[ALL_NODES], moved[ALL_NODES];
    int tri[3 * GRID_TRIS], i;
    nts_scene* s;
    nts_error err;
    grid_and_disk(pos, tri);
    s = grid_scene(pos, tri, &err);
    CU_ASSERT_FATAL(s != NULL);
    memcpy(moved, pos, sizeof pos);
    moved[12].y = NAN; /* the grid's centre */
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_ENONFINITE);
    ASSERT_INT_EQ(err.node, 12);
    moved[12].y = -2e100;
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.node, 12);
    memcpy(moved, pos, sizeof pos);
    for (i = GRID_NODES; i < ALL_NODES; ++i) /* the disk, 1.2e100 across */
        moved[i] = nts_v2(2e99 * (pos[i].x - 0.55) + 1e100, 2e99 * (pos[i].y + 0.29));
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(update_both(s, pos, &err), NTS_OK);
    nts_scene_destroy(s);
}

/* The scene's own positions given back (a host passing what
 * nts_scene_positions gave, as the distributed engine does for a rank whose
 * bodies did not move): each call takes them as they are, the same answer
 * (the copy may overlap its source: memmove). */
static void test_own_positions_given_back(void) {
    test_packing p = make_packing(16, 32, 1.0, 1.93, 1, 515u);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    const int n = nts_scene_node_count(s);
    nts_vec2* before = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    nts_vec2* f0 = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    CU_ASSERT_FATAL(s != NULL && c != NULL && before != NULL && f0 != NULL);
    memcpy(before, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    CU_ASSERT_EQUAL_FATAL(nts_evaluate(c, s, &o, &r0, &err), NTS_OK);
    CU_ASSERT(r0.summary.contacts > 0);
    memcpy(f0, r0.forces, sizeof(nts_vec2) * (size_t)n);
    CU_ASSERT_EQUAL(nts_scene_update_positions(s, nts_scene_positions(s), &err), NTS_OK);
    CU_ASSERT_EQUAL(nts_scene_set_positions(s, 3, nts_scene_positions(s) + nts_scene_body_node_offset(s, 3), &err),
                    NTS_OK);
    CU_ASSERT_EQUAL(nts_evaluate_positions(c, s, nts_scene_positions(s), &o, &r1, &err), NTS_OK);
    CU_ASSERT(memcmp(before, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n) == 0);
    CU_ASSERT(memcmp(&r0.summary.energy, &r1.summary.energy, sizeof(double)) == 0);
    CU_ASSERT(memcmp(f0, r1.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    free(before);
    free(f0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    free_packing(&p);
}

void register_update_suite(void) {
    CU_pSuite s = CU_add_suite("update", NULL, NULL);
    ADD_TEST(s, test_random_moves_open);
    ADD_TEST(s, test_random_moves_periodic);
    ADD_TEST(s, test_orientation_kept_or_refused);
    ADD_TEST(s, test_interior_triangle_turned_over);
    ADD_TEST(s, test_mesh_boundary_verdicts);
    ADD_TEST(s, test_reference_survives_a_rebuild);
    ADD_TEST(s, test_reference_errors_name_the_node);
    ADD_TEST(s, test_fused_checks_at_thresholds);
    ADD_TEST(s, test_fused_range_off_the_loops);
    ADD_TEST(s, test_fused_checks_at_slice_edges);
    ADD_TEST(s, test_fused_stops_before_the_checks);
    ADD_TEST(s, test_own_positions_given_back);
}
