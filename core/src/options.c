/* Options with defaults (ntscontact.h) and their validation at the boundary. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

nts_options nts_default_options(void) {
    nts_options o;
    memset(&o, 0, sizeof o);
    o.alpha = 0.2; /* as in Abaqus (docs/model.md §3) */
    o.penalty = 1.0;
    o.search_radius = -1.0; /* the median segment */
    o.solver = NTS_SOLVER_CLOSED_FORM;
    o.outputs = NTS_OUT_FORCES | NTS_OUT_ENERGY | NTS_OUT_VIRIAL;
    o.search = NTS_SEARCH_CELLS;
    o.threads = 0;
    return o;
}

static int option_error(nts_error* err, const char* name, const char* what) {
    nts_where at = nts_at(-1, -1, -1, -1);
    at.option = name;
    return nts_error_set(err, NTS_EINVALID_OPTION, at, "%s %s", name, what);
}

int nts_options_validate(const nts_options* o, nts_error* err) {
    if (o == NULL) return option_error(err, "options", "missing");
    if (!(o->alpha >= 0.0 && o->alpha <= 0.5)) return option_error(err, "alpha", "must be in [0, 0.5]");
    if (!(o->penalty > 0.0) || !nts_is_valid_double(o->penalty))
        return option_error(err, "penalty", "must be a finite number > 0");
    if (!nts_is_valid_double(o->search_radius))
        return option_error(err, "search_radius", "must be finite (negative means the median segment)");
    if (o->solver != NTS_SOLVER_CLOSED_FORM && o->solver != NTS_SOLVER_NEWTON)
        return option_error(err, "solver", "must be closed_form or newton");
    if ((o->outputs & ~(unsigned)NTS_OUT_ALL) != 0u) return option_error(err, "outputs", "has unknown flags");
    if (o->search != NTS_SEARCH_CELLS && o->search != NTS_SEARCH_BRUTE_FORCE)
        return option_error(err, "search", "must be cells or brute_force");
    if (o->threads < 0 || o->threads > 1024) return option_error(err, "threads", "must be in [0, 1024]");
    if (o->max_candidates < 0) return option_error(err, "max_candidates", "must be >= 0 (0: the default)");
    if (o->penalty_scaling != NTS_PENALTY_PER_NODE && o->penalty_scaling != NTS_PENALTY_PER_LENGTH)
        return option_error(err, "penalty_scaling", "must be node or length");
    return NTS_OK;
}
