/* libntscontact_mpi against nts_evaluate on the whole scene, under
 * mpirun -np N (ctest mpi_np1..4): every rank builds the whole scene for the
 * reference and owns a scattered share of its bodies (body b on rank
 * 7 b mod N, not blocks: the host decides). Open and periodic packings, a
 * long wall, a big body over all the slabs; positions moved so that bodies
 * cross ranks (and the periodic box's edge); the forces on each rank's nodes,
 * the energy, virial and counts must be the same bits. Bad input on one rank
 * must give every rank the same error. Exit 0 when all holds. */
#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <ntscontact/mpi.h>

static int rank_, size_, failures;
static long long last_sent; /* this rank's bytes sent in compare's evaluation */

#define CHECK(cond, ...)                                                    \
    do {                                                                    \
        if (!(cond)) {                                                      \
            ++failures;                                                     \
            fprintf(stderr, "rank %d/%d: %s:%d: ", rank_, size_, __FILE__, __LINE__); \
            fprintf(stderr, __VA_ARGS__);                                   \
            fputc('\n', stderr);                                            \
        }                                                                   \
    } while (0)

typedef struct scene_data {
    int bodies;
    nts_body_def* defs;
    nts_vec2* nodes; /* all bodies' nodes, body after body */
    int* offset;     /* bodies + 1 */
    double lx, ly;
} scene_data;

static unsigned rng_state = 12345u;
static double rnd(void) {
    rng_state = rng_state * 1664525u + 1013904223u;
    return (double)(rng_state >> 8) / 16777216.0;
}

/* count disks on a jittered grid (pressed into each other), a long wall
 * under them, and a big disk over the middle. */
static scene_data make_scene(int count, int periodic) {
    scene_data d;
    const int side = (int)ceil(sqrt((double)count)), n = 20, wall = periodic ? 0 : 400, big = periodic ? 0 : 300;
    int b, k, at = 0;
    memset(&d, 0, sizeof d);
    d.bodies = count + (wall > 0) + (big > 0);
    d.defs = (nts_body_def*)calloc((size_t)d.bodies, sizeof(nts_body_def));
    d.offset = (int*)calloc((size_t)d.bodies + 1, sizeof(int));
    d.nodes = (nts_vec2*)calloc((size_t)(count * n + wall + big), sizeof(nts_vec2));
    for (b = 0; b < count; ++b) {
        const double cx = (b % side) + 0.5 + 0.04 * (rnd() - 0.5), cy = (b / side) + 0.5 + 0.04 * (rnd() - 0.5);
        const double r = 0.54 * (0.92 + 0.12 * rnd()), ph = rnd();
        d.offset[b] = at;
        for (k = 0; k < n; ++k) {
            d.nodes[at + k].x = cx + r * cos(ph + 2 * M_PI * k / n);
            d.nodes[at + k].y = cy + r * sin(ph + 2 * M_PI * k / n);
        }
        at += n;
    }
    if (wall > 0) { /* a thin floor as long as the scene */
        d.offset[b] = at;
        for (k = 0; k < wall / 2; ++k) {
            d.nodes[at + k].x = -1.0 + (side + 2.0) * k / (wall / 2);
            d.nodes[at + k].y = -0.4;
        }
        for (k = 0; k < wall / 2; ++k) {
            d.nodes[at + wall / 2 + k].x = side + 1.0 - (side + 2.0) * k / (wall / 2);
            d.nodes[at + wall / 2 + k].y = 0.02;
        }
        at += wall;
        ++b;
    }
    if (big > 0) {
        d.offset[b] = at;
        for (k = 0; k < big; ++k) {
            d.nodes[at + k].x = 0.5 * side + 0.3 * side * cos(2 * M_PI * k / big);
            d.nodes[at + k].y = 0.5 * side + 0.3 * side * sin(2 * M_PI * k / big);
        }
        at += big;
        ++b;
    }
    d.offset[d.bodies] = at;
    for (b = 0; b < d.bodies; ++b) {
        d.defs[b].nodes = d.nodes + d.offset[b];
        d.defs[b].node_count = d.offset[b + 1] - d.offset[b];
    }
    if (b == count + 2) d.defs[count].has_alpha = 1; /* the wall: sharp corners */
    d.lx = d.ly = periodic ? side : 0.0;
    return d;
}

/* Four bodies of other kinds placed among the disks (between four of them,
 * pressed into them), appended to d: a triangle mesh with interior nodes
 * (a fan around its centre), a ring with a hole (two loops), a disk whose
 * contact surface is half its loop, and disks that may touch themselves
 * (every third). Their loops and triangles are static: one scene at a time. */
