# Reliability (issue #7): kidnapped-robot trials (library, tool and tests), degenerate views and
# numerical safety tests. The 7-Scenes source needs the data-set library (libpng).
# The trials are in gmm_mcl_experiments (cmake/figures.cmake).
if(TARGET gmm_mcl_experiments)
  add_executable(gmm_mcl_kidnap src/tools/kidnap_main.cpp)
  target_link_libraries(gmm_mcl_kidnap PRIVATE gmm_mcl_experiments gmm_mcl_cli)
endif()

if(GMM_MCL_BUILD_TESTS)
  gmm_mcl_add_gtest(test_degenerate test/reliability/test_degenerate.cpp gmm_mcl_test_utils)
  if(TARGET gmm_mcl_experiments AND TARGET gmm_mcl_fit)
    gmm_mcl_add_gtest(test_kidnap test/reliability/test_kidnap.cpp gmm_mcl_experiments gmm_mcl_fit
                      gmm_mcl_test_utils)
    set_tests_properties(test_kidnap PROPERTIES TIMEOUT 1500)
  endif()
  # The unseen-scene evaluation, shortened (test/replay/unseen_scene_test.sh; skips without data).
  if(TARGET gmm_mcl_kidnap AND TARGET gmm_mcl_render AND TARGET gmm_fit)
    add_test(NAME test_unseen_scene
             COMMAND ${CMAKE_CURRENT_LIST_DIR}/../test/replay/unseen_scene_test.sh
                     ${CMAKE_CURRENT_BINARY_DIR}/unseen_scene $<TARGET_FILE:gmm_fit>
                     $<TARGET_FILE:gmm_mcl_render> $<TARGET_FILE:gmm_mcl_replay_tool>
                     $<TARGET_FILE:gmm_mcl_kidnap>)
    set_tests_properties(test_unseen_scene PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 1200)
  endif()
endif()
