/* Reach suite (issue 22 §1): with the default search radius (the median
 * segment) every active contact that a larger radius finds is found, however
 * deep, and whatever bodies lie elsewhere; an explicit radius shorter than a
 * penetration says so. Each scene is evaluated at the default and at a radius
 * of a body's diameter or more: the active contacts must be the same records,
 * bit for bit (the same closest point, found by the same exact tests), the
 * energy, virial and forces the same to round-off (their sums add the deep
 * contacts after the others), and the answer bitwise the same for brute
 * force, cells and any number of threads. */
#include <stdlib.h>
#include <string.h>

#include "nts_support.h"
#include "suites.h"
#include "test_util.h"

static const double PI_ = 3.14159265358979323846;

/* A scene under construction with per-body options. */
typedef struct built {
    ntsx_scene x;
    nts_role role[64];
} built;

static nts_scene* scene_from(const ntsx_scene* x, const nts_role* role) {
    nts_body_def* defs = (nts_body_def*)calloc((size_t)x->body_count, sizeof(nts_body_def));
    nts_scene_def def = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    int i;
    for (i = 0; i < x->body_count; ++i) {
        defs[i].nodes = x->nodes[i];
        defs[i].node_count = x->counts[i];
        defs[i].loop_nodes = x->loop_nodes[i];
        defs[i].loop_start = x->loop_start[i];
        defs[i].loop_count = x->loop_count[i];
        defs[i].has_alpha = x->has_alpha[i];
        defs[i].alpha = x->alpha[i];
        if (role != NULL) defs[i].role = role[i];
    }
    def.bodies = defs;
    def.body_count = x->body_count;
    def.lx = x->lx;
    def.ly = x->ly;
    s = nts_scene_create(&def, &err);
    if (s == NULL) fprintf(stderr, "\n  scene: %s: %s\n", nts_status_name(err.code), err.message);
    free(defs);
    return s;
}

/* Body b of x: a polygon of n nodes, radius r, centre (cx, cy), turned by phase. */
static void put_disk(ntsx_scene* x, int b, int n, double cx, double cy, double r, double phase) {
    int i;
    x->counts[b] = n;
    x->nodes[b] = (nts_vec2*)calloc((size_t)n, sizeof(nts_vec2));
    for (i = 0; i < n; ++i) {
        const double th = phase + 2.0 * PI_ * i / n;
        x->nodes[b][i] = nts_v2(cx + r * cos(th), cy + r * sin(th));
    }
    x->total += n;
}

/* A copy of a result's contacts and forces (the context reuses its buffers). */
typedef struct kept {
    nts_result r;
    nts_contact* contacts;
    nts_vec2* forces;
} kept;

static int eval_keep(const nts_scene* s, const nts_options* o, kept* k) {
    nts_context* c = nts_context_create();
    nts_error err;
    const int n = nts_scene_node_count(s);
    int rc = nts_evaluate(c, s, o, &k->r, &err);
    if (rc != NTS_OK) fprintf(stderr, "\n  evaluate: %s: %s\n", nts_status_name(err.code), err.message);
    k->contacts = NULL;
    k->forces = NULL;
    if (rc == NTS_OK) {
        k->contacts = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(k->r.contact_count + 1));
        k->forces = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
        if (k->r.contact_count > 0) memcpy(k->contacts, k->r.contacts, sizeof(nts_contact) * (size_t)k->r.contact_count);
        if (k->r.forces != NULL) memcpy(k->forces, k->r.forces, sizeof(nts_vec2) * (size_t)n);
        k->r.contacts = k->contacts;
        k->r.forces = k->forces;
        k->r.warnings = NULL; /* the context's, gone with it: warning_count stays */
    }
    nts_context_destroy(c);
    return rc;
}

static void kept_free(kept* k) {
    free(k->contacts);
    free(k->forces);
}

static int bitwise_same(const nts_scene* s, const kept* a, const kept* b) {
    const size_t n = (size_t)nts_scene_node_count(s);
    return memcmp(&a->r.summary, &b->r.summary, sizeof a->r.summary) == 0 &&
           a->r.contact_count == b->r.contact_count &&
           memcmp(a->contacts, b->contacts, sizeof(nts_contact) * (size_t)a->r.contact_count) == 0 &&
           memcmp(a->forces, b->forces, sizeof(nts_vec2) * n) == 0;
}

/* The default against an explicit radius R at least as deep as any
 * penetration: the same active contacts, bitwise; sums to round-off; no
 * warning; at least `min_deep` contacts deeper than the default radius (the
 * scene exercises the growth). Then the default again by brute force and
 * with 2 and 3 threads: bitwise the same. Returns the default's deep count. */
