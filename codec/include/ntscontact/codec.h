/** @file
 * ntscontact codec: the JSON contract (schemas/{scene,result,error}.schema.json) over the core.
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

/** What ntsj_handle does with a request. */
typedef enum ntsj_mode {
    NTSJ_EVALUATE = 0, /**< POST /v1/contact, `ntscontact SCENE` */
    NTSJ_VALIDATE = 1  /**< POST /v1/validate, `ntscontact --validate SCENE` */
} ntsj_mode;

/** Options that override the scene's own (CLI flags): a value and `has_<name>`
 * for every option of NTS_OPTION_MAP that the CLI sets (doors ALL), as
 * has_alpha and alpha, has_outputs and outputs (NTS_OUT_*). */
typedef struct ntsj_overrides {
#define NTSJ_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    NTS_OPT_IS_##doors(int has_##field; ctype field;)
    NTS_OPTION_MAP(NTSJ_XX_)
#undef NTSJ_XX_
} ntsj_overrides;
/** Set an override from a parsed value (nts_option_value): 0, or -1 when the
 * option is not one the CLI sets. `ntsj_override_given` says whether it is set. */
NTS_API int ntsj_override_set(ntsj_overrides* overrides, int option_id, const nts_option_value* value);
/** 1 when option `option_id` is overridden, 0 when not (or not one the CLI sets). */
NTS_API int ntsj_override_given(const ntsj_overrides* overrides, int option_id);

/** The deepest nesting a request may be allowed (ntsj_config.max_depth):
 * the pre-scan keeps a path of that many levels on its stack. The CLI's and
 * the daemon's --max-depth refuse more. */
#define NTSJ_MAX_DEPTH_LIMIT 512

/** How the codec handles a request (start from ntsj_default_config). */
typedef struct ntsj_config {
    ntsj_mode mode;         /**< evaluate or validate */
    int pretty;             /**< indent the output */
    ntsj_overrides overrides; /**< options that override the scene's own */
    nts_limits limits;      /**< bodies, nodes per body, nodes per scene */
    int max_depth;          /**< JSON nesting; default 32, at most NTSJ_MAX_DEPTH_LIMIT (more is taken as that) */
    size_t max_bytes;       /**< request size; default 64 MiB */
    double max_seconds;     /**< wall-clock budget of one request, 0 = none: checked after decoding,
                             * building the scene and evaluating; over it -> limit_exceeded (400) */
    int threads;            /**< passed to nts_options.threads */
    long long max_candidates; /**< passed to nts_options.max_candidates (0: the core's default) */
    /** A front end's own reason to stop, asked with the deadline while the core
     * evaluates (every 1024 slave nodes): non-zero ends the evaluation with
     * "cancelled" (503). The daemon stops the work of a client that left. */
    int (*cancel)(void* user);
    void* cancel_user;      /**< the argument `cancel` is called with */
    int vtk;                /**< also write the result as a VTK XML unstructured grid (ntsj_response.vtk):
                             * surfaces, forces, contacts with their gaps and normals (codec/src/vtk.c) */
    /** Sessions (ntsj_session_step): the most bytes one step may add to what
     * its session holds, its answer included; 0: no bound. A step that keeps
     * records (contacts, gaps, the tangent) gets a candidate budget that fits
     * (NTSJ_STEP_BYTES_PER_CANDIDATE each), its context's growth and its
     * answer are checked against what is left, and a step that would need
     * more is limit_exceeded (400) naming `step_memory_name` (the daemon: the
     * room --session-memory leaves the session, and that flag). */
    size_t step_memory;
    const char* step_memory_name; /**< what a step's limit_exceeded names (NULL: "step_memory") */
    /** Friction's history from outside the request (the CLI's --history-in,
     * docs/model.md §14): a JSON document, a previous result or a
     * `history_out` document, whose "history" the request goes on from
     * instead of its own; NULL: none. Its faults point into it (/history/K). */
    const char* history;
    size_t history_length;  /**< the bytes of `history` */
    /** Also give the history after the evaluation (a session's: the committed
     * one after the step) as {"history": [...]} in ntsj_response.history:
     * the CLI's --history-out. */
    int history_out;
    /** A front end's own evaluation instead of nts_evaluate, given the
     * request's scene definition as decoded (in a session: at the stored
     * positions, each body's reference its first ones), for ntsj_handle and
     * sessions alike (ntscontact-mpi: the distributed one,
     * mpi/src/cli_hook.c); NULL: nts_evaluate. It returns
     * what nts_evaluate would, and its result stays valid until the
     * response is encoded. */
    int (*evaluate)(void* user, const nts_scene_def* def, const nts_scene* scene, const nts_options* opt,
                    nts_result* out, nts_error* err);
    void* evaluate_user; /**< the argument `evaluate` is called with */
} ntsj_config;
/** Evaluate, compact output, no overrides, nts_default_limits(), nesting 32,
 * requests up to 64 MiB, no time or step-memory bound, serial. */
