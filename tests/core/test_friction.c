/* Friction suite (docs/model.md §14): a rigid block on a flat floor under a
 * tilted load sticks below tan(theta) = mu and slides above it (1% either
 * side), the slip force is mu |f_N| to round-off; the tangent against
 * central finite differences of trial evaluations in stick and in slip on
 * 120 random scenes with corners (alpha > 0), periodic boxes and both
 * scalings; frame indifference (a rotated and moved scene with its history
 * gives rotated forces) and a reversed slide reverses the force; a drag
 * cycle's dissipation is >= 0 at every step and mu |f_N| times the slip;
 * friction off (mu 0) ignores a history and gives today's bits; any thread
 * count and brute force give the same bits with friction on. */
#include <stdlib.h>
#include <string.h>

#include "nts_support.h"
#include "suites.h"
#include "test_util.h"

/* ------------------------------------------------------------ helpers */

typedef struct pair_scene {
    nts_vec2 p[2][512];
    int n[2];
    nts_body_def defs[2];
    double lx, ly;
} pair_scene;

/* The bodies' definitions, with nothing of their own (the caller may then
 * set role, alpha, friction), and the scene of them. */
static void pair_defs(pair_scene* ps) {
    int b;
    for (b = 0; b < 2; ++b) {
        memset(&ps->defs[b], 0, sizeof ps->defs[b]);
        ps->defs[b].nodes = ps->p[b];
        ps->defs[b].node_count = ps->n[b];
    }
}

static nts_scene* pair_make(pair_scene* ps) {
    nts_scene_def sd = nts_default_scene_def();
    nts_error err;
    nts_scene* s;
    sd.bodies = ps->defs;
    sd.body_count = 2;
    sd.lx = ps->lx;
    sd.ly = ps->ly;
    s = nts_scene_create(&sd, &err);
    if (s == NULL) fprintf(stderr, "\n  scene: %s\n", err.message);
    return s;
}

static nts_scene* pair_create(pair_scene* ps) {
    pair_defs(ps);
    return pair_make(ps);
}

/* A rectangle [x0, x1] x [y0, y1], counter-clockwise, nb nodes along its
 * bottom (and top), one node up each side. */
static int rectangle(nts_vec2* p, double x0, double y0, double x1, double y1, int nb) {
    int i, n = 0;
    for (i = 0; i < nb; ++i) p[n++] = nts_v2(x0 + (x1 - x0) * i / (nb - 1), y0);
    p[n++] = nts_v2(x1, 0.5 * (y0 + y1));
    for (i = nb - 1; i >= 0; --i) p[n++] = nts_v2(x0 + (x1 - x0) * i / (nb - 1), y1);
    p[n++] = nts_v2(x0, 0.5 * (y0 + y1));
    return n;
}

/* The sum of body b's forces, and of its dofs' rows and columns of the
 * tangent (the 2 x 2 stiffness of a rigid translation of body b). */
static nts_vec2 body_force(const nts_scene* s, const nts_result* r, int b) {
    const int off = nts_scene_body_node_offset(s, b), n = nts_scene_body_node_count(s, b);
    nts_vec2 f = nts_v2(0.0, 0.0);
    int i;
    for (i = 0; i < n; ++i) f = nts_add(f, r->forces[off + i]);
    return f;
}

static void body_tangent(const nts_scene* s, const nts_result* r, int b, double K[2][2]) {
    const int off = nts_scene_body_node_offset(s, b), n = nts_scene_body_node_count(s, b);
    int k;
    K[0][0] = K[0][1] = K[1][0] = K[1][1] = 0.0;
    for (k = 0; k < r->stiffness.count; ++k) {
        const int ri = r->stiffness.rows[k] / 2, ci = r->stiffness.cols[k] / 2;
        if (ri >= off && ri < off + n && ci >= off && ci < off + n)
            K[r->stiffness.rows[k] % 2][r->stiffness.cols[k] % 2] += r->stiffness.values[k];
    }
}

/* Move body b of the scene rigidly by u from its base positions. */
static void move_body(nts_scene* s, const nts_vec2* base, int n, int b, nts_vec2 u) {
    nts_vec2 x[512];
    nts_error err;
    int i;
    for (i = 0; i < n; ++i) x[i] = nts_add(base[i], u);
    CU_ASSERT_FATAL(nts_scene_set_positions(s, b, x, &err) == 0);
}

/* ------------------------------------------- the block under a tilted load */

/* A rigid block (body 1, 9 bottom nodes over a width 1) on a floor (body 0,
 * a master with alpha 0), loaded by W = (W sin t, -W cos t): the load's
 * normal part first, converged and committed, then the whole. Newton on the
 * block's translation with the contacts' tangent. Returns 1 when the second
 * step converged (the block sticks), 0 when it found no equilibrium (it
 * slides): its residual along the floor stays near W cos t (tan t - mu). */
