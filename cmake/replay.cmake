# Data sets: the recorded sequences behind one Sequence class (7-Scenes, TUM RGB-D / ICL-NUIM,
# Stanford, the synthetic scene) and the folder writers. Needs no ROS; reading and writing depth
# PNGs needs libpng.
add_library(gmm_mcl_datasets STATIC
  src/datasets/sequence_base.cpp
  src/datasets/seven_scenes_sequence.cpp
  src/datasets/tum_sequence.cpp
  src/datasets/stanford_sequence.cpp
  src/datasets/sim_sequence.cpp
  src/datasets/sequence_writer.cpp
)
target_link_libraries(gmm_mcl_datasets PUBLIC gmm_mcl_sim)
target_compile_options(gmm_mcl_datasets PRIVATE -Wall -Wextra)

# Offline replay: the filter run over a recorded sequence, the protocol's odometry/attitude
# noise, the accuracy protocol, the gmm_mcl_replay tool and their tests.
add_library(gmm_mcl_replay STATIC
  src/replay/odometry_synthesizer.cpp
  src/replay/evaluation.cpp
  src/replay/replay.cpp
)
target_link_libraries(gmm_mcl_replay PUBLIC gmm_mcl_datasets)
target_compile_options(gmm_mcl_replay PRIVATE -Wall -Wextra)
add_executable(gmm_mcl_replay_tool src/tools/replay_main.cpp)
set_target_properties(gmm_mcl_replay_tool PROPERTIES OUTPUT_NAME gmm_mcl_replay)
target_link_libraries(gmm_mcl_replay_tool PRIVATE gmm_mcl_replay gmm_mcl_cli)
add_executable(gmm_mcl_score src/tools/score_main.cpp)
target_link_libraries(gmm_mcl_score PRIVATE gmm_mcl_replay gmm_mcl_cli)

if(GMM_MCL_BUILD_TESTS)
  gmm_mcl_add_gtest(test_evaluation test/replay/test_evaluation.cpp gmm_mcl_replay)
  gmm_mcl_add_gtest(test_odometry_synthesizer test/replay/test_odometry_synthesizer.cpp
                    gmm_mcl_replay)
  if(PNG_FOUND)
    # Readers on fixtures the tests write (TUM, Stanford from the synthetic scene), bad input,
    # and replay over each folder format; 7-Scenes reader checks on the shared data.
    foreach(name test_sequences test_replay_formats)
      gmm_mcl_add_gtest(${name} test/replay/${name}.cpp gmm_mcl_replay gmm_mcl_test_utils)
    endforeach()
    # The tool end to end on a TUM fixture (written by the tool's --write-fixture).
    add_test(NAME test_replay_tool_tum
      COMMAND ${CMAKE_COMMAND} -DTOOL=$<TARGET_FILE:gmm_mcl_replay_tool>
              -DWORK=${CMAKE_CURRENT_BINARY_DIR}/replay_tool_test
              -P ${CMAKE_CURRENT_SOURCE_DIR}/test/replay/replay_tool_test.cmake)
  endif()
  # Needs the map builder (gmm_mcl_fit) and libpng for the depth frames.
  if(TARGET gmm_mcl_fit AND PNG_FOUND)
    gmm_mcl_add_gtest(test_seven_scenes_regression test/replay/test_seven_scenes_regression.cpp
                      gmm_mcl_replay gmm_mcl_fit gmm_mcl_test_utils)
    set_tests_properties(test_seven_scenes_regression PROPERTIES TIMEOUT 1200)
  endif()
endif()
