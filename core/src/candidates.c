/* The kept candidate list (nts_candidates, docs/model.md §15): its object,
 * the test of its validity before each evaluation, and the bookkeeping of a
 * build (evaluate.c runs the build; search.c fills and reads the lists). */
#include <float.h>
#include <math.h>
#include <string.h>

#include "candidates.h"
#include "masters.h"

nts_candidates* nts_candidates_create(double skin) {
    nts_candidates* kc = (nts_candidates*)nts_alloc(sizeof *kc);
    if (kc == NULL) return NULL;
    memset(kc, 0, sizeof *kc);
    kc->skin_asked = skin >= 0.0 && skin <= 1e300 ? skin : -1.0;
    return kc;
}

void nts_kept_drop(nts_candidates* kc) {
    int c;
    for (c = 0; c < kc->chunk_slots; ++c) nts_free(kc->chunk[c]);
    nts_free(kc->chunk);
    nts_free(kc->chunk_cap);
    nts_free(kc->chunk_used);
    nts_free(kc->span);
    nts_free(kc->ring);
    nts_free(kc->x);
    nts_free(kc->key_base);
    kc->key_base = NULL;
    kc->key_base_cap = 0;
    kc->chunk = NULL;
    kc->chunk_cap = kc->chunk_used = kc->span = NULL;
    kc->ring = NULL;
    kc->x = NULL;
    kc->chunk_slots = kc->span_cap = kc->ring_cap = kc->x_cap = 0;
    kc->built = 0;
    kc->kept = 0;
}

void nts_candidates_destroy(nts_candidates* kc) {
    if (kc == NULL) return;
    nts_kept_drop(kc);
    nts_free(kc);
}

void nts_candidates_clear(nts_candidates* kc) {
    if (kc != NULL) kc->built = 0;
}

size_t nts_candidates_bytes(const nts_candidates* kc) {
    size_t n;
    int c;
    if (kc == NULL) return 0;
    n = sizeof *kc + (size_t)kc->x_cap * sizeof(nts_vec2) + (size_t)kc->span_cap * sizeof(int) +
        (size_t)kc->chunk_slots * (sizeof(int*) + 2 * sizeof(int)) + (size_t)kc->ring_cap * sizeof(double) +
        (size_t)kc->key_base_cap * sizeof(float);
    for (c = 0; c < kc->chunk_slots; ++c) n += (size_t)kc->chunk_cap[c] * sizeof(int);
    return n;
}

nts_candidates_info nts_candidates_get_info(const nts_candidates* kc) {
    nts_candidates_info i;
    memset(&i, 0, sizeof i);
    if (kc == NULL) return i;
    i.evaluations = kc->evaluations;
    i.builds = kc->builds;
    i.cell_builds = kc->cell_builds;
    i.moved = kc->moved;
    i.skin = kc->skin;
    i.kept = kc->kept;
    i.pruned = kc->pruned;
    i.ahead_replays = kc->ahead_replays;
    i.plain_replays = kc->plain_replays;
    return i;
}

const nts_vec2* nts_kept_since(const nts_candidates* kc, const nts_scene* s) {
    return kc != NULL && kc->built && kc->scene == s && kc->serial == s->serial ? kc->x : NULL;
}

int nts_kept_valid(nts_candidates* kc, const nts_scene* s, double moved, double alpha, double ext, double r,
                   double pad) {
    double need;
    if (!kc->built || kc->scene != s || kc->serial != s->serial || kc->alpha != alpha || kc->ext != ext) return 0;
    kc->moved = moved;
    /* Eq. (29): a master that offers a feature within r now lay within its
     * reach plus r + factor * moved at the build (each term with the
     * round-off allowance of reach_allowed). */
    need = (r + kc->factor * kc->moved) * (1.0 + 1e-9) + kc->pad + pad;
    /* (and no farther than the inner lists were pruned for, eq. (32)) */
    return need <= kc->inner && kc->moved <= kept_hold(kc);
}

double nts_kept_shift(const nts_candidates* kc, double pad) {
    /* Eq. (30): rho + factor * moved within the ring, with the allowances of (29). */
    return kc->factor * kc->moved * (1.0 + 1e-9) + kc->pad + pad;
}

