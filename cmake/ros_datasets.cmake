# Data-set converters, the ground-truth -> odometry node and offline bag replay (issue 4, ROS
# side). Included by the top-level CMakeLists.txt when GMM_MCL_BUILD_ROS is ON, after
# cmake/ros.cmake (catkin, messages, gmm_mcl_ros) and after the replay library.

# Bag writing shared by the converters (make_sim_bag can adopt it) and sequence -> bag.
add_library(gmm_mcl_datasets_ros STATIC
  src/ros_tools/bag_writer.cpp
  src/ros_tools/sequence_bag.cpp)
target_link_libraries(gmm_mcl_datasets_ros PUBLIC gmm_mcl_ros gmm_mcl_replay)
target_compile_options(gmm_mcl_datasets_ros PRIVATE -Wall -Wextra)

# gmm_mcl_make_bag: 7-Scenes / TUM / Stanford folders or the synthetic scene -> bag.
add_executable(gmm_mcl_make_bag src/ros_tools/make_bag_main.cpp)
# gmm_mcl_ground_truth_odometry: a ground-truth stream -> noisy odometry, IMU, truth (node).
add_executable(gmm_mcl_ground_truth_odometry src/ros_tools/ground_truth_odometry_node.cpp)
# gmm_mcl_replay_bag: a bag through the core localizer with the rosbag API, no master.
add_executable(gmm_mcl_replay_bag src/ros_tools/replay_bag_main.cpp)
set(GMM_MCL_DATASET_TOOLS gmm_mcl_make_bag gmm_mcl_ground_truth_odometry gmm_mcl_replay_bag)
foreach(t ${GMM_MCL_DATASET_TOOLS})
  target_link_libraries(${t} PRIVATE gmm_mcl_datasets_ros gmm_mcl_cli)
  target_compile_options(${t} PRIVATE -Wall -Wextra)
  set_target_properties(${t} PROPERTIES
    RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
endforeach()
# make_7scenes_bag (cmake/ros.cmake) now writes through the same code.
if(TARGET make_7scenes_bag)
  target_link_libraries(make_7scenes_bag PRIVATE gmm_mcl_datasets_ros)
endif()
install(TARGETS ${GMM_MCL_DATASET_TOOLS} RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING AND GMM_MCL_BUILD_TESTS)
  # Converters without a master: TUM, Stanford (fixtures the test writes), 7-Scenes (shared
  # data, skipped without), the cow_and_lady layout; and the bag replay tool on them.
  add_executable(test_make_bag test/ros/test_make_bag.cpp)
  target_link_libraries(test_make_bag PRIVATE gmm_mcl_datasets_ros gmm_mcl_test_utils
                        GTest::gtest_main)
  target_include_directories(test_make_bag PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test/replay)
  target_compile_definitions(test_make_bag PRIVATE
    GMM_MCL_MAKE_BAG="$<TARGET_FILE:gmm_mcl_make_bag>"
    GMM_MCL_REPLAY_BAG="$<TARGET_FILE:gmm_mcl_replay_bag>")
  add_dependencies(test_make_bag gmm_mcl_make_bag gmm_mcl_replay_bag)
  add_test(NAME test_make_bag COMMAND test_make_bag)

  # The cow_and_lady-layout bag of the rostest: 150 frames (5 s), 160x120 organized clouds,
  # a marker -> camera calibration of 16 cm and 11.5 deg (the same in ground_truth_odometry.test).
  set(GMM_MCL_COW_DIR ${CMAKE_CURRENT_BINARY_DIR}/ros_test_datasets)
  set(GMM_MCL_COW_BAG ${GMM_MCL_COW_DIR}/sim_cow.bag)
  set(GMM_MCL_COW_CALIB "0.1,-0.05,0.12,0,0,0.0998334,0.9950042")
  add_custom_command(OUTPUT ${GMM_MCL_COW_BAG} ${GMM_MCL_COW_DIR}/sim_cow.gmm
    COMMAND ${CMAKE_COMMAND} -E make_directory ${GMM_MCL_COW_DIR}
    COMMAND $<TARGET_FILE:gmm_mcl_make_bag> --format sim ${GMM_MCL_COW_BAG} --frames 150
            --width 160 --seed 4 --layout cow_and_lady --marker-to-camera ${GMM_MCL_COW_CALIB}
            --init-half-extent 0.5 --init-yaw-half-range 0.3 --quiet
    DEPENDS gmm_mcl_make_bag
    COMMENT "Writing the cow_and_lady-layout test bag")
  add_custom_target(gmm_mcl_datasets_test_data ALL DEPENDS ${GMM_MCL_COW_BAG})

  add_executable(rostest_ground_truth_odometry test/ros/rostest_ground_truth_odometry.cpp)
  target_link_libraries(rostest_ground_truth_odometry PRIVATE gmm_mcl_ros GTest::gtest)
  set_target_properties(rostest_ground_truth_odometry PROPERTIES
    RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
  add_dependencies(rostest_ground_truth_odometry gmm_mcl_datasets_test_data
                   gmm_mcl_ground_truth_odometry gmm_mcl_node)
  add_rostest(test/ros/ground_truth_odometry.test
    ARGS dir:=${GMM_MCL_COW_DIR}
    DEPENDENCIES rostest_ground_truth_odometry gmm_mcl_ground_truth_odometry gmm_mcl_ros)
endif()
