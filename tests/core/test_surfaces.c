/* Surfaces suite (docs/model.md §13, the contact surfaces): the contact-level
 * patch test (uniform penetration gives uniform traction, corner nodes
 * included, for matching and non-matching meshes, alpha 0 and 0.2, one- and
 * two-pass, both solvers, any threads); what a flush stack gives without
 * surfaces, and why; a surface naming every segment answers bitwise as none;
 * partial surfaces against a closest-point reference written here (every
 * surface feature of every other body tried, the corner roots from the
 * long-double reference), cells against brute force, 1 to 4 threads
 * bitwise; nodes and segments off the surface take part in nothing; deep
 * contacts through a surface; the tangent at a surface's end against finite
 * differences; every bad surface refused with its pair named. */
#include <stdlib.h>
#include <string.h>

#include "nts_support.h"
#include "suites.h"
#include "test_util.h"

/* ------------------------------------------------------------ blocks */

/* A block [x0, x0 + w] x [y0, y0 + h] as one counter-clockwise loop: `nb`
 * nodes along the bottom (left to right, corners included), `ns` inner nodes
 * up each side, `nt` nodes along the top (right to left, corners included).
 * Its bottom edge is nodes 0 .. nb-1, its top edge nodes nb+ns-1 .. nb+ns+nt-2
 * (surface pairs in *bottom, *top: nb - 1 and nt - 1 pairs). */
typedef struct block {
    nts_vec2 p[256];
    int n;
    int bottom[2 * 64], top[2 * 64];
    int nbottom, ntop;
} block;

static void make_block(block* b, double x0, double y0, double w, double h, int nb, int ns, int nt) {
    int i;
    b->n = 0;
    for (i = 0; i < nb; ++i) b->p[b->n++] = nts_v2(x0 + w * i / (nb - 1), y0);
    for (i = 1; i <= ns; ++i) b->p[b->n++] = nts_v2(x0 + w, y0 + h * i / (ns + 1));
    for (i = 0; i < nt; ++i) b->p[b->n++] = nts_v2(x0 + w * (nt - 1 - i) / (nt - 1), y0 + h);
    for (i = 1; i <= ns; ++i) b->p[b->n++] = nts_v2(x0, y0 + h * (ns + 1 - i) / (ns + 1));
    b->nbottom = nb - 1;
    for (i = 0; i + 1 < nb; ++i) {
        b->bottom[2 * i] = i + 1; /* either direction: this one against the loop's */
        b->bottom[2 * i + 1] = i;
    }
    b->ntop = nt - 1;
    for (i = 0; i + 1 < nt; ++i) {
        b->top[2 * i] = nb + ns + i;
        b->top[2 * i + 1] = nb + ns + i + 1;
    }
}

static nts_body_def block_def(const block* b, const int* surface, int count, nts_role role) {
    nts_body_def d;
    memset(&d, 0, sizeof d);
    d.nodes = b->p;
    d.node_count = b->n;
    d.surface = surface;
    d.surface_count = count;
    d.role = role;
    return d;
}

static nts_scene* scene_of(const nts_body_def* defs, int count, nts_error* err) {
    nts_scene_def sd = nts_default_scene_def();
    sd.bodies = defs;
    sd.body_count = count;
    return nts_scene_create(&sd, err);
}

/* The tributary length of entry k of a loop over the surface's segments:
 * half of each of its two segments that is on (docs/model.md §10, §13). */
static double surface_tributary(const nts_scene* s, int b, int node) {
    const nts_vec2* x = nts_scene_positions(s) + nts_scene_body_node_offset(s, b);
    int l, k;
    for (l = 0; l < nts_scene_body_loop_count(s, b); ++l) {
        const int* loop;
        const int m = nts_scene_body_loop(s, b, l, &loop);
        for (k = 0; k < m; ++k)
            if (loop[k] == node) {
                double t = 0.0;
                if (nts_scene_on_surface(s, b, l, (k + m - 1) % m))
                    t += 0.5 * nts_length(nts_sub(x[loop[k]], x[loop[(k + m - 1) % m]]));
                if (nts_scene_on_surface(s, b, l, k)) t += 0.5 * nts_length(nts_sub(x[loop[(k + 1) % m]], x[loop[k]]));
                return t;
            }
    }
    return 0.0;
}

/* ------------------------------------------- the contact-level patch test */

/* Two blocks of width 1 with flush sides, the upper's bottom edge 0.01 into
 * the lower's top edge, the two edges as surfaces, "length" scaling: every
 * slave node (corners included) has one contact at gap -0.01, its slave
 * force over its tributary length is eps g to 1e-12 and so is its pressure;
 * every body's forces add up to the uniform pressure over the width (per
 * pass), both bodies' to zero; the energy is eps g^2 / 2 over the width per
 * pass. */