NTS_API ntsj_config ntsj_default_config(void);

/** The answer to a request, filled by ntsj_handle and ntsj_session_step;
 * release its buffers with ntsj_response_free. */
typedef struct ntsj_response {
    int ok;           /**< 1 when body is a result (or a validation report) */
    int http_status;  /**< 200, or the 4xx/5xx this error maps to */
    const char* code; /**< stable error code ("invalid_json", "degenerate_segment", ...), "ok" on success */
    char* body;       /**< NUL-terminated JSON (result or error document), ends with '\n';
                       * for a binary session answer (binary == 1): the raw forces */
    size_t length;    /**< strlen(body), or the bytes of a binary answer */
    int binary;       /**< ok and body holds 16 N bytes: little-endian float64 forces, x then y per node */
    nts_summary summary; /**< of a successful evaluation (for a binary answer's headers, a front end's counters) */
    int friction;        /**< friction was on (nts_friction_on): the summary's dissipation, sticking, slipping
                          * and the virial's yx are the answer's (NTS-Dissipation, ... headers) */
    nts_warning warnings[NTS_WARN_COUNT_]; /**< what the evaluation may have left out (nts_result.warnings) */
    int warning_count;   /**< how many `warnings` */
    double elapsed_ms;   /**< of the request, rounded to whole microseconds */
    int triplets;        /**< a binary answer with outputs stiffness: the triplets after the forces
                          * (int32 rows, int32 cols, float64 values, little-endian), else 0 */
    char* vtk;           /**< with ntsj_config.vtk, on success: the .vtu document (NUL-terminated) */
    size_t vtk_length;   /**< the bytes of `vtk` */
    char* history;       /**< with ntsj_config.history_out, on success and friction on: {"history": [...]} */
    size_t history_length; /**< the bytes of `history` */
} ntsj_response;

/** Decode, validate, evaluate and encode. Never crashes on any input bytes;
 * returns 0 (the response is filled either way, with an error document when
 * !ok) or NTS_ENOMEM when even the error document could not be built. */
NTS_API int ntsj_handle(const char* json, size_t length, const ntsj_config* config, ntsj_response* out);
/** Frees the response's body, vtk and history (nts_free) and zeroes those
 * fields, so that a second call is harmless; NULL is a no-op. */
NTS_API void ntsj_response_free(ntsj_response* response);
/** @fn size_t ntsj_memory_estimate(const char* json, size_t length)
 * An upper estimate of the memory, in bytes, that handling a JSON request of
 * these bytes may need at its peak (the body itself included): cJSON's tree
 * dominates, one item per value, then the core's scene and context. One pass
 * over the bytes, counting values (NTSJ_BYTES_PER_VALUE each); measured in
 * docs/reliability.md ("Memory budget"). A front end reserves it before the
 * work starts. */
/** The bytes one JSON value may cost at the peak (ntsj_memory_estimate). */
#define NTSJ_BYTES_PER_VALUE 136
NTS_API size_t ntsj_memory_estimate(const char* json, size_t length);

/** Check json[0..length) as every request is checked before it is read:
 * strict RFC 8259 (no trailing data, no leading zero, no "\u0000"), UTF-8,
 * nesting within max_depth (< 1: the default config's). Returns NULL when it
 * is JSON, else its stable code ("invalid_json", "too_deep", ...) with the
 * fault's JSON pointer and message (with its line and column) copied to pointer
 * and message, NUL-terminated and truncated to their sizes. For front ends
 * that read JSON of their own (ntscontact-mpi's --part). */
NTS_API const char* ntsj_json_check(const char* json, size_t length, int max_depth, char* pointer,
                                    size_t pointer_size, char* message, size_t message_size);

