/* Coulomb friction (friction.c, history.c; docs/model.md §14): what an
 * active contact's tangential part gives, from the committed anchor it
 * starts from, and its tangent. The contact law (contact_law.h) calls it for
 * every active record when friction is on; without friction nothing here
 * runs (a scene without friction gives today's bits). */
#ifndef NTSCONTACT_FRICTION_H
#define NTSCONTACT_FRICTION_H

#include "search.h"

/* The committed anchors (nts_history), sorted by key. */
struct nts_history {
    nts_anchor* a;
    int count, cap;
};

/* The pair's coefficient: the smaller of the two bodies' (each its own, or
 * the options'), docs/model.md §14. */
static inline double friction_pair_mu(const nts_scene* s, int slave_body, int master_body, double mu) {
    const double ms = s->body_friction[slave_body] >= 0.0 ? s->body_friction[slave_body] : mu;
    const double mm = s->body_friction[master_body] >= 0.0 ? s->body_friction[master_body] : mu;
    return ms < mm ? ms : mm;
}

/* What friction makes of one active record. */
typedef struct friction_out {
    nts_vec2 f;        /* the whole force on the slave: -eps g n + t tau (10), (24) */
    nts_vec2 tau;      /* the unit tangent at the closest point, (-n_y, n_x) */
    double t;          /* the tangential traction on the slave along tau (24) */
    double energy_t;   /* the tangential spring's energy, eps_T g_e^2 / 2 (26) */
    double slip;       /* this step's slip (0 in stick) */
    double dissipation;/* mu |f_N| slip (27) */
    double eps_t;      /* the tangential penalty of this slave */
    double mu;         /* the pair's coefficient */
    int state;         /* nts_friction_state */
    int found;         /* 1: the step started from a committed anchor; 0: new, at the closest point */
    nts_anchor from;   /* the anchor the step started from */
    nts_anchor anchor; /* the anchor after the step (returned in slip) */
} friction_out;

/* The friction of active record b (gap < 0) of slave entry b->slave;
 * *hint: nts_history_find's, kept by the caller across its records. */
void nts_friction_eval(const search_env* env, const candidate* b, friction_out* out, int* hint);

/* Append the friction tangent -d f_T / dx of active record b (its
 * tangential forces on the slave and the master nodes, over the slave, the
 * master nodes and the anchor's nodes). 0 or NTS_ENOMEM. */
int nts_friction_tangent_add(nts_kbuf* kb, const search_env* env, const candidate* b, const friction_out* fo);

/* Whether history h's anchors are anchors of scene s (nts_history_set's
 * checks: bodies and nodes in range, each a segment, corner or vertex of
 * its master's loops): NTS_OK, or NTS_EINVALID_HISTORY naming the entry. A
 * history committed from another scene's evaluation (another mesh, other
 * bodies) is refused where it is used, not read out of range. entry_of:
 * s->node_count ints of scratch. */
int nts_history_check(const nts_history* h, const nts_scene* s, int* entry_of, nts_error* err);
/* The bodies whose coefficient is above 0, by role (history.c), and
 * whether those make some pair that can meet rub: friction's switch,
 * decided on the whole scene (nts_frame.rubbing on a distributed one). */
void nts_friction_counts(const nts_scene* s, const nts_options* o, long long c[4]);
int nts_friction_rubs(const long long c[4]);

/* The committed anchor of key (slave body, slave node, master body), or NULL.
 * *hint (may be NULL; start at 0) is where the last lookup ended: the
 * records come in slave order, so the next key is mostly just after it, and
 * a few steps forward find it before a bisection would. */
const nts_anchor* nts_history_find(const nts_history* h, int slave_body, int slave_node, int master_body, int* hint);

#endif