static void patch(int nlo, int nup, double alpha, int passes, nts_solver solver, int threads) {
    const double g = -0.01, eps = 250.0, w = 1.0;
    block lo, up;
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    nts_vec2 sum[2] = {{0.0, 0.0}, {0.0, 0.0}};
    int i, b, slaves = 0;
    make_block(&lo, 0.0, 0.0, w, 1.0, 3, 2, nlo);
    make_block(&up, 0.0, 1.0 + g, w, 1.0, nup, 1, 4);
    defs[0] = block_def(&lo, lo.top, lo.ntop, passes == 1 ? NTS_ROLE_MASTER : NTS_ROLE_BOTH);
    defs[1] = block_def(&up, up.bottom, up.nbottom, NTS_ROLE_BOTH);
    s = scene_of(defs, 2, &err);
    CU_ASSERT_FATAL(s != NULL && ctx != NULL);
    CU_ASSERT(nts_scene_has_surfaces(s));
    o.alpha = alpha;
    o.penalty = eps;
    o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
    o.solver = solver;
    o.threads = threads;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS | NTS_OUT_PRESSURE;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    slaves = nup + (passes == 2 ? nlo : 0);
    ASSERT_INT_EQ(r.contact_count, slaves);
    for (i = 0; i < r.contact_count; ++i) {
        const nts_contact* c = &r.contacts[i];
        const double l = surface_tributary(s, c->slave_body, c->slave_node);
        const int gi = nts_scene_body_node_offset(s, c->slave_body) + c->slave_node;
        ASSERT_NEAR(c->gap, g, 1e-12);
        CU_ASSERT(l > 0.0);
        ASSERT_NEAR(nts_length(c->force) / l, -eps * g, 1e-12 * eps * fabs(g));
        ASSERT_NEAR(r.pressure[gi], -eps * g, 1e-12 * eps * fabs(g));
        ASSERT_NEAR(c->penalty, eps * l, 1e-14 * eps);
    }
    for (b = 0; b < 2; ++b) {
        const int off = nts_scene_body_node_offset(s, b), n = nts_scene_body_node_count(s, b);
        for (i = 0; i < n; ++i) sum[b] = nts_add(sum[b], r.forces[off + i]);
    }
    /* the upper body is pushed up by the pressure over the width, once per pass */
    ASSERT_NEAR(sum[1].x, 0.0, 1e-13);
    ASSERT_NEAR(sum[1].y, -eps * g * w * passes, 1e-12 * eps * fabs(g));
    ASSERT_NEAR(sum[0].x + sum[1].x, 0.0, 1e-13);
    ASSERT_NEAR(sum[0].y + sum[1].y, 0.0, 1e-13);
    ASSERT_NEAR(r.summary.energy, 0.5 * eps * g * g * w * passes, 1e-12 * eps * g * g);
    nts_scene_destroy(s);
    nts_context_destroy(ctx);
}

static void test_patch_uniform_traction(void) {
    static const int meshes[][2] = {{5, 5}, {7, 5}, {5, 7}, {4, 9}, {2, 2}, {13, 6}};
    static const double alphas[] = {0.0, 0.2, 0.5};
    int m, a, passes, solver, threads;
    for (m = 0; m < 6; ++m)
        for (a = 0; a < 3; ++a)
            for (passes = 1; passes <= 2; ++passes)
                for (solver = 0; solver < 2; ++solver)
                    for (threads = 0; threads <= 3; threads += 3)
                        patch(meshes[m][0], meshes[m][1], alphas[a], passes,
                              solver ? NTS_SOLVER_NEWTON : NTS_SOLVER_CLOSED_FORM, threads);
}

/* Flush up to round-off (docs/model.md §13): the upper block moved 1e-9 to
 * the left, its left corner node lies past the lower block's surface end by
 * that much; with the default extension (0.01 of the end segment) it is in
 * contact as the others are, with none (0) it is not, and past the
 * extension (a 2% overhang) it is not either. */
static void test_flush_up_to_round_off(void) {
    static const double shifts[] = {-1e-9, -1e-9, -0.02 * 0.25};
    static const double exts[] = {0.01, 0.0, 0.01};
    int k;
    for (k = 0; k < 3; ++k) {
        block lo, up;
        nts_body_def defs[2];
        nts_scene* s;
        nts_context* ctx = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r;
        nts_error err;
        int i, left = 0;
        make_block(&lo, 0.0, 0.0, 1.0, 1.0, 2, 0, 5); /* top segments 0.25 */
        make_block(&up, shifts[k], 0.99, 1.0, 1.0, 7, 0, 2);
        defs[0] = block_def(&lo, lo.top, lo.ntop, NTS_ROLE_MASTER);
        defs[1] = block_def(&up, up.bottom, up.nbottom, NTS_ROLE_BOTH);
        s = scene_of(defs, 2, &err);
        CU_ASSERT_FATAL(s != NULL);
        ASSERT_NEAR(o.surface_extension, 0.01, 0.0); /* the default */
        o.surface_extension = exts[k];
        o.penalty = 100.0;
        o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
        o.outputs = NTS_OUT_CONTACTS | NTS_OUT_PRESSURE;
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
        for (i = 0; i < r.contact_count; ++i) {
            left += r.contacts[i].slave_node == 0;
            ASSERT_NEAR(r.contacts[i].gap, -0.01, 1e-12);
        }
        ASSERT_INT_EQ(left, k == 0 ? 1 : 0);
        ASSERT_INT_EQ(r.contact_count, k == 0 ? 7 : 6);
        if (k == 0) {
            CU_ASSERT(r.contacts[0].param > 1.0 && r.contacts[0].param < 1.0 + 1e-8); /* in the extension */
            ASSERT_NEAR(r.pressure[nts_scene_body_node_offset(s, 1)], 1.0, 1e-12);
        }
        nts_scene_destroy(s);
        nts_context_destroy(ctx);
    }
}

