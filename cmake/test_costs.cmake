# ctest -j2 (scripts/test.sh) starts the tests with the highest COST first; a clean clone has no
# timing history, so the long ones are named here (seconds on this 2-core machine, loaded).
# Included last by test/CMakeLists.txt, after every add_test (a test's properties can only be
# set in the folder that registers it).
set(_gmm_mcl_long_tests
  test_kidnap 220 test_unseen_scene 150 test_seven_scenes_regression 130 test_localizer 60
  test_localizer_no_odometry 50
  test_degenerate 15 test_sensitivity 12 test_replay_tool_tum 11 test_make_bag 11)
if(GMM_MCL_SANITIZE)  # under ASan and UBSan (scripts/test.sh's sanitizer stage)
  list(APPEND _gmm_mcl_long_tests test_pose_refinement 95 test_membership 65)
endif()
list(LENGTH _gmm_mcl_long_tests _n)
math(EXPR _last "${_n} - 1")
foreach(_i RANGE 0 ${_last} 2)
  math(EXPR _j "${_i} + 1")
  list(GET _gmm_mcl_long_tests ${_i} _test)
  list(GET _gmm_mcl_long_tests ${_j} _cost)
  if(TEST ${_test})
    set_tests_properties(${_test} PROPERTIES COST ${_cost})
  endif()
endforeach()
