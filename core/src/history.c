/* The committed friction anchors of a sequence of steps (nts_history,
 * docs/model.md §14): kept by the caller, read by the evaluation, replaced
 * by a result's anchors on commit. Sorted by key, looked up by bisection. */
#include <stdlib.h>
#include <string.h>

#include "friction.h"

nts_history* nts_history_create(void) {
    nts_history* h = (nts_history*)nts_alloc(sizeof *h);
    if (h != NULL) memset(h, 0, sizeof *h);
    return h;
}

void nts_history_destroy(nts_history* h) {
    if (h == NULL) return;
    nts_free(h->a);
    nts_free(h);
}

void nts_history_clear(nts_history* h) {
    if (h != NULL) h->count = 0;
}

size_t nts_history_bytes(const nts_history* h) {
    return h == NULL ? 0 : sizeof *h + (size_t)h->cap * sizeof(nts_anchor);
}

const nts_anchor* nts_history_anchors(const nts_history* h, int* count) {
    if (count != NULL) *count = h != NULL ? h->count : 0;
    return h != NULL ? h->a : NULL;
}

static int key_cmp(const nts_anchor* a, int sb, int sn, int mb) {
    if (a->slave_body != sb) return a->slave_body < sb ? -1 : 1;
    if (a->slave_node != sn) return a->slave_node < sn ? -1 : 1;
    return (a->master_body > mb) - (a->master_body < mb);
}

static int anchor_order(const void* pa, const void* pb) {
    const nts_anchor* b = (const nts_anchor*)pb;
    return key_cmp((const nts_anchor*)pa, b->slave_body, b->slave_node, b->master_body);
}