/* Without surfaces (docs/model.md §13, "A flush stack"): two stacked unit
 * squares 0.01 into each other. At alpha 0 each penetrating corner node lies
 * exactly on the other body's side segment: that side is its closest
 * feature at |g| = 0, so it is no active contact; at alpha 0.2 it lies
 * outside the other body's rounded corner (g > 0). With four nodes a body
 * there is nothing else to push: 0 contacts, 0 energy. With finer edges the
 * inner nodes push and the corner nodes still get nothing. */
static void test_flush_stack_without_surfaces(void) {
    static const double alphas[] = {0.0, 0.2};
    int a, fine;
    for (fine = 0; fine < 2; ++fine)
        for (a = 0; a < 2; ++a) {
            block lo, up;
            nts_body_def defs[2];
            nts_scene* s;
            nts_context* ctx = nts_context_create();
            nts_options o = nts_default_options();
            nts_result r;
            nts_error err;
            int i, corners = 0;
            make_block(&lo, 0.0, 0.0, 1.0, 1.0, 2, 0, fine ? 5 : 2);
            make_block(&up, 0.0, 0.99, 1.0, 1.0, fine ? 7 : 2, 0, 2);
            defs[0] = block_def(&lo, NULL, 0, NTS_ROLE_BOTH);
            defs[1] = block_def(&up, NULL, 0, NTS_ROLE_BOTH);
            s = scene_of(defs, 2, &err);
            CU_ASSERT_FATAL(s != NULL);
            CU_ASSERT(!nts_scene_has_surfaces(s));
            o.alpha = alphas[a];
            o.penalty = 100.0;
            o.outputs = NTS_OUT_ENERGY | NTS_OUT_CONTACTS | NTS_OUT_GAPS;
            CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
            ASSERT_INT_EQ(r.contact_count, fine ? 3 + 5 : 0);
            if (!fine) ASSERT_NEAR(r.summary.energy, 0.0, 0.0);
            for (i = 0; i < r.gap_count; ++i) {
                const nts_contact* c = &r.gaps[i];
                const nts_vec2 x = nts_scene_positions(s)[nts_scene_body_node_offset(s, c->slave_body) + c->slave_node];
                if (x.x != 0.0 && x.x != 1.0) continue;
                /* a penetrating corner node: on the other body's side, |g| = 0 */
                if ((c->slave_body == 1 && x.y == 0.99) || (c->slave_body == 0 && x.y == 1.0)) {
                    if (alphas[a] == 0.0) { /* on the other body's side segment */
                        ASSERT_INT_EQ(c->kind, NTS_KIND_SEGMENT);
                        ASSERT_NEAR(c->gap, 0.0, 0.0);
                        ASSERT_NEAR(fabs(c->normal.x), 1.0, 1e-15);
                    } else { /* outside the other body's rounded corner */
                        ASSERT_INT_EQ(c->kind, NTS_KIND_CORNER);
                        CU_ASSERT(c->gap > 0.0);
                    }
                    ++corners;
                }
            }
            ASSERT_INT_EQ(corners, 4);
            nts_scene_destroy(s);
            nts_context_destroy(ctx);
        }
}

/* ------------------------------------------------ a reference, written here */

/* The closest point of a slave on one master body's surface, feature by
 * feature as docs/model.md §4, §5 and §13 state them: the flat part of each
 * surface segment on [alpha, 1 - alpha], or up to s = -ext (1 + ext) at a
 * start (end) of the surface; the corner (alpha > 0) or vertex (alpha = 0) of each node
 * whose two segments are on, in its zone; the root nearest to the slave from
 * the long-double reference; ties to the smaller node, segment first, then
 * (corner roots) the smaller xi. Explicit radius r. Open scenes. */
typedef struct ref_hit {
    int found, node, kind;
    double gap;
} ref_hit;

