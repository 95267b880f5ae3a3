/* The daemon's routes, written once (issue 24 §3). Each row of
 * NTSD_ROUTE_MAP is one path template and everything the daemon does by
 * route; the router (routes.c), the dispatch to the handlers (server.c), the
 * Allow and Access-Control-Allow-Methods headers, the token check, the body a
 * route reads and the metrics' route labels (metrics.c) are all generated
 * from it, so a new route is a row and its handler. tests/python/tables.py
 * reads the rows back and test_tables.py compares them with
 * schemas/openapi.json (written by hand: the independent account) and with
 * what a running daemon answers and counts.
 *
 * XX(id, pattern, methods, param, body, auth, handler, label, evaluates)
 *   id        NTSD_ROUTE_<id>, the route's kind (server.h); the rows' order is
 *             the order of the metrics' series
 *   pattern   the path template, OpenAPI's spelling: a {name} is one path
 *             segment, bound by `param`
 *   methods   what the path answers, as its Allow header lists them (OPTIONS,
 *             the CORS preflight, is added to Allow: server.c answers it for
 *             any route). HEAD goes with GET (libmicrohttpd drops the body)
 *   param     how the {name} segment binds (routes.c, bind_<param>): NONE (no
 *             segment), SESSION (a session id, kept: a malformed one still
 *             routes, and 404s as an unknown scene), SCHEMA (an embedded
 *             schema, else no route: 404), OPENAPI (the fixed path names the
 *             embedded openapi.json)
 *   body      what a request may carry: NONE (any body is refused unread),
 *             JSON (application/json, required), STEP (a session step: JSON,
 *             application/octet-stream float64 positions, or none; its query
 *             carries step options)
 *   auth      TOKEN (with --token-file, a bearer token is needed) or OPEN
 *             (answered without one; the handler may say less)
 *   handler   server.c's answer once the request is complete
 *   label     the metrics' route label. Both asset paths share "/v1/schemas":
 *             the label they had before the table, kept so that dashboards
 *             keep their series
 *   evaluates 1 when a success counts in ntscontactd_evaluations_total and
 *             its nodes and contacts (a scene or a step evaluated) */
#ifndef NTSD_ROUTES_H
#define NTSD_ROUTES_H

/* clang-format off */
#define NTSD_ROUTE_MAP(XX)                                                                                            \
    XX(CONTACT,       "/v1/contact",             "POST",              NONE,    JSON, TOKEN, answer_contact,  "/v1/contact",             1) \
    XX(VALIDATE,      "/v1/validate",            "POST",              NONE,    JSON, TOKEN, answer_validate, "/v1/validate",            0) \
    XX(HEALTH,        "/v1/health",              "GET, HEAD",         NONE,    NONE, OPEN,  answer_health,   "/v1/health",              0) \
    XX(OPENAPI,       "/v1/openapi.json",        "GET, HEAD",         OPENAPI, NONE, TOKEN, answer_asset,    "/v1/schemas",             0) \
    XX(SCHEMA,        "/v1/schemas/{name}",      "GET, HEAD",         SCHEMA,  NONE, TOKEN, answer_asset,    "/v1/schemas",             0) \
    XX(SCENES,        "/v1/scenes",              "POST",              NONE,    JSON, TOKEN, answer_create,   "/v1/scenes",              0) \
    XX(SCENE,         "/v1/scenes/{id}",         "GET, HEAD, DELETE", SESSION, NONE, TOKEN, answer_scene,    "/v1/scenes/{id}",         0) \
    XX(SCENE_CONTACT, "/v1/scenes/{id}/contact", "POST",              SESSION, STEP, TOKEN, answer_step,     "/v1/scenes/{id}/contact", 1) \
    XX(SCENE_SURFACE, "/v1/scenes/{id}/surface", "GET, HEAD",         SESSION, NONE, TOKEN, answer_surface,  "/v1/scenes/{id}/surface", 0) \
    XX(METRICS,       "/metrics",                "GET, HEAD",         NONE,    NONE, TOKEN, answer_metrics,  "/metrics",                0)
/* clang-format on */

/* What a route's request may carry (the `body` column). */
typedef enum ntsd_body_kind { NTSD_BODY_NONE = 0, NTSD_BODY_JSON, NTSD_BODY_STEP } ntsd_body_kind;

/* Whether a route needs the bearer token (the `auth` column). */
typedef enum ntsd_auth_kind { NTSD_AUTH_TOKEN = 0, NTSD_AUTH_OPEN } ntsd_auth_kind;

#endif