static int check_default_finds_all(const nts_scene* s, double alpha, double penalty, double R, int min_deep,
                                   const char* what) {
    nts_options o = nts_default_options();
    kept d, big, other;
    int i, n = nts_scene_node_count(s), deep = 0, th;
    double fscale = 0.0;
    o.alpha = alpha;
    o.penalty = penalty;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(eval_keep(s, &o, &d) == NTS_OK);
    o.search_radius = R;
    CU_ASSERT_FATAL(eval_keep(s, &o, &big) == NTS_OK);
    deep = d.r.summary.deep_contacts;
    if (d.r.contact_count != big.r.contact_count || deep < min_deep)
        fprintf(stderr, "\n  %s: default %d contacts (%d deep, r = %g), radius %g: %d contacts\n", what,
                d.r.contact_count, deep, d.r.summary.search_radius, R, big.r.contact_count);
    ASSERT_INT_EQ(d.r.contact_count, big.r.contact_count);
    CU_ASSERT(d.r.contact_count > 0);
    CU_ASSERT(deep >= min_deep);
    ASSERT_INT_EQ(d.r.warning_count, 0);
    ASSERT_INT_EQ(big.r.warning_count, 0);
    if (d.r.contact_count == big.r.contact_count)
        CU_ASSERT(memcmp(d.contacts, big.contacts, sizeof(nts_contact) * (size_t)d.r.contact_count) == 0);
    ASSERT_NEAR(d.r.summary.energy, big.r.summary.energy, 1e-12 * big.r.summary.energy);
    ASSERT_NEAR(d.r.summary.virial.xx, big.r.summary.virial.xx, 1e-12 * fabs(big.r.summary.virial.xx) + 1e-300);
    ASSERT_NEAR(d.r.summary.virial.yy, big.r.summary.virial.yy, 1e-12 * fabs(big.r.summary.virial.yy) + 1e-300);
    CU_ASSERT(d.r.summary.max_penetration == big.r.summary.max_penetration);
    for (i = 0; i < n; ++i) fscale = fmax(fscale, fabs(big.forces[i].x) + fabs(big.forces[i].y));
    for (i = 0; i < n; ++i) {
        if (fabs(d.forces[i].x - big.forces[i].x) > 1e-12 * fscale ||
            fabs(d.forces[i].y - big.forces[i].y) > 1e-12 * fscale) {
            fprintf(stderr, "\n  %s: node %d force differs\n", what, i);
            CU_FAIL("force differs");
            break;
        }
    }
    /* Brute force and threads: the same bits. */
    o.search_radius = -1.0;
    o.search = NTS_SEARCH_BRUTE_FORCE;
    if (nts_scene_surface_node_count(s) <= 40000) {
        CU_ASSERT_FATAL(eval_keep(s, &o, &other) == NTS_OK);
        other.r.summary.cell_size = d.r.summary.cell_size;
        CU_ASSERT(bitwise_same(s, &d, &other));
        kept_free(&other);
    }
    o.search = NTS_SEARCH_CELLS;
    for (th = 2; th <= 3; ++th) {
        o.threads = th;
        CU_ASSERT_FATAL(eval_keep(s, &o, &other) == NTS_OK);
        if (!bitwise_same(s, &d, &other)) fprintf(stderr, "\n  %s: %d threads differ\n", what, th);
        CU_ASSERT(bitwise_same(s, &d, &other));
        kept_free(&other);
        /* Without records (the threads' force shares, the direct path). */
        o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
        CU_ASSERT_FATAL(eval_keep(s, &o, &other) == NTS_OK);
        CU_ASSERT(memcmp(&d.r.summary, &other.r.summary, sizeof d.r.summary) == 0);
        CU_ASSERT(memcmp(d.forces, other.forces, sizeof(nts_vec2) * (size_t)n) == 0);
        kept_free(&other);
        o.outputs |= NTS_OUT_CONTACTS;
    }
    o.threads = 0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    CU_ASSERT_FATAL(eval_keep(s, &o, &other) == NTS_OK);
    CU_ASSERT(memcmp(&d.r.summary, &other.r.summary, sizeof d.r.summary) == 0);
    CU_ASSERT(memcmp(d.forces, other.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    kept_free(&other);
    kept_free(&d);
    kept_free(&big);
    return deep;
}

/* The issue's packing: 400 disks of 32 to 64 nodes, radius 1 +- 1%, on a
 * periodic lattice of spacing 1.9, centres jittered +- 0.04; penalty 10,
 * alpha 0.2. The default radius (0.1265) dropped 7.6% of the contacts and
 * 25% of the energy, the deepest ones. */
static void test_issue_packing(void) {
    ntsx_scene x;
    ntsx_packing_def d = ntsx_default_packing(400, 1, 7);
    nts_scene* s;
    d.radius = 1.0;
    d.radius_jitter = 0.02;
    d.spacing = 1.9;
    d.centre_jitter = 0.08;
    ntsx_packing(&x, &d);
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 2.0, 200, "400 disks");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* The benchmark's own packing (2,000 particles, about 1e5 nodes): 1.8% of
 * the contacts and 11% of the energy were missing at the default. */
static void test_benchmark_packing(void) {
    ntsx_scene x;
    ntsx_packing_def d = ntsx_default_packing(2000, 1, 1);
    nts_scene* s;
    ntsx_packing(&x, &d);
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 1.0, 2.1, 100, "benchmark packing");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* Two unit disks overlapping by 0.1, alone and with 36 small grains 10
 * units away: the grains pull the median segment down to 0.0096, and every
 * contact was lost (E = 0). A verdict must not depend on bodies far away. */
static void test_far_grains(void) {
    ntsx_scene two, all;
    nts_options o = nts_default_options();
    kept a, b;
    nts_scene *s2, *s38;
    int g, i;
    ntsx_two_disks(&two, 64, 0.1, 0.5);
    ntsx_scene_init(&all, 38);
    for (i = 0; i < 2; ++i) {
        all.counts[i] = two.counts[i];
        all.nodes[i] = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)two.counts[i]);
        memcpy(all.nodes[i], two.nodes[i], sizeof(nts_vec2) * (size_t)two.counts[i]);
        all.total += two.counts[i];
    }
    for (g = 0; g < 36; ++g) put_disk(&all, 2 + g, 8, 12.0 + 0.05 * (g % 6), 0.05 * (g / 6), 0.0125, 0.0);
    s2 = scene_from(&two, NULL);
    s38 = scene_from(&all, NULL);
    CU_ASSERT_FATAL(s2 != NULL && s38 != NULL);
    check_default_finds_all(s2, 0.2, 100.0, 2.0, 1, "two disks");
    check_default_finds_all(s38, 0.2, 100.0, 2.0, 1, "two disks and grains");
    o.penalty = 100.0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(eval_keep(s2, &o, &a) == NTS_OK && eval_keep(s38, &o, &b) == NTS_OK);
    CU_ASSERT(a.r.summary.search_radius > 5.0 * b.r.summary.search_radius); /* the grains do shrink r */
    ASSERT_INT_EQ(b.r.contact_count, a.r.contact_count);
    CU_ASSERT(a.r.contact_count >= 6);
    if (a.r.contact_count == b.r.contact_count)
        CU_ASSERT(memcmp(a.contacts, b.contacts, sizeof(nts_contact) * (size_t)a.r.contact_count) == 0);
    ASSERT_NEAR(b.r.summary.energy, a.r.summary.energy, 1e-13 * a.r.summary.energy);
    kept_free(&a);
    kept_free(&b);
    nts_scene_destroy(s2);
    nts_scene_destroy(s38);
    ntsx_scene_free(&two);
    ntsx_scene_free(&all);
}

