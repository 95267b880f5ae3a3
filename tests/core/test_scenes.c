/* Scenes as users build them (issue 12): per-body alpha and roles, penalty per
 * length, long walls in the cell list (against brute force, bitwise), local
 * tolerances, the supported range from 1e-300 to 1e300, meshes in several
 * pieces, and the tie rule of two equally near corner roots. */
#define _POSIX_C_SOURCE 199309L /* nanosleep */
#include <float.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "suites.h"
#include "nts_support.h"
#include "test_util.h"

/* A body definition over a test body, with loops when it has them. */
static nts_body_def def_of(const test_body* b) {
    nts_body_def d;
    memset(&d, 0, sizeof d);
    d.nodes = b->nodes;
    d.node_count = b->node_count;
    if (b->loop_count > 0) {
        d.loop_nodes = b->loop_nodes;
        d.loop_start = b->loop_start;
        d.loop_count = b->loop_count;
    }
    return d;
}

static nts_scene* scene_of(const nts_body_def* defs, int count, double lx, double ly, nts_error* err) {
    nts_scene_def def = nts_default_scene_def();
    def.bodies = defs;
    def.body_count = count;
    def.lx = lx;
    def.ly = ly;
    return nts_scene_create(&def, err);
}

/* A square container wall: outer square [lo - w, hi + w]^2 counter-clockwise,
 * the inner square [lo, hi]^2 a clockwise hole: 8 nodes, 8 long segments. */
static void make_container(test_body* b, double lo, double hi, double w) {
    nts_vec2 pts[8] = {{lo - w, lo - w}, {hi + w, lo - w}, {hi + w, hi + w}, {lo - w, hi + w},
                       {lo, lo},         {lo, hi},         {hi, hi},         {hi, lo}};
    int i;
    memset(b, 0, sizeof *b);
    memcpy(b->nodes, pts, sizeof pts);
    b->node_count = 8;
    for (i = 0; i < 8; ++i) b->loop_nodes[i] = i;
    b->loop_start[0] = 0;
    b->loop_start[1] = 4;
    b->loop_start[2] = 8;
    b->loop_count = 2;
}

/* Disks in a container of long walls: the cell list (long masters listed in
 * every cell their reach box overlaps) gives brute force's result, bitwise. */
static void check_container(double alpha, double radius, int threads) {
    enum { SIDE = 6 };
    ntsx_scene b;
    nts_scene* s;
    nts_context *cc = nts_context_create(), *cb = nts_context_create();
    nts_options o = nts_default_options();
    nts_result rc, rb;
    nts_error err;
    int i;
    /* The scene of scenes_bench (support/scenes.c): every outer disk 0.01 into its walls. */
    ntsx_container(&b, SIDE, 1, 24, 0);
    s = ntsx_scene_create(&b, &err);
    ntsx_scene_free(&b);
    CU_ASSERT_FATAL(s != NULL);
    o.alpha = alpha;
    o.search_radius = radius;
    o.threads = threads;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(cc, s, &o, &rc, &err) == 0);
    /* The cell side follows the disks' segments, not the 12-unit walls. */
    CU_ASSERT(rc.summary.cell_size < 1.0);
    o.search = NTS_SEARCH_BRUTE_FORCE;
    CU_ASSERT_FATAL(nts_evaluate(cb, s, &o, &rb, &err) == 0);
    CU_ASSERT(rc.contact_count > 40);
    {
        int walls = 0;
        for (i = 0; i < rc.contact_count; ++i) walls += rc.contacts[i].master_body == 0;
        /* The disks along the walls touch them (at alpha = 0.5 the 12-unit
         * walls are rounded into one curve: fewer contacts, by the model). */
        CU_ASSERT(walls >= (alpha <= 0.2 ? 4 * SIDE : 1));
    }
    CU_ASSERT(same_answer(s, &rc, &rb, NTST_SUMMARY_BUT_CELLS));
    nts_context_destroy(cc);
    nts_context_destroy(cb);
    nts_scene_destroy(s);
}

static void test_long_walls_equal_brute_force(void) {
    check_container(0.0, -1.0, 0);
    check_container(0.2, -1.0, 0);
    check_container(0.5, 0.05, 0);
    check_container(0.2, -1.0, 3);
}

