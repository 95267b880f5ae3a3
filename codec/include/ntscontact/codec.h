/* ntscontact codec: the JSON contract (schemas/*.schema.json) over the core.
 * One call takes a request body and gives a response body, so the CLI and the
 * server answer alike, byte for byte (elapsed_ms aside).
 *
 * Ownership: ntsj_response.body is allocated by the codec (through nts_alloc)
 * and released with ntsj_response_free. Thread-safe: no globals, no setlocale. */
#ifndef NTSCONTACT_CODEC_H
#define NTSCONTACT_CODEC_H

#include <stddef.h>

#include "ntscontact.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum ntsj_mode {
    NTSJ_EVALUATE = 0, /* POST /v1/contact, `ntscontact SCENE` */
    NTSJ_VALIDATE = 1  /* POST /v1/validate, `ntscontact --validate SCENE` */
} ntsj_mode;

/* Options that override the scene's own (CLI flags). `has_*` says which are set. */
typedef struct ntsj_overrides {
    int has_alpha, has_penalty, has_search_radius, has_solver, has_outputs;
    double alpha, penalty, search_radius;
    nts_solver solver;
    unsigned outputs; /* NTS_OUT_* */
} ntsj_overrides;

typedef struct ntsj_config {
    ntsj_mode mode;
    int pretty;             /* indent the output */
    ntsj_overrides overrides;
    nts_limits limits;      /* bodies, nodes per body, nodes per scene */
    int max_depth;          /* JSON nesting; default 32 */
    size_t max_bytes;       /* request size; default 64 MiB */
    double max_seconds;     /* wall-clock budget of one evaluation, 0 = none */
    int threads;            /* passed to nts_options.threads */
} ntsj_config;
ntsj_config ntsj_default_config(void);

typedef struct ntsj_response {
    int ok;           /* 1 when body is a result (or a validation report) */
    int http_status;  /* 200, or the 4xx/5xx this error maps to */
    const char* code; /* stable error code ("invalid_json", "degenerate_segment", ...), "ok" on success */
    char* body;       /* NUL-terminated JSON (result or error document), ends with '\n' */
    size_t length;    /* strlen(body) */
} ntsj_response;

/* Decode, validate, evaluate and encode. Never crashes on any input bytes;
 * returns 0 (the response is filled either way, with an error document when
 * !ok) or NTS_ENOMEM when even the error document could not be built. */
int ntsj_handle(const char* json, size_t length, const ntsj_config* config, ntsj_response* out);
void ntsj_response_free(ntsj_response* response);

/* An error document {"error": {"code", "message", "pointer"}} for front ends
 * (the server's 404/405/413/415/503). Returned buffer is freed with nts_free. */
char* ntsj_error_document(const char* code, const char* message, const char* pointer);

#ifdef __cplusplus
}
#endif
#endif