static int tilted_block(double mu, double tan_t, double* slip_force_err, double* residual) {
    pair_scene ps;
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_history* h = nts_history_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    const double W = 1e-2, ct = 1.0 / sqrt(1.0 + tan_t * tan_t), st = tan_t * ct;
    nts_vec2 u = nts_v2(0.0, 0.0), load;
    int step, it, converged = 0;
    memset(&ps, 0, sizeof ps);
    ps.n[0] = rectangle(ps.p[0], -3.0, -1.0, 3.0, 0.0, 7);
    ps.n[1] = rectangle(ps.p[1], -0.5, 0.0, 0.5, 0.5, 9);
    pair_defs(&ps);
    ps.defs[0].role = NTS_ROLE_MASTER; /* a rigid floor with sharp corners */
    ps.defs[0].has_alpha = 1;
    ps.defs[0].alpha = 0.0;
    s = pair_make(&ps);
    CU_ASSERT_FATAL(s != NULL && ctx != NULL && h != NULL);
    o.penalty = 10.0;
    o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
    o.friction = mu;
    o.history = h;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_STIFFNESS | NTS_OUT_CONTACTS;
    *slip_force_err = 0.0;
    u.y = -0.5 * W / o.penalty; /* into the floor: a contact from the start */
    for (step = 0; step < 2; ++step) {
        load = step == 0 ? nts_v2(0.0, -W * ct) : nts_v2(W * st, -W * ct);
        converged = 0;
        for (it = 0; it < 60; ++it) {
            double K[2][2], det;
            nts_vec2 res;
            move_body(s, ps.p[1], ps.n[1], 1, u);
            CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
            res = nts_add(body_force(s, &r, 1), load); /* what is left unbalanced */
            *residual = fabs(res.x);
            if (fabs(res.x) + fabs(res.y) < 1e-13 * W) {
                converged = 1;
                break;
            }
            body_tangent(s, &r, 1, K);
            det = K[0][0] * K[1][1] - K[0][1] * K[1][0];
            if (K[0][0] == 0.0) { /* new contacts hold nothing tangentially yet: the normal alone */
                if (res.x != 0.0 || !(K[1][1] > 0.0)) break;
                u.y += res.y / K[1][1];
                continue;
            }
            if (!(fabs(det) > 0.0)) break;
            /* K du = res (K = -df/dx) */
            u.x += (K[1][1] * res.x - K[0][1] * res.y) / det;
            u.y += (-K[1][0] * res.x + K[0][0] * res.y) / det;
        }
        if (step == 0) {
            CU_ASSERT(converged);
            CU_ASSERT_FATAL(nts_history_commit(h, &r) == 0);
            ASSERT_INT_EQ(r.summary.slipping, 0);
        }
    }
    {
        int k;
        for (k = 0; k < r.contact_count; ++k) {
            const nts_contact* c = &r.contacts[k];
            if (c->state != NTS_SLIP) continue;
            /* |t| = mu |f_N| = mu (-eps g) */
            *slip_force_err = fmax(*slip_force_err, fabs(nts_length(c->tangential_force) + mu * c->penalty * c->gap) /
                                                        (mu * c->penalty * -c->gap));
        }
    }
    nts_history_destroy(h);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    return converged;
}

static void test_block_sticks_below_and_slides_above_mu(void) {
    static const double mus[] = {0.2, 0.5, 1.0};
    int k;
    for (k = 0; k < 3; ++k) {
        double err, res;
        CU_ASSERT(tilted_block(mus[k], 0.99 * mus[k], &err, &res) == 1);
        CU_ASSERT(tilted_block(mus[k], 1.01 * mus[k], &err, &res) == 0);
        /* the slip force is mu |f_N| to round-off, and the block is driven by
         * about W cos t (tan t - mu) = 1e-4 mu W */
        ASSERT_NEAR(err, 0.0, 1e-13);
        CU_ASSERT(res > 0.5e-2 * mus[k] * 1e-2 * 0.99);
    }
}

/* ------------------------------------------------ the tangent, by differences */

/* A random pair of polygons pressed into each other, a first evaluation
 * committed, then a random tangential shear of one: the trial evaluation's
 * tangent against central differences of its forces (the same history),
 * column by column; a column is skipped where a contact changes feature or
 * state between the two sides (a switch). Returns the worst relative error
 * and counts the slipping and sticking contacts seen. */
