/* Contact memory suite (issue 24 §4): contact keys, and the previous step's
 * contacts matched to the new ones by key, against a brute-force matcher on
 * random walks of a packing; a memory never changes an evaluation. */
#include <stdlib.h>
#include <string.h>

#include "suites.h"
#include "test_util.h"

static int same_pair(const nts_contact* a, const nts_contact* b) {
    return a->slave_body == b->slave_body && a->slave_node == b->slave_node && a->master_body == b->master_body;
}

/* Every match by brute force: the previous contact of the same pair (at most
 * one), persisted when the keys are equal field by field. */
static void check_step(const nts_contact* prev, int np, const nts_result* r, const nts_contact_match* match,
                       const nts_contact_changes* ch) {
    int k, j, persisted = 0, moved = 0, added = 0;
    char* used = (char*)calloc((size_t)np + 1, 1);
    for (k = 0; k < r->contact_count; ++k) {
        int found = -1;
        for (j = 0; j < np; ++j)
            if (same_pair(&prev[j], &r->contacts[k])) {
                CU_ASSERT(found < 0); /* one contact per pair */
                found = j;
            }
        ASSERT_INT_EQ(match[k].previous, found);
        if (found >= 0) {
            const nts_contact_key a = nts_contact_key_of(&prev[found]), b = nts_contact_key_of(&r->contacts[k]);
            const int eq = memcmp(&a, &b, sizeof a) == 0;
            ASSERT_INT_EQ(match[k].persisted, eq);
            used[found] = 1;
            if (eq) ++persisted;
            else ++moved;
        } else {
            CU_ASSERT(match[k].persisted == 0);
            ++added;
        }
    }
    ASSERT_INT_EQ(ch->persisted, persisted);
    ASSERT_INT_EQ(ch->moved, moved);
    ASSERT_INT_EQ(ch->added, added);
    for (j = 0, k = 0; j < np; ++j) k += !used[j];
    ASSERT_INT_EQ(ch->ended, k);
    free(used);
}