static ref_hit reference_pair(const nts_scene* s, nts_vec2 xs, int body, double alpha, double ext, double r) {
    const nts_vec2* x = nts_scene_positions(s) + nts_scene_body_node_offset(s, body);
    ref_hit best;
    int l, k;
    best.found = 0;
    best.node = best.kind = -1;
    best.gap = 0.0;
    for (l = 0; l < nts_scene_body_loop_count(s, body); ++l) {
        const int* loop;
        const int m = nts_scene_body_loop(s, body, l, &loop);
        for (k = 0; k < m; ++k) {
            const int kp = (k + m - 1) % m, kn = (k + 1) % m;
            const int on = nts_scene_on_surface(s, body, l, k), on_prev = nts_scene_on_surface(s, body, l, kp),
                      on_next = nts_scene_on_surface(s, body, l, kn);
            const nts_vec2 p0 = x[loop[k]], t = nts_sub(x[loop[kn]], p0), tp = nts_sub(p0, x[loop[kp]]);
            const nts_vec2 d = nts_sub(xs, p0), dp = nts_sub(xs, x[loop[kp]]);
            const double sj = nts_dot(d, t) / nts_length_sq(t), sp = nts_dot(dp, tp) / nts_length_sq(tp);
            ref_hit c;
            c.found = 0;
            if (!on) continue;
            if (sj >= (on_prev ? alpha : -ext) && sj <= (on_next ? 1.0 - alpha : 1.0 + ext)) {
                const nts_vec2 n = nts_v2(t.y / nts_length(t), -t.x / nts_length(t));
                c.found = 1;
                c.gap = nts_dot(d, n);
                c.kind = NTS_KIND_SEGMENT;
                c.node = loop[k];
                if (fabs(c.gap) <= r && (!best.found || fabs(c.gap) < fabs(best.gap) ||
                                         (fabs(c.gap) == fabs(best.gap) && c.node < best.node)))
                    best = c;
            }
            if (!on_prev) continue;
            if (alpha > 0.0 && sp >= 1.0 - alpha && sj <= alpha) {
                int roots;
                const double xi = (double)ntsx_corner_xi(nts_neg(tp), t, alpha, d, &roots);
                const double n2 = alpha * (1 - xi) * (1 - xi) / 4, n4 = alpha * (1 + xi) * (1 + xi) / 4;
                const nts_vec2 tau = nts_add(nts_scale(alpha * (1 + xi) / 2, t), nts_scale(alpha * (1 - xi) / 2, tp));
                const nts_vec2 X = nts_add(p0, nts_add(nts_scale(-n2, tp), nts_scale(n4, t)));
                const nts_vec2 n = nts_scale(1.0 / nts_length(tau), nts_v2(tau.y, -tau.x));
                c.found = 1;
                c.gap = nts_dot(nts_sub(xs, X), n);
                c.kind = NTS_KIND_CORNER;
                c.node = loop[k];
            } else if (alpha == 0.0 && sp >= 1.0 && sj <= 0.0) {
                const nts_vec2 pseudo = nts_add(nts_v2(tp.y / nts_length(tp), -tp.x / nts_length(tp)),
                                                nts_v2(t.y / nts_length(t), -t.x / nts_length(t)));
                c.found = 1;
                c.gap = (nts_dot(d, pseudo) >= 0.0 ? 1.0 : -1.0) * nts_length(d);
                c.kind = NTS_KIND_VERTEX;
                c.node = loop[k];
            } else {
                continue;
            }
            if (fabs(c.gap) <= r && (!best.found || fabs(c.gap) < fabs(best.gap) ||
                                     (fabs(c.gap) == fabs(best.gap) && c.node < best.node)))
                best = c;
        }
    }
    return best;
}

/* A packing of polygons whose bodies name random partial surfaces (a third
 * of the bodies none: their whole boundary), some bodies with surfaces of
 * a few runs of consecutive segments. */
typedef struct surf_packing {
    ntsx_scene x;
    int** pairs;
    int* count;
    nts_body_def* defs;
} surf_packing;

static void surf_packing_make(surf_packing* p, int particles, uint64_t seed, double keep) {
    ntsx_packing_def d = ntsx_default_packing(particles, 0, seed);
    uint64_t st = seed * 7919u + 17u;
    int b, i;
    d.nodes_min = 6;
    d.nodes_max = 18;
    ntsx_packing(&p->x, &d);
    p->pairs = (int**)calloc((size_t)p->x.body_count, sizeof(int*));
    p->count = (int*)calloc((size_t)p->x.body_count, sizeof(int));
    p->defs = (nts_body_def*)calloc((size_t)p->x.body_count, sizeof(nts_body_def));
    CU_ASSERT_FATAL(p->pairs && p->count && p->defs);
    for (b = 0; b < p->x.body_count; ++b) {
        const int n = p->x.counts[b];
        const int whole = ntsx_urand(&st) < 1.0 / 3.0;
        p->defs[b].nodes = p->x.nodes[b];
        p->defs[b].node_count = n;
        if (whole) continue;
        p->pairs[b] = (int*)malloc(sizeof(int) * 2 * (size_t)n);
        CU_ASSERT_FATAL(p->pairs[b] != NULL);
        for (i = 0; i < n; ++i) {
            /* runs: keep a segment with probability `keep`, in a random direction */
            if (ntsx_urand(&st) >= keep) continue;
            if (ntsx_urand(&st) < 0.5) {
                p->pairs[b][2 * p->count[b]] = i;
                p->pairs[b][2 * p->count[b] + 1] = (i + 1) % n;
            } else {
                p->pairs[b][2 * p->count[b]] = (i + 1) % n;
                p->pairs[b][2 * p->count[b] + 1] = i;
            }
            ++p->count[b];
        }
        p->defs[b].surface = p->pairs[b];
        p->defs[b].surface_count = p->count[b];
    }
}

static void surf_packing_free(surf_packing* p) {
    int b;
    for (b = 0; b < p->x.body_count; ++b) free(p->pairs[b]);
    free(p->pairs);
    free(p->count);
    free(p->defs);
    ntsx_scene_free(&p->x);
}

static int same_bits(const void* a, const void* b, size_t n) { return n == 0 || memcmp(a, b, n) == 0; }