static double fd_case(uint64_t seed, int* sticking, int* slipping, int* columns) {
    pair_scene ps;
    nts_scene* s;
    nts_context* ctx = nts_context_create();
    nts_history* h = nts_history_create();
    nts_options o = nts_default_options();
    nts_result r, rp, rm;
    nts_error err;
    nts_csr K;
    uint64_t st = seed * 6364136223846793005ull + 1442695040888963407ull;
    const int periodic = seed % 3 == 0;
    const double R = 1.0, gap0 = 0.05 + 0.1 * ntsx_urand(&st);
    int b, i, j, n, k;
    double worst = 0.0, scale = 0.0;
    nts_vec2 base[2][512];
    memset(&ps, 0, sizeof ps);
    for (b = 0; b < 2; ++b) {
        const int m = 24 + (int)(ntsx_urand(&st) * 40);
        const double cx = 2.0 + (b ? 2.0 * R - gap0 : 0.0), cy = 2.0 + 0.3 * (ntsx_urand(&st) - 0.5);
        const double ph = 6.283185307179586 * ntsx_urand(&st);
        for (i = 0; i < m; ++i) {
            const double a = ph + 6.283185307179586 * (i + 0.3 * (ntsx_urand(&st) - 0.5)) / m;
            const double rr = R * (1.0 + 0.1 * (ntsx_urand(&st) - 0.5));
            ps.p[b][i] = nts_v2(cx + rr * cos(a), cy + rr * sin(a));
        }
        ps.n[b] = m;
    }
    if (periodic) {
        ps.lx = ps.ly = 7.0;
        for (i = 0; i < ps.n[1]; ++i) ps.p[1][i].x -= 7.0; /* across the box: its images meet */
    }
    s = pair_create(&ps);
    CU_ASSERT_FATAL(s != NULL);
    o.alpha = seed % 7 == 0 ? 0.0 : 0.05 + 0.4 * ntsx_urand(&st); /* 0: segments and vertices */
    o.penalty = 100.0;
    o.penalty_scaling = seed % 2 ? NTS_PENALTY_PER_LENGTH : NTS_PENALTY_PER_NODE;
    o.friction = 0.1 + 0.5 * ntsx_urand(&st);
    o.tangential_penalty = seed % 5 == 0 ? 0.0 : 30.0 + 200.0 * ntsx_urand(&st);
    o.solver = seed % 4 == 1 ? NTS_SOLVER_NEWTON : NTS_SOLVER_CLOSED_FORM;
    o.history = h;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_CONTACTS | NTS_OUT_STIFFNESS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_history_commit(h, &r) == 0);
    /* shear body 1 along y by up to a quarter of its segments, and squeeze it a little */
    {
        const double shear = 0.06 * (ntsx_urand(&st) - 0.5), sq = 0.01 * ntsx_urand(&st);
        for (b = 0; b < 2; ++b)
            for (i = 0; i < ps.n[b]; ++i) {
                base[b][i] = ps.p[b][i];
                if (b == 1) base[b][i] = nts_add(base[b][i], nts_v2(-sq, shear));
            }
        for (b = 0; b < 2; ++b) CU_ASSERT_FATAL(nts_scene_set_positions(s, b, base[b], &err) == 0);
    }
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    *sticking += r.summary.sticking;
    *slipping += r.summary.slipping;
    CU_ASSERT_FATAL(nts_triplets_to_csr(&r.stiffness, &K, &err) == 0);
    n = nts_scene_node_count(s);
    {
        /* the states and features of the unperturbed trial */
        int c0 = r.contact_count;
        int state0[256], key0[256];
        double* fp = (double*)calloc(2 * (size_t)n, sizeof(double));
        double* fm = (double*)calloc(2 * (size_t)n, sizeof(double));
        const double hstep = 1e-7;
        CU_ASSERT_FATAL(c0 < 256 && fp && fm);
        for (k = 0; k < c0; ++k) {
            state0[k] = r.contacts[k].state;
            key0[k] = (int)r.contacts[k].kind * 1000000 + r.contacts[k].master_nodes[0] * 1000 + r.contacts[k].slave_node;
        }
        for (i = 0; i < n; ++i) scale = fmax(scale, fabs(r.forces[i].x) + fabs(r.forces[i].y));
        for (j = 0; j < 2 * n; ++j) {
            const int bj = j / 2 < ps.n[0] ? 0 : 1, nj = j / 2 - (bj ? ps.n[0] : 0);
            int sgn, same = 1;
            for (sgn = 0; sgn < 2; ++sgn) {
                nts_vec2 x[512];
                nts_result* rr = sgn ? &rp : &rm;
                double* f = sgn ? fp : fm;
                memcpy(x, base[bj], sizeof(nts_vec2) * (size_t)ps.n[bj]);
                if (j % 2) x[nj].y += sgn ? hstep : -hstep;
                else x[nj].x += sgn ? hstep : -hstep;
                CU_ASSERT_FATAL(nts_scene_set_positions(s, bj, x, &err) == 0);
                CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, rr, &err) == 0);
                if (rr->contact_count != c0) same = 0;
                for (k = 0; k < rr->contact_count && same; ++k)
                    if (rr->contacts[k].state != state0[k] ||
                        (int)rr->contacts[k].kind * 1000000 + rr->contacts[k].master_nodes[0] * 1000 +
                                rr->contacts[k].slave_node != key0[k])
                        same = 0;
                for (i = 0; i < n; ++i) {
                    f[2 * i] = rr->forces[i].x;
                    f[2 * i + 1] = rr->forces[i].y;
                }
            }
            CU_ASSERT_FATAL(nts_scene_set_positions(s, bj, base[bj], &err) == 0);
            if (!same) continue; /* a switch of feature or state: not differentiable there */
            ++*columns;
            for (i = 0; i < 2 * n; ++i) {
                double kij = 0.0, fd = -(fp[i] - fm[i]) / (2.0 * hstep);
                int q;
                for (q = K.row_start[i]; q < K.row_start[i + 1]; ++q)
                    if (K.cols[q] == j) kij = K.values[q];
                worst = fmax(worst, fabs(kij - fd));
            }
        }
        free(fp);
        free(fm);
    }
    {
        /* the largest tangent entry sets the scale of the differences' error */
        int q;
        double kmax = 0.0;
        for (q = 0; q < K.nnz; ++q) kmax = fmax(kmax, fabs(K.values[q]));
        worst = kmax > 0.0 ? worst / kmax : 0.0;
    }
    (void)scale;
    nts_csr_free(&K);
    nts_history_destroy(h);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    return worst;
}

