/* Contact state that persists (ntscontact.h: nts_contact_memory): the
 * previous step's contacts, and each new contact matched to them by its key
 * (docs/model.md §11). A scene has at most one contact per (slave node,
 * master body) pair (§5), so a pair finds at most one previous contact: the
 * kept contacts are indexed by pair, sorted, and each new contact looks its
 * pair up (binary search); the feature then says whether it persisted or
 * moved. Nothing here touches an evaluation. */
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* A step's contacts, and their indices sorted by pair (for the lookup). */
typedef struct contact_set {
    nts_contact* c;
    int count, cap;
    int* order;
    int order_cap;
} contact_set;

/* Three sets, rotated: the committed step's (what the next match is against),
 * the one before it (what the matches of the last commit point into), and the
 * last match's, pending until committed (a trial step: an implicit solver's
 * Newton iterations; a session's step whose answer is refused). */
struct nts_contact_memory {
    contact_set kept, prev, pending;
    int has_pending;
    nts_contact_match* match;
    int match_cap;
};

nts_contact_key nts_contact_key_of(const nts_contact* c) {
    nts_contact_key k;
    k.slave_body = c->slave_body;
    k.slave_node = c->slave_node;
    k.master_body = c->master_body;
    k.kind = c->kind;
    /* the corner's middle node X3 (master_nodes: X2, X3, X4); else the first */
    k.feature_node = c->kind == NTS_KIND_CORNER ? c->master_nodes[1] : c->master_nodes[0];
    return k;
}

/* Pairs in (slave body, slave node, master body) order. */
static int pair_cmp(const nts_contact* a, const nts_contact* b) {
    if (a->slave_body != b->slave_body) return a->slave_body < b->slave_body ? -1 : 1;
    if (a->slave_node != b->slave_node) return a->slave_node < b->slave_node ? -1 : 1;
    if (a->master_body != b->master_body) return a->master_body < b->master_body ? -1 : 1;
    return 0;
}

/* qsort has no context argument: sort the indices with the array beside
 * them, a pair's index at most once (no ties to order). */
typedef struct sort_item {
    const nts_contact* c;
    int index;
} sort_item;
static int item_cmp(const void* a, const void* b) {
    return pair_cmp(((const sort_item*)a)->c, ((const sort_item*)b)->c);
}

nts_contact_memory* nts_contact_memory_create(void) {
    nts_contact_memory* m = (nts_contact_memory*)nts_alloc(sizeof *m);
    if (m != NULL) memset(m, 0, sizeof *m);
    return m;
}

static void set_free(contact_set* cs) {
    nts_free(cs->c);
    nts_free(cs->order);
}

void nts_contact_memory_destroy(nts_contact_memory* m) {
    if (m == NULL) return;
    set_free(&m->kept);
    set_free(&m->prev);
    set_free(&m->pending);
    nts_free(m->match);
    nts_free(m);
}

static size_t set_bytes(const contact_set* cs) {
    return (size_t)cs->cap * sizeof(nts_contact) + (size_t)cs->order_cap * sizeof(int);
}

size_t nts_contact_memory_bytes(const nts_contact_memory* m) {
    if (m == NULL) return 0;
    return sizeof *m + set_bytes(&m->kept) + set_bytes(&m->prev) + set_bytes(&m->pending) +
           (size_t)m->match_cap * sizeof(nts_contact_match);
}

void nts_contact_memory_clear(nts_contact_memory* m) {
    if (m == NULL) return;
    m->kept.count = m->prev.count = m->pending.count = 0;
    m->has_pending = 0;
}

const nts_contact* nts_contact_memory_previous(const nts_contact_memory* m, int* count) {
    /* the base of the last match: the committed step while it is pending,
     * the one before once committed */
    const contact_set* cs = m == NULL ? NULL : (m->has_pending ? &m->kept : &m->prev);
    if (count != NULL) *count = cs != NULL ? cs->count : 0;
    return cs != NULL && cs->count > 0 ? cs->c : NULL;
}

