/* The URL space of ntscontactd: which path answers which methods, and the
 * media types. It knows nothing of the server's state. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "assets.h"
#include "server.h"

/* The methods of each kind of path, and its Allow header: those and OPTIONS
 * (a CORS preflight, answered for an Origin of --allow-origin). */
#define METHODS_POST "POST"
#define METHODS_GET "GET, HEAD"
#define METHODS_SCENE "GET, HEAD, DELETE"
#define WITH_OPTIONS ", OPTIONS"

static int method_in(const char* method, const char* methods) {
    if (strcmp(methods, METHODS_POST) == 0) return strcmp(method, "POST") == 0;
    if (strcmp(method, "DELETE") == 0) return strcmp(methods, METHODS_SCENE) == 0;
    return strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
}

static void set_methods(ntsd_route* r, const char* methods, const char* allow) {
    r->methods = methods;
    r->allow = allow;
}
#define ROUTE_POST(r) set_methods(&(r), METHODS_POST, METHODS_POST WITH_OPTIONS)
#define ROUTE_GET(r) set_methods(&(r), METHODS_GET, METHODS_GET WITH_OPTIONS)
#define ROUTE_SCENE(r) set_methods(&(r), METHODS_SCENE, METHODS_SCENE WITH_OPTIONS)

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

ntsd_route ntsd_route_find(const char* path, const char* method) {
    static const char schemas[] = "/v1/schemas/";
    ntsd_route r;
    r.kind = NTSD_ROUTE_NONE;
    r.allow = r.methods = "";
    r.method_ok = 0;
    r.asset = -1;
    r.scene_id[0] = '\0';
    if (strcmp(path, "/v1/contact") == 0) {
        r.kind = NTSD_ROUTE_CONTACT;
        ROUTE_POST(r);
    } else if (strcmp(path, "/v1/validate") == 0) {
        r.kind = NTSD_ROUTE_VALIDATE;
        ROUTE_POST(r);
    } else if (strcmp(path, "/v1/scenes") == 0) {
        r.kind = NTSD_ROUTE_SCENES;
        ROUTE_POST(r);
    } else if (strncmp(path, "/v1/scenes/", 11) == 0 && path[11] != '\0') {
        static const char tail[] = "/contact";
        const char* id = path + 11;
        size_t n = strcspn(id, "/");
        if (id[n] == '\0') {
            r.kind = NTSD_ROUTE_SCENE;
            ROUTE_SCENE(r);
            take_scene_id(id, n, &r);
        } else if (strcmp(id + n, tail) == 0) {
            r.kind = NTSD_ROUTE_SCENE_CONTACT;
            ROUTE_POST(r);
            take_scene_id(id, n, &r);
        }
    } else if (strcmp(path, "/metrics") == 0) {
        r.kind = NTSD_ROUTE_METRICS;
        ROUTE_GET(r);
    } else if (strcmp(path, "/v1/health") == 0) {
        r.kind = NTSD_ROUTE_HEALTH;
        ROUTE_GET(r);
    } else if (strcmp(path, "/v1/openapi.json") == 0) {
        r.kind = NTSD_ROUTE_ASSET;
        ROUTE_GET(r);
        r.asset = find_asset("openapi");
    } else if (strncmp(path, schemas, sizeof schemas - 1) == 0) {
        const char* name = path + sizeof schemas - 1;
        if (strcmp(name, "openapi") != 0 && (r.asset = find_asset(name)) >= 0) {
            r.kind = NTSD_ROUTE_ASSET;
            ROUTE_GET(r);
        }
    }
    if (r.kind != NTSD_ROUTE_NONE) r.method_ok = method_in(method, r.methods);
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