/* Random packings with overlaps up to 20% of the radius, open and periodic,
 * alpha 0, 0.2 and 0.5, some bodies with their own alpha. */
static void test_random_packings(void) {
    static const double alphas[3] = {0.0, 0.2, 0.5};
    int seed, deep = 0;
    for (seed = 0; seed < 12; ++seed) {
        ntsx_scene x;
        ntsx_packing_def d = ntsx_default_packing(49 + 13 * (seed % 4), seed % 2, 100 + (uint64_t)seed);
        nts_scene* s;
        int b;
        d.radius = 1.0;
        d.spacing = 2.0 - 0.2 * (0.5 + 0.5 * (seed % 3) / 2.0); /* overlaps 0.1 to 0.2 */
        d.centre_jitter = 0.1;
        d.nodes_min = 16;
        d.nodes_max = 72;
        ntsx_packing(&x, &d);
        for (b = 0; b < x.body_count; b += 5) {
            x.has_alpha[b] = 1;
            x.alpha[b] = alphas[(seed + b) % 3];
        }
        s = scene_from(&x, NULL);
        CU_ASSERT_FATAL(s != NULL);
        deep += check_default_finds_all(s, alphas[seed % 3], 3.0, 2.5, 0, "random packing");
        nts_scene_destroy(s);
        ntsx_scene_free(&x);
    }
    CU_ASSERT(deep > 100);
}

/* Slaves next to segments longer than 2 r: a square of 4 nodes whose corner
 * is 0.3 deep in a fine disk (its segments 40 times the median one, so no
 * node of the square is within r of the disk), and a disk pressed 0.35 into
 * a wall of four long segments (an obstacle). */
