/* The URL space of ntscontactd: which path answers which methods, and the
 * media types. It knows nothing of the server's state. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "assets.h"
#include "server.h"

/* The routes' matching and headers come from NTSD_ROUTE_MAP (routes.h): a
 * row's methods are its Allow header with OPTIONS (a CORS preflight, answered
 * for an Origin of --allow-origin) added. */
#define WITH_OPTIONS ", OPTIONS"

/* One row of the table as the router uses it. */
typedef struct route_row {
    const char* pattern;
    const char* methods;
    const char* allow;
    int (*bind)(const char* segment, size_t n, ntsd_route* r);
    ntsd_body_kind body;
    ntsd_auth_kind auth;
    int evaluates;
} route_row;

/* `method` is one of the comma-separated `methods` ("GET, HEAD"). */
static int method_in(const char* method, const char* methods) {
    size_t m = strlen(method);
    const char* p = methods;
    while (*p != '\0') {
        size_t n = strcspn(p, ",");
        if (n == m && strncmp(p, method, m) == 0) return 1;
        p += n;
        while (*p == ',' || *p == ' ') p++;
    }
    return 0;
}

/* The {id} of /v1/scenes/{id}[/contact]: 32 to 64 URL-safe characters (the
 * store's own ids, or a proxy's); anything else names no session. */
int ntsd_is_session_id(const char* id, size_t n) {
    size_t i;
    if (n < NTSD_SESSION_ID_MIN || n > NTSD_SESSION_ID_MAX) return 0;
    for (i = 0; i < n; ++i) {
        char c = id[i];
        if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_'))
            return 0;
    }
    return 1;
}

static void take_scene_id(const char* id, size_t n, ntsd_route* r) {
    r->scene_id[0] = '\0';
    if (!ntsd_is_session_id(id, n)) return;
    memcpy(r->scene_id, id, n);
    r->scene_id[n] = '\0';
}

static int find_asset(const char* name) {
    int i;
    for (i = 0; i < ntsd_asset_count; i++)
        if (strcmp(ntsd_assets[i].name, name) == 0) return i;
    return -1;
}

/* The binders of a route's {name} segment (the `param` column): 0 when the
 * segment names nothing this route serves (then no route: 404). */
static int bind_NONE(const char* segment, size_t n, ntsd_route* r) {
    (void)segment, (void)n, (void)r;
    return 1;
}

/* A session id binds even when malformed (scene_id stays ""): the path is a
 * scene's, its methods apply (405), and an unknown scene answers 404. */
static int bind_SESSION(const char* segment, size_t n, ntsd_route* r) {
    take_scene_id(segment, n, r);
    return 1;
}

/* One of the embedded schemas; openapi is served at /v1/openapi.json only. */
static int bind_SCHEMA(const char* segment, size_t n, ntsd_route* r) {
    char name[64];
    if (n == 0 || n >= sizeof name) return 0;
    memcpy(name, segment, n);
    name[n] = '\0';
    if (strcmp(name, "openapi") == 0) return 0;
    return (r->asset = find_asset(name)) >= 0;
}

static int bind_OPENAPI(const char* segment, size_t n, ntsd_route* r) {
    (void)segment, (void)n;
    r->asset = find_asset("openapi");
    return 1;
}

#define ROUTE_ROW_(id, pattern, methods, param, body, auth, handler, label, evaluates) \
    {pattern, methods, methods WITH_OPTIONS, bind_##param, NTSD_BODY_##body, NTSD_AUTH_##auth, evaluates},
static const route_row rows[NTSD_ROUTE_KINDS] = {{"", "", "", bind_NONE, NTSD_BODY_NONE, NTSD_AUTH_TOKEN, 0},
                                                 NTSD_ROUTE_MAP(ROUTE_ROW_)};
#undef ROUTE_ROW_

/* `path` against a template: literal text alike, and a {name} taking one
 * segment (the text up to the next '/'), which may be empty only when more of
 * the path follows ("/v1/scenes//contact" is a scene's step with a malformed
 * id; "/v1/scenes/" is no scene: a trailing slash). On a match, *segment and
 * *n are the {name}'s text (n = 0 and segment NULL without one). */
static int match(const char* pattern, const char* path, const char** segment, size_t* n) {
    *segment = NULL;
    *n = 0;
    while (*pattern != '\0') {
        if (*pattern == '{') {
            size_t k = strcspn(path, "/");
            if (k == 0 && *path == '\0') return 0;
            *segment = path;
            *n = k;
            path += k;
            pattern = strchr(pattern, '}');
            if (pattern == NULL) return 0;
            pattern++;
        } else if (*pattern++ != *path++) {
            return 0;
        }
    }
    return *path == '\0';
}

ntsd_route ntsd_route_find(const char* path, const char* method) {
    ntsd_route r;
    int k;
    memset(&r, 0, sizeof r);
    r.kind = NTSD_ROUTE_NONE;
    r.allow = r.methods = "";
    r.body = NTSD_BODY_NONE;
    r.auth = NTSD_AUTH_TOKEN;
    r.asset = -1;
    for (k = 1; k < NTSD_ROUTE_KINDS; ++k) {
        const char* segment;
        size_t n;
        if (!match(rows[k].pattern, path, &segment, &n)) continue;
        if (!rows[k].bind(segment, n, &r)) {
            r.asset = -1;
            continue;
        }
        r.kind = (ntsd_route_kind)k;
        r.methods = rows[k].methods;
        r.allow = rows[k].allow;
        r.body = rows[k].body;
        r.auth = rows[k].auth;
        r.evaluates = rows[k].evaluates;
        r.method_ok = method_in(method, r.methods);
        break;
    }
    return r;
}

int ntsd_is_json_media_type(const char* ct) {
    size_t n;
    if (ct == NULL) return 0; /* no Content-Type is not JSON (a browser form post has none to match) */
    while (*ct == ' ' || *ct == '\t') ct++;
    n = strcspn(ct, "; \t");
    if (n == 16 && strncasecmp(ct, "application/json", 16) == 0) return 1;
    /* Structured syntax suffix (RFC 6839): application/vnd.x+json */
    if (n > 17 && strncasecmp(ct, "application/", 12) == 0 && strncasecmp(ct + n - 5, "+json", 5) == 0)
        return 1;
    return 0;
}

int ntsd_is_media_type(const char* ct, const char* type) {
    size_t n, m = strlen(type);
    if (ct == NULL) return 0;
    while (*ct == ' ' || *ct == '\t') ct++;
    n = strcspn(ct, "; \t");
    return n == m && strncasecmp(ct, type, m) == 0;
}

