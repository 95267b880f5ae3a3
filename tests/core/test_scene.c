/* Scene suite: validation errors name the body, loop and node; orientation is
 * normalised; triangle meshes give their boundary loops. */
#include <string.h>

#include "suites.h"
#include "test_util.h"

static nts_body_def body_of(const nts_vec2* nodes, int n, const int* loop_nodes, const int* loop_start, int loops) {
    nts_body_def b;
    memset(&b, 0, sizeof b);
    b.nodes = nodes;
    b.node_count = n;
    b.loop_nodes = loop_nodes;
    b.loop_start = loop_start;
    b.loop_count = loops;
    return b;
}

static int create_error(const nts_body_def* bodies, int count, nts_error* err) {
    nts_scene_def def = nts_default_scene_def();
    nts_scene* s;
    def.bodies = bodies;
    def.body_count = count;
    s = nts_scene_create(&def, err);
    if (s != NULL) {
        nts_scene_destroy(s);
        return 0;
    }
    return err->code;
}

static const nts_vec2 square[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};

static void test_valid_square(void) {
    nts_body_def b[2];
    nts_vec2 sq2[4];
    nts_error err;
    nts_scene_def def = nts_default_scene_def();
    nts_scene* s;
    int i;
    for (i = 0; i < 4; ++i) sq2[i] = nts_add(square[i], nts_v2(3, 0));
    b[0] = body_of(square, 4, NULL, NULL, 0);
    b[1] = body_of(sq2, 4, NULL, NULL, 0);
    def.bodies = b;
    def.body_count = 2;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_body_count(s), 2);
    ASSERT_INT_EQ(nts_scene_surface_node_count(s), 8);
    ASSERT_INT_EQ(nts_scene_loops_reversed(s), 0);
    ASSERT_INT_EQ(nts_scene_body_node_offset(s, 1), 4);
    nts_scene_destroy(s);
}

static void test_errors_name_the_fault(void) {
    nts_error err;
    nts_body_def b[2];
    nts_vec2 pts[5] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0.5}};
    int two[2] = {0, 1}, two_start[2] = {0, 2};
    int bad_index[4] = {0, 1, 7, 3}, start4[2] = {0, 4};
    int reuse[7] = {0, 1, 2, 3, 0, 1, 2}, reuse_start[3] = {0, 4, 7};
    nts_vec2 nan_pts[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    nts_vec2 dup[4] = {{0, 0}, {1, 0}, {1, 0}, {0, 1}};
    nts_vec2 flat[4] = {{0, 0}, {1, 0}, {2, 0}, {3, 0}};
    /* Node 4 = (0.5, 2): both neighbours lie below it on the same ray. */
    nts_vec2 spike[7] = {{0, 0}, {1, 0}, {1, 1}, {0.5, 1}, {0.5, 2}, {0.5, 1.5}, {0, 1}};

    b[0] = body_of(square, 4, NULL, NULL, 0);

    b[1] = body_of(pts, 5, two, two_start, 1);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ELOOP_TOO_SHORT);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.loop, 0);

    b[1] = body_of(pts, 5, bad_index, start4, 1);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_EINDEX_RANGE);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.loop_pos, 2);

    b[1] = body_of(pts, 5, reuse, reuse_start, 2);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ENODE_REUSED);
    ASSERT_INT_EQ(err.loop, 1);
    ASSERT_INT_EQ(err.node, 0);

    nan_pts[2].y = NAN;
    b[1] = body_of(nan_pts, 4, NULL, NULL, 0);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ENONFINITE);
    ASSERT_INT_EQ(err.node, 2);
    nan_pts[2].y = INFINITY;
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ENONFINITE);

    b[1] = body_of(dup, 4, NULL, NULL, 0);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.node, 1);

    b[1] = body_of(flat, 4, NULL, NULL, 0);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ESPIKE); /* node 3 turns back on itself */

    b[1] = body_of(spike, 7, NULL, NULL, 0);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_ESPIKE);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.node, 4);

    {
        /* Collinear triangle: zero area, without any spike (the turn at each node is
         * 180 or 0 degrees? a, b, c on a line with b between: b is straight, a and c spikes). */
        nts_vec2 zero[3] = {{0, 0}, {1, 1}, {2, 2}};
        b[1] = body_of(zero, 3, NULL, NULL, 0);
        CU_ASSERT(create_error(b, 2, &err) != 0);
    }
    {
        nts_body_def none = body_of(square, 0, NULL, NULL, 0);
        ASSERT_INT_EQ(create_error(&none, 1, &err), NTS_ENO_NODES);
        ASSERT_INT_EQ(create_error(b, 0, &err), NTS_EEMPTY_SCENE);
    }
}