static void test_long_segments(void) {
    ntsx_scene x;
    nts_role roles[2] = {NTS_ROLE_BOTH, NTS_ROLE_BOTH};
    nts_scene* s;
    ntsx_scene_init(&x, 2);
    put_disk(&x, 0, 256, 0.0, 0.0, 1.0, 0.0);
    put_disk(&x, 1, 4, 1.7, 0.0, 1.0, 0.0); /* its corner at (0.7, 0) */
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 2.0, 2, "square corner in a disk");
    check_default_finds_all(s, 0.0, 10.0, 2.0, 2, "square corner in a disk, alpha 0");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);

    ntsx_scene_init(&x, 2);
    put_disk(&x, 0, 48, 0.0, 0.65, 1.0, 0.1);
    x.counts[1] = 4;
    x.nodes[1] = (nts_vec2*)calloc(4, sizeof(nts_vec2));
    x.nodes[1][0] = nts_v2(-20.0, -3.0);
    x.nodes[1][1] = nts_v2(20.0, -3.0);
    x.nodes[1][2] = nts_v2(20.0, 0.0);
    x.nodes[1][3] = nts_v2(-20.0, 0.0);
    x.total += 4;
    roles[1] = NTS_ROLE_MASTER;
    s = scene_from(&x, roles);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 4.0, 2, "disk in a wall");
    nts_scene_destroy(s);
    roles[1] = NTS_ROLE_BOTH; /* the wall's corners are slaves too, far from everything */
    s = scene_from(&x, roles);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 4.0, 2, "disk in a wall of both roles");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* Chains across the ends of chunks (1,024 slaves) and of a loop: a body of
 * 3,000 nodes (its entries span three chunks) pressed 0.3 deep by small
 * disks where its loop starts and where the chunks meet. */
