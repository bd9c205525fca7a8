# Offline replay and evaluation (issue 4): the 7-Scenes sequence reader, the accuracy protocol,
# the gmm_mcl_replay tool and their tests. Needs no ROS; reading depth PNGs needs libpng.
add_library(gmm_mcl_replay STATIC
  src/replay/seven_scenes_sequence.cpp
  src/replay/evaluation.cpp
  src/replay/replay.cpp
)
target_link_libraries(gmm_mcl_replay PUBLIC gmm_mcl_core)
target_compile_options(gmm_mcl_replay PRIVATE -Wall -Wextra)
add_executable(gmm_mcl_replay_tool src/tools/replay_main.cpp)
set_target_properties(gmm_mcl_replay_tool PROPERTIES OUTPUT_NAME gmm_mcl_replay)
target_link_libraries(gmm_mcl_replay_tool PRIVATE gmm_mcl_replay)

if(GMM_MCL_BUILD_TESTS)
  enable_testing()
  if(NOT TARGET GTest::gtest)
    include(${CMAKE_CURRENT_LIST_DIR}/gtest.cmake)
  endif()
  add_executable(test_evaluation test/replay/test_evaluation.cpp)
  target_link_libraries(test_evaluation PRIVATE gmm_mcl_replay GTest::gtest_main)
  add_test(NAME test_evaluation COMMAND test_evaluation)
  # Needs the map builder (gmm_mcl_fit) and libpng for the depth frames.
  if(TARGET gmm_mcl_fit AND PNG_FOUND)
    add_executable(test_seven_scenes_regression test/replay/test_seven_scenes_regression.cpp)
    target_link_libraries(test_seven_scenes_regression PRIVATE gmm_mcl_replay gmm_mcl_fit
                          gmm_mcl_test_utils GTest::gtest_main)
    add_test(NAME test_seven_scenes_regression COMMAND test_seven_scenes_regression)
    set_tests_properties(test_seven_scenes_regression PROPERTIES TIMEOUT 1200)
  endif()
endif()