enum { FAN = 16, RING_OUT = 24, RING_IN = 12, HALF = 20 };
static int fan_tri[3 * FAN], ring_loops[RING_OUT + RING_IN], ring_start[3], half_surface[2 * (HALF / 2)];
static void add_specials(scene_data* d) {
    const int extra = (FAN + 1) + (RING_OUT + RING_IN) + HALF + 20, b0 = d->bodies, n0 = d->offset[d->bodies];
    const double cx[4] = {1.0, 3.0, 2.0, 4.0}, cy[4] = {1.0, 2.0, 3.0, 4.0};
    int b, k, at = n0;
    d->bodies += 4;
    d->defs = (nts_body_def*)realloc(d->defs, sizeof(nts_body_def) * (size_t)d->bodies);
    d->offset = (int*)realloc(d->offset, sizeof(int) * ((size_t)d->bodies + 1));
    d->nodes = (nts_vec2*)realloc(d->nodes, sizeof(nts_vec2) * (size_t)(n0 + extra));
    memset(d->defs + b0, 0, 4 * sizeof(nts_body_def));
    d->offset[b0] = at; /* the fan: its centre last */
    for (k = 0; k < FAN; ++k) {
        d->nodes[at + k] = nts_v2(cx[0] + 0.3 * cos(2 * M_PI * k / FAN), cy[0] + 0.3 * sin(2 * M_PI * k / FAN));
        fan_tri[3 * k] = FAN;
        fan_tri[3 * k + 1] = k;
        fan_tri[3 * k + 2] = (k + 1) % FAN;
    }
    d->nodes[at + FAN] = nts_v2(cx[0] + 0.01, cy[0] - 0.02);
    at += FAN + 1;
    d->offset[b0 + 1] = at; /* the ring: the outer loop counter-clockwise, the hole clockwise */
    for (k = 0; k < RING_OUT; ++k) {
        d->nodes[at + k] = nts_v2(cx[1] + 0.32 * cos(2 * M_PI * k / RING_OUT), cy[1] + 0.32 * sin(2 * M_PI * k / RING_OUT));
        ring_loops[k] = k;
    }
    for (k = 0; k < RING_IN; ++k) {
        d->nodes[at + RING_OUT + k] =
            nts_v2(cx[1] + 0.15 * cos(-2 * M_PI * k / RING_IN), cy[1] + 0.15 * sin(-2 * M_PI * k / RING_IN));
        ring_loops[RING_OUT + k] = RING_OUT + k;
    }
    ring_start[0] = 0;
    ring_start[1] = RING_OUT;
    ring_start[2] = RING_OUT + RING_IN;
    at += RING_OUT + RING_IN;
    d->offset[b0 + 2] = at; /* half a contact surface */
    for (k = 0; k < HALF; ++k)
        d->nodes[at + k] = nts_v2(cx[2] + 0.3 * cos(2 * M_PI * k / HALF), cy[2] + 0.3 * sin(2 * M_PI * k / HALF));
    for (k = 0; k < HALF / 2; ++k) {
        half_surface[2 * k] = k;
        half_surface[2 * k + 1] = k + 1;
    }
    at += HALF;
    d->offset[b0 + 3] = at; /* a C-shaped body that may touch itself: its arms' tips close to each other */
    for (k = 0; k < 20; ++k) {
        const double a = 0.35 + (2 * M_PI - 0.7) * k / 19, r = k % 2 == 0 ? 0.34 : 0.3;
        d->nodes[at + k] = nts_v2(cx[3] + r * cos(a), cy[3] + r * sin(a));
    }
    at += 20;
    d->offset[d->bodies] = at;
    for (b = 0; b < d->bodies; ++b) { /* (realloc moved the nodes) */
        d->defs[b].nodes = d->nodes + d->offset[b];
        d->defs[b].node_count = d->offset[b + 1] - d->offset[b];
    }
    d->defs[b0].triangles = fan_tri;
    d->defs[b0].triangle_count = FAN;
    d->defs[b0 + 1].loop_nodes = ring_loops;
    d->defs[b0 + 1].loop_start = ring_start;
    d->defs[b0 + 1].loop_count = 2;
    d->defs[b0 + 2].surface = half_surface;
    d->defs[b0 + 2].surface_count = HALF / 2;
    d->defs[b0 + 3].self_contact = 1;
    for (b = 0; b < b0; b += 3) d->defs[b].self_contact = 1;
}

static void free_scene(scene_data* d) {
    free(d->defs);
    free(d->nodes);
    free(d->offset);
}

/* This rank's bodies' nodes of `all` (every body's, body after body), in
 * its order, into mine; how many. */
static int mine_of(const scene_data* d, const int* ids, int count, const nts_vec2* all, nts_vec2* mine) {
    int k, at = 0;
    for (k = 0; k < count; ++k) {
        const int n = d->offset[ids[k] + 1] - d->offset[ids[k]];
        memcpy(mine + at, all + d->offset[ids[k]], sizeof(nts_vec2) * (size_t)n);
        at += n;
    }
    return at;
}

/* The distributed answer against the whole scene's, at the current positions. */
static int last_replayed; /* this rank's part replayed its kept candidate list in compare's evaluation */
/* ... with options `opt`, and friction's history h (NULL: none): its
 * anchors given to both, the reference's answer committed to it. */