static void test_chunk_and_loop_ends(void) {
    static const int at[4] = {0, 1024, 1536, 2048};
    ntsx_scene x;
    nts_scene* s;
    int k;
    ntsx_scene_init(&x, 5);
    put_disk(&x, 0, 3000, 0.0, 0.0, 10.0, 0.0);
    for (k = 0; k < 4; ++k) {
        const double th = 2.0 * PI_ * at[k] / 3000.0;
        put_disk(&x, 1 + k, 120, 10.7 * cos(th), 10.7 * sin(th), 1.0, 0.01);
    }
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 3.0, 40, "chunk and loop ends");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* A single node deeper than r whose neighbours are both within r of the
 * master (a spike's tip: its segments 1.8 r, not long), where both of its
 * neighbour pairs cross an end: the tip is its loop's first entry (its
 * previous neighbour is the loop's last) and the last slave of the first
 * chunk (its next is the next chunk's first). Only the comparison across
 * those ends (reach.c: edges) can ask for it. */
static void test_single_node_across_both_ends(void) {
    const double r = 0.02; /* the median segment: the box's and the far disk's */
    ntsx_scene x;
    nts_scene* s;
    int i, n;
    ntsx_scene_init(&x, 3);
    put_disk(&x, 0, 1023, 20.0, 20.0, 1023 * r / (2.0 * PI_), 0.0); /* entries 0..1022, far away */
    x.counts[1] = 5;                                                   /* the spike: entries 1023.. */
    x.nodes[1] = (nts_vec2*)calloc(5, sizeof(nts_vec2));
    x.nodes[1][0] = nts_v2(0.0, -1.5 * r); /* the tip, 1.5 r deep in the box */
    x.nodes[1][1] = nts_v2(0.5 * r, 0.2 * r);
    x.nodes[1][2] = nts_v2(0.5 * r, 0.5);
    x.nodes[1][3] = nts_v2(-0.5 * r, 0.5);
    x.nodes[1][4] = nts_v2(-0.5 * r, 0.2 * r);
    x.total += 5;
    n = (int)(4.0 / r + 0.5); /* the box [-2, 2] x [-1, 0], every side cut into segments of r */
    x.counts[2] = 2 * n + 2 * (n / 4);
    x.nodes[2] = (nts_vec2*)calloc((size_t)x.counts[2], sizeof(nts_vec2));
    for (i = 0; i < n; ++i) x.nodes[2][i] = nts_v2(-2.0 + r * i, -1.0);
    for (i = 0; i < n / 4; ++i) x.nodes[2][n + i] = nts_v2(2.0, -1.0 + r * i);
    for (i = 0; i < n; ++i) x.nodes[2][n + n / 4 + i] = nts_v2(2.0 - r * i, 0.0);
    for (i = 0; i < n / 4; ++i) x.nodes[2][2 * n + n / 4 + i] = nts_v2(-2.0, -r * i);
    x.total += x.counts[2];
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 2.0, 1, "a spike's tip across both ends");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* A periodic box, a disk across its edge pressed deep into another across
 * the corner. */
static void test_periodic_edge(void) {
    ntsx_scene x;
    nts_scene* s;
    ntsx_scene_init(&x, 2);
    put_disk(&x, 0, 64, 0.2, 0.1, 1.0, 0.0);
    put_disk(&x, 1, 64, 9.2, 9.0, 1.0, 0.3); /* 1.49 from the first across the corner */
    x.lx = x.ly = 10.0;
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.2, 10.0, 2.0, 4, "periodic edge");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* In a periodic box no search reaches past half its side (an image could be
 * nearer): a square nearly as large as the box, and a needle from the gap
 * between its images to its centre, 1.48 deep where half the box less the
 * longest segment is 1.45. The nodes there are counted as a warning
 * (penetration_beyond_reach); the search out to that limit from a node
 * outside every body finds nothing and says nothing. */
static void test_periodic_reach_limit(void) {
    const double h = 0.05, lo = 0.02, hi = 2.98;
    ntsx_scene x;
    nts_scene* s;
    nts_options o = nts_default_options();
    nts_context* c = nts_context_create();
    nts_result r;
    nts_error err;
    int i, n = (int)((hi - lo) / h + 0.5), m = (int)(1.5 / h + 0.5);
    ntsx_scene_init(&x, 2);
    x.counts[0] = 4 * n;
    x.nodes[0] = (nts_vec2*)calloc((size_t)(4 * n), sizeof(nts_vec2));
    for (i = 0; i < n; ++i) {
        const double t = lo + (hi - lo) * i / n;
        x.nodes[0][i] = nts_v2(t, lo);
        x.nodes[0][n + i] = nts_v2(hi, t);
        x.nodes[0][2 * n + i] = nts_v2(hi + lo - t, hi);
        x.nodes[0][3 * n + i] = nts_v2(lo, hi + lo - t);
    }
    x.total += 4 * n;
    x.counts[1] = 2 * m + 2; /* a needle along y = 1.5 from x = 0 to x = 1.5, 0.02 wide */
    x.nodes[1] = (nts_vec2*)calloc((size_t)(2 * m + 2), sizeof(nts_vec2));
    for (i = 0; i <= m; ++i) {
        x.nodes[1][i] = nts_v2(h * i, 1.49);
        x.nodes[1][2 * m + 1 - i] = nts_v2(h * i, 1.51);
    }
    x.total += 2 * m + 2;
    x.lx = x.ly = 3.0;
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL && c != NULL);
    o.penalty = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == NTS_OK);
    CU_ASSERT(r.summary.deep_contacts > 20);
    CU_ASSERT_FATAL(r.warning_count == 1);
    ASSERT_INT_EQ(r.warnings[0].code, NTS_WARN_PENETRATION_BEYOND_REACH);
    CU_ASSERT(r.warnings[0].count >= 2 && r.warnings[0].count <= 8);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* An explicit radius shorter than a penetration: the contacts deeper than it
 * are left out (the model's rule), and the result says how many. */
static void test_explicit_radius_warns(void) {
    ntsx_scene x;
    ntsx_packing_def d = ntsx_default_packing(400, 1, 7);
    nts_options o = nts_default_options();
    nts_scene* s;
    kept def, small;
    nts_context* c = nts_context_create();
    nts_result r;
    nts_error err;
    d.radius = 1.0;
    d.radius_jitter = 0.02;
    d.spacing = 1.9;
    d.centre_jitter = 0.08;
    ntsx_packing(&x, &d);
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL && c != NULL);
    o.penalty = 10.0;
    o.outputs = NTS_OUT_ENERGY | NTS_OUT_CONTACTS | NTS_OUT_FORCES;
    CU_ASSERT_FATAL(eval_keep(s, &o, &def) == NTS_OK);
    o.search_radius = 0.1;
    CU_ASSERT_FATAL(eval_keep(s, &o, &small) == NTS_OK);
    ASSERT_INT_EQ(small.r.summary.deep_contacts, 0);
    CU_ASSERT(small.r.summary.max_penetration <= 0.1);
    ASSERT_INT_EQ(small.r.warning_count, 1);
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == NTS_OK);
    CU_ASSERT_FATAL(r.warning_count == 1 && r.warnings != NULL);
    ASSERT_INT_EQ(r.warnings[0].code, NTS_WARN_PENETRATION_BEYOND_RADIUS);
    /* Every contact deeper than 0.1 that the default finds, counted. */
    {
        long long deeper = 0;
        int i;
        for (i = 0; i < def.r.contact_count; ++i) deeper += -def.contacts[i].gap > 0.1;
        ASSERT_INT_EQ(r.warnings[0].count, deeper);
        ASSERT_INT_EQ(small.r.contact_count + deeper, def.r.contact_count);
        CU_ASSERT(deeper > 100);
    }
    CU_ASSERT(strcmp(nts_warning_name(NTS_WARN_PENETRATION_BEYOND_RADIUS), "penetration_beyond_radius") == 0);
    CU_ASSERT(strcmp(nts_warning_name(NTS_WARN_PENETRATION_BEYOND_REACH), "penetration_beyond_reach") == 0);
    CU_ASSERT(strlen(nts_warning_message(NTS_WARN_PENETRATION_BEYOND_RADIUS)) > 20);
    /* A radius as deep as everything: nothing to say. */
    o.search_radius = 0.5;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == NTS_OK);
    ASSERT_INT_EQ(r.warning_count, 0);
    CU_ASSERT(r.warnings == NULL);
    nts_context_destroy(c);
    kept_free(&def);
    kept_free(&small);
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* Adversarial (h-adv): in a periodic box a chain of deep slaves is cut
 * where it passes a node deeper than the box allows (half the box less the
 * longest segment): the nodes past it, within reach, are lost too, and the
 * warning counts only the nodes that were out of reach. A disk of radius 2.9
 * (segments 0.15) fills a box of 6: at its centre it is 2.9 deep, the reach
 * 2.85. A needle (segments 0.05 = r) enters it from the left, passes the
 * centre and ends 1.4 short of its right side: only its nodes within 0.05 of
 * the centre lie beyond reach, but every contact past them is missing at the
 * default, though a radius of 2.8 finds them all. */
