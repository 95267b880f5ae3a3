/* The session store: scene sessions by id, bounded in count, idle time and
 * memory. A hash of ids for lookups and a least-recently-used list for
 * eviction, under one lock held only for bookkeeping, never during an
 * evaluation. A session in use (a request holds it) is never evicted or freed:
 * deleting it only unlinks it, and its last user frees it. Steps on one
 * session are serialised by its own lock.
 *
 * Clients (issue 23). A session belongs to the client that created it
 * (ntsd_client_key: its token, or its address): for any other it does not
 * exist. One client holds at most max_per_client sessions: at its quota, a
 * new one takes the place of its own least recently used idle session. When
 * the store is full (by count or by memory), the room comes from the client
 * holding the most (sessions, or bytes), counting the one being created:
 * never from a client within its fair share (the limit over the clients
 * holding sessions) while another holds more. So a client creating sessions
 * as fast as it can recycles its own and cannot push out anyone else's.
 * Before any session is evicted for memory, idle sessions give back their
 * evaluation contexts' buffers (ntsj_session_trim): a warm context is a cache,
 * a session is not. After a step, a session keeps what the step grew only
 * within keep_limit (one large step does not hold its buffers for the
 * session's life). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>

#include "server.h"

static unsigned hash_id(const char* id) {
    unsigned h = 2166136261u; /* FNV-1a */
    for (; *id; ++id) h = (h ^ (unsigned char)*id) * 16777619u;
    return h;
}

int ntsd_sessions_init(ntsd_sessions* st, int max, int max_per_client, unsigned ttl_s, size_t memory_max) {
    unsigned n = 16;
    memset(st, 0, sizeof *st);
    while (n < 2u * (unsigned)max && n < (1u << 22)) n *= 2;
    st->buckets = calloc(n, sizeof *st->buckets);
    if (st->buckets == NULL) return -1;
    st->bucket_count = n;
    st->max = max;
    st->max_per_client = max_per_client > 0 ? max_per_client : 1;
    st->ttl_s = ttl_s;
    st->memory_max = memory_max;
    pthread_mutex_init(&st->lock, NULL);
    return 0;
}

static void entry_free(ntsd_session_entry* e) {
    ntsj_session_destroy(e->session);
    pthread_mutex_destroy(&e->step_lock);
    free(e);
}

/* ------------------------------------------------------------ clients */

static ntsd_session_client* client_find(ntsd_sessions* st, const char* key) {
    ntsd_session_client* c = st->clients;
    while (c != NULL && strcmp(c->key, key) != 0) c = c->next;
    return c;
}

/* The client's record, made when it holds nothing yet; NULL without memory. */
static ntsd_session_client* client_get(ntsd_sessions* st, const char* key) {
    ntsd_session_client* c = client_find(st, key);
    if (c != NULL) return c;
    c = calloc(1, sizeof *c);
    if (c == NULL) return NULL;
    snprintf(c->key, sizeof c->key, "%s", key);
    c->next = st->clients;
    st->clients = c;
    st->client_count++;
    return c;
}

/* Drop a client's record once it holds nothing (unlink_entry leaves that to
 * its callers: a creator's record must outlive the eviction of its last). */
static void client_forget(ntsd_sessions* st, ntsd_session_client* c) {
    ntsd_session_client** p = &st->clients;
    if (c == NULL || c->count > 0) return;
    while (*p != NULL && *p != c) p = &(*p)->next;
    if (*p == c) {
        *p = c->next;
        st->client_count--;
        free(c);
    }
}

/* A linked session now holds `memory` bytes. */
static void set_memory(ntsd_sessions* st, ntsd_session_entry* e, size_t memory) {
    st->memory = st->memory - e->memory + memory;
    e->client->memory = e->client->memory - e->memory + memory;
    e->memory = memory;
}