static void test_tangent_against_differences(void) {
    int seed, sticking = 0, slipping = 0, columns = 0;
    double worst = 0.0;
    for (seed = 1; seed <= 120; ++seed) {
        const double w = fd_case((uint64_t)seed, &sticking, &slipping, &columns);
        if (w > 1e-6) fprintf(stderr, "\n  friction FD seed %d: relative error %.3g\n", seed, w);
        worst = fmax(worst, w);
    }
    fprintf(stderr, "[friction tangent: %d sticking, %d slipping contacts, %d columns, worst relative error %.2g]\n",
            sticking, slipping, columns, worst);
    CU_ASSERT(sticking > 100 && slipping > 100 && columns > 2000);
    ASSERT_NEAR(worst, 0.0, 1e-6);
}

/* ------------------------------------------------ a block dragged on a floor */

/* A rigid block (9 bottom nodes over width 1) pressed 1e-3 into a floor
 * (master, alpha 0), then moved rigidly by dx from where the history was
 * committed. */
typedef struct drag {
    pair_scene ps;
    nts_scene* s;
    nts_context* ctx;
    nts_history* h;
    nts_options o;
} drag;

static void drag_open(drag* d, double mu) {
    nts_result r;
    nts_error err;
    memset(d, 0, sizeof *d);
    d->ps.n[0] = rectangle(d->ps.p[0], -30.0, -1.0, 30.0, 0.0, 121);
    d->ps.n[1] = rectangle(d->ps.p[1], -0.5, -1e-3, 0.5, 0.5, 9);
    pair_defs(&d->ps);
    d->ps.defs[0].role = NTS_ROLE_MASTER;
    d->ps.defs[0].has_alpha = 1;
    d->ps.defs[0].alpha = 0.0;
    d->s = pair_make(&d->ps);
    d->ctx = nts_context_create();
    d->h = nts_history_create();
    CU_ASSERT_FATAL(d->s != NULL && d->ctx != NULL && d->h != NULL);
    d->o = nts_default_options();
    d->o.penalty = 100.0;
    d->o.tangential_penalty = 300.0;
    d->o.penalty_scaling = NTS_PENALTY_PER_LENGTH;
    d->o.friction = mu;
    d->o.history = d->h;
    d->o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL | NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(nts_evaluate(d->ctx, d->s, &d->o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_history_commit(d->h, &r) == 0);
}

/* The block at dx: evaluate (and commit when asked). */
static void drag_at(drag* d, double dx, int commit, nts_result* r) {
    nts_error err;
    move_body(d->s, d->ps.p[1], d->ps.n[1], 1, nts_v2(dx, 0.0));
    CU_ASSERT_FATAL(nts_evaluate(d->ctx, d->s, &d->o, r, &err) == 0);
    if (commit) CU_ASSERT_FATAL(nts_history_commit(d->h, r) == 0);
}

static void drag_close(drag* d) {
    nts_history_destroy(d->h);
    nts_context_destroy(d->ctx);
    nts_scene_destroy(d->s);
}

/* Dragged 0 -> +D -> -D -> 0 in steps, committing each: every step's
 * dissipation is >= 0, and the whole is mu N times the slip distance
 * 4 D - 5 g_e (the elastic range g_e = mu |f_N| / eps_T is travelled once
 * at the start and twice at each of the two reversals), N the normal load. */
static void test_drag_cycle_dissipation(void) {
    const double mu = 0.4, D = 0.05, step = D / 40.0;
    drag d;
    nts_result r;
    double total = 0.0, N = 0.0, x = 0.0, ge;
    int k, leg, negative = 0, slipping = 0;
    drag_open(&d, mu);
    for (leg = 0; leg < 3; ++leg) {
        const double target = leg == 0 ? D : (leg == 1 ? -D : 0.0);
        const int n = (int)floor(fabs(target - x) / step + 0.5);
        const double dir = target > x ? 1.0 : -1.0;
        for (k = 1; k <= n; ++k) {
            drag_at(&d, x + dir * step * k, 1, &r);
            negative += r.summary.dissipation < 0.0;
            slipping += r.summary.slipping;
            total += r.summary.dissipation;
        }
        x = target;
    }
    for (k = 0; k < r.contact_count; ++k) N += -r.contacts[k].penalty * r.contacts[k].gap;
    ASSERT_INT_EQ(r.contact_count, 9);
    ASSERT_INT_EQ(negative, 0);
    CU_ASSERT(slipping > 0);
    /* g_e = mu eps |g| / eps_T, the same for every node (both penalties scale with its length) */
    ge = mu * d.o.penalty * 1e-3 / d.o.tangential_penalty;
    ASSERT_NEAR(total, mu * N * (4.0 * D - 5.0 * ge), 1e-9 * mu * N * D);
    drag_close(&d);
}

/* From one committed state, a slide of +dx and one of -dx give opposite
 * tangential forces (the block and the floor are symmetric about x = 0),
 * in stick and in slip. */
static void test_reversed_slide_reverses_the_force(void) {
    static const double dxs[] = {5e-5, 5e-3}; /* the elastic range g_e is 1e-4 */
    int k;
    for (k = 0; k < 2; ++k) {
        drag d;
        nts_result r;
        nts_vec2 fp, fm;
        drag_open(&d, 0.3);
        drag_at(&d, dxs[k], 0, &r);
        fp = body_force(d.s, &r, 1);
        ASSERT_INT_EQ(k == 0 ? r.summary.sticking : r.summary.slipping, 9);
        drag_at(&d, -dxs[k], 0, &r);
        fm = body_force(d.s, &r, 1);
        CU_ASSERT(fabs(fp.x) > 1e-6);
        ASSERT_NEAR(fp.x, -fm.x, 1e-13 * fabs(fp.x));
        ASSERT_NEAR(fp.y, fm.y, 1e-13 * fabs(fp.y));
        drag_close(&d);
    }
}

/* Frame indifference: the scene rotated by phi and moved, with the same
 * history (anchors are material points: features and parameters), gives
 * the forces rotated, and the same energy, dissipation and states. */
static void test_frame_indifference(void) {
    int seed;
    for (seed = 1; seed <= 10; ++seed) {
        pair_scene a, b;
        nts_scene *sa, *sb;
        nts_context* ctx = nts_context_create();
        nts_history* h = nts_history_create();
        nts_options o = nts_default_options();
        nts_result ra, rb;
        nts_error err;
        uint64_t st = (uint64_t)seed * 977u;
        const double phi = 6.283185307179586 * ntsx_urand(&st), c = cos(phi), sn = sin(phi);
        const nts_vec2 shift = nts_v2(10.0 * ntsx_urand(&st), -7.0 * ntsx_urand(&st));
        int i, bo, k, n;
        memset(&a, 0, sizeof a);
        for (bo = 0; bo < 2; ++bo) {
            const int m = 40;
            for (i = 0; i < m; ++i) {
                const double t = 6.283185307179586 * i / m + 0.1 * bo;
                a.p[bo][i] = nts_v2((bo ? 1.9 : 0.0) + cos(t), 0.1 * bo + sin(t));
            }
            a.n[bo] = m;
        }
        b = a;
        sa = pair_create(&a);
        CU_ASSERT_FATAL(sa != NULL);
        o.penalty = 100.0;
        o.friction = 0.3;
        o.history = h;
        o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_CONTACTS;
        CU_ASSERT_FATAL(nts_evaluate(ctx, sa, &o, &ra, &err) == 0);
        CU_ASSERT_FATAL(nts_history_commit(h, &ra) == 0);
        /* slide body 1 along y: some contacts stick, some slip */
        for (i = 0; i < a.n[1]; ++i) a.p[1][i].y += 0.004 + 0.002 * seed;
        for (bo = 0; bo < 2; ++bo) {
            for (i = 0; i < a.n[bo]; ++i)
                b.p[bo][i] = nts_add(nts_v2(c * a.p[bo][i].x - sn * a.p[bo][i].y, sn * a.p[bo][i].x + c * a.p[bo][i].y),
                                     shift);
            CU_ASSERT_FATAL(nts_scene_set_positions(sa, bo, a.p[bo], &err) == 0);
        }
        sb = pair_create(&b);
        CU_ASSERT_FATAL(sb != NULL);
        CU_ASSERT_FATAL(nts_evaluate(ctx, sa, &o, &ra, &err) == 0);
        {
            /* the other context: ra stays valid */
            nts_context* cb = nts_context_create();
            CU_ASSERT_FATAL(nts_evaluate(cb, sb, &o, &rb, &err) == 0);
            n = nts_scene_node_count(sa);
            ASSERT_INT_EQ(ra.contact_count, rb.contact_count);
            CU_ASSERT(ra.summary.slipping > 0 || ra.summary.sticking > 0);
            for (k = 0; k < ra.contact_count && k < rb.contact_count; ++k) ASSERT_INT_EQ(ra.contacts[k].state, rb.contacts[k].state);
            for (i = 0; i < n; ++i) {
                const nts_vec2 f = ra.forces[i], g = rb.forces[i];
                const double scale = 1e-9 * (1.0 + nts_length(f));
                ASSERT_NEAR(g.x, c * f.x - sn * f.y, scale);
                ASSERT_NEAR(g.y, sn * f.x + c * f.y, scale);
            }
            ASSERT_NEAR(rb.summary.energy, ra.summary.energy, 1e-9 * ra.summary.energy);
            ASSERT_NEAR(rb.summary.dissipation, ra.summary.dissipation, 1e-9 * (ra.summary.dissipation + 1e-300));
            nts_context_destroy(cb);
        }
        nts_scene_destroy(sa);
        nts_scene_destroy(sb);
        nts_history_destroy(h);
        nts_context_destroy(ctx);
    }
}

/* Friction off (mu 0) ignores any history and gives the same bits as no
 * friction at all; with friction on, 1 to 4 threads and brute force give
 * the same bits; a new contact starts sticking with no tangential force; a
 * warm context allocates nothing. */
static long g_allocs;
static void* count_alloc(size_t size, void* user) {
    (void)user;
    __atomic_add_fetch(&g_allocs, 1, __ATOMIC_RELAXED);
    return malloc(size);
}
static void count_free(void* p, void* user) {
    (void)user;
    free(p);
}

static void test_bits_threads_and_new_contacts(void) {
    test_packing p = make_packing(36, 24, 1.05, 2.0, 1, 77u);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context *c0 = nts_context_create(), *c1 = nts_context_create();
    nts_history* h = nts_history_create();
    nts_options o = nts_default_options();
    nts_result r0, r1;
    nts_error err;
    const int n = nts_scene_node_count(s);
    int th, k, i;
    CU_ASSERT_FATAL(s != NULL && h != NULL);
    o.penalty = 50.0;
    o.outputs = NTS_OUT_ALL;
    /* friction off, a history given or not: the same bits */
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    o.friction = 0.5;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    /* new contacts: sticking, no tangential force, anchors at their closest points */
    CU_ASSERT(r1.summary.contacts > 20);
    ASSERT_INT_EQ(r1.summary.sticking, r1.summary.contacts);
    ASSERT_INT_EQ(r1.anchor_count, r1.contact_count);
    for (k = 0; k < r1.contact_count; ++k) {
        CU_ASSERT(r1.contacts[k].tangential_force.x == 0.0 && r1.contacts[k].tangential_force.y == 0.0);
        ASSERT_INT_EQ(r1.anchors[k].slave_node, r1.contacts[k].slave_node);
        ASSERT_NEAR(r1.anchors[k].param, r1.contacts[k].kind == NTS_KIND_VERTEX ? 0.0 : r1.contacts[k].param, 0.0);
    }
    CU_ASSERT_FATAL(nts_history_commit(h, &r1) == 0);
    o.friction = 0.0;
    o.history = h;
    CU_ASSERT_FATAL(nts_evaluate(c1, s, &o, &r1, &err) == 0);
    CU_ASSERT(r1.anchors == NULL && r1.anchor_count == 0);
    CU_ASSERT(memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)n) == 0);
    CU_ASSERT(memcmp(&r0.summary, &r1.summary, sizeof r0.summary) == 0);
    ASSERT_INT_EQ(r0.stiffness.count, r1.stiffness.count);
    CU_ASSERT(memcmp(r0.stiffness.values, r1.stiffness.values, sizeof(double) * (size_t)r0.stiffness.count) == 0);
    /* friction on, everything moved a little: threads and brute force bitwise */
    {
        nts_vec2 x[4096];
        for (k = 0; k < p.count; ++k) {
            for (i = 0; i < p.bodies[k].node_count; ++i)
                x[i] = nts_add(p.bodies[k].nodes[i], nts_v2(0.003 * sin(1.3 * k + i), 0.003 * cos(0.7 * k - i)));
            CU_ASSERT_FATAL(nts_scene_set_positions(s, k, x, &err) == 0);
        }
    }
    o.friction = 0.4;
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    CU_ASSERT(r0.summary.slipping > 0 && r0.summary.sticking > 0 && r0.summary.dissipation > 0.0);
    for (th = 1; th <= 5; ++th) {
        nts_options ot = o;
        ot.threads = th <= 4 ? th : 0;
        ot.search = th == 5 ? NTS_SEARCH_BRUTE_FORCE : NTS_SEARCH_CELLS;
        CU_ASSERT_FATAL(nts_evaluate(c1, s, &ot, &r1, &err) == 0);
        CU_ASSERT(memcmp(r0.forces, r1.forces, sizeof(nts_vec2) * (size_t)n) == 0);
        CU_ASSERT(r0.summary.energy == r1.summary.energy && r0.summary.dissipation == r1.summary.dissipation);
        CU_ASSERT(memcmp(&r0.summary.virial, &r1.summary.virial, sizeof(nts_virial)) == 0);
        ASSERT_INT_EQ(r0.contact_count, r1.contact_count);
        CU_ASSERT(memcmp(r0.contacts, r1.contacts, sizeof(nts_contact) * (size_t)r0.contact_count) == 0);
        CU_ASSERT(memcmp(r0.anchors, r1.anchors, sizeof(nts_anchor) * (size_t)r0.anchor_count) == 0);
        ASSERT_INT_EQ(r0.stiffness.count, r1.stiffness.count);
        if (r0.stiffness.count == r1.stiffness.count)
            CU_ASSERT(memcmp(r0.stiffness.values, r1.stiffness.values, sizeof(double) * (size_t)r0.stiffness.count) ==
                      0);
    }
    /* the virial is no longer symmetric with slipping contacts */
    CU_ASSERT(r0.summary.virial.xy != r0.summary.virial.yx);
    /* a warm context allocates nothing, friction on */
    g_allocs = 0;
    nts_set_allocator(count_alloc, count_free, NULL);
    CU_ASSERT_FATAL(nts_evaluate(c0, s, &o, &r0, &err) == 0);
    nts_set_allocator(NULL, NULL, NULL);
    ASSERT_INT_EQ(g_allocs, 0);
    nts_history_destroy(h);
    nts_context_destroy(c0);
    nts_context_destroy(c1);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* Every pair that meets at coefficient 0 (the options' 0.4, one of the two
 * bodies 0: the smaller of the two): none of friction runs, and a step after
 * a tangential move is the frictionless answer bit for bit (docs/model.md
 * §14); with the body at 0.2 the same step rubs. */
