/* Shared helpers of the core tests: typed asserts that print both values,
 * scene builders (polygons, jittered packings) and a deterministic RNG. */
#ifndef NTS_TEST_UTIL_H
#define NTS_TEST_UTIL_H

#include <CUnit/CUnit.h>
#include <math.h>
#include <stdio.h>

#include <ntscontact/ntscontact.h>

/* Like CU_ASSERT_DOUBLE_EQUAL, but prints the values and where. */
#define ASSERT_NEAR(actual, expected, tol)                                                              \
    do {                                                                                                \
        double a_ = (actual), e_ = (expected), t_ = (tol);                                              \
        int ok_ = fabs(a_ - e_) <= t_;                                                                  \
        if (!ok_) fprintf(stderr, "\n  %s:%d: %s = %.17g, expected %.17g (tol %.3g, diff %.3g)\n", __FILE__, \
                          __LINE__, #actual, a_, e_, t_, fabs(a_ - e_));                                \
        CU_ASSERT(ok_);                                                                                 \
    } while (0)

#define ASSERT_INT_EQ(actual, expected)                                                                  \
    do {                                                                                                 \
        long long a_ = (actual), e_ = (expected);                                                        \
        if (a_ != e_) fprintf(stderr, "\n  %s:%d: %s = %lld, expected %lld\n", __FILE__, __LINE__, #actual, a_, e_); \
        CU_ASSERT(a_ == e_);                                                                             \
    } while (0)

#define ADD_TEST(suite, fn) CU_add_test(suite, #fn, fn)

/* xorshift64*: deterministic across platforms. */
typedef struct test_rng { unsigned long long s; } test_rng;
double rng_uniform(test_rng* r); /* [0, 1) */

/* A body under construction (owns its arrays). */
typedef struct test_body {
    nts_vec2 nodes[4096];
    int node_count;
    int loop_nodes[4096];
    int loop_start[9];
    int loop_count;
} test_body;

/* Regular polygon (counter-clockwise) of n nodes, radius r, centre c, phase. */
void make_polygon(test_body* b, int n, double r, nts_vec2 c, double phase);
/* Scene from test bodies (loops as given, or implicit when loop_count == 0). */
nts_scene* make_scene(const test_body* bodies, int count, double lx, double ly);

/* A jittered packing of `count` deformable disks with `nodes` nodes each, on a
 * square lattice of spacing `spacing`, radius jittered so neighbours overlap. */
typedef struct test_packing {
    test_body* bodies;
    int count;
    double lx, ly; /* 0 unless periodic */
} test_packing;
test_packing make_packing(int count, int nodes, double radius, double spacing, int periodic, unsigned long long seed);
void free_packing(test_packing* p);

/* Evaluate and return a copy of the forces (caller frees) and the result. */
int eval_scene(const nts_scene* s, const nts_options* opt, nts_result* res, nts_context** ctx_out);

/* Total energy for finite differences. */
double scene_energy(const nts_scene* s, const nts_options* opt);

/* Whether two results of scene s hold bitwise the same answer: forces,
 * pressure, gaps, contacts, the tangent's triplets, friction's anchors (an
 * output not asked for is a null pointer on both sides), and the summary:
 * whole with NTST_SUMMARY_WHOLE, else all but cell_size (a search by cells
 * and a brute-force one answer alike but start from different cells). */
enum { NTST_SUMMARY_WHOLE = 1, NTST_SUMMARY_BUT_CELLS = 0 };
int same_answer(const nts_scene* s, const nts_result* a, const nts_result* b, int summary);

/* nts_scene_update_positions(s, pos, err), checked against
 * nts_evaluate_positions on the same positions from the same scene: the same
 * status, the same error record, the same positions taken (or kept), and when
 * taken an answer equal bit for bit to nts_evaluate's after the update. */
int update_both(nts_scene* s, const nts_vec2* pos, nts_error* err);

#endif