static void test_random_walk(void) {
    test_packing p = make_packing(25, 32, 1.0, 1.93, 0, 4711);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* ctx = nts_context_create();
    nts_contact_memory* mem = nts_contact_memory_create();
    nts_options o = nts_default_options();
    test_rng rng = {12345};
    nts_contact* prev = NULL;
    int np = 0, step, n = nts_scene_node_count(s), total_moved = 0, total_persisted = 0, total_ended = 0;
    nts_vec2* x = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    CU_ASSERT_FATAL(s != NULL && ctx != NULL && mem != NULL && x != NULL);
    o.outputs = NTS_OUT_CONTACTS | NTS_OUT_FORCES;
    memcpy(x, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    for (step = 0; step < 12; ++step) {
        nts_result r;
        nts_error err;
        const nts_contact_match* match;
        nts_contact_changes ch;
        const nts_contact* kept_prev;
        int kept_np, i;
        CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
        CU_ASSERT_FATAL(nts_contact_memory_step(mem, &r, &match, &ch) == NTS_OK);
        kept_prev = nts_contact_memory_previous(mem, &kept_np);
        ASSERT_INT_EQ(kept_np, np);
        if (np > 0) CU_ASSERT(memcmp(kept_prev, prev, sizeof(nts_contact) * (size_t)np) == 0);
        check_step(prev, np, &r, match, &ch);
        if (step == 0) ASSERT_INT_EQ(ch.added, r.contact_count);
        if (step > 0) {
            total_moved += ch.moved;
            total_persisted += ch.persisted;
            total_ended += ch.ended;
        }
        free(prev);
        np = r.contact_count;
        prev = (nts_contact*)malloc(sizeof(nts_contact) * (size_t)(np + 1));
        memcpy(prev, r.contacts, sizeof(nts_contact) * (size_t)np);
        /* every node moves by up to 2% of a segment; a body in four drifts */
        for (i = 0; i < n; ++i) {
            x[i].x += 0.004 * (rng_uniform(&rng) - 0.5);
            x[i].y += 0.004 * (rng_uniform(&rng) - 0.5);
        }
        CU_ASSERT_FATAL(update_both(s, x, &err) == NTS_OK);
    }
    /* the walk met every kind of change */
    CU_ASSERT(total_persisted > 0);
    CU_ASSERT(total_moved > 0);
    CU_ASSERT(total_ended > 0);
    free(prev);
    free(x);
    nts_contact_memory_destroy(mem);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* The same positions twice: every contact persisted, at its own index. */
static void test_same_positions_persist(void) {
    test_packing p = make_packing(9, 40, 1.0, 1.93, 1, 99);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* ctx = nts_context_create();
    nts_contact_memory* mem = nts_contact_memory_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    const nts_contact_match* match;
    nts_contact_changes ch;
    int k;
    o.outputs = NTS_OUT_CONTACTS;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT(r.contact_count > 10);
    CU_ASSERT_FATAL(nts_contact_memory_step(mem, &r, NULL, NULL) == NTS_OK);
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_contact_memory_step(mem, &r, &match, &ch) == NTS_OK);
    ASSERT_INT_EQ(ch.persisted, r.contact_count);
    CU_ASSERT(ch.moved == 0 && ch.added == 0 && ch.ended == 0);
    for (k = 0; k < r.contact_count; ++k) CU_ASSERT(match[k].previous == k && match[k].persisted == 1);
    /* Cleared: all new. */
    nts_contact_memory_clear(mem);
    CU_ASSERT_FATAL(nts_contact_memory_step(mem, &r, &match, &ch) == NTS_OK);
    ASSERT_INT_EQ(ch.added, r.contact_count);
    /* Contacts not asked for while some are active: refused, memory as before. */
    o.outputs = NTS_OUT_FORCES;
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT(nts_contact_memory_step(mem, &r, &match, &ch) == NTS_EINVALID_ARGUMENT);
    CU_ASSERT(nts_contact_memory_step(NULL, &r, &match, &ch) == NTS_EINVALID_ARGUMENT);
    nts_contact_memory_destroy(mem);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* Trial steps (an implicit solver's Newton iterations): each is matched
 * against the committed step, not against the trial before it; a commit
 * makes the last match the committed step. */
static void test_trial_and_commit(void) {
    test_packing p = make_packing(16, 40, 1.0, 1.93, 0, 314);
    nts_scene* s = make_scene(p.bodies, p.count, p.lx, p.ly);
    nts_context* ctx = nts_context_create();
    nts_contact_memory* mem = nts_contact_memory_create();
    nts_options o = nts_default_options();
    nts_result r;
    nts_error err;
    const nts_contact_match* match;
    nts_contact_changes ch, first;
    const nts_contact* base;
    nts_vec2* x;
    int n = nts_scene_node_count(s), i, committed, count;
    CU_ASSERT_FATAL(s != NULL && ctx != NULL && mem != NULL);
    x = (nts_vec2*)malloc(sizeof(nts_vec2) * (size_t)n);
    o.outputs = NTS_OUT_CONTACTS;
    CU_ASSERT(nts_contact_memory_commit(mem) == NTS_EINVALID_ARGUMENT); /* nothing pending */
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_contact_memory_step(mem, &r, NULL, NULL) == NTS_OK);
    committed = r.contact_count;
    /* Trial 1: every node pushed outward by 0.02; trial 2 from the same committed step. */
    memcpy(x, nts_scene_positions(s), sizeof(nts_vec2) * (size_t)n);
    for (i = 0; i < n; ++i) x[i].x *= 1.01;
    CU_ASSERT_FATAL(update_both(s, x, &err) == NTS_OK);
    CU_ASSERT_FATAL(nts_evaluate(ctx, s, &o, &r, &err) == 0);
    CU_ASSERT_FATAL(nts_contact_memory_match(mem, &r, &match, &first) == NTS_OK);
    base = nts_contact_memory_previous(mem, &count);
    ASSERT_INT_EQ(count, committed);
    CU_ASSERT(base != NULL);
    CU_ASSERT_FATAL(nts_contact_memory_match(mem, &r, &match, &ch) == NTS_OK);
    CU_ASSERT(memcmp(&ch, &first, sizeof ch) == 0); /* the same base: the same answer */
    ASSERT_INT_EQ(ch.persisted + ch.moved + ch.ended, committed);
    /* Commit: the trial's contacts are the committed step; matched again, all persist. */
    CU_ASSERT(nts_contact_memory_commit(mem) == NTS_OK);
    CU_ASSERT(nts_contact_memory_commit(mem) == NTS_EINVALID_ARGUMENT);
    (void)nts_contact_memory_previous(mem, &count);
    ASSERT_INT_EQ(count, committed); /* the last match's base, until the next match */
    CU_ASSERT_FATAL(nts_contact_memory_match(mem, &r, &match, &ch) == NTS_OK);
    ASSERT_INT_EQ(ch.persisted, r.contact_count);
    (void)nts_contact_memory_previous(mem, &count);
    ASSERT_INT_EQ(count, r.contact_count);
    free(x);
    nts_contact_memory_destroy(mem);
    nts_context_destroy(ctx);
    nts_scene_destroy(s);
    free_packing(&p);
}

/* Keys: a corner is keyed at its middle node, a segment and a vertex at
 * their first. */
static void test_keys(void) {
    nts_contact c;
    nts_contact_key k;
    memset(&c, 0, sizeof c);
    c.slave_body = 1;
    c.slave_node = 7;
    c.master_body = 3;
    c.kind = NTS_KIND_CORNER;
    c.master_count = 3;
    c.master_nodes[0] = 4;
    c.master_nodes[1] = 5;
    c.master_nodes[2] = 6;
    k = nts_contact_key_of(&c);
    CU_ASSERT(k.slave_body == 1 && k.slave_node == 7 && k.master_body == 3 && k.kind == NTS_KIND_CORNER &&
              k.feature_node == 5);
    c.kind = NTS_KIND_SEGMENT;
    c.master_count = 2;
    CU_ASSERT(nts_contact_key_of(&c).feature_node == 4);
}

void register_contact_memory_suite(void) {
    CU_pSuite s = CU_add_suite("contact memory", NULL, NULL);
    ADD_TEST(s, test_keys);
    ADD_TEST(s, test_same_positions_persist);
    ADD_TEST(s, test_random_walk);
    ADD_TEST(s, test_trial_and_commit);
}
