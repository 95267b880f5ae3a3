/* ntscontact internals shared by the core's .c files (not installed). */
#ifndef NTSCONTACT_INTERNAL_H
#define NTSCONTACT_INTERNAL_H

#include <assert.h>

#include <ntscontact/config.h>
#include <ntscontact/ntscontact.h>

/* The scene: topology (normalised loops) and positions, flat arrays in global
 * node order. A "surface entry" is one place of one loop; its prev/next are the
 * neighbouring entries of the same loop (cyclic), in the normalised orientation
 * (interior on the left). */
struct nts_scene {
    int body_count;
    int node_count;
    int surface_count;
    int loop_total;
    int loops_reversed;
    double lx, ly;
    nts_vec2* pos;        /* node_count */
    int* body_node_start; /* body_count + 1 */
    int* body_loop_start; /* body_count + 1, into loop_start */
    int* loop_start;      /* loop_total + 1, into the surface arrays */
    int* surf_node;       /* surface entry -> global node */
    int* surf_local;      /* surface entry -> node index inside its body */
    int* surf_prev;       /* surface entry -> previous entry of its loop */
    int* surf_next;       /* surface entry -> next entry of its loop */
    int* surf_body;       /* surface entry -> body */
    /* What nts_scene_update_positions needs to tell whether new positions keep
     * the normalisation that nts_scene_create gave (sessions): */
    unsigned char* loop_reversed; /* loop_total: 1 when stored reversed from the input order (for a
                                     mesh: from its piece's orientation by connectivity) */
    int* body_outer;      /* body_count: the outer loop (index into loop_start); loop bodies */
    int* loop_piece;      /* loop_total: a mesh loop's piece, named by its first loop (index into
                             loop_start); -1 for loop bodies */
    double* piece_area2;  /* loop_total: scratch of the update's piece verdicts */
    /* Per-body model options (nts_body_def) and the reference configuration: */
    unsigned char* body_role;  /* nts_role */
    unsigned char* body_mesh;  /* 1: loops from triangles, each piece oriented by its outer loop */
    double* body_alpha;        /* the body's own alpha, or -1: the options' */
    double* body_friction;     /* the body's own friction coefficient, or -1: the options' */
    unsigned char* body_self;  /* 1: the body's nodes are tested against its own surface (§16) */
    int self_bodies;           /* how many bodies have self-contact (0: nothing of it runs) */
    double* surf_trib;         /* surface entry -> tributary length in the reference configuration,
                                  over the contact surface's segments (0 off the surface) */
    /* The contact surfaces (nts_body_def.surface; docs/model.md §13): per
     * surface entry, NTS_SF_* bits; NULL when no body names one (every
     * segment is on, and nothing reads it). */
    unsigned char* surf_flag;
    int surf_ends;             /* entries at an end of a contact surface (no end: no extension) */
    /* Which scene this is, among every scene the process made (a freed
     * scene's address may come back): a kept candidate list is bound to one. */
    unsigned long long serial;
    /* nts_scene_update_positions' scratch: 3 doubles a node of its longest loop. */
    double* steps;
    int longest_loop;
};

/* The checks of nts_scene_update_positions in parts, for the evaluation that
 * checks new positions in its segment pass (nts_evaluate_positions):
 * whether every coordinate of the nodes on no loop (a mesh's interior) is in
 * the supported range (check_point's verdict; the segment pass judges the
 * others), and whether loops of twice the signed areas area_perim[2 l] and
 * perimeters area_perim[2 l + 1] (each in the caller's order, as the scene's
 * check of a loop sums them) all enclose an area and keep the scene's
 * normalisation. Verdicts only: the errors are the update's own (scene.c). */
int nts_scene_interior_in_range(const nts_scene* s, const nts_vec2* pos);
int nts_scene_keeps_shape(nts_scene* s, const double* area_perim);

/* A surface entry's flags (nts_scene.surf_flag): its own segment (from it to
 * the next entry) is on the contact surface, the previous one is, the next
 * one is. The entry's node is a slave when either of its segments is on; its
 * segment is a master when SEG; its corner (or vertex) exists when SEG and
 * PREV; its flat part reaches s = 0 without PREV and s = 1 without NEXT. */
enum { NTS_SF_SEG = 1, NTS_SF_PREV = 2, NTS_SF_NEXT = 4, NTS_SF_ALL = 7, NTS_SF_NODE = NTS_SF_SEG | NTS_SF_PREV };

/* Body b's entries on its loops, [first, *end) (its loops are consecutive). */
static inline int nts_body_entries(const struct nts_scene* s, int b, int* end) {
    *end = s->loop_start[s->body_loop_start[b + 1]];
    return s->loop_start[s->body_loop_start[b]];
}
/* Whether every node of body b is on one of its loops (no mesh interior, no
 * node left out): a node is on one place at most, so as many entries as
 * nodes. */
static inline int nts_body_all_on_loops(const struct nts_scene* s, int b) {
    int end;
    const int first = nts_body_entries(s, b, &end);
    return end - first == s->body_node_start[b + 1] - s->body_node_start[b];
}
/* The node body b's shape is measured from (nts_body_shape): its first,
 * when all its nodes are on its loops, else the node of its first entry
 * (contact reads a body's loops alone: a node on none, stale in a surface
 * exchange, decides nothing). */
