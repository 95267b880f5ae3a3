/* The kept candidate list (candidates.c, docs/model.md §15): per slave, the
 * masters within its reach plus a skin at the last build, which the search
 * tries instead of screening the cells, while no node has moved far enough
 * that the list could miss a master the cells would give. */
#ifndef NTSCONTACT_CANDIDATES_H
#define NTSCONTACT_CANDIDATES_H

#include "segments.h"

/* The lists are built and read by chunks of this many slaves (the search's
 * CHUNK_SLAVES: one build task per search chunk), each chunk's masters in
 * one buffer of its own. */
enum { KEPT_CHUNK = 1024 };
/* At most this many masters kept per chunk (about 64 a slave): past it the
 * bodies overlap far more than contact does, and the evaluation searches
 * from scratch (the same answer; the list only saves time). */
enum { KEPT_CHUNK_BUDGET = 64 * KEPT_CHUNK + 65536 };

struct nts_candidates {
    double skin_asked;         /* < 0: 0.3 r at each build */
    /* The scene and options of the last build (built: the lists are valid
     * for them, at positions x). */
    const nts_scene* scene;
    unsigned long long serial;
    int built;
    int surface_count;
    double alpha, ext;
    /* At the build: the search radius, the skin, the radii kept (inner =
     * r + skin, which the search tries; outer = inner + r, which the
     * widened searches of the deep contacts read), the round-off allowance
     * of the frame, and the factor of the largest displacement in the test
     * of validity (eq. (29)). */
    double r, skin, inner, outer, pad, factor;
    /* Per surface entry, the radius of its list's outer ring (eq. (30)):
     * inner + its longer segment (at least r, at most 4 r) + 2 skin / factor,
     * enough for the widened searches that ask for it; outer the largest. */
    double* ring;
    int ring_cap;
    double moved;              /* the largest displacement since the build, at the last evaluation */
    nts_vec2* x;               /* surface entries' positions at the build */
    int x_cap;
    /* Slave e's masters: chunk[e / KEPT_CHUNK][lo[e] .. hi[e]), those within
     * the inner radius first, up to mid[e], but for those the build's replay
     * found cannot offer (eq. (32)), which it moved past mid[e]; hi[e] = -1:
     * not a slave. */
    int* span;                 /* lo, mid, hi: 3 surface_count */
    int span_cap;
    int** chunk;
    int* chunk_cap;
    int* chunk_used;
    int chunk_slots;
    float* key_base;           /* per master key of the build's cells: sqrt(reach2) - outer (scaled) + slack */
    int key_base_cap;
    long long evaluations, builds, cell_builds, kept;
    long long pruned;          /* of kept, those the last build's replay moved out of the inner lists */
    int backoff;               /* evaluations left before a build is tried again (one was over budget) */
    /* Whether a replay asks for the masters' lines ahead (nts_kept_ahead):
     * each way's search time a replay for this scene, a running mean (0: not
     * timed yet), the replays timed, whether this evaluation built the lists
     * (its replay is not timed) and whether its time is to be taken, and
     * the evaluations that asked and that did not. */
    double ahead_s[2];
    long long ahead_timed;
    int ahead_built, ahead_take;
    long long ahead_replays, plain_replays;
};

/* Slave e's chunk buffer (e >= 0: the division is a shift). */
static inline int* kept_chunk_of(const nts_candidates* kc, int e) { return kc->chunk[(unsigned)e / KEPT_CHUNK]; }

/* Whether the lists hold, for scene s whose nodes moved at most `moved`
 * since the build (the segment pass's), every master the cells could give
 * within radius r (eq. (29)); sets kc->moved.
 * `pad`: the frame's round-off allowance now. */
int nts_kept_valid(nts_candidates* kc, const nts_scene* s, double moved, double alpha, double ext, double r,
                   double pad);
/* The positions the segment pass measures the displacement from (its
 * `since`): the last build's, when kc is built for scene s; else NULL. */
const nts_vec2* nts_kept_since(const nts_candidates* kc, const nts_scene* s);
/* What a widened search's radius rho must leave of a slave's ring to be
 * covered, rho (1 + 1e-9) + this <= ring (eq. (30)). */
double nts_kept_shift(const nts_candidates* kc, double pad);
/* A build begins (room for scene s, the radii of search radius r) and ends
 * (the positions of `seg` kept, the lists valid). */
int nts_kept_begin(nts_candidates* kc, const nts_scene* s, const seg_data* seg, double alpha, double alpha_max,
                   double ext, double r, double pad);
void nts_kept_end(nts_candidates* kc, const nts_scene* s, const seg_data* seg);
/* Give back every buffer (a build over its budget: what it grew is not held). */
void nts_kept_drop(nts_candidates* kc);
/* Whether this replay of the lists (of a scene of `surface_count` entries)
 * asks for its masters' lines ahead (search_env.kept_ahead), and what its
 * search took, in seconds, once it ran (nts_kept_ahead_timed). It decides
 * no result: the same masters are tried in the same order either way. */
int nts_kept_ahead(nts_candidates* kc, int surface_count);
void nts_kept_ahead_timed(nts_candidates* kc, int ahead, double seconds);
/* key_base for the `count` keys of the build's cells (their frame's `scale`;
 * `coord` the largest coordinate plus a periodic box's sides), and KEY_PAD
 * more past them (masters.h), never kept. */
int nts_kept_key_bases(nts_candidates* kc, const float* reach2, int count, double scale, double coord);

/* The largest displacement the lists hold for, skin / factor: a master
 * that can offer nothing at any positions within it of the build's is kept
 * out of the inner ring (eq. (32)), so the lists also end when some node
 * moves farther (were the search radius to shrink, eq. (29) alone would
 * allow more). */
static inline double kept_hold(const nts_candidates* kc) { return kc->skin / kc->factor; }

static inline const int* kept_lo(const nts_candidates* kc) { return kc->span; }
static inline const int* kept_mid(const nts_candidates* kc) { return kc->span + kc->surface_count; }
static inline const int* kept_hi(const nts_candidates* kc) { return kc->span + 2 * kc->surface_count; }

#endif