/** An error document {"error": {"code", "message", "pointer"}} for front ends
 * (the server's 404/405/413/415/503). Returned buffer is freed with nts_free. */
NTS_API char* ntsj_error_document(const char* code, const char* message, const char* pointer);

/** The HTTP status of a stable code (schemas/error.schema.json): 200 for "ok",
 * 400 for input faults, 404/405/413/415/503 for the front ends' own codes, 500
 * for internal ones and for a name it does not know. */
NTS_API int ntsj_code_http_status(const char* code);

/** Read the pointer and message back from an error document (the body of a
 * response with !ok), for one-line diagnostics. Copies NUL-terminated,
 * truncated strings; returns 0, or -1 when `body` is not an error document. */
NTS_API int ntsj_error_fields(const char* body, size_t length, char* pointer, size_t pointer_size, char* message,
                      size_t message_size);

/** The stable error codes of the codec and the front ends, each spelled here
 * once (the core's are NTS_ERRNO_MAP, base.h; a test checks both lists against
 * schemas/error.schema.json). XX(enum suffix, stable name, HTTP status).
 * Never rename, only append. */
#define NTSJ_CODE_MAP(XX)                                       \
    XX(INVALID_JSON, "invalid_json", 400)                   \
    XX(INVALID_TYPE, "invalid_type", 400)                   \
    XX(MISSING_FIELD, "missing_field", 400)                 \
    XX(UNKNOWN_FIELD, "unknown_field", 400)                 \
    XX(DUPLICATE_KEY, "duplicate_key", 400)                 \
    XX(DUPLICATE_ID, "duplicate_id", 400)                   \
    XX(INVALID_VALUE, "invalid_value", 400)                 \
    XX(TOO_DEEP, "too_deep", 400)                           \
    XX(EMPTY_BODY, "empty_body", 400)                       \
    XX(PAYLOAD_TOO_LARGE, "payload_too_large", 413)         \
    XX(NOT_FOUND, "not_found", 404)                         \
    XX(METHOD_NOT_ALLOWED, "method_not_allowed", 405)       \
    XX(UNSUPPORTED_MEDIA_TYPE, "unsupported_media_type", 415)\
    XX(OVERLOADED, "overloaded", 503)                       \
    XX(TIMEOUT, "timeout", 503)                             \
    XX(UNKNOWN_SCENE, "unknown_scene", 404)                   \
    XX(UNAUTHORIZED, "unauthorized", 401)                     \
    XX(FORBIDDEN, "forbidden", 403)                           \
    XX(BAD_REQUEST, "bad_request", 400)

/** A codec code: NTSJ_<suffix> of NTSJ_CODE_MAP. */
typedef enum ntsj_code {
#define NTSJ_XX_(e, name, status) NTSJ_##e,
    NTSJ_CODE_MAP(NTSJ_XX_)
#undef NTSJ_XX_
    NTSJ_CODE_COUNT_
} ntsj_code;
/** The stable name of a codec code ("invalid_json", ...). */
NTS_API const char* ntsj_code_name(ntsj_code code);

/* ------------------------------------------------------------ sessions
 * A session holds one decoded scene (topology, options, positions), its core
 * scene and a warm evaluation context, so that a solver evaluates the same
 * topology at many positions without sending or parsing it again. An answer
 * equals, bit for bit (elapsed_ms aside), what ntsj_handle gives for the full
 * scene at the same positions and options. Not thread-safe: one step at a time
 * per session (the server serialises them). */
/** A session (opaque): ntsj_session_create, ntsj_session_step, ntsj_session_destroy. */
typedef struct ntsj_session ntsj_session;

/** What a session holds and has done (ntsj_session_get_info). */
typedef struct ntsj_session_info {
    /** the scene's bodies, nodes and surface nodes @{ */
    int bodies, nodes, surface_nodes;
    /** @} */
    unsigned long long steps;  /**< successful evaluations */
    size_t memory_bytes;       /**< everything the session holds */
} ntsj_session_info;

/** The form of a step's body. */
typedef enum ntsj_step_body {
    NTSJ_STEP_EMPTY = 0,  /**< evaluate at the stored positions */
    NTSJ_STEP_JSON = 1,   /**< {"positions": [[x, y], ...], "options": {...}}, both optional */
    NTSJ_STEP_BINARY = 2  /**< exactly 16 N bytes: little-endian float64, x then y per node (16 S with nodes=surface) */
} ntsj_step_body;

