/* Every CUnit suite of the core registers itself through one function here. */
#ifndef NTS_TEST_SUITES_H
#define NTS_TEST_SUITES_H
void register_geometry_suite(void);
void register_scene_suite(void);
void register_contact_suite(void);
void register_invariants_suite(void);
void register_search_suite(void);
void register_hard_cases_suite(void);
void register_update_suite(void);
void register_scenes_suite(void);
void register_stiffness_suite(void);
void register_alloc_suite(void);
void register_parallel_suite(void);
void register_reach_suite(void);
void register_backend_suite(void);
void register_contact_memory_suite(void);
void register_pressure_suite(void);
void register_surfaces_suite(void);
void register_friction_suite(void);
void register_candidates_suite(void);
void register_self_contact_suite(void);
#endif