/* A long bar in a periodic box, across its edge, with disks on it. */
static void test_long_bar_periodic_equals_brute_force(void) {
    test_body b[9];
    nts_body_def defs[9];
    nts_scene* s;
    nts_context *cc = nts_context_create(), *cb = nts_context_create();
    nts_options o = nts_default_options();
    nts_result rc, rb;
    nts_error err;
    int i;
    memset(&b[0], 0, sizeof b[0]);
    b[0].nodes[0] = nts_v2(30.0, 1.0);
    b[0].nodes[1] = nts_v2(46.0, 1.0); /* beyond the box edge at 40 */
    b[0].nodes[2] = nts_v2(46.0, 2.0);
    b[0].nodes[3] = nts_v2(30.0, 2.0);
    b[0].node_count = 4;
    defs[0] = def_of(&b[0]);
    defs[0].has_alpha = 1; /* a sharp bar: the disks over its ends touch it too */
    defs[0].alpha = 0.0;
    for (i = 1; i < 9; ++i) {
        make_polygon(&b[i], 20, 1.0, nts_v2(fmod(28.5 + 2.0 * i, 40.0), 2.98), 0.3 * i);
        defs[i] = def_of(&b[i]);
    }
    s = scene_of(defs, 9, 40.0, 40.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(cc, s, &o, &rc, &err) == 0);
    CU_ASSERT(rc.summary.cell_size < 8.0); /* the 16-unit bar does not set it */
    o.search = NTS_SEARCH_BRUTE_FORCE;
    CU_ASSERT_FATAL(nts_evaluate(cb, s, &o, &rb, &err) == 0);
    if (rc.contact_count < 8) fprintf(stderr, "\n  bar contacts %d\n", rc.contact_count);
    CU_ASSERT(rc.contact_count >= 8);
    CU_ASSERT(same_answer(s, &rc, &rb, NTST_SUMMARY_BUT_CELLS));
    nts_context_destroy(cc);
    nts_context_destroy(cb);
    nts_scene_destroy(s);
}

