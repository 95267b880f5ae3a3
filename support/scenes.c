/* The scenes the tests and the benchmarks build (nts_support.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "nts_support.h"

static const double PI = 3.14159265358979323846;

double ntsx_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

double ntsx_median(double* v, int n) {
    if (n <= 0) return 0.0;
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void ntsx_range(const double* v, int n, double* lo, double* hi) {
    int k;
    *lo = *hi = v[0];
    for (k = 1; k < n; ++k) {
        *lo = v[k] < *lo ? v[k] : *lo;
        *hi = v[k] > *hi ? v[k] : *hi;
    }
}

static void* xcalloc(size_t n, size_t size) {
    void* p = calloc(n ? n : 1, size ? size : 1);
    if (p == NULL) {
        fprintf(stderr, "nts_support: out of memory\n");
        exit(2);
    }
    return p;
}

void ntsx_scene_init(ntsx_scene* s, int bodies) {
    memset(s, 0, sizeof *s);
    s->body_count = bodies;
    s->counts = xcalloc((size_t)bodies, sizeof(int));
    s->nodes = xcalloc((size_t)bodies, sizeof(nts_vec2*));
    s->loop_nodes = xcalloc((size_t)bodies, sizeof(int*));
    s->loop_start = xcalloc((size_t)bodies, sizeof(int*));
    s->loop_count = xcalloc((size_t)bodies, sizeof(int));
    s->has_alpha = xcalloc((size_t)bodies, sizeof(int));
    s->alpha = xcalloc((size_t)bodies, sizeof(double));
    s->cx = xcalloc((size_t)bodies, sizeof(double));
    s->cy = xcalloc((size_t)bodies, sizeof(double));
    s->R = xcalloc((size_t)bodies, sizeof(double));
}

void ntsx_scene_free(ntsx_scene* s) {
    int i;
    for (i = 0; i < s->body_count; ++i) {
        free(s->nodes[i]);
        free(s->loop_nodes[i]);
        free(s->loop_start[i]);
    }
    free(s->counts);
    free(s->nodes);
    free(s->loop_nodes);
    free(s->loop_start);
    free(s->loop_count);
    free(s->has_alpha);
    free(s->alpha);
    free(s->cx);
    free(s->cy);
    free(s->R);
    memset(s, 0, sizeof *s);
}

nts_scene* ntsx_scene_create(const ntsx_scene* s, nts_error* err) {
    nts_body_def* defs = xcalloc((size_t)s->body_count, sizeof(nts_body_def));
    nts_scene_def def = nts_default_scene_def();
    nts_scene* out;
    int i;
    for (i = 0; i < s->body_count; ++i) {
        defs[i].nodes = s->nodes[i];
        defs[i].node_count = s->counts[i];
        defs[i].loop_nodes = s->loop_nodes[i];
        defs[i].loop_start = s->loop_start[i];
        defs[i].loop_count = s->loop_count[i];
#if NTS_VERSION_MAJOR > 0 || NTS_VERSION_MINOR >= 2
        /* Per-body alpha came with 0.2: built against 0.1 (bench/cross.c),
         * every body takes the options' alpha. */
        defs[i].has_alpha = s->has_alpha[i];
        defs[i].alpha = s->alpha[i];
#endif
#ifdef NTS_HAS_SELF_CONTACT
        defs[i].self_contact = s->self_contact;
#endif
    }
    def.bodies = defs;
    def.body_count = s->body_count;
    def.lx = s->lx;
    def.ly = s->ly;
    out = nts_scene_create(&def, err);
    free(defs);
    return out;
}

