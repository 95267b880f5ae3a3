/* The session store: scene sessions by id, bounded in count, idle time and
 * memory. A hash of ids for lookups and a least-recently-used list for
 * eviction, under one lock held only for bookkeeping, never during an
 * evaluation. A session in use (a request holds it) is never evicted or freed:
 * deleting it only unlinks it, and its last user frees it. Steps on one
 * session are serialised by its own lock. */
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

int ntsd_sessions_init(ntsd_sessions* st, int max, unsigned ttl_s, size_t memory_max) {
    unsigned n = 16;
    memset(st, 0, sizeof *st);
    while (n < 2u * (unsigned)max && n < (1u << 22)) n *= 2;
    st->buckets = calloc(n, sizeof *st->buckets);
    if (st->buckets == NULL) return -1;
    st->bucket_count = n;
    st->max = max;
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

/* Unlink from the hash and the LRU list; the caller holds st->lock. */
static void unlink_entry(ntsd_sessions* st, ntsd_session_entry* e) {
    ntsd_session_entry** p = &st->buckets[hash_id(e->id) & (st->bucket_count - 1)];
    while (*p != NULL && *p != e) p = &(*p)->hnext;
    if (*p == e) *p = e->hnext;
    if (e->prev) e->prev->next = e->next; else st->head = e->next;
    if (e->next) e->next->prev = e->prev; else st->tail = e->prev;
    e->prev = e->next = e->hnext = NULL;
    st->count--;
    st->memory -= e->memory;
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
            unlink_entry(st, e);
            retire(e);
            st->expired++;
        }
        e = prev;
    }
}

/* Evict idle sessions other than `keep`, least recently used first, until
 * `slots` more sessions and `extra` more bytes fit. The caller holds st->lock. */
static void evict_locked(ntsd_sessions* st, const ntsd_session_entry* keep, int slots, size_t extra) {
    ntsd_session_entry* v = st->tail;
    while (v != NULL && (st->count + slots > st->max || st->memory + extra > st->memory_max)) {
        ntsd_session_entry* prev = v->prev;
        if (v->users == 0 && v != keep) {
            unlink_entry(st, v);
            retire(v);
            st->evicted++;
        }
        v = prev;
    }
}

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

static void move_to_front(ntsd_sessions* st, ntsd_session_entry* e) {
    if (st->head == e) return;
    e->prev->next = e->next;
    if (e->next) e->next->prev = e->prev; else st->tail = e->prev;
    e->prev = NULL;
    e->next = st->head;
    st->head->prev = e;
    st->head = e;
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

int ntsd_sessions_add(ntsd_sessions* st, ntsj_session* session, const char* given_id,
                      char id_out[NTSD_SESSION_ID_MAX + 1]) {
    ntsd_session_entry* e;
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
    evict_locked(st, NULL, 1, memory); /* make room: the least recently used idle ones first */
    if (st->count >= st->max || st->memory + memory > st->memory_max) {
        pthread_mutex_unlock(&st->lock);
        free(e);
        return NTSD_SESSIONS_FULL; /* every session is in use */
    }
    e->session = session;
    {
        ntsj_session_info info = ntsj_session_get_info(session);
        e->bodies = info.bodies;
        e->nodes = info.nodes;
        e->surface_nodes = info.surface_nodes;
    }
    pthread_mutex_init(&e->step_lock, NULL);
    e->created = e->last_used = now;
    e->memory = memory;
    e->linked = 1;
    b = hash_id(e->id) & (st->bucket_count - 1);
    e->hnext = st->buckets[b];
    st->buckets[b] = e;
    e->next = st->head;
    if (st->head) st->head->prev = e; else st->tail = e;
    st->head = e;
    st->count++;
    st->memory += memory;
    st->created++;
    memcpy(id_out, e->id, sizeof e->id);
    pthread_mutex_unlock(&st->lock);
    return 0;
}

ntsd_session_entry* ntsd_sessions_acquire(ntsd_sessions* st, const char* id) {
    ntsd_session_entry* e;
    double now = ntsd_now();
    pthread_mutex_lock(&st->lock);
    expire_locked(st, now);
    e = find_locked(st, id);
    if (e != NULL) {
        e->users++;
        e->last_used = now;
        move_to_front(st, e);
    }
    pthread_mutex_unlock(&st->lock);
    return e;
}

void ntsd_sessions_release(ntsd_sessions* st, ntsd_session_entry* e, size_t stepped_memory) {
    pthread_mutex_lock(&st->lock);
    if (stepped_memory > 0 && e->linked) {
        /* The context's buffers grow with the outputs asked for. */
        size_t memory = stepped_memory + sizeof *e;
        st->memory = st->memory - e->memory + memory;
        e->memory = memory;
        e->steps++;
        evict_locked(st, e, 0, 0); /* grown past the budget: the least recently used idle ones go */
    }
    e->last_used = ntsd_now();
    e->users--;
    if (e->doomed && e->users == 0) {
        pthread_mutex_unlock(&st->lock);
        entry_free(e);
        return;
    }
    pthread_mutex_unlock(&st->lock);
}

int ntsd_sessions_remove(ntsd_sessions* st, const char* id) {
    ntsd_session_entry* e;
    pthread_mutex_lock(&st->lock);
    e = find_locked(st, id);
    if (e != NULL) {
        unlink_entry(st, e);
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
    s.memory = st->memory;
    s.created = st->created;
    s.evicted = st->evicted;
    s.expired = st->expired;
    s.deleted = st->deleted;
    pthread_mutex_unlock(&st->lock);
    return s;
}

int ntsd_sessions_describe(ntsd_sessions* st, const char* id, ntsd_session_meta* out) {
    ntsd_session_entry* e;
    double now = ntsd_now();
    pthread_mutex_lock(&st->lock);
    expire_locked(st, now);
    e = find_locked(st, id);
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
    while (e != NULL) {
        ntsd_session_entry* next = e->next;
        entry_free(e); /* the daemon has stopped: no users are left */
        e = next;
    }
    free(st->buckets);
    pthread_mutex_destroy(&st->lock);
    memset(st, 0, sizeof *st);
}
