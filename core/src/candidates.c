/* The kept candidate list (nts_candidates, docs/model.md §15): its object,
 * the test of its validity before each evaluation, and the bookkeeping of a
 * build (evaluate.c runs the build; search.c fills and reads the lists). */
#include <math.h>
#include <string.h>

#include "candidates.h"

nts_candidates* nts_candidates_create(double skin) {
    nts_candidates* kc = (nts_candidates*)nts_alloc(sizeof *kc);
    if (kc == NULL) return NULL;
    memset(kc, 0, sizeof *kc);
    kc->skin_asked = skin >= 0.0 && skin <= 1e300 ? skin : -1.0;
    return kc;
}

void nts_candidates_destroy(nts_candidates* kc) {
    int c;
    if (kc == NULL) return;
    for (c = 0; c < kc->chunk_slots; ++c) nts_free(kc->chunk[c]);
    nts_free(kc->chunk);
    nts_free(kc->chunk_cap);
    nts_free(kc->chunk_used);
    nts_free(kc->span);
    nts_free(kc->x);
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
        (size_t)kc->chunk_slots * (sizeof(int*) + 2 * sizeof(int));
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
    return i;
}

/* The largest displacement of a surface node since the build (the minimum
 * image in a periodic box: a node that wrapped moved by its image). */
static double largest_move(const nts_candidates* kc, const nts_scene* s, const seg_data* seg) {
    double m2 = 0.0;
    int e;
    for (e = 0; e < s->surface_count; ++e) {
        double dx = seg[e].p.x - kc->x[e].x, dy = seg[e].p.y - kc->x[e].y, d2;
        if (s->lx > 0.0) {
            dx = nts_min_image_1(dx, s->lx);
            dy = nts_min_image_1(dy, s->ly);
        }
        d2 = dx * dx + dy * dy;
        if (d2 > m2) m2 = d2;
    }
    return sqrt(m2);
}

int nts_kept_valid(nts_candidates* kc, const nts_scene* s, const seg_data* seg, double alpha, double ext, double r,
                   double pad) {
    double need;
    if (!kc->built || kc->scene != s || kc->serial != s->serial || kc->alpha != alpha || kc->ext != ext) return 0;
    kc->moved = largest_move(kc, s, seg);
    /* Eq. (29): a master that offers a feature within r now lay within its
     * reach plus r + factor * moved at the build (each term with the
     * round-off allowance of reach_allowed). */
    need = (r + kc->factor * kc->moved) * (1.0 + 1e-9) + kc->pad + pad;
    return need <= kc->inner && kc->moved <= 1e300;
}

double nts_kept_reach(const nts_candidates* kc, double pad) {
    /* Eq. (30): the largest rho with rho + factor * moved within the outer
     * radius, with the same allowances. */
    return (kc->outer - kc->pad - pad) / (1.0 + 1e-9) - kc->factor * kc->moved;
}

int nts_kept_begin(nts_candidates* kc, const nts_scene* s, double alpha, double alpha_max, double ext, double r,
                   double pad) {
    const int chunks = (s->surface_count + KEPT_CHUNK - 1) / KEPT_CHUNK;
    int c;
    kc->built = 0;
    if (nts_grow((void**)&kc->span, &kc->span_cap, 3 * s->surface_count, sizeof(int)) != NTS_OK ||
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
    kc->scene = s;
    kc->serial = s->serial;
    kc->surface_count = s->surface_count;
    kc->alpha = alpha;
    kc->ext = ext;
    kc->r = r;
    kc->skin = kc->skin_asked >= 0.0 ? kc->skin_asked : 0.3 * r;
    kc->inner = r + kc->skin;
    kc->outer = kc->inner + r;
    kc->pad = pad;
    /* Eq. (29): the slave and the master's middle each move at most `moved`,
     * and its reach grows at most (1 + 2 ext + 2 alpha) moved. */
    kc->factor = 3.0 + 2.0 * ext + 2.0 * alpha_max;
    kc->moved = 0.0;
    return NTS_OK;
}

void nts_kept_end(nts_candidates* kc, const nts_scene* s, const seg_data* seg) {
    int e, c;
    for (e = 0; e < s->surface_count; ++e) kc->x[e] = seg[e].p;
    kc->kept = 0;
    for (c = 0; c < (s->surface_count + KEPT_CHUNK - 1) / KEPT_CHUNK; ++c) kc->kept += kc->chunk_used[c];
    kc->built = 1;
    ++kc->builds;
}