int nts_kept_begin(nts_candidates* kc, const nts_scene* s, const seg_data* seg, double alpha, double alpha_max,
                   double ext, double r, double pad) {
    const int chunks = (s->surface_count + KEPT_CHUNK - 1) / KEPT_CHUNK;
    int c, e;
    kc->built = 0;
    kc->kept = 0; /* (nts_kept_end counts them: a build cancelled or failed keeps none) */
    if (nts_grow((void**)&kc->span, &kc->span_cap, 3 * s->surface_count, sizeof(int)) != NTS_OK ||
        nts_grow((void**)&kc->ring, &kc->ring_cap, s->surface_count, sizeof(double)) != NTS_OK ||
        nts_grow((void**)&kc->x, &kc->x_cap, s->surface_count, sizeof(nts_vec2)) != NTS_OK)
        return NTS_ENOMEM;
    if (chunks > kc->chunk_slots) {
        int** chunk = (int**)nts_alloc(sizeof(int*) * (size_t)chunks);
        int* cap = (int*)nts_alloc(sizeof(int) * (size_t)chunks);
        int* used = (int*)nts_alloc(sizeof(int) * (size_t)chunks);
        if (chunk == NULL || cap == NULL || used == NULL) {
            nts_free(chunk);
            nts_free(cap);
            nts_free(used);
            return NTS_ENOMEM;
        }
        for (c = 0; c < chunks; ++c) {
            chunk[c] = c < kc->chunk_slots ? kc->chunk[c] : NULL;
            cap[c] = c < kc->chunk_slots ? kc->chunk_cap[c] : 0;
            used[c] = 0;
        }
        nts_free(kc->chunk);
        nts_free(kc->chunk_cap);
        nts_free(kc->chunk_used);
        kc->chunk = chunk;
        kc->chunk_cap = cap;
        kc->chunk_used = used;
        kc->chunk_slots = chunks;
    }
    if (kc->scene != s || kc->serial != s->serial || kc->surface_count != s->surface_count) {
        /* another scene: its replays' times are its own (nts_kept_ahead) */
        kc->ahead_s[0] = kc->ahead_s[1] = 0.0;
        kc->ahead_timed = 0;
    }
    kc->scene = s;
    kc->serial = s->serial;
    kc->surface_count = s->surface_count;
    kc->alpha = alpha;
    kc->ext = ext;
    kc->r = r;
    /* The default skin: 0.3 r, and the two round-off pads that the test of
     * (29) adds (nothing at moderate coordinates; where the coordinates
     * dwarf the segments, 1e7 against 1e-7, the pads alone exceeded 0.3 r
     * and no list ever held). */
    kc->skin = kc->skin_asked >= 0.0 ? kc->skin_asked : 0.3 * r + 2.0 * pad;
    kc->inner = r + kc->skin;
    kc->pad = pad;
    /* Eq. (29): the slave and the master's middle each move at most `moved`,
     * and its reach grows at most (1 + 2 ext + 2 alpha) moved. */
    kc->factor = 3.0 + 2.0 * ext + 2.0 * alpha_max;
    kc->pruned = 0;
    kc->moved = 0.0;
    /* Eq. (30): a widened search around e asks for at most r plus its
     * longer segment (reach.c: a neighbour's gap and the segment between,
     * or the long segment at a chain's end), which grows 2 moved while the
     * list holds (moved <= skin / factor); past 2 r, reach.c tries the
     * body's entries or builds the cells (the ring sizes the cells the
     * lists are built from: every slave pays for the largest). */
    kc->outer = kc->inner;
    for (e = 0; e < s->surface_count; ++e) {
        const double l = seg[seg[e].prev].len > seg[e].len ? seg[seg[e].prev].len : seg[e].len;
        kc->ring[e] = kc->inner + (l < r ? r : (l > 2.0 * r ? 2.0 * r : l)) + 2.0 * kc->skin / kc->factor;
        if (kc->ring[e] > kc->outer) kc->outer = kc->ring[e];
    }
    return NTS_OK;
}

void nts_kept_end(nts_candidates* kc, const nts_scene* s, const seg_data* seg) {
    int e, c;
    for (e = 0; e < s->surface_count; ++e) kc->x[e] = seg[e].p;
    kc->kept = 0;
    for (c = 0; c < (s->surface_count + KEPT_CHUNK - 1) / KEPT_CHUNK; ++c) kc->kept += kc->chunk_used[c];
    kc->built = 1;
    ++kc->builds;
    kc->ahead_built = 1; /* this evaluation's replay is not timed */
}

