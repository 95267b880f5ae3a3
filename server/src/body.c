/* A request body accumulated with a cap (libmicrohttpd's largepost.c pattern):
 * the buffer grows geometrically but never beyond `max` + 1 bytes (the NUL). */
#include <stdlib.h>
#include <string.h>

#include "server.h"

void ntsd_body_init(ntsd_body* b, size_t max) {
    b->data = NULL;
    b->length = 0;
    b->capacity = 0;
    b->max = max;
}

static int grow(ntsd_body* b, size_t need) {
    size_t cap = b->capacity ? b->capacity : 4096;
    char* p;
    while (cap < need) cap = cap > b->max / 2 ? b->max : cap * 2;
    if (cap < need) cap = need;
    p = realloc(b->data, cap + 1);
    if (p == NULL) return -1;
    b->data = p;
    b->capacity = cap;
    return 0;
}

int ntsd_body_reserve(ntsd_body* b, size_t expected) {
    if (expected > b->max) return 1;
    if (expected <= b->capacity) return 0;
    return grow(b, expected);
}

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
