/**
 * @file ntscontact/engine.h
 * @brief The codec in process, for hosts that call C through a foreign-function
 * interface (Python's ctypes, Julia's ccall, ...).
 *
 * Opaque handles and flat calls: a host mirrors no struct layout, so a change of
 * ntsj_config or ntsj_response never breaks it silently. Every answer is the
 * daemon's, byte for byte (elapsed_ms aside): the same codec decodes the same
 * JSON, evaluates and encodes; a binary session answer carries the summary as
 * the daemon's NTS-* header lines (ntsj_binary_headers_of).
 *
 * Ownership: an ntsj_answer belongs to the caller until ntsj_answer_free; the
 * pointers it gives (body, headers, code) live as long as it does. Threads: an
 * engine may serve calls from many threads at once; a session takes one step at
 * a time (the caller serialises its steps, as the daemon does).
 */
#ifndef NTSCONTACT_ENGINE_H
#define NTSCONTACT_ENGINE_H

#include <stddef.h>

#include <ntscontact/codec.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A configuration shared by calls: the threads of each evaluation and the
 * codec's default limits (ntsj_default_config). Immutable once created. */
typedef struct ntsj_engine ntsj_engine;
/** One answer: a result or error document, or a binary session answer. */
typedef struct ntsj_answer ntsj_answer;

/** An engine whose evaluations run on `threads` threads (0: serial; the
 * answer's bits do not depend on it). NULL when out of memory. */
NTS_API ntsj_engine* ntsj_engine_create(int threads);
/** ntsj_engine_create with the largest JSON text that a call, or a
 * session's scene, takes: `max_bytes` (0: the default, 64 MiB; the daemon's
 * --max-bytes). Past it an answer is payload_too_large (413). A scene
 * larger than the default goes in process only so (a session's steps send
 * positions, but its scene is JSON too). */
NTS_API ntsj_engine* ntsj_engine_create_sized(int threads, size_t max_bytes);
/** Free an engine (NULL is fine). Its sessions stay valid: they hold no
 * pointer to it. */
NTS_API void ntsj_engine_destroy(ntsj_engine* engine);

/** Evaluate a scene document (`validate`: only check it, as POST
 * /v1/validate): ntsj_handle's answer. NULL only when out of memory. */
NTS_API ntsj_answer* ntsj_engine_contact(const ntsj_engine* engine, const char* json, size_t length, int validate);

/** Build a session from a scene document (ntsj_session_create). On success
 * the answer is ok with an empty body and *session is set; else it holds the
 * error document and *session is NULL. NULL only when out of memory. */
NTS_API ntsj_answer* ntsj_engine_session_create(const ntsj_engine* engine, const char* json, size_t length,
                                                ntsj_session** session);

/** One session step (ntsj_session_step): `kind` is an ntsj_step_body,
 * `body` the positions (16 N bytes for NTSJ_STEP_BINARY, read in place, not
 * copied), the parameters as the daemon's query (penalty, alpha,
 * search_radius, solver, outputs, commit). The step's contacts are the kept
 * ones at once (no deferred commit). NULL only when out of memory. */
NTS_API ntsj_answer* ntsj_engine_step(const ntsj_engine* engine, ntsj_session* session, int kind, const char* body,
                                      size_t length, int answer_binary, int param_count,
                                      const char* const* param_names, const char* const* param_values);

/** A session's counts, into out[5]: bodies, nodes, surface nodes, successful
 * steps, bytes held. */
NTS_API void ntsj_engine_session_counts(const ntsj_session* session, long long out[5]);

/** 1 when the answer is a result (or a validation report, or a made session). */
NTS_API int ntsj_answer_ok(const ntsj_answer* answer);
/** The HTTP status the daemon would answer with (200, 400, 413, 503, ...). */
NTS_API int ntsj_answer_status(const ntsj_answer* answer);
/** The stable code ("ok", "invalid_json", ...), a static string. */
NTS_API const char* ntsj_answer_code(const ntsj_answer* answer);
/** The body (a JSON document, or for a binary answer the raw little-endian
 * bytes: forces, then the tangent's triplets, then the pressure). */
NTS_API const char* ntsj_answer_body(const ntsj_answer* answer);
/** The body's length in bytes. */
NTS_API size_t ntsj_answer_length(const ntsj_answer* answer);
/** 1 when the body is a binary session answer. */
NTS_API int ntsj_answer_binary(const ntsj_answer* answer);
/** A binary answer's summary as the daemon's header lines, "Name: value\n"
 * each (NTS-Energy, NTS-Virial, ...); "" for any other answer. */
NTS_API const char* ntsj_answer_headers(const ntsj_answer* answer);
/** Free an answer and everything it gave (NULL is fine). */
NTS_API void ntsj_answer_free(ntsj_answer* answer);

#ifdef __cplusplus
}
#endif
#endif
