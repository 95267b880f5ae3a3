/* A body on the wire (docs/distributed.md): its definition as bytes, sent
 * whole to every slab it reaches, and growing buffers. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"



void* ntsm_bytes_room(bytes* b, size_t n) {
    size_t need = b->n + ((n + 7u) & ~(size_t)7u);
    if (b->oom) return NULL;
    if (need > b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 4096;
        char* p;
        while (cap < need) cap *= 2;
        if ((p = (char*)realloc(b->p, cap)) == NULL) {
            b->oom = 1;
            return NULL;
        }
        b->p = p;
        b->cap = cap;
    }
    {
        char* at = b->p + b->n;
        memset(at, 0, need - b->n);
        b->n = need;
        return at;
    }
}

void ntsm_bytes_put(bytes* b, const void* v, size_t n) {
    void* at = ntsm_bytes_room(b, n);
    if (at != NULL && n > 0) memcpy(at, v, n);
}

/* Grow an array to hold `count` items of `size` bytes (1 on success). */
int ntsm_grow(void* pp, int* cap, long long count, size_t size) {
    void** p = (void**)pp;
    long long c;
    void* q;
    if (count <= *cap) return 1;
    if (count > INT_MAX) return 0;
    c = *cap > 0 ? *cap : 64;
    while (c < count) c *= 2;
    if (c > INT_MAX) c = INT_MAX;
    if ((q = realloc(*p, (size_t)c * size)) == NULL) return 0;
    *p = q;
    *cap = (int)c;
    return 1;
}

/* ------------------------------------------------------------ a body's bytes */

/* A body as bytes: its header, alpha and friction, nodes, reference,
 * loop_start, loop_nodes, triangles, surface (each 8-byte aligned). */
enum { H_ID, H_NODES, H_LOOPS, H_LOOPLEN, H_TRIS, H_ROLE, H_HAS_ALPHA, H_SURF, H_HAS_FRIC, H_SELF, H_PARTS, H_COUNT };

void ntsm_body_write(bytes* b, const nts_body_def* d, int id, const nts_vec2* reference) {
    int h[H_COUNT];
    double ad[2];
    const int looplen = d->loop_count > 0 ? d->loop_start[d->loop_count] : 0;
    h[H_ID] = id;
    h[H_NODES] = d->node_count;
    h[H_LOOPS] = d->loop_count > 0 ? d->loop_count : 0;
    h[H_LOOPLEN] = looplen;
    h[H_TRIS] = d->triangles != NULL ? d->triangle_count : 0;
    h[H_ROLE] = (int)d->role;
    h[H_HAS_ALPHA] = d->has_alpha;
    h[H_SURF] = d->surface != NULL ? d->surface_count : -1;
    h[H_HAS_FRIC] = d->has_friction;
    h[H_SELF] = d->self_contact;
    h[H_PARTS] = 0;
    ad[0] = d->alpha;
    ad[1] = d->friction;
    ntsm_bytes_put(b, h, sizeof h);
    ntsm_bytes_put(b, ad, sizeof ad);
    ntsm_bytes_put(b, d->nodes, sizeof(nts_vec2) * (size_t)d->node_count);
    ntsm_bytes_put(b, reference, sizeof(nts_vec2) * (size_t)d->node_count);
    if (h[H_LOOPS] > 0) {
        ntsm_bytes_put(b, d->loop_start, sizeof(int) * (size_t)(d->loop_count + 1));
        ntsm_bytes_put(b, d->loop_nodes, sizeof(int) * (size_t)looplen);
    }
    if (h[H_TRIS] > 0) ntsm_bytes_put(b, d->triangles, sizeof(int) * 3u * (size_t)h[H_TRIS]);
    if (h[H_SURF] > 0) ntsm_bytes_put(b, d->surface, sizeof(int) * 2u * (size_t)h[H_SURF]);
}

void* ntsm_scratch(scratch* s, size_t need) {
    if (need > s->cap) {
        size_t cap = s->cap > 0 ? s->cap : 4096;
        void* p;
        while (cap < need) cap *= 2;
        if ((p = realloc(s->p, cap)) == NULL) return NULL;
        s->p = p;
        s->cap = cap;
    }
    return s->p;
}

size_t ntsm_al8(size_t n) { return (n + 7u) & ~(size_t)7u; }

void ntsm_body_set_parts(char* p, int parts) { ((int*)(void*)p)[H_PARTS] = parts; }

int ntsm_body_parts(const char* p) { return ((const int*)(const void*)p)[H_PARTS]; }

/* The body at p (pointers into p); returns the bytes it takes. */
size_t ntsm_body_read(const char* p, nts_body_def* d, int* id) {
    const int* h = (const int*)(const void*)p;
    const double* ad = (const double*)(const void*)(p + ntsm_al8(sizeof(int) * H_COUNT));
    size_t at = ntsm_al8(sizeof(int) * H_COUNT) + ntsm_al8(2 * sizeof(double));
    memset(d, 0, sizeof *d);
    *id = h[H_ID];
    d->node_count = h[H_NODES];
    d->role = (nts_role)h[H_ROLE];
    d->has_alpha = h[H_HAS_ALPHA];
    d->alpha = ad[0];
    d->has_friction = h[H_HAS_FRIC];
    d->friction = ad[1];
    d->self_contact = h[H_SELF];
    d->nodes = (const nts_vec2*)(const void*)(p + at);
    at += ntsm_al8(sizeof(nts_vec2) * (size_t)h[H_NODES]);
    d->reference = (const nts_vec2*)(const void*)(p + at);
    at += ntsm_al8(sizeof(nts_vec2) * (size_t)h[H_NODES]);
    if (h[H_LOOPS] > 0) {
        d->loop_count = h[H_LOOPS];
        d->loop_start = (const int*)(const void*)(p + at);
        at += ntsm_al8(sizeof(int) * (size_t)(h[H_LOOPS] + 1));
        d->loop_nodes = (const int*)(const void*)(p + at);
        at += ntsm_al8(sizeof(int) * (size_t)h[H_LOOPLEN]);
    }
    if (h[H_TRIS] > 0) {
        d->triangle_count = h[H_TRIS];
        d->triangles = (const int*)(const void*)(p + at);
        at += ntsm_al8(sizeof(int) * 3u * (size_t)h[H_TRIS]);
    }
    if (h[H_SURF] >= 0) {
        static const int no_pair[2] = {0, 0};
        d->surface_count = h[H_SURF];
        d->surface = h[H_SURF] > 0 ? (const int*)(const void*)(p + at) : no_pair;
        at += ntsm_al8(sizeof(int) * 2u * (size_t)h[H_SURF]);
    }
    return at;
}