static inline int nts_body_origin(const struct nts_scene* s, int b) {
    int end;
    return nts_body_all_on_loops(s, b) ? s->body_node_start[b] : s->surf_node[nts_body_entries(s, b, &end)];
}

/* Whether entry e's segment is on the contact surface (a master segment). */
static inline int nts_on_surface(const struct nts_scene* s, int e) {
    return s->surf_flag == NULL || (s->surf_flag[e] & NTS_SF_SEG) != 0;
}
/* Whether entry e's node is on the contact surface (may be a slave). */
static inline int nts_node_on_surface(const struct nts_scene* s, int e) {
    return s->surf_flag == NULL || (s->surf_flag[e] & NTS_SF_NODE) != 0;
}

/* Where an error is (nts_error's indices and option; -1 and "" when they do
 * not apply) and the one function that fills an error record: code, place and
 * a printf message. Returns `code`, so a caller writes `return nts_error_set(...)`. */
typedef struct nts_where {
    int body, loop, loop_pos, node, triangle, corner, item;
    const char* option;
} nts_where;
static inline nts_where nts_at(int body, int loop, int loop_pos, int node) {
    nts_where w;
    w.body = body;
    w.loop = loop;
    w.loop_pos = loop_pos;
    w.node = node;
    w.triangle = w.corner = w.item = -1;
    w.option = "";
    return w;
}
/* The same place, naming the option (or limit) at fault: err->option. */
static inline nts_where nts_naming(nts_where w, const char* option) {
    w.option = option;
    return w;
}
int nts_error_set(nts_error* err, int code, nts_where at, const char* fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

/* Wall-clock seconds from an arbitrary origin (monotonic where the platform
 * has it), for the phase profile of a build without OpenMP (base.c). */
double nts_wall_seconds(void);

/* Growable array helper: ensures *cap >= need (elements of `size` bytes), keeping
 * the contents. Returns 0 or NTS_ENOMEM (the old block stays valid). */
int nts_grow(void** ptr, int* cap, int need, size_t size);

/* Boundary of a triangle mesh (triangles.c), from its connectivity alone:
 * loops as CSR arrays allocated with nts_alloc, each connected piece oriented
 * consistently (from its first triangle as given, whatever the positions);
 * loop_piece[l] is the first loop of loop l's piece (<= l). The scene turns
 * a piece over when its outer loop (largest |area|) runs clockwise.
 * Errors: an index out of range, a triangle that repeats a node, an edge in
 * more than two triangles, a mesh that is not orientable, a pinched or open
 * boundary, no boundary; each names the triangle or node at fault. */
typedef struct nts_boundary {
    int* loop_nodes;
    int* loop_start;
    int* loop_piece;
    int loop_count;
} nts_boundary;
int nts_boundary_from_triangles(int node_count, const int* tri, int tri_count, nts_boundary* out, nts_error* err);
void nts_boundary_free(nts_boundary* b);

/* A hint to load a line that will be read (written) soon. */
#if defined(__GNUC__)
#define NTS_PREFETCH(p) __builtin_prefetch(p)
#define NTS_PREFETCH_W(p) __builtin_prefetch(p, 1)
#else
#define NTS_PREFETCH(p) ((void)0)
#define NTS_PREFETCH_W(p) ((void)0)
#endif
/* Inlined whatever the optimiser's estimate (the search's hot helpers). */
#if defined(__GNUC__)
#define NTS_ALWAYS_INLINE __attribute__((always_inline))
#else
#define NTS_ALWAYS_INLINE
#endif

/* Growable triplet buffers of the tangent (stiffness.c). */
typedef struct nts_kbuf {
    int* rows;
    int* cols;
    double* values;
    int count, cap;
} nts_kbuf;
/* Append the tangent of one active contact (its 2(m+1) x 2(m+1) dense block)
 * with `alpha` the master body's. 0 or NTS_ENOMEM. */
int nts_stiffness_add(nts_kbuf* k, const nts_scene* s, const nts_contact* c, double alpha);
void nts_kbuf_free(nts_kbuf* k);
/* Room for `extra` more triplets. 0 or NTS_ENOMEM. */
int nts_kbuf_reserve(nts_kbuf* k, int extra);


/* p - q as nts_min_image gives it in a box of sides lx, ly, both positive
 * or both zero (a scene is periodic on both axes or on neither: scene.c),
 * its near test done once for both axes: a pair within a quarter box on
 * both is d + 0.0 on each, as nts_min_image_1 gives it (the same bits).
 * The sides by value, so that a loop that stores doubles keeps them in
 * registers. */
static inline nts_vec2 nts_box_diff(nts_vec2 p, nts_vec2 q, double lx, double ly) {
    nts_vec2 d = nts_sub(p, q);
    if (!(lx > 0.0)) return d;
    if (fabs(d.x) < 0.25 * lx && fabs(d.y) < 0.25 * ly) {
        d.x += 0.0;
        d.y += 0.0;
        return d;
    }
    return nts_min_image(d, lx, ly);
}
static inline nts_vec2 nts_scene_diff(const nts_scene* s, nts_vec2 p, nts_vec2 q) {
    return nts_box_diff(p, q, s->lx, s->ly);
}

#endif
