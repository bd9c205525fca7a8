# Reliability (issue #7): kidnapped-robot trials (library, tool and tests), degenerate views and
# numerical safety tests. The 7-Scenes source needs the replay library (libpng).
if(TARGET gmm_mcl_replay)
  add_library(gmm_mcl_reliability STATIC src/reliability/kidnap.cpp)
  target_link_libraries(gmm_mcl_reliability PUBLIC gmm_mcl_replay)
  target_compile_options(gmm_mcl_reliability PRIVATE -Wall -Wextra)
  add_executable(gmm_mcl_kidnap src/tools/kidnap_main.cpp)
  target_link_libraries(gmm_mcl_kidnap PRIVATE gmm_mcl_reliability)
endif()

if(GMM_MCL_BUILD_TESTS)
  add_executable(test_degenerate test/reliability/test_degenerate.cpp)
  target_link_libraries(test_degenerate PRIVATE gmm_mcl_test_utils GTest::gtest_main)
  add_test(NAME test_degenerate COMMAND test_degenerate)
  if(TARGET gmm_mcl_reliability AND TARGET gmm_mcl_fit)
    add_executable(test_kidnap test/reliability/test_kidnap.cpp)
    target_link_libraries(test_kidnap PRIVATE gmm_mcl_reliability gmm_mcl_fit gmm_mcl_test_utils
                          GTest::gtest_main)
    add_test(NAME test_kidnap COMMAND test_kidnap)
    set_tests_properties(test_kidnap PROPERTIES TIMEOUT 1500)
  endif()
endif()