static void test_zero_pairs_are_frictionless_bit_for_bit(void) {
    pair_scene ps;
    const double mus[2] = {0.0, 0.2};
    int m;
    ps.lx = ps.ly = 0.0;
    ps.n[0] = rectangle(ps.p[0], 0.0, 0.0, 4.0, 1.0, 9);
    ps.n[1] = rectangle(ps.p[1], 1.0, 0.98, 3.0, 2.0, 6);
    for (m = 0; m < 2; ++m) {
        nts_context* c = nts_context_create();
        nts_history* h = nts_history_create();
        nts_options o = nts_default_options();
        nts_options off;
        nts_result r, r0;
        nts_error err;
        nts_vec2 moved[512];
        nts_scene* s;
        int i, n;
        pair_defs(&ps);
        ps.defs[0].has_friction = 1;
        ps.defs[0].friction = mus[m];
        s = pair_make(&ps);
        CU_ASSERT_FATAL(s != NULL && c != NULL && h != NULL);
        n = nts_scene_node_count(s);
        o.penalty = 100.0;
        o.outputs = NTS_OUT_ALL;
        o.friction = 0.4;
        o.history = h;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == NTS_OK);
        CU_ASSERT_FATAL(r.contact_count > 0 && nts_history_commit(h, &r) == NTS_OK);
        for (i = 0; i < ps.n[1]; ++i) moved[i] = nts_add(ps.p[1][i], nts_v2(0.01, 0.0));
        CU_ASSERT_FATAL(nts_scene_set_positions(s, 1, moved, &err) == NTS_OK);
        off = o;
        off.friction = 0.0;
        off.history = NULL;
        CU_ASSERT_FATAL(nts_evaluate(c, s, &off, &r0, &err) == NTS_OK);
        {
            nts_vec2* f0 = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
            double* k0 = (double*)malloc(sizeof(double) * (size_t)r0.stiffness.count);
            const double e0 = r0.summary.energy;
            int same;
            CU_ASSERT_FATAL(f0 != NULL && k0 != NULL);
            memcpy(f0, r0.forces, sizeof(nts_vec2) * (size_t)n);
            memcpy(k0, r0.stiffness.values, sizeof(double) * (size_t)r0.stiffness.count);
            CU_ASSERT_FATAL(nts_evaluate(c, s, &o, &r, &err) == NTS_OK);
            same = memcmp(f0, r.forces, sizeof(nts_vec2) * (size_t)n) == 0 && r.summary.energy == e0 &&
                   r.stiffness.count == r0.stiffness.count &&
                   memcmp(k0, r.stiffness.values, sizeof(double) * (size_t)r0.stiffness.count) == 0;
            if (m == 0) {
                CU_ASSERT(same);
                ASSERT_INT_EQ(r.anchor_count, 0);
            } else {
                CU_ASSERT(!same && r.summary.dissipation + fabs(r.summary.virial.xy - r.summary.virial.yx) > 0.0);
            }
            free(f0);
            free(k0);
        }
        nts_history_destroy(h);
        nts_context_destroy(c);
        nts_scene_destroy(s);
    }
}

