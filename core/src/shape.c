/* A body's shape as the reach and the widened search ask it (docs/model.md
 * §4.5): a circle around its nodes, the deepest a point inside can lie, its
 * bounding box; and whether a point lies outside that circle, so outside the
 * body. Its own file: the search (search.c) and the reach (reach.c) both use
 * it, and the reach uses the search. */
#include <math.h>

#include "context.h"

/* What the reach asks of a body's shape, from its nodes (the scene's
 * positions, 16 bytes a node, each as its minimum image from the body's first
 * node, so a body across a periodic box's edge is measured whole), once per
 * evaluation: a circle around its nodes (the centre of their bounding box,
 * relative to the first node, and the largest distance of a node from it,
 * squared), and the deepest a point inside the body can lie below its
 * surface, half the smaller side of the bounding box (a line through the
 * point along that side's axis leaves the body within the box, on both
 * sides). The smoothed surface lies in the nodes' hull (a corner curve is a
 * convex combination of three nodes, eq. (2)-(3)), so a point outside the
 * circle is outside the body. Then its bounding box, relative to the first
 * node: x0, x1, y0, y1. shape[SHAPE b + 3] < 0: not yet. The nodes are
 * its loops' (relative to nts_body_origin): a node on no loop is not read. */
const double* nts_body_shape(const search_env* env, double* shape, int b) {
    double* c = shape + SHAPE * b;
    if (c[3] < 0.0) {
        const nts_scene* s = env->s;
        /* the body's loops' nodes: its nodes, or its entries' when some are
         * on no loop (a mesh's interior: contact reads the loops alone) */
        const int all = nts_body_all_on_loops(s, b);
        int e1;
        const int e0 = nts_body_entries(s, b, &e1);
        const int m0 = all ? s->body_node_start[b] : e0, m1 = all ? s->body_node_start[b + 1] : e1;
        const nts_vec2 p0 = s->pos[nts_body_origin(s, b)];
        double x0 = 0.0, x1 = 0.0, y0 = 0.0, y1 = 0.0, r2 = 0.0;
        int m;
        for (m = m0; m < m1; ++m) {
            const nts_vec2 d = nts_scene_diff(s, s->pos[all ? m : s->surf_node[m]], p0);
            x0 = d.x < x0 ? d.x : x0;
            x1 = d.x > x1 ? d.x : x1;
            y0 = d.y < y0 ? d.y : y0;
            y1 = d.y > y1 ? d.y : y1;
        }
        if (s->lx > 0.0 && (x1 - x0 > 0.25 * s->lx || y1 - y0 > 0.25 * s->ly)) {
            /* A body more than a quarter of the periodic box: its nodes' minimum
             * images from one node need not be one piece. No circle (it rules
             * nothing out), and the depth from its loops walked by their
             * segments (each shorter than half the box), which are. */
            int l;
            x0 = x1 = y0 = y1 = 0.0;
            for (l = s->body_loop_start[b]; l < s->body_loop_start[b + 1]; ++l) {
                const int f0 = s->loop_start[l], f1 = s->loop_start[l + 1];
                nts_vec2 p = nts_scene_diff(s, env->seg[f0].p, p0);
                int e;
                for (e = f0; e < f1; ++e) {
                    x0 = p.x < x0 ? p.x : x0;
                    x1 = p.x > x1 ? p.x : x1;
                    y0 = p.y < y0 ? p.y : y0;
                    y1 = p.y > y1 ? p.y : y1;
                    p = nts_add(p, env->seg[e].t);
                }
            }
            c[0] = c[1] = 0.0;
            c[2] = HUGE_VAL;
        } else {
            c[0] = 0.5 * (x0 + x1);
            c[1] = 0.5 * (y0 + y1);
            for (m = m0; m < m1; ++m) {
                const nts_vec2 d = nts_scene_diff(s, s->pos[all ? m : s->surf_node[m]], p0);
                const double dx = d.x - c[0], dy = d.y - c[1], d2 = dx * dx + dy * dy;
                r2 = d2 > r2 ? d2 : r2;
            }
            c[2] = r2;
        }
        c[3] = 0.5 * (x1 - x0 < y1 - y0 ? x1 - x0 : y1 - y0);
        c[4] = x0;
        c[5] = x1;
        c[6] = y0;
        c[7] = y1;
    }
    return c;
}

/* Whether [q - pad, q + pad] misses [lo, hi] for every image q + k l of
 * q (l = 0: open, the interval itself). */
static int misses(double q, double pad, double lo, double hi, double l) {
    double k;
    if (!(l > 0.0)) return q + pad < lo || q - pad > hi;
    if (hi - lo + 2.0 * pad >= l) return 0;
    k = ceil((lo - pad - q) / l); /* the first image at or past lo - pad */
    return q + k * l - pad > hi;
}

/* Whether X lies outside body b's circle or outside its bounding box (any
 * image of it, in a periodic box), allowing for the round-off of the
 * minimum images: then it is outside the body. A rule of the pair alone,
 * which every search applies the same (the body grid of reach.c lists a
 * body in the cells its box overlaps, and this decides): for a loop that
 * crosses itself, whose gaps can be negative outside its hull, it is what
 * settles such points outside, whichever search asks. */
int nts_outside_bounds(const search_env* env, double* shape, int b, nts_vec2 x) {
    const nts_scene* s = env->s;
    const double* c = nts_body_shape(env, shape, b);
    const nts_vec2 q = nts_scene_diff(s, x, s->pos[nts_body_origin(s, b)]);
    const double dx = q.x - c[0], dy = q.y - c[1];
    /* a contact surface's ends reach up to ext L_max past the nodes (docs/model.md §13) */
    const double past = env->ext * env->wide_lmax + 2.0 * env->wide_pad;
    const double pad = past + 1e-9 * (fabs(q.x) + fabs(q.y));
    if (misses(q.x, pad, c[4], c[5], s->lx) || misses(q.y, pad, c[6], c[7], s->ly)) return 1;
    if (env->ext > 0.0) {
        const double R = sqrt(c[2]) * (1.0 + 1e-9) + past;
        return dx * dx + dy * dy > R * R;
    }
    return dx * dx + dy * dy > c[2] * (1.0 + 1e-9) + 4.0 * env->wide_pad * env->wide_pad;
}