/** One step of a session: its body and how to answer it. */
typedef struct ntsj_step {
    ntsj_step_body kind;     /**< the form of `body` */
    const char* body;        /**< the step's bytes (not read with NTSJ_STEP_EMPTY) */
    size_t length;           /**< the bytes of `body` */
    int answer_binary;   /**< answer the forces as raw bytes (ntsj_response.binary) */
    /** Option overrides as text, for binary steps (a URL's query): penalty, alpha,
     * search_radius, solver, outputs (comma-separated names, empty for none);
     * commit (true or false); nodes (all, or surface: ntsj_session_surface). */
    /** @{ */
    int param_count;
    const char* const* param_names;
    const char* const* param_values;
    /** @} */
    /** A session that keeps contacts ("session": {"keep_contacts": true}) makes
     * an answered step's contacts the ones the next step is matched against.
     * 0: at once; 1: only at ntsj_session_commit, for a caller that may still
     * refuse the answer (the daemon's memory budget). */
    int defer_commit;
} ntsj_step;

/** Decode and build a session from a scene document (the schema of ntsj_handle),
 * and evaluate it once with no outputs, so that every fault ntsj_handle would
 * report shows now and the context is warm. Returns 0 with *out set, or fills
 * *error with the error document (the same as ntsj_handle's) and sets *out to
 * NULL; NTS_ENOMEM when even that failed. */
NTS_API int ntsj_session_create(const char* json, size_t length, const ntsj_config* config, ntsj_session** out,
                        ntsj_response* error);
/** Frees the session and everything it holds; NULL is a no-op. */
NTS_API void ntsj_session_destroy(ntsj_session* session);
/** The session's counts and bytes (all zero for NULL). */
NTS_API ntsj_session_info ntsj_session_get_info(const ntsj_session* session);
/** Give back the buffers of the session's evaluation context (nts_context_trim):
 * what one large step (gaps on a wide radius) grew is not held for the steps
 * after it. The next step allocates what it needs again and answers the same
 * bits. */
NTS_API void ntsj_session_trim(ntsj_session* session);
/** @fn int ntsj_session_step(ntsj_session* session, const ntsj_step* step, const ntsj_config* config, ntsj_response* out)
 * Evaluate at new positions (which become the stored ones once they pass the
 * scene's checks). Fills *out like ntsj_handle; errors name their place:
 * /positions/17 for a bad position, /options/alpha for a bad option.
 * config->step_memory bounds what the step may add to the session. What the
 * step grew in the context stays for the next steps (they need the same
 * buffers), unless the step failed: then it is given back at once
 * (ntsj_session_trim). */
/** A session step's bytes per candidate under ntsj_config.step_memory. */
#define NTSJ_STEP_BYTES_PER_CANDIDATE 256 /* a record (64) and its gap (sizeof(nts_contact)), rounded up */
NTS_API int ntsj_session_step(ntsj_session* session, const ntsj_step* step, const ntsj_config* config, ntsj_response* out);
/** After a step with defer_commit whose answer is sent: its contacts become the
 * kept ones (nothing to do for a session that keeps none, or after a failed
 * step). */
NTS_API void ntsj_session_commit(ntsj_session* session);
/** The session's surface nodes: the nodes on its scene's loops (a mesh's
 * boundary, every node of a polygon), each once, in ascending global order;
 * *count of them. A step with the query parameter nodes=surface takes and
 * answers their positions and forces alone, in this order (16 S bytes each
 * way: the only nodes contact reads or pushes). Fixed for the session's
 * life; NULL and 0 for NULL. */
NTS_API const int* ntsj_session_surface(const ntsj_session* session, int* count);

/** The summary of a successful binary session answer as header pairs, in the
 * daemon's order: NTS-Energy, NTS-Virial, NTS-Contacts, ..., friction's three
 * when it is on, NTS-Warnings when something may be missing. Each value reads
 * back bitwise (ntsj_format_double). The daemon sends them as HTTP headers; the
 * in-process engine (engine.h) hands the same text to the same reader. */
