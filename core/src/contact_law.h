/* The contact law: what one active contact gives, in one place (docs/model.md
 * §6, §7, §10). Every path of the scatter (search.h: direct, shares,
 * records) and the tangent call these and nothing else, so that they give
 * the same bits and a new law (friction) changes this file and the state it
 * reads, not the paths.
 *
 * A contact is active when its gap g < 0; n is the unit normal at the
 * closest point X, Xs - X = g n; the master nodes k carry the weights N_k of
 * the feature (the segment's two ends, the corner's three nodes, or the
 * vertex). `eg` below is eps g. */
#ifndef NTSCONTACT_CONTACT_LAW_H
#define NTSCONTACT_CONTACT_LAW_H

#include <math.h>

#include "internal.h"

/* The slave's penalty (§10): per node, or per unit of slave entry i's
 * tributary length trib[i] (a pressure stiffness). The length is read only
 * then: an argument would be loaded for every active contact, a stall on an
 * array nothing else reads (8 MB at 1e6 nodes). */
static inline double law_penalty(double eps, int per_length, const double* trib, int i) {
    return per_length ? eps * trib[i] : eps;
}

/* The energy (9): eps g^2 / 2. */
static inline double law_energy(double eps, double g) { return 0.5 * eps * g * g; }

/* The forces (10): f_s = -eps g n on the slave, f_k = eps g N_k n on master
 * node k. */
static inline nts_vec2 law_slave_force(double eg, nts_vec2 n) { return nts_scale(-eg, n); }
static inline nts_vec2 law_master_force(double eg, double w, nts_vec2 n) { return nts_scale(eg * w, n); }
/* The slave's force along n as a magnitude, -eps g >= 0: what the pressure
 * (21) sums. */
static inline double law_slave_normal(double eg) { return -eg; }

/* The virial (11): -sum_k f_k (X_k - Xs) over the contact's nodes is
 * -eps g n (X - Xs) with X the closest point, and Xs - X = g n there, so it
 * is eps g^2 n n: no node positions needed. */
static inline nts_virial law_virial(double eg, double g, nts_vec2 n) {
    const double e2 = eg * g;
    nts_virial v;
    v.xx = e2 * n.x * n.x;
    v.yy = e2 * n.y * n.y;
    v.xy = e2 * n.x * n.y;
    v.yx = v.xy;
    return v;
}

/* The virial of a contact whose slave force f has a tangential part
 * (docs/model.md (28)): -sum_k f_k (X_k - Xs) = f (X - Xs) = -g f n, no
 * longer symmetric. */
static inline nts_virial law_virial_force(double g, nts_vec2 f, nts_vec2 n) {
    nts_virial v;
    v.xx = -g * f.x * n.x;
    v.yy = -g * f.y * n.y;
    v.xy = -g * f.x * n.y;
    v.yx = -g * f.y * n.x;
    return v;
}

/* What active contacts add up to: their count, energy (9), virial (11) and
 * largest penetration, and whether one overflowed a double; with friction
 * (§14) the virial's yx, the dissipation (27) and the sticking and slipping
 * contacts. */
typedef struct contact_sums {
    double energy, vxx, vyy, vxy, maxpen;
    int active, overflow;
    double vyx, dissipation;
    int sticking, slipping;
} contact_sums;

/* An active record's forces (10), node by node: f_s = -eps g n on the slave
 * (node[0]), f_k = eps g N_k n on master node k (node[1..3], -1 past the
 * last). Kept as eps g, n and the N_k, one 64-byte line: share_force makes
 * each node's force by the same products wherever it runs (the same bits). */
typedef struct force_shares {
    int node[4];
    double eg;
    nts_vec2 n;
    double w[3];
} force_shares;

typedef char nts_force_shares_are_one_line[sizeof(force_shares) == 64 ? 1 : -1];

/* With friction (§14) a record's shares carry its whole slave force f as
 * eg = 1 and n = -f: share_force then gives f on the slave and -N_k f on
 * master node k exactly (a product by 1 and a sign change lose nothing). */

static inline nts_vec2 share_force(const force_shares* sh, int q) {
    return q == 0 ? law_slave_force(sh->eg, sh->n) : law_master_force(sh->eg, sh->w[q - 1], sh->n);
}

/* Add an active contact of penalty eps, gap g and normal n to the sums. */
static inline void law_sum(contact_sums* cs, double eps, double g, nts_vec2 n, int want_virial) {
    ++cs->active;
    cs->energy += law_energy(eps, g);
    if (-g > cs->maxpen) cs->maxpen = -g;
    cs->overflow |= !isfinite(eps * g);
    if (want_virial) {
        const nts_virial v = law_virial(eps * g, g, n);
        cs->overflow |= !isfinite(v.xx + v.yy + v.xy);
        cs->vxx += v.xx;
        cs->vyy += v.yy;
        cs->vxy += v.xy;
        cs->vyx += v.yx;
    }
}

/* Add an active contact with friction (§14): f the whole force on the
 * slave, energy_t its tangential spring's energy (26), the dissipation
 * (27) and its state. */
static inline void law_sum_friction(contact_sums* cs, double eps, double g, nts_vec2 n, nts_vec2 f, double energy_t,
                                    double dissipation, int state, int want_virial) {
    ++cs->active;
    cs->energy += law_energy(eps, g) + energy_t;
    cs->dissipation += dissipation;
    cs->sticking += state == NTS_STICK;
    cs->slipping += state == NTS_SLIP;
    if (-g > cs->maxpen) cs->maxpen = -g;
    cs->overflow |= !isfinite(eps * g) || !isfinite(f.x + f.y) || !isfinite(energy_t + dissipation);
    if (want_virial) {
        const nts_virial v = law_virial_force(g, f, n);
        cs->overflow |= !isfinite(v.xx + v.yy + v.xy + v.yx);
        cs->vxx += v.xx;
        cs->vyy += v.yy;
        cs->vxy += v.xy;
        cs->vyx += v.yx;
    }
}

/* Add share q of a contact's forces into F (every path adds them the same
 * way: the same bits). Returns 1 when the sum it wrote is not finite. Every
 * force is a sum of shares from zero, and a sum that has overflowed never
 * turns finite again (infinity plus a finite share stays infinite, plus the
 * other infinity is NaN, and NaN stays NaN): the adds' own verdicts say
 * whether every force is finite, without a pass over all the nodes (most of
 * a mesh's are inside, never touched). */
static inline int law_add_share(nts_vec2* F, const force_shares* sh, int q) {
    const nts_vec2 f = nts_add(F[sh->node[q]], share_force(sh, q));
    F[sh->node[q]] = f;
    return !nts_is_valid_vec2(f);
}

/* Add a contact's force shares into F, node by node in order; 1 when a sum
 * it wrote is not finite. */
static inline int law_add_shares(nts_vec2* F, const force_shares* sh) {
    int q, bad = 0;
    for (q = 0; q < 4 && sh->node[q] >= 0; ++q) bad |= law_add_share(F, sh, q);
    return bad;
}

/* The tangent (§7) of one active contact: its 2(m+1) x 2(m+1) dense block
 * over (slave, master nodes), with `alpha` the master body's; node[] are
 * global node indices, k[2 a + i][2 b + j] the entry of node a's component i
 * and node b's component j (contact_law.c). */
typedef struct law_block {
    int m;       /* master nodes: 1 to 3 */
    int node[4]; /* slave, then the master nodes */
    double k[8][8];
} law_block;
void nts_law_tangent(const nts_scene* s, const nts_contact* c, double alpha, law_block* out);

#endif