/* The committed contact of c's pair, or -1. */
static int find_pair(const contact_set* kept, const nts_contact* c) {
    int lo = 0, hi = kept->count - 1;
    while (lo <= hi) {
        const int mid = lo + (hi - lo) / 2, k = kept->order[mid];
        const int d = pair_cmp(&kept->c[k], c);
        if (d == 0) return k;
        if (d < 0) lo = mid + 1;
        else hi = mid - 1;
    }
    return -1;
}

int nts_contact_memory_match(nts_contact_memory* m, const nts_result* r, const nts_contact_match** match,
                             nts_contact_changes* changes) {
    const int n = r != NULL ? r->contact_count : 0;
    contact_set* pd;
    sort_item* items = NULL;
    int k, matched = 0;
    nts_contact_changes ch;
    if (match != NULL) *match = NULL;
    if (m == NULL || r == NULL) return NTS_EINVALID_ARGUMENT;
    if (r->contacts == NULL && r->summary.contacts > 0) return NTS_EINVALID_ARGUMENT;
    pd = &m->pending;
    /* Room first, so that a failure leaves the memory as it was (a pending
     * match is replaced by this one in any case). */
    m->has_pending = 0;
    if (nts_grow((void**)&pd->c, &pd->cap, n, sizeof(nts_contact)) != NTS_OK ||
        nts_grow((void**)&pd->order, &pd->order_cap, n, sizeof(int)) != NTS_OK ||
        nts_grow((void**)&m->match, &m->match_cap, n, sizeof(nts_contact_match)) != NTS_OK)
        return NTS_ENOMEM;
    if (n > 0 && (items = (sort_item*)nts_alloc(sizeof(sort_item) * (size_t)n)) == NULL) return NTS_ENOMEM;
    memset(&ch, 0, sizeof ch);
    for (k = 0; k < n; ++k) {
        const nts_contact* c = &r->contacts[k];
        const int p = find_pair(&m->kept, c);
        m->match[k].previous = p;
        m->match[k].persisted = 0;
        if (p < 0) {
            ++ch.added;
            continue;
        }
        ++matched;
        {
            /* the pair is equal: the key is when the feature is */
            const nts_contact_key a = nts_contact_key_of(&m->kept.c[p]), b = nts_contact_key_of(c);
            m->match[k].persisted = a.kind == b.kind && a.feature_node == b.feature_node;
        }
        if (m->match[k].persisted) ++ch.persisted;
        else ++ch.moved;
    }
    ch.ended = m->kept.count - matched;
    pd->count = n;
    if (n > 0) memcpy(pd->c, r->contacts, sizeof(nts_contact) * (size_t)n);
    for (k = 0; k < n; ++k) {
        items[k].c = &pd->c[k];
        items[k].index = k;
    }
    if (n > 1) qsort(items, (size_t)n, sizeof(sort_item), item_cmp);
    for (k = 0; k < n; ++k) pd->order[k] = items[k].index;
    nts_free(items);
    m->has_pending = 1;
    if (match != NULL) *match = n > 0 ? m->match : NULL;
    if (changes != NULL) *changes = ch;
    return NTS_OK;
}

int nts_contact_memory_commit(nts_contact_memory* m) {
    contact_set t;
    if (m == NULL || !m->has_pending) return NTS_EINVALID_ARGUMENT;
    /* prev <- kept <- pending, the old prev's buffers the next pending's */
    t = m->prev;
    m->prev = m->kept;
    m->kept = m->pending;
    m->pending = t;
    m->pending.count = 0;
    m->has_pending = 0;
    return NTS_OK;
}

int nts_contact_memory_step(nts_contact_memory* m, const nts_result* r, const nts_contact_match** match,
                            nts_contact_changes* changes) {
    const int rc = nts_contact_memory_match(m, r, match, changes);
    return rc != NTS_OK ? rc : nts_contact_memory_commit(m);
}
