/* ntscontact codec internals: the pieces ntsj_handle strings together, split so
 * that the benchmark (codec/bench) can time each one on its own.
 *
 *   scan.c    strict RFC 8259 pre-scan: grammar, UTF-8, nesting depth, with the
 *             JSON pointer of the first fault (cJSON itself is lenient)
 *   decode.c  cJSON tree -> ntsj_scene (nts_scene_def + ids + options)
 *   encode.c  nts_result -> JSON text with our own number printer
 *   numfmt.c  the growable output buffer and shortest round-trip doubles
 *   codes.c   the stable error codes and their HTTP status
 *   handle.c  ntsj_handle: size check, scan, parse, decode, evaluate, encode */
#ifndef NTSJ_CODEC_INTERNAL_H
#define NTSJ_CODEC_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include <ntscontact/codec.h>

/* ------------------------------------------------------------ errors */

/* A decode error: a stable code, a JSON pointer (RFC 6901) and a message. */
typedef struct ntsj_fault {
    const char* code; /* static string, NULL when there is no fault */
    char pointer[256];
    char message[256];
} ntsj_fault;

void ntsj_fault_set(ntsj_fault* f, const char* code, const char* pointer, const char* fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

/* ------------------------------------------------------------ buffer */

/* A growable NUL-terminated byte buffer (through nts_alloc). After a failed
 * allocation `oom` is set and further writes are ignored. `max` (0: none)
 * bounds its capacity: past it `over` and `oom` are set (a session step's
 * answer within what its session may still take). */
typedef struct ntsj_buf {
    char* data;
    size_t len, cap;
    int oom;
    size_t max;
    int over;
} ntsj_buf;

void ntsj_buf_init(ntsj_buf* b);
void ntsj_buf_free(ntsj_buf* b);
int ntsj_buf_reserve(ntsj_buf* b, size_t extra);
/* Room for about `extra` more bytes, a guess that saves copies: cut to `max`,
 * it never sets `over` (only a write past `max` does). */
void ntsj_buf_hint(ntsj_buf* b, size_t extra);
void ntsj_buf_put(ntsj_buf* b, const char* s, size_t n);
void ntsj_buf_puts(ntsj_buf* b, const char* s);
void ntsj_buf_putc(ntsj_buf* b, char c);
void ntsj_buf_int(ntsj_buf* b, long long v);
/* A JSON string literal with escapes (the input is valid UTF-8). */
void ntsj_buf_string(ntsj_buf* b, const char* s);
/* A double that reads back bitwise equal with strtod; NaN and infinities are
 * written as null (the encoder never hands them over). Always has a '.' or an
 * exponent, so readers that split integers from reals see a real. */
void ntsj_buf_double(ntsj_buf* b, double v);
/* The room ntsj_format_double writes into: its text is 24 characters at
 * most, its NUL included ("-2.2250738585072014e-308"), and the bytes after
 * the NUL, up to 32, may be overwritten (numfmt.c's fixed-size copies). */
#define NTSJ_DOUBLE_MAX 32
/* ntsj_format_double is public (codec.h). */
/* The JSON number (RFC 8259 §6) that starts at p (before end): its length,
 * *out the nearest double (ties to even: strtod's bits); 0 when no number
 * starts there, or one of 64 characters or more that only strtod reads
 * (numparse.c). */
size_t ntsj_parse_number(const char* p, const char* end, double* out);
/* 10^-q's multipliers, q = 0..341: floor(2^(bits(5^q) - 1 + 125) / 5^q) + 1,
 * each {low 64 bits, high 64 bits}; the printer's, and the reader's to divide
 * by 5^q (generated: numfmt_pow5.h, defined in numfmt.c). */
extern const uint64_t ntsj_pow5_inv[342][2];
/* The bits of 5^e (e >= 1; 1 for e = 0): ceil(e log2 5), exact for e < 3529. */
static inline uint32_t ntsj_pow5_bits(uint32_t e) { return ((e * 1217359u) >> 19) + 1u; }

/* ------------------------------------------------------------ scan */

/* Check `json[0..length)` strictly against RFC 8259 (plus: no "\u0000" escape)
 * and that nesting stays within max_depth. Returns 0 or fills *fault. */
int ntsj_scan(const char* json, size_t length, int max_depth, ntsj_fault* fault);

/* ------------------------------------------------------------ decode */

typedef struct ntsj_id {
    int is_int;
    long long ival;
    char* sval; /* owned, NUL-terminated, when !is_int */
} ntsj_id;

typedef struct ntsj_scene {
    int body_count;
    nts_body_def* defs; /* body_count; arrays owned below */
    ntsj_id* ids;
    int* has_loops;     /* 1 when the body came with explicit "loops" */
    nts_vec2** nodes;   /* owned per body */
    int** ints;         /* owned per body: loop_nodes + loop_start, or triangles */
    nts_vec2** refs;    /* owned per body: its reference configuration ("reference"), or NULL */
    int** surfs;        /* owned per body: its contact surface's pairs ("surface"), or NULL */
    nts_options options;
    double lx, ly;
    int has_periodic;
    /* "session": {"keep_contacts": true}: a session keeps each step's contacts
     * and matches the next step's to them (nts_contact_memory); a stateless
     * request may not ask (handle.c). */
    int has_session, keep_contacts;
    /* "session": {"keep_candidates", "skin"}: a session keeps a candidate
     * list (nts_candidates, docs/model.md §15; on unless false) with this
     * skin (negative: the default, 0.3 times the search radius). */
    int keep_candidates;
    double skin;
    /* "history" (friction, docs/model.md §14): the anchors a request goes on
     * from, bodies as indices (handle.c and session.c hand them to
     * nts_history_set, whose faults point at /history/K). */
    int has_history;
    nts_anchor* history;
    int history_count;
    /* While a session encodes a step that keeps contacts: each contact's
     * match and the step's changes (encode.c); NULL otherwise. */
    const nts_contact_match* match;
    const nts_contact_changes* changes;
} ntsj_scene;

struct cJSON;
/* Decode a parsed request. Returns 0, or -1 with *fault filled (the scene is
 * then freed already), or NTS_ENOMEM. Applies config->overrides. */
int ntsj_decode(const struct cJSON* root, const ntsj_config* config, ntsj_scene* out, ntsj_fault* fault);
/* The same for a part of a scene that a front end holds with others (a
 * rank's bodies: ntscontact.mpi): it may hold no bodies. */
int ntsj_decode_part(const struct cJSON* root, const ntsj_config* config, ntsj_scene* out, ntsj_fault* fault);
void ntsj_scene_free(ntsj_scene* s);
/* Append "/<key>" to the NUL-terminated pointer ptr with RFC 6901's escapes
 * (~ as ~0, / as ~1), cut to size (decode.c; ntscontact-mpi's --part). */
void ntsj_pointer_append_key(char* ptr, size_t size, const char* key);
/* The JSON pointer of a core error against the decoded request. */
void ntsj_pointer_of_error(const ntsj_scene* s, const nts_error* err, char* out, size_t size);

/* ------------------------------------------------------------ encode */

typedef struct ntsj_timing {
    double elapsed_ms;
} ntsj_timing;

void ntsj_encode_result(ntsj_buf* b, const ntsj_scene* s, const nts_scene* scene, const nts_result* r,
                        double elapsed_ms, int pretty);
void ntsj_encode_validation(ntsj_buf* b, const nts_scene* scene, double elapsed_ms, int pretty);
void ntsj_encode_error(ntsj_buf* b, const char* code, const char* message, const char* pointer, int pretty);
/* {"history": [...]}: anchors as a request's "history" takes them (§14). */
void ntsj_encode_history(ntsj_buf* b, const ntsj_scene* s, const nts_anchor* anchors, int count);
/* The result as a VTK XML unstructured grid (vtk.c); needs forces and contacts. */
void ntsj_encode_vtk(ntsj_buf* b, const ntsj_scene* s, const nts_scene* scene, const nts_result* r);
/* Attach the VTK document of a successful evaluation to `out` (when asked):
 * 0, or NTS_ENOMEM. */
int ntsj_attach_vtk(ntsj_response* out, const ntsj_scene* s, const nts_scene* scene, const nts_result* r);

/* ------------------------------------------------------------ codes */

/* 1 when `code` is one of the stable codes (error.schema.json). */
int ntsj_code_known(const char* code);

/* ------------------------------------------------------------ handle */
/* Whether the request has used more than cfg->max_seconds since t0 (what
 * ntsj_over_budget answers, without answering). */
int ntsj_past_budget(const ntsj_config* cfg, double t0);

/* Shared by ntsj_handle and the sessions (session.c). */
double ntsj_now_ms(void);                 /* monotonic milliseconds */
double ntsj_round_us(double ms);          /* rounded to whole microseconds */
/* Hand the buffer over as the response (status from the code's table). */
int ntsj_finish(ntsj_response* out, ntsj_buf* b, const char* code);
/* A successful evaluation's summary and warnings into the response (for a
 * binary answer's headers, the CLI's standard error, a front end's counters). */
void ntsj_keep_summary(ntsj_response* out, const nts_result* r, int friction);
int ntsj_respond_error(ntsj_response* out, const char* code, const char* message, const char* pointer, int pretty);
int ntsj_respond_fault(ntsj_response* out, const ntsj_fault* f, int pretty);
/* The request's "history" (s->has_history) into `h` (NULL: its allocation
 * failed), checked against the scene (§14): 0, or 1 with *out the error
 * (invalid_history at /history/K, out_of_memory) and *rc what answering it
 * returned (0, or NTS_ENOMEM), as ntsj_over_budget does. */
int ntsj_set_history(nts_history* h, const ntsj_scene* s, const nts_scene* scene, ntsj_response* out, int pretty,
                     int* rc);
/* A core error, with the JSON pointer of its place in the scene document. */
int ntsj_respond_core(ntsj_response* out, const ntsj_scene* s, const nts_error* err, int status, int pretty);
/* 1 (with *rc and *out set to limit_exceeded) when the request is over max_seconds. */
int ntsj_over_budget(const ntsj_config* cfg, double t0, ntsj_response* out, const char* phase, int* rc);
/* The request's deadline (max_seconds) and the front end's cancel hook
 * (ntsj_config.cancel) as the core's cancel hook: `t0` in ntsj_now_ms; armed
 * only when there is one or the other. */
typedef struct ntsj_deadline {
    double until_ms; /* HUGE_VAL: none */
    int (*cancel)(void* user);
    void* cancel_user;
} ntsj_deadline;
void ntsj_arm_deadline(nts_options* opt, ntsj_deadline* d, const ntsj_config* cfg, double t0);
/* 1 (with *f set to non_finite) when a finite input gave a result a double cannot hold. */
int ntsj_result_overflows(const ntsj_scene* s, const nts_scene* scene, const nts_result* r, ntsj_fault* f);
/* The options' doors (codec/src/options.c, over NTS_OPTION_MAP). */
/* Decode "outputs" (an array of names) at pointer `ptr`; 0 or -1 with *fault. */
int ntsj_decode_outputs(const struct cJSON* v, const char* ptr, unsigned* out, ntsj_fault* fault);
/* "an object", "a number", ...: what a JSON value is, for messages. */
const char* ntsj_json_type_name(const struct cJSON* v);
/* The members a scene document may have at its root (decode.c reads them;
 * ntscontact-mpi's --part names a stray one as the decoder would). */
enum { NTSJ_ROOT_COUNT = 6 };
extern const char* const ntsj_root_fields[NTSJ_ROOT_COUNT];
/* An option's value from JSON (a scene's or a step's "options") or from text
 * (a query parameter), at pointer `ptr` ("/options/<name>"): 0, or -1 with
 * *fault. Not for OBJECT rows (the periodic box, friction: decode.c). */
int ntsj_option_json(int id, const struct cJSON* v, const char* ptr, nts_option_value* out, ntsj_fault* fault);
int ntsj_option_text(int id, const char* text, const char* ptr, nts_option_value* out, ntsj_fault* fault);
/* The JSON names of the options of a door (NTS_OPTION_DOOR_*), "a, b, c". */
int ntsj_option_door_names(int door, char* out, size_t size);
/* A number's range where the codec checks it (the table's CODEC rows): 0
 * with out->number = v, or -1 with *fault. */
int ntsj_option_number_check(int id, double v, const char* ptr, nts_option_value* out, ntsj_fault* fault);
/* An override's value as a double (for the range checks). */
double ntsj_override_number(const ntsj_overrides* ov, int id);
/* Copy the overrides that are set into *o. */
void ntsj_overrides_apply(const ntsj_overrides* ov, nts_options* o);

#endif