/* Unlink from the hash, the LRU list and its client; the caller holds st->lock. */
static void unlink_entry(ntsd_sessions* st, ntsd_session_entry* e) {
    ntsd_session_entry** p = &st->buckets[hash_id(e->id) & (st->bucket_count - 1)];
    ntsd_session_client* c = e->client;
    while (*p != NULL && *p != e) p = &(*p)->hnext;
    if (*p == e) *p = e->hnext;
    if (e->prev) e->prev->next = e->next; else st->head = e->next;
    if (e->next) e->next->prev = e->prev; else st->tail = e->prev;
    if (e->cprev) e->cprev->cnext = e->cnext; else c->head = e->cnext;
    if (e->cnext) e->cnext->cprev = e->cprev; else c->tail = e->cprev;
    e->prev = e->next = e->hnext = e->cprev = e->cnext = NULL;
    st->count--;
    st->memory -= e->memory;
    c->count--;
    c->memory -= e->memory;
    e->client = NULL;
    e->linked = 0;
}

/* Drop an unlinked entry now, or leave it to its last user. */
static void retire(ntsd_session_entry* e) {
    if (e->users == 0) entry_free(e);
    else e->doomed = 1;
}

/* Drop the idle sessions past their time-to-live (from the LRU tail, where the
 * oldest uses are). The caller holds st->lock. */
static void expire_locked(ntsd_sessions* st, double now) {
    ntsd_session_entry* e = st->tail;
    while (e != NULL) {
        ntsd_session_entry* prev = e->prev;
        if (now - e->last_used <= (double)st->ttl_s) break; /* the rest were used later */
        if (e->users == 0) {
            ntsd_session_client* c = e->client;
            unlink_entry(st, e);
            client_forget(st, c);
            retire(e);
            st->expired++;
        }
        e = prev;
    }
}

/* ------------------------------------------------------------ making room */

/* The least recently used idle session of `c` other than `keep` (with
 * `warm`: one whose buffers were not given back yet), or NULL. From the
 * tail of the client's own list: past its busy and cold ones only. */
static ntsd_session_entry* oldest_idle(const ntsd_session_client* c, const ntsd_session_entry* keep, int warm) {
    ntsd_session_entry* v;
    for (v = c->tail; v != NULL; v = v->cprev)
        if (v->users == 0 && v != keep && !(warm && v->cold)) return v;
    return NULL;
}

/* What a client holds in the measure that is short: sessions or bytes, with
 * what `creator` is adding. */
static double holding(const ntsd_session_client* c, int by_count, const ntsd_session_client* creator, int slots,
                      size_t extra) {
    if (by_count) return (double)c->count + (c == creator ? slots : 0);
    return (double)c->memory + (c == creator ? (double)extra : 0.0);
}

/* The session room is taken from, for `creator` (its new session: `slots`,
 * `extra` bytes; or a step that grew one): the least recently used idle one
 * (other than `keep`; with `warm`, with buffers to give back) of the client
 * holding the most among those that have one, if that client holds the most
 * of all, is over its fair share (the limit over the clients) or is the
 * creator itself; else the creator's own; else none (NULL). Between equal
 * holdings the creator gives first, then the client whose candidate is the
 * least recently used. So a client within its share is never taken from for
 * another client that holds more than it does. */
static ntsd_session_entry* victim(ntsd_sessions* st, ntsd_session_client* creator, const ntsd_session_entry* keep,
                                  int by_count, int slots, size_t extra, int warm) {
    ntsd_session_client *c, *best = NULL;
    double top = 0.0, most = -1.0, share;
    for (c = st->clients; c != NULL; c = c->next) {
        double h = holding(c, by_count, creator, slots, extra);
        if (h > top) top = h;
        c->pick = oldest_idle(c, keep, warm);
        if (c->pick == NULL) continue;
        if (h > most || (h == most && best != creator &&
                         (c == creator || c->pick->last_used < best->pick->last_used))) {
            most = h;
            best = c;
        }
    }
    if (best == NULL) return NULL;
    share = (by_count ? (double)st->max : (double)st->memory_max) / (double)(st->client_count > 0 ? st->client_count : 1);
    if (best == creator || most >= top || most > share) return best->pick;
    return creator != NULL ? creator->pick : NULL;
}

/* Give back an idle session's context buffers: it stays, cold. Safe under
 * st->lock: no request holds it, and none can take it before we let go. */
static void trim_idle(ntsd_sessions* st, ntsd_session_entry* v) {
    ntsj_session_trim(v->session);
    set_memory(st, v, ntsj_session_get_info(v->session).memory_bytes + sizeof *v);
    v->cold = 1;
    st->trimmed++;
}

