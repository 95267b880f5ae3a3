/* A request body accumulated with a cap (libmicrohttpd's largepost.c pattern):
 * the buffer grows geometrically as bytes arrive, never beyond `max` + 1 bytes
 * (the NUL), nor beyond an announced length: it holds what was received (the
 * memory budget counts it, server.c), not what was promised. */
#include <stdlib.h>
#include <string.h>

#include "server.h"

void ntsd_body_init(ntsd_body* b, size_t max) {
    b->data = NULL;
    b->length = 0;
    b->capacity = 0;
    b->expected = 0;
    b->max = max;
}

static int grow(ntsd_body* b, size_t need) {
    size_t cap = b->capacity ? b->capacity : 4096;
    char* p;
    const size_t top = b->expected >= need && b->expected < b->max ? b->expected : b->max;
    while (cap < need) cap = cap > top / 2 ? top : cap * 2;
    if (cap < need) cap = need;
    p = realloc(b->data, cap + 1);
    if (p == NULL) return -1;
    b->data = p;
    b->capacity = cap;
    return 0;
}

void ntsd_body_expect(ntsd_body* b, size_t expected) { b->expected = expected; }

int ntsd_body_append(ntsd_body* b, const char* data, size_t size) {
    if (size > b->max - b->length) return 1;
    if (b->length + size > b->capacity && grow(b, b->length + size) != 0) return -1;
    memcpy(b->data + b->length, data, size);
    b->length += size;
    b->data[b->length] = '\0';
    return 0;
}

void ntsd_body_free(ntsd_body* b) {
    free(b->data);
    ntsd_body_init(b, b->max);
}
