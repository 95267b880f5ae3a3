/* The contact law's tangent (contact_law.h; docs/model.md §7).
 *
 * For an active contact (g < 0) the energy is phi = eps/2 g^2 = eps psi with
 * psi(x) = 1/2 |r(xi, x)|^2 at the closest point xi = xi(x), where
 * r = Xs - X(xi) = sum_k w_k(xi) x_k is linear in the nodes for fixed xi:
 * w = (1, -N_1, ..., -N_m) over (slave, master nodes). xi is a stationary
 * point of psi (psi_xi = -F = 0, docs/model.md §4), so by the
 * implicit function theorem dxi/dx = -psi_xix / psi_xixi and
 *   K = eps (psi_xx - psi_xxi psi_xix^T / psi_xixi),
 *   psi_xx  (block k, l) = w_k w_l I,
 *   psi_xxi (block k)    = v_k = w_k r_xi + w'_k r,
 *   psi_xixi             = |r_xi|^2 + r . r_xixi,
 * with r_xi = -sum N'_k x_k (minus the tangent) and r_xixi = -sum N''_k x_k
 * (the curvature of the Hermite polynomial enters here). The segment is the
 * same with xi = s (N = 1-s, s; N'' = 0); the vertex (alpha = 0) has no xi:
 * K = eps w w^T (x) I, a radial spring. K is symmetric by construction. */
#include "contact_law.h"

void nts_law_tangent(const nts_scene* s, const nts_contact* c, double alpha, law_block* out) {
    int* node = out->node;
    int m = c->master_count, k, l;
    double w[4], w1[4], w2[4], eps = c->penalty, pxx = 0.0, scale;
    nts_vec2 v[4], r, rx = {0.0, 0.0}, rxx = {0.0, 0.0};
    const int sb = s->body_node_start[c->slave_body], mb = s->body_node_start[c->master_body];
    const nts_vec2 xs = s->pos[sb + c->slave_node];
    assert(m >= 1 && m <= 3);
    node[0] = sb + c->slave_node;
    w[0] = 1.0;
    w1[0] = w2[0] = 0.0;
    for (k = 0; k < m; ++k) {
        node[k + 1] = mb + c->master_nodes[k];
        w[k + 1] = -c->weights[k];
    }
    if (c->kind == NTS_KIND_SEGMENT) {
        w1[1] = 1.0; /* -N'_0 = -(-1) */
        w1[2] = -1.0;
        w2[1] = w2[2] = 0.0;
    } else if (c->kind == NTS_KIND_CORNER) {
        /* N2 = a(1-x)^2/4, N3 = 1 - a(1+x^2)/2, N4 = a(1+x)^2/4 (docs/model.md §12, correction 1). */
        double x = c->param;
        w1[1] = alpha * (1.0 - x) / 2.0;
        w1[2] = alpha * x;
        w1[3] = -alpha * (1.0 + x) / 2.0;
        w2[1] = -alpha / 2.0;
        w2[2] = alpha;
        w2[3] = -alpha / 2.0;
    } else {
        w1[1] = w2[1] = 0.0;
    }
    /* r = g n at the closest point (the force is -eps r); its xi-derivatives
     * from the master nodes relative to the slave (minimum image): the weights
     * of each derivative sum to zero, so only differences enter. */
    r = nts_scale(c->gap, c->normal);
    for (k = 1; k <= m; ++k) {
        nts_vec2 rel = nts_scene_diff(s, s->pos[node[k]], xs);
        rx = nts_mul_add(rx, w1[k], rel);
        rxx = nts_mul_add(rxx, w2[k], rel);
    }
    if (c->kind != NTS_KIND_VERTEX) pxx = nts_dot(rx, rx) + nts_dot(r, rxx);
    for (k = 0; k <= m; ++k) v[k] = nts_add(nts_scale(w[k], rx), nts_scale(w1[k], r));
    /* psi_xixi > 0 at a strict minimum; it vanishes only for a slave at a
     * centre of curvature (on the evolute), where xi(x) is not differentiable:
     * there the xi term is left out (docs/model.md). */
    scale = c->kind == NTS_KIND_VERTEX || !(pxx > 1e-12 * nts_dot(rx, rx)) ? 0.0 : 1.0 / pxx;
    out->m = m;
    for (k = 0; k <= m; ++k)
        for (l = 0; l <= m; ++l) {
            int a, b;
            double vk[2] = {v[k].x, v[k].y}, vl[2] = {v[l].x, v[l].y};
            for (a = 0; a < 2; ++a)
                for (b = 0; b < 2; ++b) out->k[2 * k + a][2 * l + b] = eps * ((a == b ? w[k] * w[l] : 0.0) - vk[a] * vl[b] * scale);
        }
}