/* Two results bitwise equal in every output asked for. */
static void assert_same_result(const nts_result* a, const nts_result* b, int nodes) {
    CU_ASSERT(same_bits(&a->summary.energy, &b->summary.energy, sizeof(double)));
    CU_ASSERT(same_bits(&a->summary.virial, &b->summary.virial, sizeof(nts_virial)));
    CU_ASSERT(same_bits(&a->summary.search_radius, &b->summary.search_radius, sizeof(double)));
    ASSERT_INT_EQ(a->summary.deep_contacts, b->summary.deep_contacts);
    ASSERT_INT_EQ(a->contact_count, b->contact_count);
    ASSERT_INT_EQ(a->gap_count, b->gap_count);
    CU_ASSERT(same_bits(a->forces, b->forces, sizeof(nts_vec2) * (size_t)nodes));
    if (a->pressure && b->pressure) CU_ASSERT(same_bits(a->pressure, b->pressure, sizeof(double) * (size_t)nodes));
    if (a->contact_count == b->contact_count)
        CU_ASSERT(same_bits(a->contacts, b->contacts, sizeof(nts_contact) * (size_t)a->contact_count));
    if (a->gap_count == b->gap_count) CU_ASSERT(same_bits(a->gaps, b->gaps, sizeof(nts_contact) * (size_t)a->gap_count));
    ASSERT_INT_EQ(a->stiffness.count, b->stiffness.count);
    if (a->stiffness.count == b->stiffness.count && a->stiffness.count > 0) {
        CU_ASSERT(same_bits(a->stiffness.rows, b->stiffness.rows, sizeof(int) * (size_t)a->stiffness.count));
        CU_ASSERT(same_bits(a->stiffness.cols, b->stiffness.cols, sizeof(int) * (size_t)a->stiffness.count));
        CU_ASSERT(same_bits(a->stiffness.values, b->stiffness.values, sizeof(double) * (size_t)a->stiffness.count));
    }
}

/* Every closest point (gaps output, explicit radius) against the reference:
 * the same pairs, features and gaps (to 1e-12 of the scale). Then cells
 * against brute force and 1 to 4 threads: bitwise. */
static void test_partial_surfaces_against_reference(void) {
    static const double alphas[] = {0.0, 0.2, 0.45};
    int seed, a, checked = 0, partial = 0;
    for (seed = 1; seed <= 6; ++seed)
        for (a = 0; a < 3; ++a) {
            surf_packing p;
            nts_scene* s;
            nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
            nts_options o = nts_default_options();
            nts_result r0, r1;
            nts_error err;
            int i, b, th, k = 0, slaves = 0;
            surf_packing_make(&p, 36, (uint64_t)seed, seed % 2 ? 0.7 : 0.4);
            s = scene_of(p.defs, p.x.body_count, &err);
            CU_ASSERT_FATAL(s != NULL && c0 != NULL && c1 != NULL);
            o.alpha = alphas[a];
            o.surface_extension = a == 0 ? 0.0 : (a == 1 ? 0.01 : 0.3); /* none, the default, large */
            o.search_radius = 0.3;
            o.penalty = 100.0;
            o.outputs = NTS_OUT_ALL;
            CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
            /* the reference: every surface node of every body against every
             * other body, in the result's order (slave entries, then master
             * body), record for record */
            for (b = 0; b < p.x.body_count; ++b) {
                int l;
                for (l = 0; l < nts_scene_body_loop_count(s, b); ++l) {
                    const int* loop;
                    const int m = nts_scene_body_loop(s, b, l, &loop);
                    int j, q;
                    for (j = 0; j < m; ++j) {
                        const int node = loop[j];
                        const nts_vec2 xs = nts_scene_positions(s)[nts_scene_body_node_offset(s, b) + node];
                        if (!nts_scene_on_surface(s, b, l, j) && !nts_scene_on_surface(s, b, l, (j + m - 1) % m)) {
                            ++partial; /* off the surface: no slave, no record */
                            continue;
                        }
                        ++slaves;
                        for (q = 0; q < p.x.body_count; ++q) {
                            ref_hit h;
                            if (q == b) continue;
                            h = reference_pair(s, xs, q, o.alpha, o.surface_extension, o.search_radius);
                            if (!h.found) continue;
                            CU_ASSERT_FATAL(k < r0.gap_count);
                            ASSERT_INT_EQ(r0.gaps[k].slave_body, b);
                            ASSERT_INT_EQ(r0.gaps[k].slave_node, node);
                            ASSERT_INT_EQ(r0.gaps[k].master_body, q);
                            ASSERT_INT_EQ(r0.gaps[k].kind, h.kind);
                            ASSERT_NEAR(r0.gaps[k].gap, h.gap, 1e-12);
                            ++k;
                            ++checked;
                        }
                    }
                }
            }
            ASSERT_INT_EQ(k, r0.gap_count);
            /* the reference found as many as the result holds */
            CU_ASSERT(checked > 0);
            {
                nts_options ob = o;
                ob.search = NTS_SEARCH_BRUTE_FORCE;
                CU_ASSERT_FATAL(nts_evaluate(c1, s, &ob, &r1, &err) == 0);
                assert_same_result(&r0, &r1, nts_scene_node_count(s));
            }
            for (th = 2; th <= 4; ++th) {
                nts_options ot = o;
                ot.threads = th;
                CU_ASSERT_FATAL(nts_evaluate(c1, s, &ot, &r1, &err) == 0);
                assert_same_result(&r0, &r1, nts_scene_node_count(s));
            }
            for (i = 0; i < r0.gap_count; ++i) CU_ASSERT(r0.gaps[i].gap <= o.search_radius);
            CU_ASSERT(slaves > 0);
            nts_scene_destroy(s);
            nts_context_destroy(c0);
            nts_context_destroy(c1);
            surf_packing_free(&p);
        }
    CU_ASSERT(partial > 100);
    CU_ASSERT(checked > 500);
}