/* The default search radius is the median segment: one long wall does not change it. */
static void test_default_radius_is_the_median_segment(void) {
    test_body b[3];
    nts_body_def defs[3];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    double seg = 2.0 * sin(3.14159265358979323846 / 32.0);
    make_polygon(&b[0], 32, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&b[1], 32, 1.0, nts_v2(1.98, 0.0), 0.0);
    make_container(&b[2], -1.5, 100.0, 1.0);
    defs[0] = def_of(&b[0]);
    defs[1] = def_of(&b[1]);
    s = scene_of(defs, 2, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    ASSERT_NEAR(r.summary.search_radius, seg, 1e-12);
    nts_scene_destroy(s);
    defs[2] = def_of(&b[2]);
    s = scene_of(defs, 3, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    ASSERT_NEAR(r.summary.search_radius, seg, 1e-12);
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

/* On a scene large enough that the median is bracketed by a sample of the
 * lengths (more than 4 x 4096 segments), the default radius is still the
 * median exactly: with lengths spread at random (the bracket holds it) and
 * with the sampled entries' segments three times the others' (the bracket
 * misses, and every length is selected). */
static int cmp_double(const void* a, const void* b) {
    const double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

static void test_default_radius_is_the_median_of_many(void) {
    enum { BODIES = 6, NODES = 3000, N = BODIES * NODES, SAMPLE = 4096 };
    const double pi = 3.14159265358979323846;
    static test_body b[BODIES];
    static double len[N];
    static unsigned char sampled[N];
    nts_body_def defs[BODIES];
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    test_rng rng = {12345u};
    int pass, i, k;
    for (i = 0; i < SAMPLE; ++i) sampled[(long long)i * N / SAMPLE] = 1; /* the library's stride */
    for (pass = 0; pass < 2; ++pass) {
        nts_scene* s;
        nts_result r;
        nts_error err;
        for (i = 0; i < BODIES; ++i) {
            /* Angles from cumulative weights: a segment's length grows with its weight. */
            double w[NODES], total = 0.0, th = 0.0;
            const nts_vec2 centre = nts_v2(300.0 * i, 0.0);
            memset(&b[i], 0, sizeof b[i]);
            for (k = 0; k < NODES; ++k) {
                w[k] = pass == 0 ? 0.5 + rng_uniform(&rng) : (sampled[i * NODES + k] ? 3.0 : 1.0);
                total += w[k];
            }
            for (k = 0; k < NODES; ++k) {
                b[i].nodes[k] = nts_v2(centre.x + 100.0 * cos(th), centre.y + 100.0 * sin(th));
                th += 2.0 * pi * w[k] / total;
            }
            b[i].node_count = NODES;
            defs[i] = def_of(&b[i]);
            for (k = 0; k < NODES; ++k) { /* as the library computes it: X_{k+1} - X_k */
                const nts_vec2 d = nts_sub(b[i].nodes[(k + 1) % NODES], b[i].nodes[k]);
                len[i * NODES + k] = sqrt(d.x * d.x + d.y * d.y);
            }
        }
        s = scene_of(defs, BODIES, 0.0, 0.0, &err);
        CU_ASSERT_FATAL(s != NULL);
        ASSERT_INT_EQ(nts_scene_surface_node_count(s), N);
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        qsort(len, N, sizeof(double), cmp_double);
        ASSERT_NEAR(r.summary.search_radius, len[(N - 1) / 2], 0.0);
        if (pass == 1) CU_ASSERT(len[(N - 1) / 2] < 0.5 * len[N - 1]); /* the short ones, not the sampled */
        nts_scene_destroy(s);
    }
    nts_context_destroy(c);
}

/* The median of many lengths that are equal, or nearly: rectangles walked
 * in steps of 1 or 2, so the sample's bracket holds whole runs of equal
 * lengths, or is a single value when every step is 1; in the last pass the
 * nodes are moved along their side by up to 1e-6, so thousands of distinct
 * lengths share the bracket's first bin. The default radius is still the
 * median, with any number of threads. */
static void test_median_of_equal_lengths(void) {
    enum { BODIES = 12, SIDE = 600, MAXN = 4 * SIDE, PASSES = 4 };
    static test_body b[BODIES];
    static double len[BODIES * MAXN];
    const double ones[PASSES] = {1.0, 0.5, 0.7, 0.6};
    nts_body_def defs[BODIES];
    nts_context* c = nts_context_create();
    test_rng rng = {777u};
    int pass, i;
    for (pass = 0; pass < PASSES; ++pass) {
        const double jitter = pass == PASSES - 1 ? 1e-6 : 0.0;
        nts_scene* s;
        nts_error err;
        int n = 0, threads, k;
        for (i = 0; i < BODIES; ++i) {
            /* Corners, counter-clockwise; each side in steps of 1 or 2. */
            const double x0 = 700.0 * (i % 4), y0 = 700.0 * (i / 4);
            const double cx[4] = {x0, x0 + SIDE, x0 + SIDE, x0}, cy[4] = {y0, y0, y0 + SIDE, y0 + SIDE};
            int side;
            memset(&b[i], 0, sizeof b[i]);
            for (side = 0; side < 4; ++side) {
                const double dx = (cx[(side + 1) % 4] - cx[side]) / SIDE, dy = (cy[(side + 1) % 4] - cy[side]) / SIDE;
                int at = 0;
                while (at < SIDE) {
                    const double along = at + (at > 0 ? jitter * rng_uniform(&rng) : 0.0);
                    int step = rng_uniform(&rng) < ones[pass] ? 1 : 2;
                    if (at + step > SIDE) step = 1;
                    b[i].nodes[b[i].node_count++] = nts_v2(cx[side] + dx * along, cy[side] + dy * along);
                    at += step;
                }
            }
            defs[i] = def_of(&b[i]);
            for (k = 0; k < b[i].node_count; ++k) { /* as the library computes it: X_{k+1} - X_k */
                const nts_vec2 d = nts_sub(b[i].nodes[(k + 1) % b[i].node_count], b[i].nodes[k]);
                len[n++] = sqrt(d.x * d.x + d.y * d.y);
            }
        }
        s = scene_of(defs, BODIES, 0.0, 0.0, &err);
        CU_ASSERT_FATAL(s != NULL);
        ASSERT_INT_EQ(nts_scene_surface_node_count(s), n);
        CU_ASSERT_FATAL(n > 4 * 4096); /* large enough for the sample's bracket */
        qsort(len, (size_t)n, sizeof(double), cmp_double);
        for (threads = 1; threads <= 3; ++threads) {
            nts_options o = nts_default_options();
            nts_result r;
            o.threads = threads;
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
            ASSERT_NEAR(r.summary.search_radius, len[(n - 1) / 2], 0.0);
        }
        if (pass == 0) ASSERT_NEAR(len[0], len[n - 1], 0.0); /* one value */
        if (pass == PASSES - 1) { /* the median near 1, among thousands of distinct lengths */
            int distinct = 1;
            for (k = 1; k < n; ++k) distinct += len[k] > len[k - 1];
            CU_ASSERT(len[(n - 1) / 2] < 1.5 && distinct > 5000);
        }
        nts_scene_destroy(s);
    }
    nts_context_destroy(c);
}

/* A disk resting in a container's corner, 0.02 into both walls. With the
 * scene's alpha = 0.2 the 12-unit walls' inner corner is rounded over 2.4
 * units: a spurious deep contact. The container's own alpha = 0 keeps its
 * corner sharp: every gap is the real penetration. */
static void test_body_alpha_keeps_a_container_sharp(void) {
    test_body b[2];
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    double worst_rounded = 0.0, worst_sharp = 0.0;
    int i, pass;
    make_container(&b[0], 0.0, 12.0, 1.0);
    make_polygon(&b[1], 64, 1.0, nts_v2(0.98, 0.98), 0.0);
    for (pass = 0; pass < 2; ++pass) {
        defs[0] = def_of(&b[0]);
        defs[1] = def_of(&b[1]);
        if (pass == 1) {
            defs[0].has_alpha = 1;
            defs[0].alpha = 0.0;
        }
        s = scene_of(defs, 2, 0.0, 0.0, &err);
        CU_ASSERT_FATAL(s != NULL);
        o.search_radius = 0.5;
        o.outputs = NTS_OUT_CONTACTS;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        for (i = 0; i < r.contact_count; ++i) {
            if (r.contacts[i].master_body != 0) continue;
            if (pass == 0 && r.contacts[i].gap < worst_rounded) worst_rounded = r.contacts[i].gap;
            if (pass == 1 && r.contacts[i].gap < worst_sharp) worst_sharp = r.contacts[i].gap;
            if (pass == 1) CU_ASSERT(r.contacts[i].kind != NTS_KIND_CORNER);
        }
        nts_scene_destroy(s);
    }
    CU_ASSERT(worst_rounded < -0.3);                 /* the spurious contact */
    CU_ASSERT(worst_sharp >= -0.02 - 1e-3);          /* only the real 0.02 penetration */
    CU_ASSERT(worst_sharp < -0.01);
    nts_context_destroy(c);
}

/* Roles: a master floor's nodes are never slaves, two masters never interact,
 * a slave-only body offers no surface; reactions on a master are returned. */
static void test_roles(void) {
    test_body b[4];
    nts_body_def defs[4];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    nts_vec2 total = {0.0, 0.0};
    double floor_force = 0.0;
    int i, n;
    make_container(&b[0], 0.0, 10.0, 1.0);                     /* master: a box around everything */
    make_polygon(&b[1], 40, 1.0, nts_v2(5.0, 0.98), 0.0);     /* both: rests on the floor */
    make_polygon(&b[2], 40, 1.0, nts_v2(6.9, 0.98), 0.05);    /* slave: presses into body 1 */
    make_container(&b[3], 0.1, 9.9, 0.05);                    /* master, overlapping body 0 */
    for (i = 0; i < 4; ++i) defs[i] = def_of(&b[i]);
    defs[0].role = NTS_ROLE_MASTER;
    defs[3].role = NTS_ROLE_MASTER;
    defs[2].role = NTS_ROLE_SLAVE;
    s = scene_of(defs, 4, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_ALL;
    o.search_radius = 0.2;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    CU_ASSERT(r.contact_count > 0);
    for (i = 0; i < r.gap_count; ++i) {
        const nts_contact* k = &r.gaps[i];
        CU_ASSERT(k->slave_body != 0 && k->slave_body != 3); /* masters' nodes are never slaves */
        CU_ASSERT(k->master_body != 2);                      /* the slave body offers no surface */
    }
    {
        int slave_on_1 = 0, on_floor = 0;
        for (i = 0; i < r.contact_count; ++i) {
            slave_on_1 += r.contacts[i].slave_body == 2 && r.contacts[i].master_body == 1;
            on_floor += r.contacts[i].slave_body == 1 && r.contacts[i].master_body == 0;
        }
        CU_ASSERT(slave_on_1 > 0);
        CU_ASSERT(on_floor > 0);
    }
    /* The reaction on the master floor, and the balance of all forces. */
    for (n = 0; n < nts_scene_node_count(s); ++n) total = nts_add(total, r.forces[n]);
    for (n = 0; n < 8; ++n) floor_force += nts_length(r.forces[nts_scene_body_node_offset(s, 0) + n]);
    CU_ASSERT(floor_force > 0.0);
    ASSERT_NEAR(total.x, 0.0, 1e-12);
    ASSERT_NEAR(total.y, 0.0, 1e-12);
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

/* Penalty per length: each contact's eps is eps times the slave's tributary
 * length at creation, the forces are still minus the energy's gradient, and
 * after moves the tributary lengths stay those of the reference. */
static void test_penalty_per_length(void) {
    test_body b[2];
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int i;
    double e0, h = 1e-7;
    make_polygon(&b[0], 48, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&b[1], 16, 1.0, nts_v2(1.95, 0.0), 0.1); /* coarser: different tributary lengths */
    defs[0] = def_of(&b[0]);
    defs[1] = def_of(&b[1]);
    s = scene_of(defs, 2, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    o.penalty = 50.0;
    o.alpha = 0.2;
    o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
    o.outputs = NTS_OUT_ALL;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(r.contact_count > 0);
    for (i = 0; i < r.contact_count; ++i) {
        const nts_contact* k = &r.contacts[i];
        const int nb = k->slave_body == 0 ? 48 : 16;
        ASSERT_NEAR(k->penalty, 50.0 * 2.0 * sin(3.14159265358979323846 / nb), 1e-12);
    }
    /* Forces are -dE/dx: central differences of the energy at one slave node. */
    e0 = r.summary.energy;
    {
        int node = r.contacts[0].slave_node, body = r.contacts[0].slave_body, off, axis;
        off = nts_scene_body_node_offset(s, body);
        for (axis = 0; axis < 2; ++axis) {
            nts_vec2 f = r.forces[off + node], p = b[body].nodes[node];
            double ep, em, d;
            b[body].nodes[node] = axis ? nts_v2(p.x, p.y + h) : nts_v2(p.x + h, p.y);
            CU_ASSERT_FATAL(nts_scene_set_positions(s, body, b[body].nodes, &err) == 0);
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
            ep = r.summary.energy;
            b[body].nodes[node] = axis ? nts_v2(p.x, p.y - h) : nts_v2(p.x - h, p.y);
            CU_ASSERT_FATAL(nts_scene_set_positions(s, body, b[body].nodes, &err) == 0);
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
            em = r.summary.energy;
            b[body].nodes[node] = p;
            CU_ASSERT_FATAL(nts_scene_set_positions(s, body, b[body].nodes, &err) == 0);
            d = -(ep - em) / (2.0 * h);
            ASSERT_NEAR(axis ? f.y : f.x, d, 1e-6 * (fabs(d) + 1.0));
        }
    }
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    ASSERT_NEAR(r.summary.energy, e0, 0.0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

/* Length tolerances are local: a body flung to 1e12 changes no verdict on the
 * others, and a degenerate segment is blamed on its own body. */
static void test_tolerances_are_local(void) {
    test_body b[3];
    nts_body_def defs[3];
    nts_scene* s;
    nts_error err;
    int i;
    memset(&b[0], 0, sizeof b[0]);
    for (i = 0; i < 4; ++i) b[0].nodes[i] = nts_v2((i == 1 || i == 2) ? 0.0488 : 0.0, i >= 2 ? 0.0488 : 0.0);
    b[0].node_count = 4; /* a small floor tile */
    make_polygon(&b[1], 16, 1.0, nts_v2(1e12, 1e12), 0.0);
    make_polygon(&b[2], 16, 1.0, nts_v2(3.0, 0.0), 0.0);
    for (i = 0; i < 3; ++i) defs[i] = def_of(&b[i]);
    s = scene_of(defs, 3, 0.0, 0.0, &err);
    CU_ASSERT(s != NULL);
    nts_scene_destroy(s);
    /* Now body 2 has a doubled node: the error names body 2. */
    b[2].nodes[5] = nts_v2(b[2].nodes[4].x + 1e-14, b[2].nodes[4].y);
    defs[2] = def_of(&b[2]);
    s = scene_of(defs, 3, 0.0, 0.0, &err);
    CU_ASSERT(s == NULL);
    ASSERT_INT_EQ(err.code, NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 2);
    /* A segment below the resolution of its coordinates (1e12 +- 1e-5). */
    b[2] = b[1];
    b[2].nodes[3] = nts_v2(b[2].nodes[2].x + 1e-5, b[2].nodes[2].y);
    defs[2] = def_of(&b[2]);
    defs[1] = def_of(&b[0]);
    s = scene_of(defs, 3, 0.0, 0.0, &err);
    CU_ASSERT(s == NULL);
    ASSERT_INT_EQ(err.code, NTS_EDEGENERATE_SEGMENT);
    ASSERT_INT_EQ(err.body, 2);
}

/* From 1e-300 to 1e300: two pressed disks either give the unit-scale answer
 * scaled (gaps / scale equal to 1e-12) or a clear error; never a silent
 * wrong answer. The supported range is |x| <= 1e100, segments >= 1e-100. */
static void test_scales(void) {
    static const double scales[] = {1e-300, 1e-200, 1e-120, 1e-90, 1e-30, 1e-10, 1.0,
                                    1e10,   1e30,   1e90,   1e120, 1e200, 1e300};
    test_body b[2];
    nts_body_def defs[2];
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    double unit_gap[64];
    int unit_count = 0, k, i;
    o.outputs = NTS_OUT_CONTACTS;
    for (k = 0; k < (int)(sizeof scales / sizeof scales[0]); ++k) {
        double sc = scales[k];
        nts_scene* s;
        make_polygon(&b[0], 32, sc, nts_v2(0.0, 0.0), 0.0);
        make_polygon(&b[1], 32, sc, nts_v2(1.97 * sc, 0.0), 0.05);
        defs[0] = def_of(&b[0]);
        defs[1] = def_of(&b[1]);
        s = scene_of(defs, 2, 0.0, 0.0, &err);
        if (sc < 1e-95) { /* segments ~0.2 scale < 1e-100 */
            CU_ASSERT(s == NULL && err.code == NTS_EDEGENERATE_SEGMENT);
            continue;
        }
        if (sc > 1e95) {
            CU_ASSERT(s == NULL && err.code == NTS_EOUT_OF_RANGE);
            continue;
        }
        CU_ASSERT_FATAL(s != NULL);
        o.penalty = 1.0;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        CU_ASSERT_FATAL(r.contact_count > 0 && r.contact_count <= 64);
        if (sc == 1.0) {
            unit_count = r.contact_count;
            for (i = 0; i < r.contact_count; ++i) unit_gap[i] = r.contacts[i].gap;
        }
        nts_scene_destroy(s);
    }
    CU_ASSERT_FATAL(unit_count > 0);
    for (k = 0; k < (int)(sizeof scales / sizeof scales[0]); ++k) {
        double sc = scales[k];
        nts_scene* s;
        if (sc < 1e-95 || sc > 1e95) continue;
        make_polygon(&b[0], 32, sc, nts_v2(0.0, 0.0), 0.0);
        make_polygon(&b[1], 32, sc, nts_v2(1.97 * sc, 0.0), 0.05);
        defs[0] = def_of(&b[0]);
        defs[1] = def_of(&b[1]);
        s = scene_of(defs, 2, 0.0, 0.0, &err);
        CU_ASSERT_FATAL(s != NULL);
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
        ASSERT_INT_EQ(r.contact_count, unit_count);
        for (i = 0; i < r.contact_count && i < unit_count; ++i) ASSERT_NEAR(r.contacts[i].gap / sc, unit_gap[i], 1e-12);
        nts_scene_destroy(s);
    }
    nts_context_destroy(c);
}

/* One triangle-mesh body in two pieces: each piece keeps its own outer loop
 * counter-clockwise (from the windings), so a slave inside the smaller piece
 * finds a real (negative) gap. */
static void test_two_piece_mesh(void) {
    nts_vec2 pts[8] = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {6, 0}, {7, 0}, {7, 1}, {6, 1}};
    int tri[4 * 3] = {0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6}; /* the small piece given clockwise */
    test_body probe;
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int i, inside = 0;
    memset(&defs[0], 0, sizeof defs[0]);
    defs[0].nodes = pts;
    defs[0].node_count = 8;
    defs[0].triangles = tri;
    defs[0].triangle_count = 4;
    make_polygon(&probe, 12, 0.3, nts_v2(6.5, 1.2), 0.0); /* pokes 0.1 into the small piece */
    defs[1] = def_of(&probe);
    s = scene_of(defs, 2, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    ASSERT_INT_EQ(nts_scene_body_loop_count(s, 0), 2);
    ASSERT_INT_EQ(nts_scene_loops_reversed(s), 0);
    for (i = 0; i < 2; ++i) { /* both loops counter-clockwise */
        const int* loop;
        int n = nts_scene_body_loop(s, 0, i, &loop), k;
        double a2 = 0.0;
        for (k = 0; k < n; ++k) a2 += nts_cross(pts[loop[k]], pts[loop[(k + 1) % n]]);
        CU_ASSERT(a2 > 0.0);
    }
    o.outputs = NTS_OUT_CONTACTS;
    o.search_radius = 0.5;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0);
    for (i = 0; i < r.contact_count; ++i)
        if (r.contacts[i].slave_body == 1 && r.contacts[i].master_body == 0) {
            ++inside;
            CU_ASSERT(r.contacts[i].gap > -0.11 && r.contacts[i].gap < 0.0);
            CU_ASSERT(r.contacts[i].normal.y > 0.5); /* outward: up, out of the small piece */
        }
    CU_ASSERT(inside > 0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

/* A slave on the symmetry axis of a corner, beyond its evolute: two roots
 * equally near. Both solvers pick the smaller xi. */
static void test_equal_roots_tie_to_the_smaller_xi(void) {
    double alpha = 0.5;
    nts_corner k = nts_corner_make(nts_v2(-1.0, 0.3), nts_v2(1.0, 0.3), alpha);
    nts_corner_solution a = nts_corner_solve(k, nts_v2(0.0, 1.78), NTS_SOLVER_CLOSED_FORM);
    nts_corner_solution b = nts_corner_solve(k, nts_v2(0.0, 1.78), NTS_SOLVER_NEWTON);
    CU_ASSERT(a.ok && b.ok);
    ASSERT_INT_EQ(a.roots, 3);
    ASSERT_INT_EQ(b.roots, 3);
    CU_ASSERT(a.xi < -0.5 && b.xi < -0.5); /* +-0.715: the negative one */
    ASSERT_NEAR(a.xi, b.xi, 1e-12);
    ASSERT_NEAR(a.gap, b.gap, 1e-12);
    /* Mirrored data, same rule: still the smaller xi. */
    k = nts_corner_make(nts_v2(-1.0, 0.3), nts_v2(1.0, 0.3), alpha);
    a = nts_corner_solve(k, nts_v2(-0.0, 1.78), NTS_SOLVER_CLOSED_FORM);
    CU_ASSERT(a.xi < -0.5);
}

/* Bodies piled on one spot: every slave sees every other body within the
 * radius. The candidate budget turns that into a clear error, whatever the
 * thread count, instead of gigabytes of records. */
static void test_candidate_budget(void) {
    enum { N = 200 };
    test_body* b = (test_body*)calloc(N, sizeof(test_body));
    nts_body_def defs[N];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int i, th;
    for (i = 0; i < N; ++i) {
        memset(&b[i], 0, sizeof b[i]);
        b[i].nodes[0] = nts_v2(0.0, 0.0);
        b[i].nodes[1] = nts_v2(1.0, 0.0);
        b[i].nodes[2] = nts_v2(0.0, 1.0);
        b[i].node_count = 3;
        defs[i] = def_of(&b[i]);
    }
    s = scene_of(defs, N, 0.0, 0.0, &err);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_GAPS;
    CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == 0); /* 600 x 199 within the default */
    CU_ASSERT(r.gap_count >= 3 * N * (N - 1) / 2);
    o.max_candidates = 5000;
    for (th = 0; th <= 3; ++th) {
        o.threads = th;
        ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), NTS_ELIMIT);
        CU_ASSERT(strcmp(err.option, "max_candidates") == 0);
    }
    o.max_candidates = -1;
    ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), NTS_EINVALID_OPTION);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    free(b);
}

static int g_cancel_calls;
static int cancel_after_one(void* user) {
    (void)user;
#ifdef _OPENMP
#pragma omp atomic
#endif
    ++g_cancel_calls;
    return 1;
}

/* The cancel hook stops an evaluation within 1024 slaves, for any thread count. */
static void test_cancel_hook(void) {
    test_packing p = make_packing(100, 40, 1.0, 1.93, 1, 5);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int th;
    CU_ASSERT_FATAL(s != NULL);
    o.cancel = cancel_after_one;
    for (th = 0; th <= 2; ++th) {
        g_cancel_calls = 0;
        o.threads = th;
        ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), NTS_ECANCELLED);
        CU_ASSERT(g_cancel_calls >= 1 && g_cancel_calls <= 4);
    }
    o.cancel = NULL;
    CU_ASSERT(nts_evaluate(c, s, &o, &r, &err) == 0); /* and the context still works */
    nts_context_destroy(c);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* The default radius, the median segment, is selected among the sampled
 * bracket's one bin when the scene has enough segments to sample, at one
 * thread and several: a bracket that missed the median would give the
 * same answer through a selection among every length, so only the count
 * shows it (nts_profile.median_from). Smaller scenes select among all; an
 * explicit radius selects nothing. */
static void test_median_bracket_holds(void) {
    test_packing p = make_packing(576, 40, 1.0, 1.93, 1, 77); /* 23,040 entries: past 4 x 4,096 */
    test_packing q = make_packing(64, 40, 1.0, 1.93, 1, 78);  /* 2,560 */
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_scene* small = make_scene(q.bodies, q.count, q.lx, q.ly);
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int th, n;
    CU_ASSERT_FATAL(s != NULL && small != NULL && c != NULL);
    n = nts_scene_surface_node_count(s);
    CU_ASSERT_FATAL(n > 4 * 4096);
    for (th = 1; th <= 3; ++th) {
        nts_profile pr;
        o.threads = th;
        ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), 0);
        pr = nts_context_profile(c);
        if (!(pr.median_from > 0 && pr.median_from <= n / 64))
            fprintf(stderr, "\n  median selected among %d of %d lengths (%d threads)\n", pr.median_from, n, th);
        CU_ASSERT(pr.median_from > 0 && pr.median_from <= n / 64);
    }
    o.threads = 1;
    ASSERT_INT_EQ(nts_evaluate(c, small, &o, &r, &err), 0);
    ASSERT_INT_EQ(nts_context_profile(c).median_from, nts_scene_surface_node_count(small));
    o.search_radius = 0.05;
    ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), 0);
    ASSERT_INT_EQ(nts_context_profile(c).median_from, 0);
    nts_context_destroy(c);
    nts_scene_destroy(s);
    nts_scene_destroy(small);
    free_packing(&p);
    free_packing(&q);
}