/* Room for `slots` more sessions and `extra` more bytes, for `creator`,
 * never taking `keep`: buffers given back first when memory is short, then
 * (`evict`) idle sessions evicted, each from the client victim() names.
 * 0 when it fits, -1 otherwise. The caller holds st->lock. */
static int make_room(ntsd_sessions* st, ntsd_session_client* creator, const ntsd_session_entry* keep, int slots,
                     size_t extra, int evict) {
    for (;;) {
        const int by_count = st->count + slots > st->max;
        ntsd_session_client* c;
        ntsd_session_entry* v;
        if (!by_count && st->memory + extra <= st->memory_max) return 0;
        if (!by_count && (v = victim(st, creator, keep, 0, slots, extra, 1)) != NULL) {
            trim_idle(st, v);
            continue;
        }
        if (!evict || (v = victim(st, creator, keep, by_count, slots, extra, 0)) == NULL) return -1;
        c = v->client;
        if (c == creator) st->evicted_own++;
        unlink_entry(st, v);
        if (c != creator) client_forget(st, c); /* the creator's record is about to hold its new one */
        retire(v);
        st->evicted++;
    }
}

/* ------------------------------------------------------------ the calls */

void ntsd_sessions_sweep(ntsd_sessions* st) {
    pthread_mutex_lock(&st->lock);
    expire_locked(st, ntsd_now());
    pthread_mutex_unlock(&st->lock);
}

static ntsd_session_entry* find_locked(ntsd_sessions* st, const char* id) {
    ntsd_session_entry* e = st->buckets[hash_id(id) & (st->bucket_count - 1)];
    while (e != NULL && strcmp(e->id, id) != 0) e = e->hnext;
    return e;
}

/* The session of `id` if `client` owns it: another's is as missing (not
 * even its existence shows). */
static ntsd_session_entry* find_owned(ntsd_sessions* st, const char* id, const char* client) {
    ntsd_session_entry* e = find_locked(st, id);
    return e != NULL && strcmp(e->owner, client) == 0 ? e : NULL;
}

/* A use: first in the store's list and in its client's. */
static void move_to_front(ntsd_sessions* st, ntsd_session_entry* e) {
    ntsd_session_client* c = e->client;
    if (st->head != e) {
        e->prev->next = e->next;
        if (e->next) e->next->prev = e->prev; else st->tail = e->prev;
        e->prev = NULL;
        e->next = st->head;
        st->head->prev = e;
        st->head = e;
    }
    if (c->head != e) {
        e->cprev->cnext = e->cnext;
        if (e->cnext) e->cnext->cprev = e->cprev; else c->tail = e->cprev;
        e->cprev = NULL;
        e->cnext = c->head;
        c->head->cprev = e;
        c->head = e;
    }
}

/* 256 random bits, base64url without padding: 43 characters. */
static int new_id(char out[NTSD_SESSION_ID_LEN + 1]) {
    static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
    unsigned char raw[33];
    size_t got = 0;
    int i, k = 0;
    while (got < 32) {
        ssize_t n = getrandom(raw + got, 32 - got, 0);
        if (n <= 0) return -1;
        got += (size_t)n;
    }
    raw[32] = 0;
    for (i = 0; i < 33; i += 3) {
        unsigned v = ((unsigned)raw[i] << 16) | ((unsigned)raw[i + 1] << 8) | (unsigned)raw[i + 2];
        out[k++] = b64[(v >> 18) & 63];
        out[k++] = b64[(v >> 12) & 63];
        if (k < NTSD_SESSION_ID_LEN) out[k++] = b64[(v >> 6) & 63];
        if (k < NTSD_SESSION_ID_LEN) out[k++] = b64[v & 63];
    }
    out[NTSD_SESSION_ID_LEN] = '\0';
    return 0;
}

