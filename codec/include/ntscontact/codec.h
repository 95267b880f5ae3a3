/* ntscontact codec: the JSON contract (schemas/{scene,result,error}.schema.json) over the core.
 * One call takes a request body and gives a response body, so the CLI and the
 * server answer alike, byte for byte (elapsed_ms aside).
 *
 * Ownership: ntsj_response.body is allocated by the codec (through nts_alloc)
 * and released with ntsj_response_free. Thread-safe: no globals, no setlocale. */
#ifndef NTSCONTACT_CODEC_H
#define NTSCONTACT_CODEC_H

#include <stddef.h>

#include <ntscontact/ntscontact.h>

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
    double max_seconds;     /* wall-clock budget of one request, 0 = none: checked after decoding,
                             * building the scene and evaluating; over it -> limit_exceeded (400) */
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

/* The HTTP status of a stable code (schemas/error.schema.json): 200 for "ok",
 * 400 for input faults, 404/405/413/415/503 for the front ends' own codes, 500
 * for internal ones and for a name it does not know. */
int ntsj_code_http_status(const char* code);

/* Read the pointer and message back from an error document (the body of a
 * response with !ok), for one-line diagnostics. Copies NUL-terminated,
 * truncated strings; returns 0, or -1 when `body` is not an error document. */
int ntsj_error_fields(const char* body, size_t length, char* pointer, size_t pointer_size, char* message,
                      size_t message_size);

/* Names shared by the JSON options and the CLI flags. `ntsj_output_flag` maps
 * "forces", "energy", "virial", "contacts", "gaps" (n bytes of name) to its
 * NTS_OUT_* flag, 0 if unknown; `ntsj_solver_from_name` maps "closed_form" and
 * "newton", returning 0 or -1. */
unsigned ntsj_output_flag(const char* name, size_t n);
int ntsj_solver_from_name(const char* name, nts_solver* out);
const char* ntsj_solver_name(nts_solver solver);

#ifdef __cplusplus
}
#endif
#endif