/* loop_start's offsets start at 0 or after and never decrease: a negative
 * first offset was read before loop_nodes' start, a decreasing one gave a
 * loop of negative length. NTS_EINVALID_ARGUMENT naming the body and loop. */
static void test_loop_start_is_checked(void) {
    nts_error err;
    nts_body_def b[2];
    const int nodes[8] = {0, 1, 2, 3, 0, 1, 2, 3};
    const int before[2] = {-4, 4}, falling[3] = {0, 4, 2}, fine[2] = {4, 8};
    b[0] = body_of(square, 4, NULL, NULL, 0);
    b[1] = body_of(square, 4, nodes, before, 1);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_EINVALID_ARGUMENT);
    ASSERT_INT_EQ(err.body, 1);
    CU_ASSERT(strstr(err.message, "loop_start") != NULL);
    b[1] = body_of(square, 4, nodes, falling, 2);
    ASSERT_INT_EQ(create_error(b, 2, &err), NTS_EINVALID_ARGUMENT);
    ASSERT_INT_EQ(err.body, 1);
    ASSERT_INT_EQ(err.loop, 1);
    b[1] = body_of(square, 4, nodes, fine, 1); /* offsets from 4 on: the second copy of the loop */
    ASSERT_INT_EQ(create_error(b, 2, &err), 0);
}

static void test_zero_area_loop(void) {
    /* A bow-tie whose two lobes cancel: no spike, no short segment, zero area. */
    nts_vec2 bow[4] = {{0, 0}, {1, 1}, {1, 0}, {0, 1}};
    nts_body_def b = body_of(bow, 4, NULL, NULL, 0);
    nts_error err;
    ASSERT_INT_EQ(create_error(&b, 1, &err), NTS_EZERO_AREA);
    ASSERT_INT_EQ(err.body, 0);
}

static void test_orientation_normalised(void) {
    /* Outer loop given clockwise, hole given counter-clockwise: both reversed. */
    nts_vec2 pts[8] = {{0, 0}, {0, 4}, {4, 4}, {4, 0}, {1, 1}, {3, 1}, {3, 3}, {1, 3}};
    int loops[8] = {0, 1, 2, 3, 4, 5, 6, 7}, start[3] = {0, 4, 8};
    nts_body_def b = body_of(pts, 8, loops, start, 2);
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    const int* l;
    int n;
    def.bodies = &b;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_loops_reversed(s), 2);
    n = nts_scene_body_loop(s, 0, 0, &l);
    ASSERT_INT_EQ(n, 4);
    /* Reversed keeping the first node: 0, 3, 2, 1 (counter-clockwise). */
    ASSERT_INT_EQ(l[0], 0);
    ASSERT_INT_EQ(l[1], 3);
    ASSERT_INT_EQ(l[3], 1);
    n = nts_scene_body_loop(s, 0, 1, &l);
    ASSERT_INT_EQ(l[1], 7); /* hole now clockwise: 4, 7, 6, 5 */
    nts_scene_destroy(s);
}