int ntsd_sessions_add(ntsd_sessions* st, ntsj_session* session, const char* client, const char* given_id,
                      char id_out[NTSD_SESSION_ID_MAX + 1]) {
    ntsd_session_entry* e;
    ntsd_session_client* c;
    size_t memory = ntsj_session_get_info(session).memory_bytes + sizeof *e;
    double now = ntsd_now();
    unsigned b;
    if (memory > st->memory_max) return NTSD_SESSIONS_TOO_LARGE;
    e = calloc(1, sizeof *e);
    if (e == NULL) return NTSD_SESSIONS_FULL;
    {
        int tries, locked = 0;
        if (given_id != NULL && strlen(given_id) <= NTSD_SESSION_ID_MAX) {
            strcpy(e->id, given_id);
            pthread_mutex_lock(&st->lock);
            if (find_locked(st, e->id) == NULL) locked = 1; /* taken: a new random id below */
            else pthread_mutex_unlock(&st->lock);
        }
        for (tries = 0; tries < 4 && !locked; ++tries) {
            if (new_id(e->id) != 0) break;
            pthread_mutex_lock(&st->lock);
            if (find_locked(st, e->id) == NULL) locked = 1; /* a repeat of 256 random bits: never, but not twice */
            else pthread_mutex_unlock(&st->lock);
        }
        if (!locked) {
            free(e);
            return NTSD_SESSIONS_FULL;
        }
    }
    expire_locked(st, now);
    c = client_get(st, client);
    if (c == NULL) {
        pthread_mutex_unlock(&st->lock);
        free(e);
        return NTSD_SESSIONS_FULL;
    }
    if (c->count >= st->max_per_client) { /* at its quota: its own least recently used idle one goes */
        ntsd_session_entry* v = oldest_idle(c, NULL, 0);
        if (v == NULL) {
            st->refused++;
            pthread_mutex_unlock(&st->lock);
            free(e);
            return NTSD_SESSIONS_QUOTA;
        }
        unlink_entry(st, v); /* c's record stays: it is creating */
        retire(v);
        st->evicted++;
        st->evicted_own++;
    }
    if (make_room(st, c, NULL, 1, memory, 1) != 0) {
        st->refused++;
        client_forget(st, c);
        pthread_mutex_unlock(&st->lock);
        free(e);
        return NTSD_SESSIONS_FULL; /* no session that may fairly go is idle */
    }
    e->session = session;
    {
        ntsj_session_info info = ntsj_session_get_info(session);
        e->bodies = info.bodies;
        e->nodes = info.nodes;
        e->surface_nodes = info.surface_nodes;
    }
    snprintf(e->owner, sizeof e->owner, "%s", client);
    pthread_mutex_init(&e->step_lock, NULL);
    e->created = e->last_used = now;
    e->memory = e->created_memory = memory;
    e->linked = 1;
    e->client = c;
    b = hash_id(e->id) & (st->bucket_count - 1);
    e->hnext = st->buckets[b];
    st->buckets[b] = e;
    e->next = st->head;
    if (st->head) st->head->prev = e; else st->tail = e;
    st->head = e;
    st->count++;
    st->memory += memory;
    e->cnext = c->head;
    if (c->head) c->head->cprev = e; else c->tail = e;
    c->head = e;
    c->count++;
    c->memory += memory;
    st->created++;
    memcpy(id_out, e->id, sizeof e->id);
    pthread_mutex_unlock(&st->lock);
    return 0;
}

ntsd_session_entry* ntsd_sessions_acquire(ntsd_sessions* st, const char* id, const char* client, int use) {
    ntsd_session_entry* e;
    double now = ntsd_now();
    pthread_mutex_lock(&st->lock);
    expire_locked(st, now);
    e = find_owned(st, id, client);
    if (e != NULL) {
        e->users++;
        if (use) {
            e->last_used = now;
            move_to_front(st, e);
        }
    }
    pthread_mutex_unlock(&st->lock);
    return e;
}

size_t ntsd_sessions_step_room(ntsd_sessions* st, const ntsd_session_entry* e) {
    size_t room;
    pthread_mutex_lock(&st->lock);
    room = st->memory_max > e->memory ? st->memory_max - e->memory : 1;
    pthread_mutex_unlock(&st->lock);
    return room;
}