static int compare_with(const scene_data* d, ntsm_scene* m, nts_scene* whole, const int* mine, int count,
                        const char* what, const nts_options* opt, nts_history* h) {
    nts_context* ctx = nts_context_create();
    nts_options ref_opt = *opt;
    nts_result ref;
    ntsm_result got;
    nts_error err;
    const unsigned outputs = opt->outputs;
    int k, rc, at = 0, i, rebuilt = -1;
    if (h != NULL) {
        int n = 0;
        const nts_anchor* anchors = nts_history_anchors(h, &n);
        CHECK(ntsm_scene_set_history(m, anchors, n) == NTS_OK, "%s: history", what);
        ref_opt.history = h;
    }
    rc = nts_evaluate(ctx, whole, &ref_opt, &ref, &err);
    CHECK(rc == 0, "%s: reference: %s", what, err.message);
    rc = ntsm_evaluate(m, opt, &got, &err);
    CHECK(rc == 0, "%s: distributed: %s", what, err.message);
    if (rc == 0 && h != NULL) {
        CHECK(memcmp(&got.summary.dissipation, &ref.summary.dissipation, sizeof(double)) == 0 &&
                  got.summary.sticking == ref.summary.sticking && got.summary.slipping == ref.summary.slipping,
              "%s: friction: dissipation %.17g vs %.17g, sticking %d vs %d, slipping %d vs %d", what,
              got.summary.dissipation, ref.summary.dissipation, got.summary.sticking, ref.summary.sticking,
              got.summary.slipping, ref.summary.slipping);
        CHECK(nts_history_commit(h, &ref) == NTS_OK, "%s: commit", what);
    }
    if (rc == 0) {
        rebuilt = got.stats.rebuilt;
        last_sent = got.stats.bytes_sent;
        last_replayed = got.stats.candidates_replayed;
        CHECK(memcmp(&got.summary.energy, &ref.summary.energy, sizeof(double)) == 0, "%s: energy %.17g vs %.17g", what,
              got.summary.energy, ref.summary.energy);
        CHECK(memcmp(&got.summary.virial, &ref.summary.virial, sizeof(nts_virial)) == 0, "%s: virial", what);
        CHECK(got.summary.contacts == ref.summary.contacts && got.summary.gaps == ref.summary.gaps &&
                  got.summary.deep_contacts == ref.summary.deep_contacts,
              "%s: counts %d %d %d vs %d %d %d", what, got.summary.contacts, got.summary.gaps,
              got.summary.deep_contacts, ref.summary.contacts, ref.summary.gaps, ref.summary.deep_contacts);
        CHECK(got.summary.max_penetration == ref.summary.max_penetration, "%s: max penetration", what);
        CHECK(got.summary.search_radius == ref.summary.search_radius, "%s: radius %.17g vs %.17g", what,
              got.summary.search_radius, ref.summary.search_radius);
        CHECK(got.warning_count == ref.warning_count, "%s: warnings", what);
        for (k = 0; k < count && (outputs & NTS_OUT_FORCES); ++k) {
            const int b = mine[k], n = d->offset[b + 1] - d->offset[b];
            for (i = 0; i < n; ++i)
                CHECK(memcmp(&got.forces[at + i], &ref.forces[d->offset[b] + i], sizeof(nts_vec2)) == 0,
                      "%s: body %d node %d: force differs", what, b, i);
            at += n;
        }
        {
            /* the whole answer on rank 0, shaped as nts_evaluate's: the
             * counts, an empty array NULL, the tangent's size only when asked */
            nts_result g;
            const int grc = ntsm_gather(m, 0, &g, &err);
            CHECK(grc == 0, "%s: gather: %s", what, err.message);
            if (grc == 0 && rank_ == 0)
                CHECK(g.contact_count == ref.contact_count && (g.contacts == NULL) == (ref.contacts == NULL) &&
                          g.gap_count == ref.gap_count && (g.gaps == NULL) == (ref.gaps == NULL) &&
                          g.anchor_count == ref.anchor_count && (g.anchors == NULL) == (ref.anchors == NULL) &&
                          g.stiffness.count == ref.stiffness.count && g.stiffness.size == ref.stiffness.size &&
                          (g.stiffness.rows == NULL) == (ref.stiffness.rows == NULL),
                      "%s: gathered: contacts %d/%d gaps %d/%d anchors %d/%d triplets %d/%d size %d/%d", what,
                      g.contact_count, ref.contact_count, g.gap_count, ref.gap_count, g.anchor_count, ref.anchor_count,
                      g.stiffness.count, ref.stiffness.count, g.stiffness.size, ref.stiffness.size);
        }
        if (rank_ == 0)
            printf("%s: %d ranks, %d contacts (%d deep), energy %.17g, bitwise equal; this rank sent %lld bytes, "
                   "held %d of %d surface entries\n",
                   what, size_, got.summary.contacts, got.summary.deep_contacts, got.summary.energy,
                   got.stats.bytes_sent, got.stats.part_entries, got.summary.surface_nodes);
    }
    nts_context_destroy(ctx);
    return rebuilt;
}

static int compare(const scene_data* d, ntsm_scene* m, nts_scene* whole, const int* mine, int count, const char* what,
                   unsigned outputs) {
    nts_options opt = nts_default_options();
    opt.outputs = outputs;
    return compare_with(d, m, whole, mine, count, what, &opt, NULL);
}