#define NTSJ_BINARY_HEADERS_MAX 16
/** Header pairs of a binary answer (ntsj_binary_headers_of). */
typedef struct ntsj_binary_headers {
    int count;                                  /**< pairs filled */
    const char* names[NTSJ_BINARY_HEADERS_MAX]; /**< static names ("NTS-Energy", ...) */
    char values[NTSJ_BINARY_HEADERS_MAX][160];  /**< their values, NUL-terminated */
} ntsj_binary_headers;
/** Fill `out` with the header pairs of a successful binary answer `response`. */
NTS_API void ntsj_binary_headers_of(const ntsj_response* response, ntsj_binary_headers* out);

/** @name Names
 * Names shared by the JSON options and the CLI flags. `ntsj_output_flag` maps
 * an output's name (n bytes: one of the NTS_OUT_* flags' names, "forces" to
 * "stiffness") to its flag, 0 if unknown; `ntsj_solver_from_name` maps "closed_form" and
 * "newton", returning 0 or -1.
 * @{ */
/** The NTS_OUT_* flag of the output named by the `n` bytes at `name`, 0 if unknown. */
NTS_API unsigned ntsj_output_flag(const char* name, size_t n);
/** Every output's name, in bit order (NTS_OUTPUT_MAP): "forces,energy,...",
 * or with `last_sep` " or " as prose, "forces, energy, ... or stiffness".
 * Returns the length. */
NTS_API int ntsj_output_names_text(const char* last_sep, char* out, size_t size);
/** The name of one NTS_OUT_* flag, NULL if none. */
NTS_API const char* ntsj_output_name(unsigned flag);
/** @fn int ntsj_output_list(const char* text, int policy, unsigned* out, const char** bad, size_t* bad_length)
 * A comma-separated list of output names (a CLI flag, a query parameter) into
 * NTS_OUT_* flags: 0, or NTSJ_LIST_UNKNOWN / NTSJ_LIST_DUPLICATE with *bad and
 * *bad_length the item at fault. `policy` 0 is the rule of every door (the
 * CLI's --outputs, a step's query, as JSON's array): a name twice or a
 * trailing comma refused; NTSJ_LIST_DUPLICATES_OK and
 * NTSJ_LIST_TRAILING_COMMA_OK take them (for a host's own front end). ""
 * is no outputs. */
/** ntsj_output_list's faults. */
enum { NTSJ_LIST_UNKNOWN = 1, NTSJ_LIST_DUPLICATE = 2 };
/** ntsj_output_list's `policy` bits. */
enum { NTSJ_LIST_DUPLICATES_OK = 1, NTSJ_LIST_TRAILING_COMMA_OK = 2 };
NTS_API int ntsj_output_list(const char* text, int policy, unsigned* out, const char** bad, size_t* bad_length);
/** Sets *out to the solver named `name` ("closed_form", "newton"): 0, or -1
 * when it names none (*out is then unchanged). */
NTS_API int ntsj_solver_from_name(const char* name, nts_solver* out);
/** The JSON name of `solver` (a static string; "closed_form" for a value that is none). */
NTS_API const char* ntsj_solver_name(nts_solver solver);
/** @} */
/** The shortest text of a finite double that reads back bitwise equal with
 * strtod (always with a '.' or an exponent), into out (>= 32 bytes, any of
 * which past the text's NUL it may overwrite); returns its length. For the
 * summary headers of a binary session answer. */
NTS_API int ntsj_format_double(char* out, double v);
/** A whole text as one JSON number (RFC 8259 §6: no '+', no leading '.',
 * no hex, no space), read as a request's numbers are read (the nearest
 * double, ties to even; a number below the smallest double is 0, as
 * strtod and cJSON take it): 0 and *out; -1 when the text is not one
 * number; 1 when it lies beyond the doubles (1e999). The query parameters
 * of a session step and the command lines of ntscontact and ntscontactd
 * read their numbers with it, so one text means one value at every door. */
NTS_API int ntsj_parse_double(const char* text, double* out);
/** A count in [lo, hi] written in decimal, with an optional binary k, M or G
 * suffix when `suffixes` (1k = 1024): the command lines of ntscontact and
 * ntscontactd read their limits with it. 0, or -1 when `text` is not one. */
NTS_API int ntsj_parse_count(const char* text, int suffixes, unsigned long long lo, unsigned long long hi,
                     unsigned long long* out);

#ifdef __cplusplus
}
#endif
#endif