/* A surface that names every segment (in random directions) answers as no
 * surface at all, bitwise, every output, cells and brute force, any threads;
 * with the default radius too (deep contacts). */
static void test_whole_surface_is_the_default(void) {
    int seed, th, brute;
    for (seed = 1; seed <= 3; ++seed) {
        surf_packing p;
        nts_scene *s0, *s1;
        nts_error err;
        int b;
        surf_packing_make(&p, 49, (uint64_t)seed + 100u, 1.0); /* keep = 1: every segment */
        for (b = 0; b < p.x.body_count; ++b) CU_ASSERT(p.defs[b].surface == NULL || p.count[b] == p.x.counts[b]);
        s1 = scene_of(p.defs, p.x.body_count, &err);
        for (b = 0; b < p.x.body_count; ++b) p.defs[b].surface = NULL;
        s0 = scene_of(p.defs, p.x.body_count, &err);
        CU_ASSERT_FATAL(s0 != NULL && s1 != NULL);
        CU_ASSERT(nts_scene_has_surfaces(s1) && !nts_scene_has_surfaces(s0));
        for (brute = 0; brute < 2; ++brute)
            for (th = 0; th <= 3; ++th) {
                nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
                nts_options o = nts_default_options();
                nts_result r0, r1;
                o.penalty = 50.0;
                o.alpha = seed == 2 ? 0.0 : 0.2;
                o.penalty_scaling = seed == 3 ? NTS_PENALTY_PER_LENGTH : NTS_PENALTY_PER_NODE;
                o.threads = th;
                o.search = brute ? NTS_SEARCH_BRUTE_FORCE : NTS_SEARCH_CELLS;
                o.outputs = th == 1 ? NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL : NTS_OUT_ALL;
                CU_ASSERT_FATAL(nts_evaluate(c0, s0, &o, &r0, &err) == 0);
                CU_ASSERT_FATAL(nts_evaluate(c1, s1, &o, &r1, &err) == 0);
                CU_ASSERT(r0.summary.contacts > 20);
                assert_same_result(&r0, &r1, nts_scene_node_count(s0));
                CU_ASSERT(same_bits(&r0.summary.cell_size, &r1.summary.cell_size, sizeof(double)));
                nts_context_destroy(c0);
                nts_context_destroy(c1);
            }
        nts_scene_destroy(s0);
        nts_scene_destroy(s1);
        surf_packing_free(&p);
    }
}

/* Off the surface nothing takes part: a disk pressed into a block's side
 * (the block's surface is its top) gets no contact, and the block's side
 * nodes pressed into the disk push nothing either; the same disk pressed
 * into the top does. */
static void test_off_surface_takes_no_part(void) {
    block blk;
    test_body disk;
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int side;
    make_block(&blk, 0.0, 0.0, 2.0, 2.0, 5, 4, 5);
    for (side = 0; side < 2; ++side) {
        /* radius 0.5: into the right side (x = 2) by 0.1, or into the top (y = 2) by 0.1 */
        make_polygon(&disk, 40, 0.5, side ? nts_v2(1.0, 2.4) : nts_v2(2.4, 1.0), 0.01);
        defs[0] = block_def(&blk, blk.top, blk.ntop, NTS_ROLE_BOTH);
        memset(&defs[1], 0, sizeof defs[1]);
        defs[1].nodes = disk.nodes;
        defs[1].node_count = disk.node_count;
        s = scene_of(defs, 2, &err);
        CU_ASSERT_FATAL(s != NULL);
        o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS | NTS_OUT_GAPS;
        o.penalty = 10.0;
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
        if (!side) {
            int i;
            ASSERT_INT_EQ(r.contact_count, 0);
            for (i = 0; i < nts_scene_node_count(s); ++i) CU_ASSERT(r.forces[i].x == 0.0 && r.forces[i].y == 0.0);
        } else {
            int i, into_block = 0;
            CU_ASSERT(r.contact_count > 0);
            for (i = 0; i < r.contact_count; ++i) into_block += r.contacts[i].master_body == 0;
            CU_ASSERT(into_block > 0);
        }
        nts_scene_destroy(s);
    }
    nts_context_destroy(ctx);
}

/* Deep contacts through a surface (docs/model.md §4.5, §13): a finely
 * meshed disk pressed 0.45 into a block whose surface is its top, deeper
 * than the median segment: the default radius finds exactly the contacts of
 * a radius of 10, record for record. */