/* What a session may hold after a step and keep, warm for the next: its
 * share of the store (--session-memory over --max-sessions), or 4 times what
 * it held when created, whichever is more. A steady loop stays within (its
 * steps grow nothing after the first; the examples' sessions hold 1.1 to 2.7
 * times their size at creation, stiffness, contacts and gaps asked); a step
 * past both (gaps on a radius that covers the scene: 70 times) gives its
 * buffers back, and the next such step grows them again (issue 23). */
static size_t keep_limit(const ntsd_sessions* st, const ntsd_session_entry* e) {
    size_t share = st->memory_max / (size_t)st->max, grown = 4 * e->created_memory;
    return share > grown ? share : grown;
}

int ntsd_sessions_settle(ntsd_sessions* st, ntsd_session_entry* e, size_t stepped_memory, int stepped, int last) {
    int over = 0;
    pthread_mutex_lock(&st->lock);
    if (e->linked) {
        /* The context's buffers grow with the outputs asked for. */
        set_memory(st, e, stepped_memory + sizeof *e);
        if (stepped) e->steps++;
        e->cold = last; /* given back by the caller before its last call */
        if (last) st->trimmed++;
        if (!last && e->memory > keep_limit(st, e))
            over = 1; /* one large step: its buffers are not kept for the session's life */
        else
            over = make_room(st, e->client, e, 0, 0, last) != 0;
    }
    pthread_mutex_unlock(&st->lock);
    return over && !last;
}

void ntsd_sessions_release(ntsd_sessions* st, ntsd_session_entry* e, int use) {
    pthread_mutex_lock(&st->lock);
    if (use) e->last_used = ntsd_now();
    e->users--;
    if (e->doomed && e->users == 0) {
        pthread_mutex_unlock(&st->lock);
        entry_free(e);
        return;
    }
    pthread_mutex_unlock(&st->lock);
}

int ntsd_sessions_remove(ntsd_sessions* st, const char* id, const char* client) {
    ntsd_session_entry* e;
    pthread_mutex_lock(&st->lock);
    e = find_owned(st, id, client);
    if (e != NULL) {
        ntsd_session_client* c = e->client;
        unlink_entry(st, e);
        client_forget(st, c);
        retire(e);
        st->deleted++;
    }
    pthread_mutex_unlock(&st->lock);
    return e != NULL ? 0 : -1;
}

ntsd_sessions_stats ntsd_sessions_get_stats(ntsd_sessions* st) {
    ntsd_sessions_stats s;
    pthread_mutex_lock(&st->lock);
    expire_locked(st, ntsd_now());
    s.held = st->count;
    s.clients = st->client_count;
    s.memory = st->memory;
    s.created = st->created;
    s.evicted = st->evicted;
    s.expired = st->expired;
    s.deleted = st->deleted;
    s.evicted_own = st->evicted_own;
    s.refused = st->refused;
    s.trimmed = st->trimmed;
    pthread_mutex_unlock(&st->lock);
    return s;
}

int ntsd_sessions_describe(ntsd_sessions* st, const char* id, const char* client, ntsd_session_meta* out) {
    ntsd_session_entry* e;
    double now = ntsd_now();
    pthread_mutex_lock(&st->lock);
    expire_locked(st, now);
    e = find_owned(st, id, client);
    if (e != NULL) {
        out->bodies = e->bodies;
        out->nodes = e->nodes;
        out->surface_nodes = e->surface_nodes;
        out->steps = e->steps;
        out->memory_bytes = e->memory;
        out->idle_s = e->users > 0 ? 0.0 : now - e->last_used;
        out->age_s = now - e->created;
        out->expires_in_s = (double)st->ttl_s - out->idle_s;
        if (out->expires_in_s < 0.0) out->expires_in_s = 0.0;
    }
    pthread_mutex_unlock(&st->lock);
    return e != NULL ? 0 : -1;
}

void ntsd_sessions_free(ntsd_sessions* st) {
    ntsd_session_entry* e = st->head;
    ntsd_session_client* c = st->clients;
    while (e != NULL) {
        ntsd_session_entry* next = e->next;
        entry_free(e); /* the daemon has stopped: no users are left */
        e = next;
    }
    while (c != NULL) {
        ntsd_session_client* next = c->next;
        free(c);
        c = next;
    }
    free(st->buckets);
    pthread_mutex_destroy(&st->lock);
    memset(st, 0, sizeof *st);
}