static void test_triangle_boundary(void) {
    /* A 3x3-node grid square split into 8 triangles (mixed orientation), with the
     * centre node interior: boundary = the 8 outer nodes, counter-clockwise. */
    nts_vec2 pts[9];
    int tri[8 * 3], t = 0, i, j;
    nts_body_def b;
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    const int* l;
    int n;
    double a2 = 0.0;
    for (j = 0; j < 3; ++j)
        for (i = 0; i < 3; ++i) pts[3 * j + i] = nts_v2(i, j);
    for (j = 0; j < 2; ++j)
        for (i = 0; i < 2; ++i) {
            int v = 3 * j + i;
            tri[3 * t] = v; tri[3 * t + 1] = v + 1; tri[3 * t + 2] = v + 4; ++t;
            tri[3 * t] = v; tri[3 * t + 1] = v + 3; tri[3 * t + 2] = v + 4; ++t; /* clockwise */
        }
    memset(&b, 0, sizeof b);
    b.nodes = pts;
    b.node_count = 9;
    b.triangles = tri;
    b.triangle_count = 8;
    def.bodies = &b;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_body_loop_count(s, 0), 1);
    n = nts_scene_body_loop(s, 0, 0, &l);
    ASSERT_INT_EQ(n, 8);
    for (i = 0; i < n; ++i) {
        CU_ASSERT(l[i] != 4);
        a2 += nts_cross(pts[l[i]], pts[l[(i + 1) % n]]);
    }
    ASSERT_NEAR(a2, 8.0, 1e-12); /* twice the area, positive: counter-clockwise */
    ASSERT_INT_EQ(nts_scene_node_count(s), 9);
    ASSERT_INT_EQ(nts_scene_surface_node_count(s), 8);
    nts_scene_destroy(s);

    /* Non-manifold: a third triangle on edge (0, 4). */
    {
        int tri3[9 * 3];
        nts_vec2 pts10[10];
        memcpy(tri3, tri, sizeof tri);
        memcpy(pts10, pts, sizeof pts);
        pts10[9] = nts_v2(2.0, -1.0);
        tri3[24] = 0; tri3[25] = 4; tri3[26] = 9;
        b.nodes = pts10;
        b.node_count = 10;
        b.triangles = tri3;
        b.triangle_count = 9;
        s = nts_scene_create(&def, &err);
        CU_ASSERT(s == NULL);
        ASSERT_INT_EQ(err.code, NTS_ENONMANIFOLD);
        ASSERT_INT_EQ(err.body, 0);
        ASSERT_INT_EQ(err.triangle, 8);
        CU_ASSERT(strstr(err.message, "edge (0, 4)") != NULL);
        /* A triangle that repeats a node has no edges of its own. */
        tri3[24] = 0; tri3[25] = 1; tri3[26] = 1;
        s = nts_scene_create(&def, &err);
        CU_ASSERT(s == NULL);
        ASSERT_INT_EQ(err.code, NTS_EDEGENERATE_TRIANGLE);
        ASSERT_INT_EQ(err.triangle, 8);
        /* A zero-area sliver on the bottom edge (nodes 0, 1, 2 in a line): the
         * contact model needs the boundary only, and it is sound: 0 -> 2 in
         * one segment, node 1 inside (docs/scenes.md, "Local verdicts"). */
        tri3[24] = 0; tri3[25] = 1; tri3[26] = 2;
        s = nts_scene_create(&def, &err);
        CU_ASSERT_FATAL(s != NULL);
        ASSERT_INT_EQ(nts_scene_body_loop_count(s, 0), 1);
        n = nts_scene_body_loop(s, 0, 0, &l);
        ASSERT_INT_EQ(n, 7);
        a2 = 0.0;
        for (i = 0; i < n; ++i) {
            CU_ASSERT(l[i] != 1 && l[i] != 4 && l[i] != 9);
            a2 += nts_cross(pts10[l[i]], pts10[l[(i + 1) % n]]);
        }
        ASSERT_NEAR(a2, 8.0, 1e-12);
        nts_scene_destroy(s);
        /* Index out of range in a triangle. */
        tri3[24] = 0; tri3[25] = 1; tri3[26] = 12;
        s = nts_scene_create(&def, &err);
        CU_ASSERT(s == NULL);
        ASSERT_INT_EQ(err.code, NTS_EINDEX_RANGE);
        ASSERT_INT_EQ(err.triangle, 8);
        ASSERT_INT_EQ(err.corner, 2);
        ASSERT_INT_EQ(err.loop_pos, -1);
    }
}

