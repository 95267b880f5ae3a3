/* Status and warning names, messages, the allocator hook (base.h) and the
 * wall clock. */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#include <ntscontact/ntscontact.h>

#include "internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const char* nts_status_name(int status) {
    switch (status) {
    case NTS_OK: return "ok";
#define NTS_XX_(e, v, name, msg) case NTS_E##e: return name;
        NTS_ERRNO_MAP(NTS_XX_)
#undef NTS_XX_
    default: return "unknown_error";
    }
}

const char* nts_strerror(int status) {
    switch (status) {
    case NTS_OK: return "success";
#define NTS_XX_(e, v, name, msg) case NTS_E##e: return msg;
        NTS_ERRNO_MAP(NTS_XX_)
#undef NTS_XX_
    default: return "unknown error";
    }
}

const char* nts_warning_name(int code) {
    switch (code) {
#define NTS_XX_(e, v, name, msg) case NTS_WARN_##e: return name;
        NTS_WARNING_MAP(NTS_XX_)
#undef NTS_XX_
    default: return "unknown_warning";
    }
}

const char* nts_warning_message(int code) {
    switch (code) {
#define NTS_XX_(e, v, name, msg) case NTS_WARN_##e: return msg;
        NTS_WARNING_MAP(NTS_XX_)
#undef NTS_XX_
    default: return "unknown warning";
    }
}

int nts_error_set(nts_error* err, int code, nts_where at, const char* fmt, ...) {
    if (err != NULL) {
        va_list ap;
        *err = nts_error_none();
        err->code = code;
        err->body = at.body;
        err->loop = at.loop;
        err->loop_pos = at.loop_pos;
        err->node = at.node;
        err->triangle = at.triangle;
        err->corner = at.corner;
        err->item = at.item;
        snprintf(err->option, sizeof err->option, "%s", at.option ? at.option : "");
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}

nts_error nts_error_none(void) {
    nts_error e;
    memset(&e, 0, sizeof e);
    e.body = e.loop = e.loop_pos = e.node = e.triangle = e.corner = e.item = -1;
    return e;
}

static void* default_alloc(size_t size, void* user) {
    (void)user;
    return malloc(size);
}
static void default_free(void* ptr, void* user) {
    (void)user;
    free(ptr);
}

static nts_alloc_fn* g_alloc = default_alloc;
static nts_free_fn* g_free = default_free;
static void* g_user = NULL;

void nts_set_allocator(nts_alloc_fn* alloc_fn, nts_free_fn* free_fn, void* user) {
    if (alloc_fn == NULL || free_fn == NULL) {
        g_alloc = default_alloc;
        g_free = default_free;
        g_user = NULL;
        return;
    }
    g_alloc = alloc_fn;
    g_free = free_fn;
    g_user = user;
}

void* nts_alloc(size_t size) {
    /* Zero-size requests still return a distinct pointer, so callers can tell
     * failure (NULL) from an empty array. */
    return g_alloc(size == 0 ? 1 : size, g_user);
}

void nts_free(void* ptr) {
    if (ptr != NULL) g_free(ptr, g_user);
}

double nts_wall_seconds(void) {
#if defined(CLOCK_MONOTONIC)
    struct timespec ts;
    if (clock_gettime(CLOCK_MONOTONIC, &ts) == 0) return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
#endif
    return (double)time(NULL); /* no monotonic clock: whole seconds, still wall clock */
}

/* An array grown to hold `need` items of `size` bytes (doubling, from 16):
 * the allocator hook's one growth rule for the core's working arrays. */
int nts_grow(void** ptr, int* cap, int need, size_t size) {
    void* p;
    int ncap;
    if (need <= *cap) return NTS_OK;
    ncap = *cap > 0 ? *cap : 16;
    while (ncap < need) ncap = (ncap > (1 << 29)) ? need : 2 * ncap;
    p = nts_alloc((size_t)ncap * size);
    if (p == NULL) return NTS_ENOMEM;
    if (*ptr != NULL && *cap > 0) memcpy(p, *ptr, (size_t)(*cap) * size);
    nts_free(*ptr);
    *ptr = p;
    *cap = ncap;
    return NTS_OK;
}