static void test_periodic_chain_past_the_reach(void) {
    ntsx_scene x;
    nts_role roles[2] = {NTS_ROLE_MASTER, NTS_ROLE_SLAVE};
    nts_options o = nts_default_options();
    nts_scene* s;
    kept d, big;
    int i, k, found = 0, beyond = 0, n = 90;
    ntsx_scene_init(&x, 2);
    put_disk(&x, 0, 122, 3.0, 3.0, 2.9, 0.0);
    x.counts[1] = 2 * (n + 1);
    x.nodes[1] = (nts_vec2*)calloc((size_t)x.counts[1], sizeof(nts_vec2));
    for (i = 0; i <= n; ++i) {
        x.nodes[1][i] = nts_v2(0.0 + 0.05 * i, 2.98);
        x.nodes[1][2 * (n + 1) - 1 - i] = nts_v2(0.0 + 0.05 * i, 3.02);
    }
    x.total += x.counts[1];
    x.lx = x.ly = 6.0;
    s = scene_from(&x, roles);
    CU_ASSERT_FATAL(s != NULL);
    o.penalty = 10.0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(eval_keep(s, &o, &d) == NTS_OK);
    o.search_radius = 2.8;
    CU_ASSERT_FATAL(eval_keep(s, &o, &big) == NTS_OK);
    /* Every contact the radius 2.8 finds, the default finds, the same bits. */
    for (i = 0; i < big.r.contact_count; ++i) {
        for (k = 0; k < d.r.contact_count; ++k)
            if (d.contacts[k].slave_node == big.contacts[i].slave_node) break;
        if (k < d.r.contact_count && memcmp(&d.contacts[k], &big.contacts[i], sizeof(nts_contact)) == 0) ++found;
    }
    for (i = 0; i < d.r.contact_count; ++i) beyond += -d.contacts[i].gap > 2.8; /* out of the radius's reach */
    if (found != big.r.contact_count)
        fprintf(stderr, "\n  chain past the reach: the default finds %d of the %d contacts of radius 2.8 (%d warning)\n",
                found, big.r.contact_count, d.r.warning_count);
    ASSERT_INT_EQ(found, big.r.contact_count);
    CU_ASSERT(big.r.contact_count > 100);
    ASSERT_INT_EQ(d.r.contact_count, big.r.contact_count + beyond);
    kept_free(&d);
    kept_free(&big);
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* Adversarial (h-adv): an allocation refused inside a widened search leaves
 * the worker's body slots set (search.c: offer marks slot[body]; reach.c:
 * coarse and search_pair return on w->status without nts_search_wide_done),
 * and nts_workers_prepare does not clear them: the next evaluation on the
 * same context offers into stale slots and loses closest points. A square's
 * corner (its sides 3 long, far longer than 2 r) has 17 thin sectors around
 * it, their apexes 0.1 away: its coarse search finds 17 bodies, one more than
 * a worker's first room (16) and more than any slave of the search itself,
 * so the room grows there. Each allocation of the evaluation is refused in
 * turn; after a refusal the same context must give the reference answer. */
static long fa_calls, fa_fail_at, fa_failed;
static void* fa_alloc(size_t size, void* user) {
    (void)user;
    if (++fa_calls == fa_fail_at) {
        ++fa_failed;
        return NULL;
    }
    return malloc(size);
}
static void fa_free(void* p, void* user) {
    (void)user;
    free(p);
}

