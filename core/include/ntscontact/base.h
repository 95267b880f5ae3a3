/** @file
 * ntscontact: base definitions shared by every layer.
 * Error codes (one X-macro table gives the enum, the stable name used in JSON
 * and the human message, as libuv's UV_ERRNO_MAP does), the allocator hook and
 * the error record that names the body, loop and node at fault. */
#ifndef NTSCONTACT_BASE_H
#define NTSCONTACT_BASE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/** The library's exported functions: every public function carries NTS_API,
 * and the library is built with hidden visibility, so a shared build exports
 * exactly the API (as libuv's UV_EXTERN). */
#if defined(__GNUC__) && __GNUC__ >= 4
#define NTS_API __attribute__((visibility("default")))
#else
#define NTS_API
#endif

/* NTS_VERSION_MAJOR, _MINOR, _PATCH and _STRING: generated from CMake's
 * project() with the build's configuration. */
#include <ntscontact/config.h> /* generated: the build directory's include path */

/** XX(enum suffix, value, stable name, message). Values are negative as in libuv;
 * 0 is success. The names are part of the public JSON contract: never renumber
 * or rename, only append. */
#define NTS_ERRNO_MAP(XX)                                                                   \
    XX(NOMEM, -1, "out_of_memory", "out of memory")                                        \
    XX(INVALID_ARGUMENT, -2, "invalid_argument", "invalid argument")                       \
    XX(INVALID_OPTION, -3, "invalid_option", "option out of range")                        \
    XX(EMPTY_SCENE, -4, "empty_scene", "scene has no bodies")                              \
    XX(NO_NODES, -5, "no_nodes", "body has no nodes")                                      \
    XX(LOOP_TOO_SHORT, -6, "loop_too_short", "loop has fewer than 3 nodes")                \
    XX(INDEX_RANGE, -7, "index_out_of_range", "node index out of range")                   \
    XX(NODE_REUSED, -8, "node_in_two_loops", "node appears in more than one loop place")   \
    XX(NONFINITE, -9, "non_finite", "coordinate is not a finite number")                   \
    XX(DEGENERATE_SEGMENT, -10, "degenerate_segment", "zero-length segment")               \
    XX(ZERO_AREA, -11, "zero_area_loop", "loop encloses zero area")                        \
    XX(SPIKE, -12, "zero_angle_spike", "zero-angle spike at node")                         \
    XX(NONMANIFOLD, -13, "non_manifold_mesh", "edge shared by more than two triangles")    \
    XX(DEGENERATE_TRIANGLE, -14, "degenerate_triangle", "zero-area triangle")              \
    XX(BOX_TOO_SMALL, -15, "box_too_small", "periodic box smaller than twice the search reach") \
    XX(LIMIT, -16, "limit_exceeded", "a configured limit was exceeded")                    \
    XX(NO_BOUNDARY, -17, "no_boundary", "triangle mesh has no boundary")                   \
    XX(INTERNAL, -18, "internal_error", "internal error")                                  \
    XX(RESHAPED, -19, "reshaped", "new positions change the scene's normalisation")                 \
    XX(OUT_OF_RANGE, -20, "out_of_range", "coordinate beyond the supported range (1e100)")      \
    XX(CANCELLED, -21, "cancelled", "the evaluation was cancelled (deadline or caller)")            \
    XX(INVALID_SURFACE, -22, "invalid_surface", "a contact surface pair is not a boundary segment, or repeats one") \
    XX(INVALID_HISTORY, -23, "invalid_history", "a friction history entry is not an anchor of this scene")

/** A status: NTS_OK (0), or one of the negative NTS_E<suffix> codes of
 * NTS_ERRNO_MAP. Every function of the library that returns an int status
 * returns one of these. */
typedef enum nts_status {
    NTS_OK = 0, /**< success */
#define NTS_XX_(e, v, name, msg) NTS_E##e = (v),
    NTS_ERRNO_MAP(NTS_XX_)
#undef NTS_XX_
#define NTS_XX_(e, v, name, msg) +1
    NTS_E_COUNT_ = 1 NTS_ERRNO_MAP(NTS_XX_) /**< the table's rows and "ok" */
#undef NTS_XX_
} nts_status;

/** Stable snake_case name of a status ("ok", "degenerate_segment", ...). */
NTS_API const char* nts_status_name(int status);
/** Short human message of a status. */
NTS_API const char* nts_strerror(int status);

/** Where an error is. Every index is -1 when it does not apply. `loop_pos` is the
 * position inside the loop's index list, `node` the body's node index,
 * `triangle` the triangle index of a body given by a mesh and `corner` the
 * place (0, 1, 2) inside that triangle. `option` names the option at fault
 * ("alpha", "penalty", ...), or is empty. `item` is the index of the entry at
 * fault in the list that `option` names (a pair of nts_body_def.surface, with
 * `corner` its place 0 or 1 when one node index of it is at fault). */
typedef struct nts_error {
    int code;          /**< the status (nts_status); 0: no fault */
    int body;          /**< the body at fault, or -1 */
    int loop;          /**< the loop at fault, or -1 */
    int loop_pos;      /**< the position inside the loop's index list, or -1 */
    int node;          /**< the body's node index, or -1 */
    int triangle;      /**< the triangle of a body given by a mesh, or -1 */
    int corner;        /**< the place inside that triangle (or a surface pair), or -1 */
    int item;          /**< the entry at fault in the list `option` names, or -1 */
    char option[32];   /**< the option at fault, NUL-terminated, or empty */
    char message[192]; /**< a human message, NUL-terminated (truncated to fit) */
} nts_error;

/** An error record with no fault (code 0, every index -1). */
NTS_API nts_error nts_error_none(void);

/** @name Allocator hook
 * Allocator hook (all library allocations go through it; NULL restores malloc).
 * The hook must be thread-safe: with nts_options.threads > 1 the worker threads
 * of one evaluation call it concurrently (to grow their record buffers). Do not
 * change the hook while evaluations run.
 * @{ */
/** Allocates `size` bytes (never 0: nts_alloc asks for 1 then), or returns NULL. */
typedef void* nts_alloc_fn(size_t size, void* user);
/** Releases a block of the matching nts_alloc_fn (never called with NULL). */
typedef void nts_free_fn(void* ptr, void* user);
/** Installs the hook: both functions and their `user` pointer; either
 * function NULL restores malloc and free. */
NTS_API void nts_set_allocator(nts_alloc_fn* alloc_fn, nts_free_fn* free_fn, void* user);
/** `size` bytes through the hook, or NULL when out of memory; 0 bytes still
 * give a distinct pointer, so NULL always means failure. Release with nts_free. */
NTS_API void* nts_alloc(size_t size);
/** Releases memory from nts_alloc (and the buffers the library hands out
 * "from nts_alloc"); NULL is a no-op. */
NTS_API void nts_free(void* ptr);
/** @} */

#ifdef __cplusplus
}
#endif
#endif