/* Asking for a replay's masters' lines a few slaves ahead (search.c,
 * search_kept) pays when they are far (a scene's segment records larger
 * than the caches) and costs a loop over each list when they are near. Where
 * one turns into the other depends on the machine: on one VM the step without
 * it took 0.87 of the time at 4,786 nodes and 1.02 at 47,830, the prefetch
 * paying from 1e5 nodes; on another (2 cores of an AMD EPYC, 1 MB of L2 a
 * core, 32 MB of L3) without it took 0.90 at 48,000 nodes and 0.93 at 1e5,
 * and 1.02 at 1e6 (docs/benchmarks.md). So: never while the records fit
 * 2 MB; above, each way's search time is kept as a running mean (a quarter
 * the newest), each way is tried first, and then the faster is taken but
 * for one timed replay in AHEAD_EXPLORE, which takes the other so that its
 * mean follows the scene and the machine. The replay of a build's own
 * evaluation is not timed (its caches hold what the build read) and takes
 * the faster; a search that stopped early is not timed either (evaluate.c
 * times only one that completed). */
enum { KEPT_AHEAD_BYTES = 2 << 20, AHEAD_EXPLORE = 8 };

int nts_kept_ahead(nts_candidates* kc, int surface_count) {
    const int built = kc->ahead_built;
    int ahead;
    kc->ahead_built = 0;
    kc->ahead_take = 0;
    if (!((double)surface_count * (double)sizeof(seg_data) > (double)KEPT_AHEAD_BYTES)) {
        ahead = 0;
    } else if (kc->ahead_s[1] == 0.0 || kc->ahead_s[0] == 0.0) {
        ahead = kc->ahead_s[1] == 0.0 || built; /* each way tried first (a build's replay asks) */
        kc->ahead_take = !built;
    } else {
        ahead = kc->ahead_s[1] <= kc->ahead_s[0];
        if (!built && kc->ahead_timed % AHEAD_EXPLORE == AHEAD_EXPLORE - 1) ahead = !ahead;
        kc->ahead_take = !built;
    }
    if (ahead) ++kc->ahead_replays;
    else ++kc->plain_replays;
    return ahead;
}

void nts_kept_ahead_timed(nts_candidates* kc, int ahead, double seconds) {
    double* m = &kc->ahead_s[ahead != 0];
    if (!kc->ahead_take) return;
    kc->ahead_take = 0;
    if (!(seconds > 0.0)) seconds = 1e-9; /* (a clock too coarse: still "timed") */
    *m = *m == 0.0 ? seconds : 0.75 * *m + 0.25 * seconds;
    ++kc->ahead_timed;
}

int nts_kept_key_bases(nts_candidates* kc, const float* reach2, int count, double scale, double coord) {
    /* The slack covers the round-off of the test that reads these
     * (search.c, ring_keys), in float in the keys' frame (|values| <= 2, a
     * radius at most 1): the slave's coordinates rounded to float (2^-21 an
     * axis, as the keys' own: masters.c), a base and a radius rounded to
     * float and added (3 2^-24 relative), and the squares and their sums
     * (3 2^-24 relative): at most about 1.5e-6 on a distance of at most 2;
     * 4e-6 covers it with room. And the rounding that the keys' frame has
     * and the exact test (kept_ring) has not: a key's middle X_j + t_j / 2
     * rounded in absolute coordinates, then placed in the cells (a periodic
     * box's wrap), at most an ulp of `coord` (the largest coordinate plus
     * the box's sides) an axis, 4 DBL_EPSILON coord scaled (nothing at
     * moderate coordinates; at 1e7 with cells of 6e-5, 1.5e-4 of the
     * frame). A key that the exact test would not keep costs a try, never
     * an answer. */
    const double outer = kc->outer * scale, slack = 4e-6 + 4.0 * DBL_EPSILON * coord * scale;
    int e;
    if (nts_grow((void**)&kc->key_base, &kc->key_base_cap, count + KEY_PAD, sizeof(float)) != NTS_OK)
        return NTS_ENOMEM;
    for (e = 0; e < count; ++e) kc->key_base[e] = (float)(sqrt((double)reach2[e]) - outer + slack);
    for (e = count; e < count + KEY_PAD; ++e) kc->key_base[e] = -1.0f; /* read 4 at a time, never kept */
    return NTS_OK;
}