static void test_refused_allocation_in_a_wide_search(void) {
    const int sectors = 17, arc = 8, side = 40;
    ntsx_scene x;
    nts_scene* s;
    nts_options o = nts_default_options();
    kept ref;
    long n;
    int k, i, retried = 0, differ = 0;
    ntsx_scene_init(&x, 1 + sectors);
    x.counts[0] = 4;
    x.nodes[0] = (nts_vec2*)calloc(4, sizeof(nts_vec2));
    x.nodes[0][0] = nts_v2(0.0, 0.0);
    x.nodes[0][1] = nts_v2(3.0, 0.0);
    x.nodes[0][2] = nts_v2(3.0, 3.0);
    x.nodes[0][3] = nts_v2(0.0, 3.0);
    x.total += 4;
    for (k = 0; k < sectors; ++k) {
        const double th = (100.0 + 15.0 * k) * PI_ / 180.0, half = 6.0 * PI_ / 180.0;
        const nts_vec2 a = nts_v2(0.1 * cos(th), 0.1 * sin(th));
        nts_vec2* p;
        int m = 0;
        x.counts[1 + k] = 2 * side + arc - 1;
        p = x.nodes[1 + k] = (nts_vec2*)calloc((size_t)x.counts[1 + k], sizeof(nts_vec2));
        for (i = 0; i < side; ++i) /* apex out along th - half */
            p[m++] = nts_v2(a.x + 2.0 * i / side * cos(th - half), a.y + 2.0 * i / side * sin(th - half));
        for (i = 0; i < arc; ++i) {
            const double t = th - half + 2.0 * half * i / arc;
            p[m++] = nts_v2(a.x + 2.0 * cos(t), a.y + 2.0 * sin(t));
        }
        for (i = side; i > 1; --i) /* back along th + half */
            p[m++] = nts_v2(a.x + 2.0 * i / side * cos(th + half), a.y + 2.0 * i / side * sin(th + half));
        x.total += m;
        x.counts[1 + k] = m;
    }
    s = scene_from(&x, NULL);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(eval_keep(s, &o, &ref) == NTS_OK);
    CU_ASSERT(ref.r.contact_count == 0); /* nothing touches: gaps only */
    o.outputs |= NTS_OUT_GAPS;
    for (n = 1; n < 100000; ++n) {
        nts_context* c = nts_context_create();
        nts_result r1, r2;
        nts_error err;
        int rc, gaps_ref;
        CU_ASSERT_FATAL(c != NULL);
        /* the reference's gaps */
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r1, &err) == NTS_OK);
        gaps_ref = r1.gap_count;
        nts_context_destroy(c);
        c = nts_context_create();
        fa_calls = fa_failed = 0;
        fa_fail_at = n;
        nts_set_allocator(fa_alloc, fa_free, NULL);
        rc = nts_evaluate(c, s, &o, &r1, &err);
        fa_fail_at = 0;
        if (rc == NTS_OK && fa_failed == 0) {
            nts_set_allocator(NULL, NULL, NULL);
            nts_context_destroy(c);
            break;
        }
        if (rc != NTS_OK) {
            ++retried;
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r2, &err) == NTS_OK);
            if (r2.gap_count != gaps_ref) {
                if (differ == 0)
                    fprintf(stderr, "\n  allocation %ld refused: the retry has %d closest points, the reference %d\n", n,
                            r2.gap_count, gaps_ref);
                ++differ;
            }
        }
        nts_set_allocator(NULL, NULL, NULL);
        nts_context_destroy(c);
    }
    CU_ASSERT(retried > 10);
    ASSERT_INT_EQ(differ, 0);
    kept_free(&ref);
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* Adversarial (h-adv): in a periodic box the polygon test of a slave that no
 * search out to the reach finds anything for (reach.c: inside_body) walks
 * the body from the image of its first node nearest to the slave; when the
 * body spans more than half the box, that image need not be the one around
 * the slave. A disk of radius 2.95 (first node on its left, x = 0.05) nearly
 * fills a box of 6: a node just right of its centre lies more than 3 from
 * that node, whose nearest image is then the one on the right, and the test
 * says outside: the node is not counted (penetration_beyond_reach) and the
 * chain of deep nodes stops there, losing every contact past it. */
