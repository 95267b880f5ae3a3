/* CUnit runner for the core: one suite per concept. Exits non-zero on failure. */
#include <CUnit/Basic.h>
#include <stdio.h>

#include "suites.h"

int main(void) {
    unsigned failed;
    if (CU_initialize_registry() != CUE_SUCCESS) return 2;
    register_geometry_suite();
    register_scene_suite();
    register_contact_suite();
    register_invariants_suite();
    register_search_suite();
    register_hard_cases_suite();
    register_update_suite();
    register_scenes_suite();
    register_stiffness_suite();
    register_alloc_suite();
    register_parallel_suite();
    register_reach_suite();
    register_backend_suite();
    register_contact_memory_suite();
    register_pressure_suite();
    register_surfaces_suite();
    register_friction_suite();
    register_candidates_suite();
    register_self_contact_suite();
    CU_basic_set_mode(CU_BRM_VERBOSE);
    CU_basic_run_tests();
    failed = CU_get_number_of_failures() + CU_get_number_of_tests_failed();
    if (CU_get_error() != CUE_SUCCESS) failed += 1;
    CU_cleanup_registry();
    return failed == 0 ? 0 : 1;
}