/* nts_history_set refuses what is not an anchor of the scene, naming it. */
static void test_history_set_refuses_bad_anchors(void) {
    pair_scene ps;
    nts_scene* s;
    nts_history* h = nts_history_create();
    nts_error err;
    nts_anchor a[2];
    int k;
    memset(&ps, 0, sizeof ps);
    ps.n[0] = rectangle(ps.p[0], -3.0, -1.0, 3.0, 0.0, 7);  /* 16 nodes: 0..6 bottom, 7, 8..14 top, 15 */
    ps.n[1] = rectangle(ps.p[1], -0.5, 0.0, 0.5, 0.5, 3);
    s = pair_create(&ps);
    CU_ASSERT_FATAL(s != NULL && h != NULL);
    for (k = 0; k < 8; ++k) {
        nts_anchor good = {1, 0, 0, NTS_KIND_SEGMENT, {9, 10, -1}, 0.5};
        int want = NTS_EINVALID_HISTORY;
        a[0] = good;
        switch (k) {
        case 0: want = NTS_OK; break;
        case 1: a[0].master_body = 1; break;               /* itself */
        case 2: a[0].slave_node = 99; break;
        case 3: a[0].nodes[1] = 12; break;                 /* not a segment */
        case 4: a[0].nodes[2] = 11; break;                 /* a third node on a segment */
        case 5: a[0].param = NAN; break;
        case 6: a[0].kind = NTS_KIND_CORNER; a[0].nodes[2] = 11; want = NTS_OK; break; /* 9, 10, 11: a corner */
        case 7: a[0].kind = NTS_KIND_CORNER; a[0].nodes[2] = 9; break;
        }
        ASSERT_INT_EQ(nts_history_set(h, s, a, 1, &err), want);
        if (want != NTS_OK) {
            CU_ASSERT(strcmp(err.option, "history") == 0);
            ASSERT_INT_EQ(err.item, 0);
        }
    }
    {
        /* the same key twice */
        nts_anchor good = {1, 0, 0, NTS_KIND_SEGMENT, {10, 9, -1}, 0.25};
        int count;
        a[0] = good;
        a[1] = good;
        ASSERT_INT_EQ(nts_history_set(h, s, a, 2, &err), NTS_EINVALID_HISTORY);
        ASSERT_INT_EQ(err.item, 1); /* the second entry of the key */
        a[1].slave_node = 1;
        ASSERT_INT_EQ(nts_history_set(h, s, a, 2, &err), NTS_OK);
        CU_ASSERT(nts_history_anchors(h, &count) != NULL);
        ASSERT_INT_EQ(count, 2);
        CU_ASSERT(nts_history_bytes(h) >= 2 * sizeof(nts_anchor));
    }
    {
        /* an empty list on a fresh history (no buffer yet: the sanitizers see it) */
        nts_history* e = nts_history_create();
        int count = -1;
        CU_ASSERT_FATAL(e != NULL);
        ASSERT_INT_EQ(nts_history_set(e, s, NULL, 0, &err), NTS_OK);
        (void)nts_history_anchors(e, &count);
        ASSERT_INT_EQ(count, 0);
        nts_history_destroy(e);
    }
    nts_history_destroy(h);
    nts_scene_destroy(s);
}