/* nts_context_profile is wall clock, with or without OpenMP: an evaluation
 * whose cancel hook sleeps 50 ms (and cancels nothing) lasts at least 50 ms of
 * wall clock, phases summed, whatever the machine's speed. The build without
 * OpenMP used to report processor time (clock()), in which a sleep counts
 * nothing. A lower bound that a sleep guarantees, not a timing. */
static int g_slept;
static int sleep_once(void* user) {
    (void)user;
    if (!g_slept) {
        struct timespec ts;
        ts.tv_sec = 0;
        ts.tv_nsec = 50 * 1000 * 1000;
        g_slept = 1;
        while (nanosleep(&ts, &ts) != 0) continue;
    }
    return 0;
}

static void test_profile_is_wall_clock(void) {
    test_body b[2];
    nts_scene* s;
    nts_context* c = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    nts_profile pr;
    make_polygon(&b[0], 32, 1.0, nts_v2(0.0, 0.0), 0.0);
    make_polygon(&b[1], 32, 1.0, nts_v2(1.97, 0.0), 0.05);
    s = make_scene(b, 2, 0.0, 0.0);
    CU_ASSERT_FATAL(s != NULL && c != NULL);
    pr = nts_context_profile(c);
    CU_ASSERT(pr.segments == 0.0 && pr.cells == 0.0 && pr.search == 0.0 && pr.scatter == 0.0);
    g_slept = 0;
    o.cancel = sleep_once;
    ASSERT_INT_EQ(nts_evaluate(c, s, &o, &r, &err), 0);
    CU_ASSERT(g_slept == 1);
    pr = nts_context_profile(c);
    CU_ASSERT(pr.segments >= 0.0 && pr.cells >= 0.0 && pr.search >= 0.0 && pr.scatter >= 0.0);
    {
        double total = pr.segments + pr.cells + pr.search + pr.scatter;
        if (!(total >= 0.05)) fprintf(stderr, "\n  profile: %.3g s in all, around a sleep of 0.05 s\n", total);
        CU_ASSERT(total >= 0.05);
    }
    nts_context_destroy(c);
    nts_scene_destroy(s);
}

void register_scenes_suite(void) {
    CU_pSuite s = CU_add_suite("scenes", NULL, NULL);
    ADD_TEST(s, test_long_walls_equal_brute_force);
    ADD_TEST(s, test_long_bar_periodic_equals_brute_force);
    ADD_TEST(s, test_default_radius_is_the_median_segment);
    ADD_TEST(s, test_default_radius_is_the_median_of_many);
    ADD_TEST(s, test_median_of_equal_lengths);
    ADD_TEST(s, test_body_alpha_keeps_a_container_sharp);
    ADD_TEST(s, test_roles);
    ADD_TEST(s, test_penalty_per_length);
    ADD_TEST(s, test_tolerances_are_local);
    ADD_TEST(s, test_scales);
    ADD_TEST(s, test_two_piece_mesh);
    ADD_TEST(s, test_equal_roots_tie_to_the_smaller_xi);
    ADD_TEST(s, test_candidate_budget);
    ADD_TEST(s, test_cancel_hook);
    ADD_TEST(s, test_profile_is_wall_clock);
    ADD_TEST(s, test_median_bracket_holds);
}