/* What stays an error in a mesh, each naming the triangle or node at fault: a
 * mesh that cannot be oriented (a Moebius strip) and a pinched boundary (two
 * triangles on one node only). Positions play no part in either. */
static void test_mesh_topology_errors(void) {
    /* A strip of three quads, top 0 1 2, bottom 3 4 5, closed with a twist. */
    static const int moebius[6 * 3] = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4, 2, 3, 0, 2, 0, 5};
    static const int pinch[2 * 3] = {0, 1, 2, 0, 3, 4};
    nts_vec2 pts[6];
    nts_body_def b;
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    int i;
    for (i = 0; i < 6; ++i) pts[i] = nts_v2(cos(1.0471975511965976 * i), sin(1.0471975511965976 * i));
    memset(&b, 0, sizeof b);
    b.nodes = pts;
    b.node_count = 6;
    b.triangles = moebius;
    b.triangle_count = 6;
    def.bodies = &b;
    def.body_count = 1;
    CU_ASSERT(nts_scene_create(&def, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_ENONMANIFOLD);
    ASSERT_INT_EQ(err.body, 0);
    CU_ASSERT(err.triangle >= 0 && err.triangle < 6);
    CU_ASSERT(strstr(err.message, "not orientable") != NULL);
    /* Two triangles that meet at node 0 only. */
    pts[0] = nts_v2(0, 0);
    pts[1] = nts_v2(1, 0);
    pts[2] = nts_v2(1, 1);
    pts[3] = nts_v2(-1, 0);
    pts[4] = nts_v2(-1, -1);
    b.node_count = 5;
    b.triangles = pinch;
    b.triangle_count = 2;
    CU_ASSERT(nts_scene_create(&def, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_ENONMANIFOLD);
    ASSERT_INT_EQ(err.node, 0);
    ASSERT_INT_EQ(err.triangle, 1);
    CU_ASSERT(strstr(err.message, "pinch point") != NULL);
}

static void test_annulus_mesh_has_two_loops(void) {
    /* A ring of 8 quads (16 triangles) between radius 1 and 2: two loops, outer
     * counter-clockwise and inner clockwise, none reversed by the scene. */
    nts_vec2 pts[16];
    int tri[16 * 3], i, t = 0;
    nts_body_def b;
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    for (i = 0; i < 8; ++i) {
        double th = 6.283185307179586 * i / 8;
        pts[i] = nts_v2(cos(th), sin(th));
        pts[8 + i] = nts_v2(2 * cos(th), 2 * sin(th));
    }
    for (i = 0; i < 8; ++i) {
        int a = i, bb = (i + 1) % 8, c = 8 + (i + 1) % 8, d = 8 + i;
        tri[3 * t] = a; tri[3 * t + 1] = bb; tri[3 * t + 2] = c; ++t;
        tri[3 * t] = a; tri[3 * t + 1] = c; tri[3 * t + 2] = d; ++t;
    }
    memset(&b, 0, sizeof b);
    b.nodes = pts;
    b.node_count = 16;
    b.triangles = tri;
    b.triangle_count = 16;
    def.bodies = &b;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_body_loop_count(s, 0), 2);
    ASSERT_INT_EQ(nts_scene_loops_reversed(s), 0);
    ASSERT_INT_EQ(nts_scene_surface_node_count(s), 16);
    nts_scene_destroy(s);
}

static void test_set_positions_checks_finite(void) {
    nts_body_def b = body_of(square, 4, NULL, NULL, 0);
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    nts_vec2 moved[4] = {{0, 0}, {1, 0}, {1, NAN}, {0, 1}};
    def.bodies = &b;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_set_positions(s, 0, moved, &err), NTS_ENONFINITE);
    ASSERT_INT_EQ(err.node, 2);
    ASSERT_NEAR(nts_scene_positions(s)[2].y, 1.0, 0.0); /* unchanged */
    ASSERT_INT_EQ(nts_scene_set_positions(s, 5, moved, &err), NTS_EINVALID_ARGUMENT);
    nts_scene_destroy(s);
}