/* A history committed from one scene's evaluation, used on another (a floor
 * of 400 nodes, then of 16: the anchors name floor nodes past its end; then
 * a floor of as many nodes but whose contact lies elsewhere): refused where
 * it is used, NTS_EINVALID_HISTORY naming the entry, never read out of range
 * (it was: forces from memory past the floor, tangent triplets outside the
 * matrix; a helper's campaign through the Fortran module found it). The
 * same history on its own scene, and on that scene made anew, goes on. */
static void test_a_history_of_another_scene_is_refused(void) {
    pair_scene big, small;
    nts_scene *a, *b, *again;
    nts_context* ctx = nts_context_create();
    nts_history* h = nts_history_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    int count = 0;
    memset(&big, 0, sizeof big);  /* (err.item: the first entry at fault in key order) */
    memset(&small, 0, sizeof small);
    big.n[0] = rectangle(big.p[0], -3.0, -1.0, 3.0, 0.0, 199);   /* 400 nodes: the top edge's are 200..398 */
    big.n[1] = rectangle(big.p[1], -0.5, -0.01, 0.5, 0.5, 3);   /* pressed into it */
    small.n[0] = rectangle(small.p[0], -3.0, -1.0, 3.0, 0.0, 7); /* 16 nodes */
    small.n[1] = big.n[1];
    memcpy(small.p[1], big.p[1], sizeof(nts_vec2) * (size_t)big.n[1]);
    a = pair_create(&big);
    b = pair_create(&small);
    CU_ASSERT_FATAL(a != NULL && b != NULL && ctx != NULL && h != NULL);
    o.friction = 0.5;
    o.search_radius = 0.2;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_STIFFNESS;
    ASSERT_INT_EQ(nts_evaluate(ctx, a, &o, &r, &err), NTS_OK);
    CU_ASSERT_FATAL(r.anchor_count > 0);
    ASSERT_INT_EQ(nts_history_commit(h, &r), NTS_OK);
    {
        /* some anchor on the floor names a node past the small floor's 16 */
        const nts_anchor* an = nts_history_anchors(h, &count);
        int k, past = 0;
        for (k = 0; k < count; ++k) past += an[k].master_body == 0 && an[k].nodes[0] >= 16;
        CU_ASSERT(past > 0);
    }
    o.history = h;
    /* on its own scene: a trial from the committed anchors */
    ASSERT_INT_EQ(nts_evaluate(ctx, a, &o, &r, &err), NTS_OK);
    /* on the other: refused, the entry named */
    ASSERT_INT_EQ(nts_evaluate(ctx, b, &o, &r, &err), NTS_EINVALID_HISTORY);
    CU_ASSERT(strcmp(err.option, "history") == 0);
    CU_ASSERT(err.item >= 0 && err.item < count);
    CU_ASSERT(strstr(err.message, "history entry") != NULL);
    /* and on its own scene made anew (the same topology): it goes on */
    again = pair_create(&big);
    CU_ASSERT_FATAL(again != NULL);
    ASSERT_INT_EQ(nts_evaluate(ctx, again, &o, &r, &err), NTS_OK);
    nts_scene_destroy(again);
    nts_history_destroy(h);
    nts_context_destroy(ctx);
    nts_scene_destroy(a);
    nts_scene_destroy(b);
}

void register_friction_suite(void) {
    CU_pSuite s = CU_add_suite("friction", NULL, NULL);
    ADD_TEST(s, test_block_sticks_below_and_slides_above_mu);
    ADD_TEST(s, test_tangent_against_differences);
    ADD_TEST(s, test_drag_cycle_dissipation);
    ADD_TEST(s, test_reversed_slide_reverses_the_force);
    ADD_TEST(s, test_frame_indifference);
    ADD_TEST(s, test_bits_threads_and_new_contacts);
    ADD_TEST(s, test_zero_pairs_are_frictionless_bit_for_bit);
    ADD_TEST(s, test_history_set_refuses_bad_anchors);
    ADD_TEST(s, test_a_history_of_another_scene_is_refused);
}
