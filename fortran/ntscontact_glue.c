/* The C side of the Fortran module (fortran/ntscontact.f90): small helpers
 * that Fortran cannot write as plain interfaces to the library.
 *
 * The layout guard: the sizes of the structs
 * that fortran/ntscontact.f90 mirrors as bind(C) derived types, as the C
 * compiler that built the library lays them out. The module compares them
 * with c_sizeof of its own types before it hands C a single pointer
 * (ntsf_layout_ok), so that a Fortran compiler that pads or sizes an enum
 * differently fails with a message instead of corrupting memory. The rows
 * are in the order of ntsf_layout_ok's layout_names. */
#include <stddef.h>
#include <string.h>

#include <ntscontact/ntscontact.h>

size_t ntsf_c_sizeof(int which);
void ntsf_c_copy_string(char* dest, const char* src, size_t n);
int ntsf_c_history_count(const nts_history* history);

size_t ntsf_c_sizeof(int which) {
    static const size_t sizes[] = {
        sizeof(nts_vec2),     sizeof(nts_virial),    sizeof(nts_error),    sizeof(nts_limits),
        sizeof(nts_summary),  sizeof(nts_options),   sizeof(nts_body_def), sizeof(nts_scene_def),
        sizeof(nts_triplets), sizeof(nts_warning),   sizeof(nts_result),   sizeof(nts_csr),
        sizeof(nts_role),     sizeof(nts_solver),    sizeof(nts_candidates_info), sizeof(nts_contact),
    };
    if (which < 0 || (size_t)which >= sizeof sizes / sizeof sizes[0]) return 0;
    return sizes[which];
}

/* n bytes of a C string into a Fortran character variable, as a function
 * with no result, so that the module's text functions can stay pure (an
 * interface to memcpy itself would have to drop its result). */
void ntsf_c_copy_string(char* dest, const char* src, size_t n) {
    memcpy(dest, src, n);
}

/* How many anchors a history holds (0 for NULL), as a function of one
 * argument, so that the module's count can be pure (nts_history_anchors
 * gives it through an out argument, which a pure Fortran function cannot
 * take). */
int ntsf_c_history_count(const nts_history* history) {
    int count = 0;
    if (history != NULL) nts_history_anchors(history, &count);
    return count;
}
