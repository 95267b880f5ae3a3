/* What the tests and the benchmarks share (one copy each): the scenes they
 * build (jittered packings of deformable disks, two pressed disks, disks in a
 * container of long walls) and the long-double reference of a corner's
 * closest point. Not part of the library: a tool for checking it. Failures to
 * allocate end the process (these are test and benchmark programs). */
#ifndef NTS_SUPPORT_H
#define NTS_SUPPORT_H

#include <stdint.h>

#include <ntscontact/ntscontact.h>

/* ------------------------------------------------------------- timing */

/* Monotonic wall clock, seconds. */
double ntsx_now(void);
/* The median of v[0..n) (v is sorted; the mean of the middle two when n is even; 0 when empty). */
double ntsx_median(double* v, int n);
/* The least and the largest of v[0..n), n >= 1 (v unchanged). */
void ntsx_range(const double* v, int n, double* lo, double* hi);

/* ------------------------------------------------------------- scenes */

/* splitmix64, uniform in [0, 1): the same sequence on every platform. */
double ntsx_urand(uint64_t* state);
/* The directions of a solver loop's motion (kept_bench, nts_cross loop,
 * nts_bench's kept step): per body a unit direction, and per node a fifth as
 * much along its own (|u_i| <= 1.2), drawn from `seed`; counts[b] nodes a
 * body, dir gets every node's in body order. */
void ntsx_motion_directions(const int* counts, int body_count, uint64_t seed, nts_vec2* dir);

/* A scene under construction: per body its nodes and, optionally, explicit
 * loops and its own alpha; the circle a disk approximates (cx, cy, R). */
typedef struct ntsx_scene {
    int body_count;
    int* counts;         /* nodes per body */
    nts_vec2** nodes;
    int** loop_nodes;    /* NULL: one implicit loop */
    int** loop_start;
    int* loop_count;
    int* has_alpha;
    double* alpha;
    double *cx, *cy, *R;
    double lx, ly;       /* the periodic box, 0: open */
    int total;           /* nodes of all bodies */
    int self_contact;    /* every body meets its own surface too (0 after ntsx_scene_init) */
} ntsx_scene;

void ntsx_scene_init(ntsx_scene* s, int bodies);
void ntsx_scene_free(ntsx_scene* s);
/* The library's scene of it, or NULL with *err filled. */
nts_scene* ntsx_scene_create(const ntsx_scene* s, nts_error* err);

/* A jittered packing: particles on a square lattice of `spacing`, centres
 * moved by up to centre_jitter/2 on each axis, radii radius +- radius_jitter/2,
 * nodes_min..nodes_max nodes at angles jittered by angle_jitter/2 steps and
 * radii by node_jitter/2 (relative); a random phase per particle. Periodic:
 * the box is the lattice. The same seed gives the same scene everywhere
 * (splitmix64). */
typedef struct ntsx_packing_def {
    int particles;
    int nodes_min, nodes_max;
    double spacing, radius;
    double centre_jitter, radius_jitter, angle_jitter, node_jitter;
    int periodic;
    uint64_t seed;
} ntsx_packing_def;
/* The benchmark packing: spacing 2, radius 1.02 +- 0.03 (neighbours overlap),
 * centres +- 0.05, 32..64 nodes, angles +- 0.15 step, radii +- 0.5%. */
ntsx_packing_def ntsx_default_packing(int particles, int periodic, uint64_t seed);
void ntsx_packing(ntsx_scene* s, const ntsx_packing_def* def);

/* Two disks of radius 1 and n nodes, centres 2 - overlap apart; the second
 * disk's nodes are turned by `phase` steps. */
void ntsx_two_disks(ntsx_scene* s, int n, double overlap, double phase);

/* side x side disks of radius 1 and disk_nodes nodes (pitch 1.98: neighbours
 * 0.02 into each other, the outer ones 0.01 into the walls) in a square
 * container (body 0): an outer square 2 units out and an inner square hole
 * whose sides are cut into `pieces` collinear segments each. `sharp`: the
 * container keeps alpha = 0 (its own), whatever the options say. */
void ntsx_container(ntsx_scene* s, int side, int pieces, int disk_nodes, int sharp);

/* ---------------------------------------------- long-double reference */

typedef long double ntsx_ld;
typedef struct ntsx_lvec {
    ntsx_ld x, y;
} ntsx_lvec;

/* The corner of nts_corner_make in long double, from the same double inputs
 * (a = X2 - X3, c = X4 - X3, d = Xs - X3): A, B and e = d - A. */
typedef struct ntsx_corner {
    ntsx_lvec A, B, e;
} ntsx_corner;
ntsx_corner ntsx_corner_make(nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d);
/* F(xi) = (e - xi (B + xi A)) . (B + 2 xi A): zero at a closest point. */
ntsx_ld ntsx_corner_F(const ntsx_corner* k, ntsx_ld xi);
/* Every root of F in [-1, 1]: [-1, 1] cut at the critical points of F into
 * monotone pieces, every sign change bisected to the last bit; with no sign
 * change, the better endpoint. Returns how many (1 to 3). */
int ntsx_corner_roots(const ntsx_corner* k, ntsx_ld roots[3]);
/* The root nearest to the slave (the first of equals). */
ntsx_ld ntsx_corner_nearest(const ntsx_corner* k, const ntsx_ld* roots, int count);
/* The nearest root of the corner, and how many roots it has. */
ntsx_ld ntsx_corner_xi(nts_vec2 a, nts_vec2 c, double alpha, nts_vec2 d, int* roots);

#endif
