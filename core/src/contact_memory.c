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

struct nts_contact_memory {
    nts_contact* kept;   /* the last step's contacts (what the next step matches) */
    int kept_count, kept_cap;
    nts_contact* prev;   /* the step before it (what the last matches point into) */
    int prev_count, prev_cap;
    int* order;          /* kept contacts' indices, sorted by pair */
    int order_cap;
    int* spare_order;
    int spare_cap;
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

void nts_contact_memory_destroy(nts_contact_memory* m) {
    if (m == NULL) return;
    nts_free(m->kept);
    nts_free(m->prev);
    nts_free(m->order);
    nts_free(m->spare_order);
    nts_free(m->match);
    nts_free(m);
}

size_t nts_contact_memory_bytes(const nts_contact_memory* m) {
    if (m == NULL) return 0;
    return sizeof *m + ((size_t)m->kept_cap + (size_t)m->prev_cap) * sizeof(nts_contact) +
           ((size_t)m->order_cap + (size_t)m->spare_cap) * sizeof(int) + (size_t)m->match_cap * sizeof(nts_contact_match);
}

void nts_contact_memory_clear(nts_contact_memory* m) {
    if (m == NULL) return;
    m->kept_count = m->prev_count = 0;
}

const nts_contact* nts_contact_memory_previous(const nts_contact_memory* m, int* count) {
    if (count != NULL) *count = m != NULL ? m->prev_count : 0;
    return m != NULL && m->prev_count > 0 ? m->prev : NULL;
}

/* The kept contact of c's pair, or -1. */
static int find_pair(const nts_contact_memory* m, const nts_contact* c) {
    int lo = 0, hi = m->kept_count - 1;
    while (lo <= hi) {
        const int mid = lo + (hi - lo) / 2, k = m->order[mid];
        const int d = pair_cmp(&m->kept[k], c);
        if (d == 0) return k;
        if (d < 0) lo = mid + 1;
        else hi = mid - 1;
    }
    return -1;
}

int nts_contact_memory_step(nts_contact_memory* m, const nts_result* r, const nts_contact_match** match,
                            nts_contact_changes* changes) {
    const int n = r != NULL ? r->contact_count : 0;
    sort_item* items = NULL;
    nts_contact* t;
    int k, cap, *ti, matched = 0;
    nts_contact_changes ch;
    if (match != NULL) *match = NULL;
    if (m == NULL || r == NULL) return NTS_EINVALID_ARGUMENT;
    if (r->contacts == NULL && r->summary.contacts > 0) return NTS_EINVALID_ARGUMENT;
    /* Room first, so that a failure leaves the memory as it was. */
    if (nts_grow((void**)&m->prev, &m->prev_cap, n, sizeof(nts_contact)) != NTS_OK ||
        nts_grow((void**)&m->spare_order, &m->spare_cap, n, sizeof(int)) != NTS_OK ||
        nts_grow((void**)&m->match, &m->match_cap, n, sizeof(nts_contact_match)) != NTS_OK)
        return NTS_ENOMEM;
    if (n > 0 && (items = (sort_item*)nts_alloc(sizeof(sort_item) * (size_t)n)) == NULL) return NTS_ENOMEM;
    memset(&ch, 0, sizeof ch);
    for (k = 0; k < n; ++k) {
        const nts_contact* c = &r->contacts[k];
        const int p = find_pair(m, c);
        m->match[k].previous = p;
        m->match[k].persisted = 0;
        if (p < 0) {
            ++ch.added;
            continue;
        }
        ++matched;
        {
            /* the pair is equal: the key is when the feature is */
            const nts_contact_key a = nts_contact_key_of(&m->kept[p]), b = nts_contact_key_of(c);
            m->match[k].persisted = a.kind == b.kind && a.feature_node == b.feature_node;
        }
        if (m->match[k].persisted) ++ch.persisted;
        else ++ch.moved;
    }
    ch.ended = m->kept_count - matched;
    /* The kept become the previous; the result's contacts the kept. */
    t = m->prev;
    m->prev = m->kept;
    m->kept = t;
    cap = m->prev_cap;
    m->prev_cap = m->kept_cap;
    m->kept_cap = cap;
    m->prev_count = m->kept_count;
    m->kept_count = n;
    if (n > 0) memcpy(m->kept, r->contacts, sizeof(nts_contact) * (size_t)n);
    for (k = 0; k < n; ++k) {
        items[k].c = &m->kept[k];
        items[k].index = k;
    }
    if (n > 1) qsort(items, (size_t)n, sizeof(sort_item), item_cmp);
    for (k = 0; k < n; ++k) m->spare_order[k] = items[k].index;
    nts_free(items);
    ti = m->order;
    m->order = m->spare_order;
    m->spare_order = ti;
    cap = m->order_cap;
    m->order_cap = m->spare_cap;
    m->spare_cap = cap;
    if (match != NULL) *match = n > 0 ? m->match : NULL;
    if (changes != NULL) *changes = ch;
    return NTS_OK;
}