/* One rule for a coordinate at every entry point (docs/scenes.md, "Local
 * verdicts"): finite and within +-1e100. nts_scene_set_positions used to check
 * finiteness only, and took 1e101 that creation and updates refuse. */
static void test_set_positions_checks_the_range(void) {
    nts_body_def b = body_of(square, 4, NULL, NULL, 0);
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    nts_vec2 moved[4] = {{0, 0}, {1, 0}, {1, 1}, {-1e101, 1}}, all[4];
    int k;
    def.bodies = &b;
    def.body_count = 1;
    s = nts_scene_create(&def, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_set_positions(s, 0, moved, &err), NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.body, 0);
    ASSERT_INT_EQ(err.node, 3);
    CU_ASSERT(strstr(err.message, "node 3") != NULL);
    ASSERT_NEAR(nts_scene_positions(s)[3].x, 0.0, 0.0); /* unchanged */
    /* The same verdict as the two other entry points. */
    ASSERT_INT_EQ(update_both(s, moved, &err), NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.node, 3);
    b.nodes = moved;
    CU_ASSERT(nts_scene_create(&def, &err) == NULL);
    ASSERT_INT_EQ(err.code, NTS_EOUT_OF_RANGE);
    ASSERT_INT_EQ(err.node, 3);
    /* 1e100 itself is inside the range, for all three. */
    for (k = 0; k < 4; ++k) all[k] = nts_v2(1e100 * square[k].x, 1e100 * square[k].y);
    ASSERT_INT_EQ(nts_scene_set_positions(s, 0, all, &err), 0);
    ASSERT_INT_EQ(update_both(s, all, &err), 0);
    nts_scene_destroy(s);
}

static void test_options_validated(void) {
    nts_options o = nts_default_options();
    nts_error err;
    ASSERT_INT_EQ(nts_options_validate(&o, &err), 0);
    ASSERT_NEAR(o.alpha, 0.2, 0.0);
    o.alpha = 0.6;
    ASSERT_INT_EQ(nts_options_validate(&o, &err), NTS_EINVALID_OPTION);
    CU_ASSERT(strcmp(err.option, "alpha") == 0);
    o = nts_default_options();
    o.penalty = 0.0;
    ASSERT_INT_EQ(nts_options_validate(&o, &err), NTS_EINVALID_OPTION);
    CU_ASSERT(strcmp(err.option, "penalty") == 0);
    o.penalty = NAN;
    ASSERT_INT_EQ(nts_options_validate(&o, &err), NTS_EINVALID_OPTION);
    CU_ASSERT(strcmp(nts_status_name(NTS_EDEGENERATE_SEGMENT), "degenerate_segment") == 0);
    /* The count comes from the table: every status below it has a name. */
    {
        int k;
        for (k = 0; k < NTS_E_COUNT_; ++k) CU_ASSERT(strcmp(nts_status_name(-k), "unknown_error") != 0);
        CU_ASSERT(strcmp(nts_status_name(-NTS_E_COUNT_), "unknown_error") == 0);
        ASSERT_INT_EQ(NTS_E_COUNT_, 1 - NTS_EINVALID_HISTORY); /* the last row of the table */
    }
}

void register_scene_suite(void) {
    CU_pSuite s = CU_add_suite("scene", NULL, NULL);
    ADD_TEST(s, test_valid_square);
    ADD_TEST(s, test_errors_name_the_fault);
    ADD_TEST(s, test_loop_start_is_checked);
    ADD_TEST(s, test_zero_area_loop);
    ADD_TEST(s, test_orientation_normalised);
    ADD_TEST(s, test_triangle_boundary);
    ADD_TEST(s, test_annulus_mesh_has_two_loops);
    ADD_TEST(s, test_mesh_topology_errors);
    ADD_TEST(s, test_set_positions_checks_finite);
    ADD_TEST(s, test_set_positions_checks_the_range);
    ADD_TEST(s, test_options_validated);
}