const nts_anchor* nts_history_find(const nts_history* h, int sb, int sn, int mb, int* hint) {
    int lo = 0, hi = h->count, k;
    if (hint != NULL && *hint >= 0) {
        /* a few steps forward from the last place (slave order) */
        for (k = *hint; k < h->count && k < *hint + 4; ++k) {
            const int c = key_cmp(&h->a[k], sb, sn, mb);
            if (c == 0) {
                *hint = k + 1;
                return &h->a[k];
            }
            if (c > 0) break;
        }
    }
    while (lo < hi) {
        const int mid = lo + (hi - lo) / 2;
        const int c = key_cmp(&h->a[mid], sb, sn, mb);
        if (c == 0) {
            if (hint != NULL) *hint = mid + 1;
            return &h->a[mid];
        }
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    if (hint != NULL) *hint = lo;
    return NULL;
}

/* Room for n anchors (the contents kept). */
static int reserve(nts_history* h, int n) {
    return n <= h->cap ? NTS_OK : nts_grow((void**)&h->a, &h->cap, n, sizeof(nts_anchor));
}

int nts_history_commit(nts_history* h, const nts_result* r) {
    int rc, k;
    if (h == NULL || r == NULL || r->anchor_count < 0 || (r->anchor_count > 0 && r->anchors == NULL))
        return NTS_EINVALID_ARGUMENT;
    if ((rc = reserve(h, r->anchor_count)) != NTS_OK) return rc;
    if (r->anchor_count > 0) memcpy(h->a, r->anchors, sizeof(nts_anchor) * (size_t)r->anchor_count);
    h->count = r->anchor_count;
    /* The result's are in contact order (slave entries): mostly in key order
     * already (a check is a tenth of a sort); the keys are unique. */
    for (k = 1; k < h->count; ++k)
        if (anchor_order(&h->a[k - 1], &h->a[k]) > 0) break;
    if (k < h->count) qsort(h->a, (size_t)h->count, sizeof(nts_anchor), anchor_order);
    return NTS_OK;
}

/* Whether nodes u, v are consecutive on one of body b's loops (either way). */
static int consecutive(const nts_scene* s, const int* entry_of, int b, int u, int v) {
    const int e = entry_of[s->body_node_start[b] + u];
    if (e < 0) return 0;
    return s->surf_local[s->surf_next[e]] == v || s->surf_local[s->surf_prev[e]] == v;
}

static int fail_anchor(nts_error* err, int k, const char* what) {
    nts_where at = nts_naming(nts_at(-1, -1, -1, -1), "history");
    at.item = k;
    return nts_error_set(err, NTS_EINVALID_HISTORY, at, "history entry %d: %s", k, what);
}

/* Each node's surface entry (-1: on no loop), into entry_of. */
static void entries_of(const nts_scene* s, int* entry_of) {
    int k, e;
    for (k = 0; k < s->node_count; ++k) entry_of[k] = -1;
    for (e = 0; e < s->surface_count; ++e) entry_of[s->surf_node[e]] = e;
}

/* Whether anchors in[0..count) are anchors of scene s: NTS_OK, or
 * NTS_EINVALID_HISTORY naming the first entry at fault. */
static int check_anchors(const nts_scene* s, const int* entry_of, const nts_anchor* in, int count, nts_error* err) {
    int k, rc = NTS_OK;
    for (k = 0; k < count && rc == NTS_OK; ++k) {
        const nts_anchor* a = &in[k];
        const int need = a->kind == NTS_KIND_SEGMENT ? 2 : a->kind == NTS_KIND_CORNER ? 3 : 1;
        int q, n;
        /* a body meets itself only where it has self-contact (docs/model.md
         * §16): then its own anchors are pairs too, as its evaluations give */
        if (a->slave_body < 0 || a->slave_body >= s->body_count || a->master_body < 0 ||
            a->master_body >= s->body_count || (a->master_body == a->slave_body && !s->body_self[a->slave_body])) {
            rc = fail_anchor(err, k, "no such pair of bodies");
            break;
        }
        if (a->slave_node < 0 || a->slave_node >= nts_scene_body_node_count(s, a->slave_body)) {
            rc = fail_anchor(err, k, "slave node out of range");
            break;
        }
        if (a->kind != NTS_KIND_SEGMENT && a->kind != NTS_KIND_CORNER && a->kind != NTS_KIND_VERTEX) {
            rc = fail_anchor(err, k, "unknown kind");
            break;
        }
        if (!nts_is_valid_double(a->param) || fabs(a->param) > 1e6) {
            rc = fail_anchor(err, k, "param is not a finite number of moderate size");
            break;
        }
        n = nts_scene_body_node_count(s, a->master_body);
        for (q = 0; q < 3 && rc == NTS_OK; ++q) {
            const int v = a->nodes[q];
            if (q < need ? (v < 0 || v >= n || entry_of[s->body_node_start[a->master_body] + v] < 0) : v != -1)
                rc = fail_anchor(err, k, q < need ? "a node that is not on the master body's boundary"
                                                  : "more nodes than its kind has (-1 past them)");
        }
        if (rc != NTS_OK) break;
        /* (T) of §16: no feature of a body's own that holds the slave node counts */
        if (a->master_body == a->slave_body)
            for (q = 0; q < need && rc == NTS_OK; ++q)
                if (a->nodes[q] == a->slave_node) rc = fail_anchor(err, k, "a feature of its own that holds the slave node");
        if (rc != NTS_OK) break;
        if ((need >= 2 && !consecutive(s, entry_of, a->master_body, a->nodes[0], a->nodes[1])) ||
            (need == 3 && !consecutive(s, entry_of, a->master_body, a->nodes[1], a->nodes[2])) ||
            (need == 3 && a->nodes[0] == a->nodes[2])) {
            rc = fail_anchor(err, k, "its nodes are not a segment or a corner of the master body's boundary");
            break;
        }
    }
    return rc;
}

int nts_history_check(const nts_history* h, const nts_scene* s, int* entry_of, nts_error* err) {
    if (h == NULL || h->count == 0) return NTS_OK;
    entries_of(s, entry_of);
    return check_anchors(s, entry_of, h->a, h->count, err);
}

int nts_history_set(nts_history* h, const nts_scene* s, const nts_anchor* in, int count, nts_error* err) {
    int* entry_of = NULL;
    int k, e, rc = NTS_OK;
    if (err != NULL) *err = nts_error_none();
    if (h == NULL || s == NULL || count < 0 || (count > 0 && in == NULL))
        return nts_error_set(err, NTS_EINVALID_ARGUMENT, nts_at(-1, -1, -1, -1), "null argument");
    if (count > 0 && (entry_of = (int*)nts_alloc(sizeof(int) * (size_t)s->node_count)) == NULL)
        return nts_error_set(err, NTS_ENOMEM, nts_at(-1, -1, -1, -1), "out of memory");
    if (count > 0) {
        entries_of(s, entry_of);
        rc = check_anchors(s, entry_of, in, count, err);
    }
    nts_free(entry_of);
    if (rc != NTS_OK) return rc;
    if ((rc = reserve(h, count)) != NTS_OK)
        return nts_error_set(err, NTS_ENOMEM, nts_at(-1, -1, -1, -1), "out of memory");
    if (count > 0) memcpy(h->a, in, sizeof(nts_anchor) * (size_t)count);
    h->count = count;
    if (count > 1) qsort(h->a, (size_t)h->count, sizeof(nts_anchor), anchor_order); /* h->a may be NULL at 0 */
    for (k = 1; k < h->count; ++k)
        if (anchor_order(&h->a[k - 1], &h->a[k]) == 0) {
            /* name the list's second entry of the key (the sort lost the places) */
            const nts_anchor key = h->a[k];
            int seen = 0, at = -1;
            for (e = 0; e < count && at < 0; ++e)
                if (anchor_order(&in[e], &key) == 0 && seen++ == 1) at = e;
            h->count = 0;
            return fail_anchor(err, at, "a key (slave body, slave node, master body) appears twice");
        }
    return NTS_OK;
}

/* The bodies of s whose coefficient (their own, else the options') is
 * above 0 (friction_pair_mu): c[0] those that can be slaves, c[1] masters,
 * c[2] both, c[3] those that meet themselves. Summed over a distributed
 * scene's parts, they decide for the whole (nts_frame.rubbing). */
void nts_friction_counts(const nts_scene* s, const nts_options* o, long long c[4]) {
    int b;
    c[0] = c[1] = c[2] = c[3] = 0;
    for (b = 0; b < s->body_count; ++b) {
        const double mu = s->body_friction[b] >= 0.0 ? s->body_friction[b] : o->friction;
        const int slave = s->body_role[b] != NTS_ROLE_MASTER, master = s->body_role[b] != NTS_ROLE_SLAVE;
        if (!(mu > 0.0)) continue;
        c[0] += slave;
        c[1] += master;
        c[2] += slave && master;
        c[3] += slave && master && s->body_self[b];
    }
}

/* Friction runs when some pair of bodies that can meet has a coefficient
 * above 0 (the smaller of the two): a slave of one and a master of another
 * (ordered pairs a != b: slaves x masters less the bodies that are both),
 * or a body that meets itself. Otherwise none of it runs, and the answer is
 * the frictionless one bit for bit (docs/model.md §14). */
int nts_friction_rubs(const long long c[4]) { return c[3] > 0 || c[0] * c[1] > c[2]; }

int nts_friction_on(const nts_scene* s, const nts_options* o) {
    long long c[4];
    if (s == NULL || o == NULL) return 0;
    nts_friction_counts(s, o, c);
    return nts_friction_rubs(c);
}