static void test_periodic_inside_test_of_a_large_body(void) {
    ntsx_scene x;
    nts_role roles[2] = {NTS_ROLE_MASTER, NTS_ROLE_SLAVE};
    nts_options o = nts_default_options();
    nts_scene* s;
    kept d, big;
    nts_context* c = nts_context_create();
    nts_result res;
    nts_error err;
    int i, k, found = 0, n = 90, beyond = 0;
    ntsx_scene_init(&x, 2);
    put_disk(&x, 0, 122, 3.0, 3.0, 2.95, PI_);
    x.counts[1] = 2 * (n + 1);
    x.nodes[1] = (nts_vec2*)calloc((size_t)x.counts[1], sizeof(nts_vec2));
    for (i = 0; i <= n; ++i) {
        x.nodes[1][i] = nts_v2(0.025 + 0.05 * i, 2.98);
        x.nodes[1][2 * (n + 1) - 1 - i] = nts_v2(0.025 + 0.05 * i, 3.02);
    }
    x.total += x.counts[1];
    x.lx = x.ly = 6.0;
    s = scene_from(&x, roles);
    CU_ASSERT_FATAL(s != NULL && c != NULL);
    o.penalty = 10.0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(eval_keep(s, &o, &d) == NTS_OK);
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &res, &err) == NTS_OK);
    o.search_radius = 2.8;
    CU_ASSERT_FATAL(eval_keep(s, &o, &big) == NTS_OK);
    for (i = 0; i < big.r.contact_count; ++i) {
        for (k = 0; k < d.r.contact_count; ++k)
            if (d.contacts[k].slave_node == big.contacts[i].slave_node) break;
        if (k < d.r.contact_count && memcmp(&d.contacts[k], &big.contacts[i], sizeof(nts_contact)) == 0) ++found;
    }
    /* the needle's nodes beyond the reach (3 - 0.152 = 2.848): within 0.1 of the
     * centre (2.874 deep and more; the next ones, 2.824) */
    for (i = 0; i < 2 * (n + 1); ++i) beyond += fabs(x.nodes[1][i].x - 3.0) < 0.1;
    if (found != big.r.contact_count)
        fprintf(stderr, "\n  large body: the default finds %d of the %d contacts of radius 2.8\n", found,
                big.r.contact_count);
    ASSERT_INT_EQ(found, big.r.contact_count);
    CU_ASSERT(big.r.contact_count > 100);
    CU_ASSERT_FATAL(res.warning_count == 1);
    ASSERT_INT_EQ(res.warnings[0].code, NTS_WARN_PENETRATION_BEYOND_REACH);
    ASSERT_INT_EQ(res.warnings[0].count, beyond);
    nts_context_destroy(c);
    kept_free(&d);
    kept_free(&big);
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

/* A hole of the closest point (docs/model.md §4.5, "known limit"): a box
 * (an obstacle) whose bottom is cut into segments of 0.02 and whose right
 * side is one segment of 1, smoothed at alpha 0.45, so the corner at (1, 0)
 * between a short and a long segment is uneven (its curve runs 0.45 up the
 * side and 0.009 along the bottom); a needle (a slave body) along y = 0.3
 * from x = 0.498, inside, to 1.198, outside, crosses the side. Its node at
 * x = 0.998 is 0.0018 inside the corner curve, and its neighbour at
 * x = 0.988 lies beyond the corner's evolute, where (§4.3's zone fails) its
 * closest point is not the nearest point of the curve but the bottom, 0.3
 * deep: the neighbour is asked for within |g| + |X_k - X_i| = 0.0118, finds
 * nothing there, and is found only because the widened search doubles its
 * radius while it finds nothing (reach.c: search_pair). It guards the
 * doubling (without it, 2 of 102 contacts). */
static void test_hole_found_by_doubling(void) {
    ntsx_scene x;
    nts_role roles[2] = {NTS_ROLE_MASTER, NTS_ROLE_SLAVE};
    nts_scene* s;
    int i, m = 0;
    ntsx_scene_init(&x, 2);
    x.nodes[0] = (nts_vec2*)calloc(53, sizeof(nts_vec2));
    for (i = 0; i < 50; ++i) x.nodes[0][m++] = nts_v2(0.02 * i, 0.0);
    x.nodes[0][m++] = nts_v2(1.0, 0.0);
    x.nodes[0][m++] = nts_v2(1.0, 1.0);
    x.nodes[0][m++] = nts_v2(0.0, 1.0);
    x.counts[0] = m;
    x.total += m;
    x.counts[1] = 2 * 71;
    x.nodes[1] = (nts_vec2*)calloc((size_t)x.counts[1], sizeof(nts_vec2));
    for (i = 0; i <= 70; ++i) {
        x.nodes[1][i] = nts_v2(0.498 + 0.01 * i, 0.3);
        x.nodes[1][2 * 71 - 1 - i] = nts_v2(0.498 + 0.01 * i, 0.31);
    }
    x.total += x.counts[1];
    s = scene_from(&x, roles);
    CU_ASSERT_FATAL(s != NULL);
    check_default_finds_all(s, 0.45, 10.0, 3.0, 90, "a hole found by doubling");
    nts_scene_destroy(s);
    ntsx_scene_free(&x);
}

void register_reach_suite(void) {
    CU_pSuite s = CU_add_suite("reach", NULL, NULL);
    ADD_TEST(s, test_issue_packing);
    ADD_TEST(s, test_benchmark_packing);
    ADD_TEST(s, test_far_grains);
    ADD_TEST(s, test_random_packings);
    ADD_TEST(s, test_long_segments);
    ADD_TEST(s, test_chunk_and_loop_ends);
    ADD_TEST(s, test_single_node_across_both_ends);
    ADD_TEST(s, test_periodic_edge);
    ADD_TEST(s, test_periodic_reach_limit);
    ADD_TEST(s, test_explicit_radius_warns);
    ADD_TEST(s, test_periodic_chain_past_the_reach);
    ADD_TEST(s, test_refused_allocation_in_a_wide_search);
    ADD_TEST(s, test_periodic_inside_test_of_a_large_body);
    ADD_TEST(s, test_hole_found_by_doubling);
}