static void run_case(int count, int periodic, int specials, const char* name) {
    scene_data d = make_scene(count, periodic);
    nts_scene_def def = nts_default_scene_def();
    nts_scene* whole;
    ntsm_scene* m;
    nts_body_def* owned;
    if (specials) add_specials(&d);
    owned = (nts_body_def*)calloc((size_t)d.bodies, sizeof(nts_body_def));
    int* ids = (int*)calloc((size_t)d.bodies, sizeof(int));
    nts_vec2* moved = (nts_vec2*)calloc((size_t)d.offset[d.bodies], sizeof(nts_vec2));
    nts_vec2* mine_pos = (nts_vec2*)calloc((size_t)d.offset[d.bodies], sizeof(nts_vec2));
    nts_error err;
    int b, k, count_mine = 0, step;
    char what[96];
    def.bodies = d.defs;
    def.body_count = d.bodies;
    def.lx = d.lx;
    def.ly = d.ly;
    whole = nts_scene_create(&def, &err);
    CHECK(whole != NULL, "%s: whole scene: %s", name, err.message);
    for (b = 0; b < d.bodies; ++b)
        if ((7 * b) % size_ == rank_) {
            owned[count_mine] = d.defs[b];
            ids[count_mine++] = b;
        }
    m = ntsm_scene_create(MPI_COMM_WORLD, owned, ids, count_mine, d.lx, d.ly, nts_default_limits(), &err);
    CHECK(m != NULL, "%s: distributed scene: %s", name, err.message);
    if (m != NULL) { /* equal shares, never moved by measured times: the counts of kept steps below hold */
        double* equal = (double*)malloc(sizeof(double) * (size_t)size_);
        for (k = 0; k < size_; ++k) equal[k] = 1.0;
        CHECK(ntsm_scene_set_weights(m, equal) == NTS_OK, "%s: equal weights", name);
        free(equal);
    }
    if (whole != NULL && m != NULL) {
        int kept = 0, made = 0, replayed = 0, all_replayed;
        snprintf(what, sizeof what, "%s, at rest", name);
        CHECK(compare(&d, m, whole, ids, count_mine, what, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL) == 1,
              "%s: the first evaluation makes the decomposition", name);
        /* A random walk of small steps (the kept decomposition), then one
         * step past the skin: the same bits either way. */
        for (step = 0; step < 6; ++step) {
            const double amp = step == 5 ? 0.2 : 0.004;
            int r2;
            for (k = 0; k < d.offset[d.bodies]; ++k) {
                d.nodes[k].x += amp * (rnd() - 0.5);
                d.nodes[k].y += amp * (rnd() - 0.5);
            }
            mine_of(&d, ids, count_mine, d.nodes, mine_pos);
            CHECK(nts_scene_update_positions(whole, d.nodes, &err) == 0, "%s: walk: %s", name, err.message);
            CHECK(ntsm_scene_update_positions(m, mine_pos, &err) == 0, "%s: walk: %s", name, err.message);
            snprintf(what, sizeof what, "%s, walk %d", name, step);
            r2 = compare(&d, m, whole, ids, count_mine, what, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL);
            kept += r2 == 0;
            made += r2 == 1 && step == 5;
            replayed += last_replayed;
        }
        CHECK(kept >= 3, "%s: the small steps kept the decomposition only %d times", name, kept);
        /* the kept parts replayed their candidate lists (the first kept
         * evaluation builds them); not the two disks, whose median segment
         * (the wall's and the big disk's) is so short that every step of the
         * walk moves past the lists' skin */
        if (rank_ == 0) printf("%s: this rank's part replayed its candidate list %d times\n", name, replayed);
        MPI_Allreduce(&replayed, &all_replayed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
        if (count > 2) CHECK(all_replayed >= 3, "%s: the parts replayed their lists %d times at most", name, all_replayed);
        CHECK(made == 1, "%s: the step past the skin did not rebuild", name);
        {
            /* a NaN on the last rank only: every rank refuses the update and
             * keeps the positions it had (the next answer is the old one's) */
            const int n_mine = mine_of(&d, ids, count_mine, d.nodes, mine_pos);
            int rc2;
            if (rank_ == size_ - 1 && n_mine > 0) mine_pos[n_mine - 1].x = NAN;
            for (k = 0; k < n_mine; ++k) mine_pos[k].y += 0.01; /* the others' would move */
            rc2 = ntsm_scene_update_positions(m, mine_pos, &err);
            CHECK(rc2 != 0 && err.code == NTS_ENONFINITE, "%s: NaN on one rank: rc %d code %d", name, rc2, err.code);
            snprintf(what, sizeof what, "%s, after a refused update", name);
            compare(&d, m, whole, ids, count_mine, what, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL);
        }
        if (size_ > 1) {
            /* different options on different ranks: an error, not a hang */
            nts_options opt = nts_default_options();
            ntsm_result r;
            opt.penalty = rank_ == 0 ? 1.0 : 2.0;
            CHECK(ntsm_evaluate(m, &opt, &r, &err) == NTS_EINVALID_OPTION, "%s: differing options accepted", name);
        }
        if (size_ > 1) {
            /* uneven weights (the host's: rank 0 three times as fast): the
             * slabs are cut anew at those shares, and the answer is the same
             * bits; weights that differ between ranks, or are not positive,
             * are refused on every rank */
            double* w = (double*)malloc(sizeof(double) * (size_t)size_);
            long long* owned_all = (long long*)malloc(sizeof(long long) * (size_t)size_);
            long long mine_owned;
            nts_options opt = nts_default_options();
            ntsm_result r;
            for (k = 0; k < size_; ++k) w[k] = k == 0 ? 3.0 : 1.0;
            CHECK(ntsm_scene_set_weights(m, w) == NTS_OK, "%s: weights", name);
            snprintf(what, sizeof what, "%s, weights 3:1", name);
            CHECK(compare(&d, m, whole, ids, count_mine, what, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL) == 1,
                  "%s: new weights did not cut the slabs anew", name);
            CHECK(ntsm_evaluate(m, &opt, &r, &err) == 0, "%s: weights: %s", name, err.message);
            mine_owned = r.stats.owned_slaves;
            MPI_Allgather(&mine_owned, 1, MPI_LONG_LONG, owned_all, 1, MPI_LONG_LONG, MPI_COMM_WORLD);
            if (count > 100)
                CHECK(owned_all[0] > 2 * owned_all[1], "%s: weights 3:1 gave rank 0 %lld slaves and rank 1 %lld", name,
                      owned_all[0], owned_all[1]);
            w[size_ - 1] = rank_ == 0 ? 1.0 : 2.0; /* differs between ranks (when there are two or more) */
            CHECK(ntsm_scene_set_weights(m, w) == NTS_OK, "%s: weights", name);
            CHECK(ntsm_evaluate(m, &opt, &r, &err) == NTS_EINVALID_OPTION, "%s: differing weights accepted", name);
            w[size_ - 1] = 0.0;
            CHECK(ntsm_scene_set_weights(m, w) == NTS_OK, "%s: weights", name);
            CHECK(ntsm_evaluate(m, &opt, &r, &err) == NTS_EINVALID_OPTION, "%s: a zero weight accepted", name);
            CHECK(ntsm_scene_set_weights(m, NULL) == NTS_OK, "%s: weights", name); /* by measured time again */
            snprintf(what, sizeof what, "%s, weights by time", name);
            compare(&d, m, whole, ids, count_mine, what, NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL);
            free(w);
            free(owned_all);
        }
        for (step = 1; step <= 2; ++step) {
            /* every body moves a third of the scene along x and turns a
             * little: most cross a rank (and the box's edge when periodic) */
            const double shift = step * 0.37 * sqrt((double)count), turn = 0.01 * step;
            for (k = 0; k < d.offset[d.bodies]; ++k) {
                const nts_vec2 p = d.nodes[k];
                moved[k].x = p.x * cos(turn) - p.y * sin(turn) + shift;
                moved[k].y = p.x * sin(turn) + p.y * cos(turn);
            }
            mine_of(&d, ids, count_mine, moved, mine_pos);
            CHECK(nts_scene_update_positions(whole, moved, &err) == 0, "%s: move: %s", name, err.message);
            CHECK(ntsm_scene_update_positions(m, mine_pos, &err) == 0, "%s: move: %s", name, err.message);
            snprintf(what, sizeof what, "%s, moved %d", name, step);
            compare(&d, m, whole, ids, count_mine, what,
                    step == 1 ? NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL : NTS_OUT_FORCES | NTS_OUT_ENERGY);
        }
    }
    ntsm_scene_destroy(m);
    nts_scene_destroy(whole);
    free(owned);
    free(ids);
    free(moved);
    free(mine_pos);
    free_scene(&d);
}

/* The parts' kept candidate lists under what a solver's loop changes: two
 * threads on every rank, friction's history carried from step to step, and
 * the skin changed mid-run (smaller; 0: parts made every evaluation and no
 * list; the default again). A random walk of small steps, each bitwise
 * equal to one process; the lists replayed while the decomposition is kept,
 * never with a skin of 0. */
static void kept_lists(int periodic) {
    const double skins[4] = {-1.0, 0.03, 0.0, -1.0};
    scene_data d;
    nts_scene_def def = nts_default_scene_def();
    nts_scene* whole;
    ntsm_scene* m;
    nts_body_def* owned;
    nts_vec2* mine_pos;
    nts_history* h = nts_history_create();
    nts_options opt = nts_default_options();
    nts_error err;
    int* ids;
    int b, k, phase, step, count_mine = 0;
    char what[96];
    rng_state = periodic ? 99u : 98u;
    d = make_scene(periodic ? 100 : 81, periodic);
    owned = (nts_body_def*)calloc((size_t)d.bodies, sizeof(nts_body_def));
    ids = (int*)calloc((size_t)d.bodies, sizeof(int));
    mine_pos = (nts_vec2*)calloc((size_t)d.offset[d.bodies], sizeof(nts_vec2));
    def.bodies = d.defs;
    def.body_count = d.bodies;
    def.lx = d.lx;
    def.ly = d.ly;
    whole = nts_scene_create(&def, &err);
    CHECK(whole != NULL && h != NULL, "kept lists: whole scene: %s", err.message);
    for (b = 0; b < d.bodies; ++b)
        if ((7 * b) % size_ == rank_) {
            owned[count_mine] = d.defs[b];
            ids[count_mine++] = b;
        }
    m = ntsm_scene_create(MPI_COMM_WORLD, owned, ids, count_mine, d.lx, d.ly, nts_default_limits(), &err);
    CHECK(m != NULL, "kept lists: distributed scene: %s", err.message);
    opt.threads = 2;
    opt.friction = 0.3;
    opt.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    if (m != NULL && whole != NULL && h != NULL) {
        double* equal = (double*)malloc(sizeof(double) * (size_t)size_);
        for (k = 0; k < size_; ++k) equal[k] = 1.0;
        CHECK(ntsm_scene_set_weights(m, equal) == NTS_OK, "kept lists: equal weights");
        free(equal);
        for (phase = 0; phase < 4; ++phase) {
            int replayed = 0, made = 0, all_replayed;
            ntsm_scene_set_skin(m, skins[phase]);
            for (step = 0; step < 5; ++step) {
                for (k = 0; k < d.offset[d.bodies]; ++k) { /* a walk, and every body slides along x */
                    d.nodes[k].x += 0.004 * (rnd() - 0.5) + 0.002;
                    d.nodes[k].y += 0.004 * (rnd() - 0.5);
                }
                mine_of(&d, ids, count_mine, d.nodes, mine_pos);
                CHECK(nts_scene_update_positions(whole, d.nodes, &err) == 0, "kept lists: %s", err.message);
                CHECK(ntsm_scene_update_positions(m, mine_pos, &err) == 0, "kept lists: %s", err.message);
                snprintf(what, sizeof what, "kept lists (%s), skin %g, step %d", periodic ? "periodic" : "open",
                         skins[phase], step);
                made += compare_with(&d, m, whole, ids, count_mine, what, &opt, h) == 1;
                replayed += last_replayed;
            }
            {
                int n = 0;
                nts_history_anchors(h, &n);
                CHECK(n > 0, "kept lists: no friction anchor carried (the history is not exercised)");
            }
            MPI_Allreduce(&replayed, &all_replayed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
            if (skins[phase] == 0.0)
                CHECK(all_replayed == 0 && made == 5, "kept lists: a skin of 0 replayed %d times, made the parts %d times",
                      all_replayed, made);
            else /* a new skin makes the parts anew, the next evaluation builds the lists, the others replay them */
                CHECK(all_replayed >= 3, "kept lists: skin %g: the parts replayed their lists %d times of 5",
                      skins[phase], all_replayed);
        }
    }
    ntsm_scene_destroy(m);
    nts_scene_destroy(whole);
    nts_history_destroy(h);
    free(owned);
    free(ids);
    free(mine_pos);
    free_scene(&d);
}

/* A degenerate body on the last rank only: every rank gets its error. */
static void bad_input(void) {
    nts_vec2 good[8], bad[4] = {{0, 0}, {1, 0}, {1, 0}, {0, 1}};
    nts_body_def def;
    nts_error err;
    ntsm_scene* m;
    int k, id = rank_ == size_ - 1 ? 2 * size_ - 1 : rank_, codes[2], all[2];
    for (k = 0; k < 8; ++k) {
        good[k].x = 3.0 * rank_ + cos(2 * M_PI * k / 8);
        good[k].y = sin(2 * M_PI * k / 8);
    }
    memset(&def, 0, sizeof def);
    def.nodes = rank_ == size_ - 1 ? bad : good;
    def.node_count = rank_ == size_ - 1 ? 4 : 8;
    /* ids: 0 .. size-2 on the first ranks, the bad body's id past them */
    id = rank_ == size_ - 1 ? size_ - 1 : rank_;
    m = ntsm_scene_create(MPI_COMM_WORLD, &def, &id, 1, 0.0, 0.0, nts_default_limits(), &err);
    if (m != NULL) { /* the fault may only show when the segments are computed */
        nts_options opt = nts_default_options();
        ntsm_result r;
        int rc = ntsm_evaluate(m, &opt, &r, &err);
        CHECK(rc != 0, "the degenerate body was accepted");
        ntsm_scene_destroy(m);
    }
    codes[0] = err.code;
    codes[1] = err.body;
    MPI_Allreduce(codes, all, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    CHECK(err.code != 0 && all[0] == codes[0] && all[1] == codes[1] && err.body == size_ - 1,
          "bad input: code %d body %d (min over ranks %d %d; want body %d)", err.code, err.body, all[0], all[1],
          size_ - 1);
    if (rank_ == 0) printf("bad input on rank %d: every rank got \"%s\" (body %d)\n", size_ - 1, err.message, err.body);
}

/* The ranks must give one periodic box: the last rank's own (another lx,
 * or none against a box) is refused on every rank with the same error,
 * never evaluated with its own minimum images (it was: an answer, silently
 * not one process's). */
static void boxes_differ(void) {
    nts_vec2 nodes[8];
    nts_body_def def;
    nts_error err;
    ntsm_scene* m;
    int k, id = rank_, variant, codes[2], all[2];
    for (k = 0; k < 8; ++k) {
        nodes[k].x = 3.0 * rank_ + 1.5 + cos(2 * M_PI * k / 8);
        nodes[k].y = 1.5 + sin(2 * M_PI * k / 8);
    }
    memset(&def, 0, sizeof def);
    def.nodes = nodes;
    def.node_count = 8;
    for (variant = 0; variant < 2; ++variant) {
        const double lx = 3.0 * size_ + 3.0, ly = 20.0;
        const int last = rank_ == size_ - 1 && size_ > 1;
        m = ntsm_scene_create(MPI_COMM_WORLD, &def, &id, 1, last ? (variant == 0 ? lx + 1.0 : 0.0) : lx,
                              last && variant == 1 ? 0.0 : ly, nts_default_limits(), &err);
        if (size_ == 1) { /* one rank: nothing to differ */
            CHECK(m != NULL, "one rank's box refused: %s", err.message);
            ntsm_scene_destroy(m);
            continue;
        }
        CHECK(m == NULL && err.code == NTS_EINVALID_ARGUMENT && strstr(err.message, "periodic boxes differ") != NULL,
              "differing boxes (variant %d): %s", variant, m != NULL ? "accepted" : err.message);
        if (m != NULL) ntsm_scene_destroy(m);
        codes[0] = err.code;
        codes[1] = -err.code;
        MPI_Allreduce(codes, all, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        CHECK(all[0] == err.code && -all[1] == err.code, "differing boxes: not the same error on every rank");
    }
    if (rank_ == 0 && size_ > 1) printf("differing boxes: every rank refused them\n");
}

/* One process names the body its checks meet first (a pass over every
 * body at a time: coordinates, then loops); a rank that holds its bodies in
 * descending global order, two of them bad (the lower one held second),
 * must name the one one process names, with its message, on every rank:
 * of two faults of one kind the lower body (it named the first it held),
 * of a loop's fault on the lower and a coordinate's on the higher the
 * higher (a try of each lower body alone named the lower). At the scene's
 * making, and when the faults come with new positions. */
static void place(nts_vec2* nodes, int b) {
    int k;
    for (k = 0; k < 8; ++k) nodes[8 * b + k] = nts_v2(3.0 * b + 1.5 + cos(2 * M_PI * k / 8), 1.5 + sin(2 * M_PI * k / 8));
}

static void spoil(nts_vec2* nodes, int low, int high, int mixed) {
    nodes[8 * low + 5] = nodes[8 * low + 4]; /* a segment of zero length */
    if (mixed) nodes[8 * high + 3].x = 1e200; /* beyond the coordinates' range: checked first */
    else nodes[8 * high + 3] = nodes[8 * high + 2];
}

static void lowest_failing_body(void) {
    const int per = 3, total = per * size_;
    nts_vec2* nodes = (nts_vec2*)calloc((size_t)total * 8, sizeof(nts_vec2));
    nts_body_def* all = (nts_body_def*)calloc((size_t)total, sizeof(nts_body_def));
    nts_body_def mine[3];
    nts_vec2 moved[3 * 8];
    int ids[3], b, k, mixed, codes[2], both[2];
    const int low = total - 3, high = total - 1; /* both on the last rank, held high first */
    nts_scene_def def = nts_default_scene_def();
    nts_error want, err;
    nts_scene* whole;
    ntsm_scene* m;
    for (b = 0; b < total; ++b) {
        place(nodes, b);
        all[b].nodes = nodes + 8 * b;
        all[b].node_count = 8;
    }
    def.bodies = all;
    def.body_count = total;
    for (k = 0; k < per; ++k) { /* rank r: bodies 3 r + 2, 3 r + 1, 3 r */
        ids[k] = per * rank_ + per - 1 - k;
        mine[k] = all[ids[k]];
    }
    for (mixed = 0; mixed < 2; ++mixed) {
        /* at the scene's making */
        spoil(nodes, low, high, mixed);
        whole = nts_scene_create(&def, &want);
        CHECK(whole == NULL && want.body == (mixed ? high : low), "one process: body %d refused", want.body);
        nts_scene_destroy(whole);
        m = ntsm_scene_create(MPI_COMM_WORLD, mine, ids, per, 0.0, 0.0, nts_default_limits(), &err);
        CHECK(m == NULL && err.code == want.code && err.body == want.body && strcmp(err.message, want.message) == 0,
              "failing body (%s faults): got %s (body %d, code %d), want \"%s\" (body %d, code %d)",
              mixed ? "mixed" : "like", m != NULL ? "a scene" : err.message, err.body, err.code, want.message,
              want.body, want.code);
        ntsm_scene_destroy(m);
        codes[0] = err.body;
        codes[1] = -err.body;
        MPI_Allreduce(codes, both, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
        CHECK(both[0] == err.body && -both[1] == err.body, "failing body: not the same on every rank");
        if (rank_ == 0)
            printf("two bad bodies held in descending order (%s faults): rank 0 named body %d, one process %d\n",
                   mixed ? "mixed" : "like", err.body, want.body);
        /* the same faults arriving with new positions of a scene that held */
        place(nodes, low);
        place(nodes, high);
        whole = nts_scene_create(&def, &err);
        m = ntsm_scene_create(MPI_COMM_WORLD, mine, ids, per, 0.0, 0.0, nts_default_limits(), &err);
        CHECK(whole != NULL && m != NULL, "the scene of fine bodies refused: %s", err.message);
        spoil(nodes, low, high, mixed);
        want = nts_error_none();
        if (whole != NULL) { /* one process's update of every body (nodes: the whole's rows in order) */
            const int rc = nts_scene_update_positions(whole, nodes, &want);
            CHECK(rc != NTS_OK && want.body == (mixed ? high : low), "one process's update: body %d refused",
                  want.body);
        }
        nts_scene_destroy(whole);
        for (k = 0; k < per; ++k) memcpy(moved + 8 * k, all[ids[k]].nodes, sizeof(nts_vec2) * 8);
        if (m != NULL) {
            const int rc = ntsm_scene_update_positions(m, moved, &err);
            CHECK(rc == want.code && err.body == want.body && strcmp(err.message, want.message) == 0,
                  "failing body, new positions (%s faults): \"%s\" (body %d, code %d), want \"%s\" (body %d)",
                  mixed ? "mixed" : "like", err.message, err.body, rc, want.message, want.body);
        }
        ntsm_scene_destroy(m);
        place(nodes, low);
        place(nodes, high);
    }
    free(nodes);
    free(all);
}

/* A host that owns rows of bodies (a square periodic box, or an open scene
 * with its wall and big disk on the last rank), then the same scene turned a
 * quarter (the same bodies in the same order, the same owners, so the same
 * chunks: its rows now run along y, rank 0's at the high x, so the slabs
 * run along -x): the slabs follow the host (docs/distributed.md, "The slabs
 * follow the host"), so a kept step sends about as many bytes either way
 * (within half; the same here); slabs along x for both send several times
 * more for the first (most of its forces to other ranks' nodes). Every step
 * bitwise equal to one process, the second one kept. */
static void affinity(int periodic) {
    const int side = 16;
    long long bytes[2] = {0, 0};
    int turn;
    for (turn = 0; turn < 2; ++turn) {
        scene_data d;
        nts_scene_def def = nts_default_scene_def();
        nts_scene* whole;
        nts_body_def* owned;
        int* ids;
        double* equal = (double*)malloc(sizeof(double) * (size_t)size_);
        nts_error err;
        ntsm_scene* m;
        int b, k, count_mine = 0;
        long long mine;
        rng_state = 4242u;
        d = make_scene(side * side, periodic);
        if (turn == 1)
            for (k = 0; k < d.offset[d.bodies]; ++k) { /* (x, y) -> (L - y, x): rows become columns */
                const nts_vec2 p = d.nodes[k];
                d.nodes[k].x = side - p.y;
                d.nodes[k].y = p.x;
            }
        owned = (nts_body_def*)calloc((size_t)d.bodies, sizeof(nts_body_def));
        ids = (int*)calloc((size_t)d.bodies, sizeof(int));
        def.bodies = d.defs;
        def.body_count = d.bodies;
        def.lx = d.lx;
        def.ly = d.ly;
        whole = nts_scene_create(&def, &err);
        CHECK(whole != NULL, "affinity: whole scene: %s", err.message);
        for (b = 0; b < d.bodies; ++b)
            if ((b < side * side ? (b / side) * size_ / side : size_ - 1) == rank_) { /* (the wall and the big disk: the last rank) */
                owned[count_mine] = d.defs[b];
                ids[count_mine++] = b;
            }
        m = ntsm_scene_create(MPI_COMM_WORLD, owned, ids, count_mine, d.lx, d.ly, nts_default_limits(), &err);
        CHECK(m != NULL, "affinity: distributed scene: %s", err.message);
        if (m != NULL && whole != NULL) {
            for (k = 0; k < size_; ++k) equal[k] = 1.0;
            CHECK(ntsm_scene_set_weights(m, equal) == NTS_OK, "affinity: equal weights");
            compare(&d, m, whole, ids, count_mine, turn == 0 ? "host owns rows along x" : "host owns rows along y",
                    NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL);
            /* a kept step, the same bits */
            CHECK(compare(&d, m, whole, ids, count_mine, "kept", NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL) == 0,
                  "affinity: the second step made the slabs anew");
            mine = last_sent;
            MPI_Allreduce(&mine, &bytes[turn], 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
        }
        ntsm_scene_destroy(m);
        nts_scene_destroy(whole);
        free(owned);
        free(ids);
        free(equal);
        free_scene(&d);
    }
    if (rank_ == 0)
        printf("affinity (%s): a kept step sends %lld bytes (rows along x), %lld (along y)\n", periodic ? "periodic" : "open",
               bytes[0], bytes[1]);
    if (size_ > 1)
        CHECK(2 * bytes[0] <= 3 * bytes[1] && 2 * bytes[1] <= 3 * bytes[0],
              "affinity: a kept step sends %lld bytes when the host's rows run along x, %lld along y", bytes[0],
              bytes[1]);
}

int main(int argc, char** argv) {
    int total;
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    run_case(300, 0, 0, "open packing, a long wall, a big disk");
    run_case(256, 1, 0, "periodic packing");
    run_case(2, 0, 0, "two disks");
    run_case(36, 0, 1, "open: a mesh, a ring with a hole, a surface, self-contact");
    run_case(36, 1, 1, "periodic: a mesh, a ring with a hole, a surface, self-contact");
    affinity(1);
    affinity(0);
    kept_lists(0); /* (open: the wall and the big disk too; an evaluation on more ranks than cores costs a
                    * scheduler's slice a collective round, the periodic case would double the suite's time) */
    bad_input();
    boxes_differ();
    lowest_failing_body();
    MPI_Allreduce(&failures, &total, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    if (rank_ == 0) printf("%s\n", total == 0 ? "all equal" : "FAILED");
    MPI_Finalize();
    return total == 0 ? 0 : 1;
}