double ntsx_urand(uint64_t* state) {
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

void ntsx_motion_directions(const int* counts, int body_count, uint64_t seed, nts_vec2* dir) {
    uint64_t rng = seed;
    int body, k, at = 0;
    for (body = 0; body < body_count; ++body) {
        const double a = 6.283185307179586 * ntsx_urand(&rng);
        for (k = 0; k < counts[body]; ++k, ++at) {
            const double c = 6.283185307179586 * ntsx_urand(&rng);
            dir[at] = nts_v2(cos(a) + 0.2 * cos(c), sin(a) + 0.2 * sin(c));
        }
    }
}

ntsx_packing_def ntsx_default_packing(int particles, int periodic, uint64_t seed) {
    ntsx_packing_def d;
    d.particles = particles;
    d.nodes_min = 32;
    d.nodes_max = 64;
    d.spacing = 2.0;
    d.radius = 1.02;
    d.centre_jitter = 0.1;
    d.radius_jitter = 0.06;
    d.angle_jitter = 0.3;
    d.node_jitter = 0.01;
    d.periodic = periodic;
    d.seed = seed;
    return d;
}

void ntsx_packing(ntsx_scene* s, const ntsx_packing_def* d) {
    const int side = (int)ceil(sqrt((double)d->particles));
    const int span = d->nodes_max - d->nodes_min + 1;
    uint64_t state = d->seed;
    int p, i;
    ntsx_scene_init(s, d->particles);
    if (d->periodic) {
        s->lx = d->spacing * side;
        s->ly = d->spacing * ((d->particles + side - 1) / side);
    }
    for (p = 0; p < d->particles; ++p) {
        /* The draws in this order: the node count, the centre, the radius, the phase. */
        int m = d->nodes_min + (int)(ntsx_urand(&state) * (double)span);
        double cx = d->spacing * (p % side + 0.5) + d->centre_jitter * (ntsx_urand(&state) - 0.5);
        double cy = d->spacing * (p / side + 0.5) + d->centre_jitter * (ntsx_urand(&state) - 0.5);
        double R = d->radius + d->radius_jitter * (ntsx_urand(&state) - 0.5), phase = 2.0 * PI * ntsx_urand(&state);
        if (m > d->nodes_max) m = d->nodes_max;
        s->counts[p] = m;
        s->nodes[p] = xcalloc((size_t)m, sizeof(nts_vec2));
        s->cx[p] = cx;
        s->cy[p] = cy;
        s->R[p] = R;
        for (i = 0; i < m; ++i) {
            double th = phase + 2.0 * PI * (i + d->angle_jitter * (ntsx_urand(&state) - 0.5)) / m;
            double r = R * (1.0 + d->node_jitter * (ntsx_urand(&state) - 0.5));
            s->nodes[p][i] = nts_v2(cx + r * cos(th), cy + r * sin(th));
        }
        s->total += m;
    }
}

void ntsx_two_disks(ntsx_scene* s, int n, double overlap, double phase) {
    int k, i;
    ntsx_scene_init(s, 2);
    for (k = 0; k < 2; ++k) {
        s->counts[k] = n;
        s->nodes[k] = xcalloc((size_t)n, sizeof(nts_vec2));
        s->cx[k] = k == 0 ? 0.0 : 2.0 - overlap;
        s->cy[k] = 0.0;
        s->R[k] = 1.0;
        for (i = 0; i < n; ++i) {
            double th = 2.0 * PI * (i + (k == 0 ? 0.0 : phase)) / n;
            s->nodes[k][i] = nts_v2(s->cx[k] + cos(th), s->cy[k] + sin(th));
        }
        s->total += n;
    }
}

void ntsx_container(ntsx_scene* s, int side, int pieces, int disk_nodes, int sharp) {
    const double pitch = 1.98, w = 2.0;
    const double hi = pitch * side - 0.01; /* every outer disk 0.01 into its walls */
    const int n_in = 4 * pieces, nb = side * side + 1;
    int b, i, k;
    nts_vec2* box;
    ntsx_scene_init(s, nb);
    box = s->nodes[0] = xcalloc((size_t)(4 + n_in), sizeof(nts_vec2));
    box[0] = nts_v2(-w, -w);
    box[1] = nts_v2(hi + w, -w);
    box[2] = nts_v2(hi + w, hi + w);
    box[3] = nts_v2(-w, hi + w);
    /* The hole, clockwise: (0,0) -> (0,hi) -> (hi,hi) -> (hi,0). */
    for (k = 0; k < 4; ++k)
        for (i = 0; i < pieces; ++i) {
            double f = (double)i / pieces * hi;
            box[4 + k * pieces + i] = k == 0 ? nts_v2(0.0, f)
                                    : k == 1 ? nts_v2(f, hi)
                                    : k == 2 ? nts_v2(hi, hi - f)
                                             : nts_v2(hi - f, 0.0);
        }
    s->counts[0] = 4 + n_in;
    s->loop_nodes[0] = xcalloc((size_t)(4 + n_in), sizeof(int));
    for (i = 0; i < 4 + n_in; ++i) s->loop_nodes[0][i] = i;
    s->loop_start[0] = xcalloc(3, sizeof(int));
    s->loop_start[0][0] = 0;
    s->loop_start[0][1] = 4;
    s->loop_start[0][2] = 4 + n_in;
    s->loop_count[0] = 2;
    s->has_alpha[0] = sharp;
    s->alpha[0] = 0.0;
    s->total = 4 + n_in;
    for (b = 1; b < nb; ++b) {
        int ix = (b - 1) % side, iy = (b - 1) / side;
        s->nodes[b] = xcalloc((size_t)disk_nodes, sizeof(nts_vec2));
        s->counts[b] = disk_nodes;
        s->cx[b] = 0.99 + pitch * ix;
        s->cy[b] = 0.99 + pitch * iy;
        s->R[b] = 1.0;
        for (i = 0; i < disk_nodes; ++i) {
            double th = 2.0 * PI * (i + 0.37 * b) / disk_nodes;
            s->nodes[b][i] = nts_v2(s->cx[b] + cos(th), s->cy[b] + sin(th));
        }
        s->total += disk_nodes;
    }
}