static void test_deep_through_a_surface(void) {
    block blk;
    test_body disk;
    nts_body_def defs[2];
    nts_scene* s;
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    int i;
    make_block(&blk, 0.0, 0.0, 4.0, 2.0, 9, 3, 41);
    make_polygon(&disk, 200, 1.0, nts_v2(2.0, 2.55), 0.003);
    defs[0] = block_def(&blk, blk.top, blk.ntop, NTS_ROLE_MASTER);
    memset(&defs[1], 0, sizeof defs[1]);
    defs[1].nodes = disk.nodes;
    defs[1].node_count = disk.node_count;
    s = scene_of(defs, 2, &err);
    CU_ASSERT_FATAL(s != NULL);
    o.outputs = NTS_OUT_ALL;
    o.penalty = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    CU_ASSERT(r0.summary.deep_contacts > 10);
    CU_ASSERT(r0.summary.max_penetration > 0.4);
    ASSERT_INT_EQ(r0.warning_count, 0);
    o.search_radius = 10.0;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    ASSERT_INT_EQ(r0.contact_count, r1.contact_count);
    if (r0.contact_count == r1.contact_count)
        for (i = 0; i < r0.contact_count; ++i)
            CU_ASSERT(same_bits(&r0.contacts[i], &r1.contacts[i], sizeof(nts_contact)));
    ASSERT_NEAR(r0.summary.energy, r1.summary.energy, 1e-12 * r1.summary.energy);
    nts_scene_destroy(s);
    nts_context_destroy(c0);
    nts_context_destroy(c1);
}

/* The tangent where a surface ends (its end segment's flat part up to its
 * end node, no corner there) against central finite differences of the
 * forces, alpha 0.2: a slave at s = 0.9 of the end segment, where without
 * the end it would be in the corner's zone. */
static void test_tangent_at_a_surface_end(void) {
    block blk;
    nts_vec2 probe[3];
    nts_body_def defs[2];
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    nts_csr K;
    const double h = 1e-6;
    int i, j, n, surf[4] = {0, 1, 1, 2};
    double* f0;
    double* f1;
    double worst = 0.0, scale = 0.0;
    /* the block's top as the surface: 3 nodes (right to left: 1.0, 0.5, 0.0) */
    make_block(&blk, 0.0, 0.0, 1.0, 1.0, 2, 0, 3);
    surf[0] = 2;
    surf[1] = 3;
    surf[2] = 3;
    surf[3] = 4;
    /* a triangle probe whose lowest node is 0.02 into the top, near x = 0.04 */
    probe[0] = nts_v2(0.045, 0.98);
    probe[1] = nts_v2(0.3, 1.3);
    probe[2] = nts_v2(0.0, 1.4);
    defs[0] = block_def(&blk, surf, 2, NTS_ROLE_MASTER);
    memset(&defs[1], 0, sizeof defs[1]);
    defs[1].nodes = probe;
    defs[1].node_count = 3;
    s = scene_of(defs, 2, &err);
    CU_ASSERT_FATAL(s != NULL);
    n = nts_scene_node_count(s);
    o.alpha = 0.2;
    o.penalty = 100.0;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS | NTS_OUT_STIFFNESS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    ASSERT_INT_EQ(r.contact_count, 1);
    ASSERT_INT_EQ(r.contacts[0].kind, NTS_KIND_SEGMENT);
    CU_ASSERT(r.contacts[0].param > 0.8); /* beyond 1 - alpha: the corner's zone without the end */
    CU_ASSERT_FATAL(nts_triplets_to_csr(&r.stiffness, &K, &err) == 0);
    f0 = (double*)calloc(2 * (size_t)n, sizeof(double));
    f1 = (double*)calloc(2 * (size_t)n, sizeof(double));
    CU_ASSERT_FATAL(f0 && f1);
    for (j = 0; j < 2 * n; ++j) {
        nts_vec2 x[16];
        int sgn, b = j / 2 < blk.n ? 0 : 1, node = j / 2 - (b ? blk.n : 0);
        const nts_vec2* base = b ? probe : blk.p;
        for (sgn = 0; sgn < 2; ++sgn) {
            double* f = sgn ? f1 : f0;
            memcpy(x, base, sizeof(nts_vec2) * (size_t)(b ? 3 : blk.n));
            if (j % 2) x[node].y += sgn ? h : -h;
            else x[node].x += sgn ? h : -h;
            CU_ASSERT_FATAL(nts_scene_set_positions(s, b, x, &err) == 0);
            CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
            for (i = 0; i < n; ++i) {
                f[2 * i] = r.forces[i].x;
                f[2 * i + 1] = r.forces[i].y;
            }
        }
        CU_ASSERT_FATAL(nts_scene_set_positions(s, b, base, &err) == 0);
        for (i = 0; i < 2 * n; ++i) {
            double k = 0.0, fd = -(f1[i] - f0[i]) / (2.0 * h);
            int q;
            for (q = K.row_start[i]; q < K.row_start[i + 1]; ++q)
                if (K.cols[q] == j) k = K.values[q];
            worst = fabs(k - fd) > worst ? fabs(k - fd) : worst;
            scale = fabs(k) > scale ? fabs(k) : scale;
        }
    }
    CU_ASSERT(scale > 1.0);
    ASSERT_NEAR(worst, 0.0, 1e-6 * scale);
    free(f0);
    free(f1);
    nts_csr_free(&K);
    nts_scene_destroy(s);
    nts_context_destroy(ctx);
}

