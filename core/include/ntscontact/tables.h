/** @file
 * ntscontact: the vocabularies of the contract, each spelled once (issue 24 §3).
 *
 * The error codes are one X-macro table (NTS_ERRNO_MAP, base.h, as libuv's
 * UV_ERRNO_MAP); the options of an evaluation are another, here. Every place
 * that needs an option's name, type, default, range, JSON name, CLI flag or
 * query parameter expands this table: the core's defaults and range checks
 * (core/src/options.c), the codec's three option parsers (a scene's
 * "options", a session step's "options", a binary step's query parameters:
 * codec/src/options.c), the CLI's flags and their help (cli/src/main.c).
 * tests/python/test_tables.py reads the table back and checks it against
 * schemas/scene.schema.json, schemas/session.schema.json and
 * schemas/openapi.json, and the CLI's --help against the table.
 *
 * Included by ntscontact.h; the macros expand only where they are used, so
 * the enums they name (nts_solver, nts_search, ...) need only be declared
 * there. */
#ifndef NTSCONTACT_TABLES_H
#define NTSCONTACT_TABLES_H

#include "base.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The outputs a caller may ask for (nts_options.outputs, a scene's "outputs",
 * the CLI's --outputs, a step's ?outputs=): one row each, in their bit order.
 *
 * XX(ID, bit, name, result, records)
 *   ID       NTS_OUT_<ID> = 1u << bit (ntscontact.h)
 *   name     its JSON name (the schemas' "output" enum)
 *   result   where the result document carries it (result.schema.json's
 *            result: "contacts", or "bodies/forces", "summary/energy")
 *   records  1 when it needs every contact's record kept (memory per
 *            candidate: a session step's budget, NTS_OUT_RECORDS_) */
#define NTS_OUTPUT_MAP(XX)                          \
    XX(FORCES, 0, "forces", "bodies/forces", 0)     \
    XX(ENERGY, 1, "energy", "summary/energy", 0)    \
    XX(VIRIAL, 2, "virial", "summary/virial", 0)    \
    XX(CONTACTS, 3, "contacts", "contacts", 1)      \
    XX(GAPS, 4, "gaps", "gaps", 1)                  \
    XX(STIFFNESS, 5, "stiffness", "stiffness", 1)   \
    XX(PRESSURE, 6, "pressure", "bodies/pressure", 1)

/** The names of an enumerated option's values: XX(C enumerator, JSON name).
 * @{ */
#define NTS_SOLVER_NAMES(XX) XX(NTS_SOLVER_CLOSED_FORM, "closed_form") XX(NTS_SOLVER_NEWTON, "newton")
#define NTS_SEARCH_NAMES(XX) XX(NTS_SEARCH_CELLS, "cells") XX(NTS_SEARCH_BRUTE_FORCE, "brute_force")
#define NTS_PENALTY_SCALING_NAMES(XX) XX(NTS_PENALTY_PER_NODE, "node") XX(NTS_PENALTY_PER_LENGTH, "length")
#define NTS_NO_NAMES(XX)
/** @} */

/** The options. One row each, in the order a scene's options are decoded
 * (the first fault found is the one reported):
 *
 * XX(ID, field, json, flag, metavar, kind, ctype, default, min, max, bound, check, presence, doors, names, help)
 *
 *   ID        NTS_OPT_<ID>, the row's index (nts_option_id)
 *   field     the nts_options member (kind OBJECT: the codec's decoder sets
 *             the fields itself: the scene holds the periodic box, friction
 *             is nts_options.friction and tangential_penalty)
 *   json      its name in a scene's "options", a step's "options" and a
 *             binary step's query (?alpha=0.1)
 *   flag      the CLI flag ("" when the CLI does not set it), metavar its
 *             value in --help
 *   kind      NUMBER (a finite double), ENUM (one of `names`), OUTPUTS (a
 *             list of NTS_OUTPUT_MAP names), OBJECT (an object decoded by hand:
 *             the periodic box {lx, ly}, friction {coefficient,
 *             tangential_penalty}; min, max, bound of friction are its
 *             coefficient's)
 *   ctype     the C type of the field
 *   default   nts_default_options()'s value (search_radius -1: the median
 *             segment, which JSON says by leaving it out)
 *   min, max, bound   the valid range: CLOSED [min, max], ABOVE (min, inf),
 *             FROM [min, inf), NONE
 *   check     who checks the range: CORE (nts_options_validate: every door
 *             gets the same error), CODEC (the JSON doors only: the core reads
 *             a negative search_radius as "the median segment"), NONE
 *   presence  REQUIRED in a scene document, or OPTIONAL
 *   doors     ALL (a scene's options, a step's options and query, the CLI
 *             flag) or SCENE (a scene's options only)
 *   names     the value names of an ENUM (NTS_NO_NAMES otherwise)
 *   help      what it is, for --help (the range or the names follow) */
#define NTS_OPTION_MAP(XX)                                                                                         \
    XX(ALPHA, alpha, "alpha", "--alpha", "A", NUMBER, double, 0.2, 0.0, 0.5, CLOSED, CORE, OPTIONAL, ALL,          \
       NTS_NO_NAMES, "smoothing fraction")                                                                         \
    XX(PENALTY, penalty, "penalty", "--penalty", "EPS", NUMBER, double, 1.0, 0.0, 0.0, ABOVE, CORE, REQUIRED, ALL, \
       NTS_NO_NAMES, "penalty stiffness")                                                                          \
    XX(SEARCH_RADIUS, search_radius, "search_radius", "--search-radius", "R", NUMBER, double, -1.0, 0.0, 0.0,      \
       FROM, CODEC, OPTIONAL, ALL, NTS_NO_NAMES, "search radius")                                                  \
    XX(PERIODIC, periodic, "periodic", "", "", OBJECT, double, 0.0, 0.0, 0.0, NONE, NONE, OPTIONAL, SCENE,            \
       NTS_NO_NAMES, "periodic box")                                                                               \
    XX(SOLVER, solver, "solver", "--solver", "NAME", ENUM, nts_solver, NTS_SOLVER_CLOSED_FORM, 0.0, 0.0, NONE,     \
       CORE, OPTIONAL, ALL, NTS_SOLVER_NAMES, "")                                                                  \
    XX(OUTPUTS, outputs, "outputs", "--outputs", "LIST", OUTPUTS, unsigned,                                        \
       NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL, 0.0, 0.0, NONE, CORE, OPTIONAL, ALL, NTS_NO_NAMES,         \
       "comma-separated:")                                                                                         \
    XX(PENALTY_SCALING, penalty_scaling, "penalty_scaling", "", "", ENUM, nts_penalty_scaling,                     \
       NTS_PENALTY_PER_NODE, 0.0, 0.0, NONE, CORE, OPTIONAL, SCENE, NTS_PENALTY_SCALING_NAMES, "")                \
    XX(SEARCH, search, "search", "", "", ENUM, nts_search, NTS_SEARCH_CELLS, 0.0, 0.0, NONE, CORE, OPTIONAL,       \
       SCENE, NTS_SEARCH_NAMES, "")                                                                                \
    XX(SURFACE_EXTENSION, surface_extension, "surface_extension", "", "", NUMBER, double, 0.01, 0.0, 0.5, CLOSED,  \
       CORE, OPTIONAL, SCENE, NTS_NO_NAMES, "how far a contact surface's end segment reaches past its end node")   \
    XX(FRICTION, friction, "friction", "", "", OBJECT, double, 0.0, 0.0, 10.0, CLOSED, CORE, OPTIONAL, SCENE,       \
       NTS_NO_NAMES, "Coulomb friction {coefficient, tangential_penalty}")

/** An option's id: NTS_OPT_<ID>, its row's index in NTS_OPTION_MAP (the `id`
 * the functions below take). */
typedef enum nts_option_id {
#define NTS_XX_(ID, field, json, flag, meta, kind, ctype, def, lo, hi, bound, check, presence, doors, names, help) \
    NTS_OPT_##ID,
    NTS_OPTION_MAP(NTS_XX_)
#undef NTS_XX_
    NTS_OPT_COUNT_
} nts_option_id;

/* The table at run time, for the loops of the parsers and the help. */
/** An option's `kind` column (NTS_OPTION_MAP): NUMBER, ENUM, OUTPUTS or OBJECT. */
typedef enum nts_option_kind {
    NTS_OPTION_KIND_NUMBER, NTS_OPTION_KIND_ENUM, NTS_OPTION_KIND_OUTPUTS, NTS_OPTION_KIND_OBJECT
} nts_option_kind;
/** An option's `bound` column: the form of its valid range [min, max]. */
typedef enum nts_option_bound {
    NTS_OPTION_BOUND_NONE, NTS_OPTION_BOUND_CLOSED, NTS_OPTION_BOUND_ABOVE, NTS_OPTION_BOUND_FROM
} nts_option_bound;
/** An option's `check` column: who checks its range. */
typedef enum nts_option_check { NTS_OPTION_CHECK_NONE, NTS_OPTION_CHECK_CORE, NTS_OPTION_CHECK_CODEC } nts_option_check;
/** The doors an option comes through (bits). */
enum {
    NTS_OPTION_DOOR_SCENE = 1, /**< a scene document's "options" */
    NTS_OPTION_DOOR_STEP = 2,  /**< a session step's "options" and a binary step's query */
    NTS_OPTION_DOOR_CLI = 4,   /**< the CLI's flag */
    NTS_OPTION_DOORS_SCENE = NTS_OPTION_DOOR_SCENE,
    NTS_OPTION_DOORS_ALL = NTS_OPTION_DOOR_SCENE | NTS_OPTION_DOOR_STEP | NTS_OPTION_DOOR_CLI
};

/** One row of NTS_OPTION_MAP at run time (nts_option_info_of). */
typedef struct nts_option_info {
    const char* json;            /**< "search_radius" */
    const char* flag;            /**< "--search-radius", "" */
    const char* metavar;         /**< "R" */
    const char* help;            /**< "search radius" */
    nts_option_kind kind;        /**< NUMBER, ENUM, OUTPUTS or OBJECT */
    /** The valid range's ends (as `bound` reads them). @{ */
    double min, max;
    /** @} */
    nts_option_bound bound;      /**< the form of the range */
    nts_option_check check;      /**< who checks the range */
    int required;                /**< in a scene document */
    int doors;                   /**< NTS_OPTION_DOOR_* */
    const char* const* names;    /**< an ENUM's value names, name_count of them */
    const int* values;           /**< their C values */
    int name_count;              /**< how many `names` and `values` (0 unless ENUM) */
} nts_option_info;

/** A parsed value of any kind. */
typedef struct nts_option_value {
    double number;   /**< NUMBER */
    int enumerated;  /**< ENUM: the C value */
    unsigned flags;  /**< OUTPUTS: NTS_OUT_* */
} nts_option_value;

struct nts_options;

/** @name Rows
 * The row of an option (NULL when out of range), the row named `json` (-1
 * when none), and the store of a value into its nts_options field (nothing
 * for OBJECT).
 * @{ */
/** The row of option `id` (a static table: never freed), NULL when out of range. */
NTS_API const nts_option_info* nts_option_info_of(int id);
/** The id of the option whose JSON name is the `n` bytes at `json` (not
 * NUL-terminated), -1 when none. */
NTS_API int nts_option_find(const char* json, size_t n);
/** Stores `v` (the member of its kind) into option `id`'s field of `o`;
 * nothing for OBJECT or an id out of range. */
NTS_API void nts_option_store(struct nts_options* o, int id, const nts_option_value* v);
/** @} */
/** "in [0, 0.5]", "> 0", ">= 0" (empty for NONE): the range as --help and the
 * messages write it. Returns the length. */
NTS_API int nts_option_range_text(int id, char* out, size_t size);
/** An ENUM's names (or the output names for OUTPUTS) as prose, "a, b or c",
 * into out. Returns the length. */
NTS_API int nts_option_names_text(int id, char* out, size_t size);
/** 1 when `v` is in the row's range, else 0. */
NTS_API int nts_option_in_range(int id, double v);

/** Helpers that expand a row by its kind, bound or doors (token pasting), so a
 * generator writes one line for every row.
 * @{ */
#define NTS_OPT_IS_ALL(x) x
#define NTS_OPT_IS_SCENE(x)
#define NTS_OPT_HAS_FIELD_NUMBER(x) x
#define NTS_OPT_HAS_FIELD_ENUM(x) x
#define NTS_OPT_HAS_FIELD_OUTPUTS(x) x
#define NTS_OPT_HAS_FIELD_OBJECT(x)
/** @} */

#ifdef __cplusplus
}
#endif
#endif