/* Every bad surface is refused, naming its pair (err->option "surface",
 * err->item, err->corner for one index). */
static void test_bad_surfaces_refused(void) {
    block blk;
    nts_body_def d;
    nts_scene* s;
    nts_error err;
    int tri_nodes[] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    nts_vec2 fan[5];
    make_block(&blk, 0.0, 0.0, 1.0, 1.0, 3, 0, 3); /* 6 nodes: 0 1 2 | 3 4 5 */
    {
        const int pairs[][4] = {
            {0, 1, 0, 2},  /* a diagonal: not a segment (pair 1) */
            {0, 1, 1, 1},  /* one node twice */
            {0, 1, 1, 0},  /* the same segment both ways: a repeat */
            {1, 2, 1, 2},  /* a repeat */
            {0, 1, 2, 6},  /* out of range: pair 1, place 1 */
            {-1, 0, 0, 1}, /* out of range: pair 0, place 0 */
        };
        const int codes[] = {NTS_EINVALID_SURFACE, NTS_EINVALID_SURFACE, NTS_EINVALID_SURFACE, NTS_EINVALID_SURFACE,
                             NTS_EINDEX_RANGE, NTS_EINDEX_RANGE};
        const int items[] = {1, 1, 1, 1, 1, 0}, places[] = {-1, -1, -1, -1, 1, 0};
        int k;
        for (k = 0; k < 6; ++k) {
            d = block_def(&blk, pairs[k], 2, NTS_ROLE_BOTH);
            s = scene_of(&d, 1, &err);
            CU_ASSERT(s == NULL);
            ASSERT_INT_EQ(err.code, codes[k]);
            CU_ASSERT(strcmp(err.option, "surface") == 0);
            ASSERT_INT_EQ(err.body, 0);
            ASSERT_INT_EQ(err.item, items[k]);
            ASSERT_INT_EQ(err.corner, places[k]);
            CU_ASSERT(strstr(err.message, "surface pair") != NULL);
            nts_scene_destroy(s);
        }
    }
    /* A mesh: its boundary is 0-1-2-3-4 (a fan around node 0); the spokes
     * 0-2 and 0-3 are inside. A pair may name the boundary either way. */
    fan[0] = nts_v2(0.0, 0.0);
    fan[1] = nts_v2(1.0, 0.0);
    fan[2] = nts_v2(1.0, 1.0);
    fan[3] = nts_v2(0.0, 1.0);
    fan[4] = nts_v2(-1.0, 0.5);
    memset(&d, 0, sizeof d);
    d.nodes = fan;
    d.node_count = 5;
    d.triangles = tri_nodes;
    d.triangle_count = 3;
    {
        const int ok[] = {2, 1, 3, 2, 4, 0};
        const int spoke[] = {1, 2, 0, 2};
        d.surface = ok;
        d.surface_count = 3;
        s = scene_of(&d, 1, &err);
        CU_ASSERT(s != NULL);
        nts_scene_destroy(s);
        d.surface = spoke;
        d.surface_count = 2;
        s = scene_of(&d, 1, &err);
        CU_ASSERT(s == NULL);
        ASSERT_INT_EQ(err.code, NTS_EINVALID_SURFACE);
        ASSERT_INT_EQ(err.item, 1);
    }
    /* An empty surface (non-NULL, no pairs): the body takes part in nothing. */
    {
        const int none[1] = {0};
        block other;
        nts_body_def defs[2];
        nts_context* ctx = nts_context_create();
        nts_options o = nts_default_options();
        nts_result r;
        make_block(&other, 0.5, 0.5, 1.0, 1.0, 2, 0, 2);
        defs[0] = block_def(&blk, none, 0, NTS_ROLE_BOTH);
        defs[1] = block_def(&other, NULL, 0, NTS_ROLE_BOTH);
        s = scene_of(defs, 2, &err);
        CU_ASSERT_FATAL(s != NULL);
        o.outputs = NTS_OUT_CONTACTS | NTS_OUT_PRESSURE;
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
        ASSERT_INT_EQ(r.contact_count, 0);
        ASSERT_INT_EQ(nts_scene_on_surface(s, 0, 0, 0), 0);
        ASSERT_INT_EQ(nts_scene_on_surface(s, 1, 0, 0), 1);
        nts_scene_destroy(s);
        nts_context_destroy(ctx);
    }
}

void register_surfaces_suite(void) {
    CU_pSuite s = CU_add_suite("surfaces", NULL, NULL);
    ADD_TEST(s, test_patch_uniform_traction);
    ADD_TEST(s, test_flush_up_to_round_off);
    ADD_TEST(s, test_flush_stack_without_surfaces);
    ADD_TEST(s, test_partial_surfaces_against_reference);
    ADD_TEST(s, test_whole_surface_is_the_default);
    ADD_TEST(s, test_off_surface_takes_no_part);
    ADD_TEST(s, test_deep_through_a_surface);
    ADD_TEST(s, test_tangent_at_a_surface_end);
    ADD_TEST(s, test_bad_surfaces_refused);
}
