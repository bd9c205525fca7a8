# ROS 1 layer (issue 5): messages, catkin_package(), the localization nodelet and its standalone
# node, the synthetic-bag writer and the rostests. Included by the top-level CMakeLists.txt when
# GMM_MCL_BUILD_ROS is ON, before gmm_mcl_core is defined (target names resolve at generation).
# Nothing here is compiled into the core: the core stays ROS-free.
set(GMM_MCL_ROS_COMPONENTS
  roscpp nodelet pluginlib std_msgs sensor_msgs geometry_msgs nav_msgs std_srvs
  visualization_msgs diagnostic_msgs diagnostic_updater tf2 tf2_ros tf2_eigen tf2_geometry_msgs
  image_transport message_filters dynamic_reconfigure rosbag message_generation)
find_package(catkin REQUIRED COMPONENTS ${GMM_MCL_ROS_COMPONENTS})

add_message_files(DIRECTORY msg FILES FilterStatus.msg)
add_service_files(DIRECTORY srv FILES ResetToPose.srv LoadMap.srv)
generate_messages(DEPENDENCIES std_msgs geometry_msgs)
generate_dynamic_reconfigure_options(cfg/Localizer.cfg)

catkin_package(
  INCLUDE_DIRS include
  LIBRARIES gmm_mcl_core gmm_mcl_ros
  CATKIN_DEPENDS roscpp nodelet std_msgs sensor_msgs geometry_msgs nav_msgs std_srvs
                 visualization_msgs diagnostic_msgs tf2_ros tf2_eigen image_transport message_filters
                 dynamic_reconfigure message_runtime)

# Message conversions and the nodelet (one library: the pluginlib export names it).
add_library(gmm_mcl_ros SHARED
  src/ros/conversions.cpp
  src/ros/compressed_depth.cpp
  src/ros/ros_params.cpp
  src/ros/ros_options_table.cpp
  src/ros/node_status.cpp
  src/ros/step_inputs.cpp
  src/ros/map_markers.cpp
  src/ros/depth_input.cpp
  src/ros/debug_image.cpp
  src/ros/frame_outputs.cpp
  src/ros/localization_nodelet.cpp)
target_include_directories(gmm_mcl_ros PUBLIC
  $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>)
target_include_directories(gmm_mcl_ros SYSTEM PUBLIC ${catkin_INCLUDE_DIRS}
  ${CATKIN_DEVEL_PREFIX}/${CATKIN_GLOBAL_INCLUDE_DESTINATION})
target_link_libraries(gmm_mcl_ros PUBLIC gmm_mcl_core ${catkin_LIBRARIES})
target_compile_options(gmm_mcl_ros PRIVATE -Wall -Wextra)
add_dependencies(gmm_mcl_ros ${PROJECT_NAME}_generate_messages_cpp ${PROJECT_NAME}_gencfg)

# Standalone node: the same nodelet, loaded in-process.
add_executable(gmm_mcl_node src/ros/localization_node.cpp)
target_link_libraries(gmm_mcl_node PRIVATE gmm_mcl_ros)
# Prints what the parameter tables generate (cfg/Localizer.cfg, docs/parameters.md, defaults).
add_executable(gmm_mcl_params src/ros_tools/params_main.cpp)
target_link_libraries(gmm_mcl_params PRIVATE gmm_mcl_ros)
# Writes the built-in synthetic scene as a bag (depth, CameraInfo, IMU, odometry, tf, truth).
add_executable(make_sim_bag src/ros_tools/make_sim_bag.cpp)
target_link_libraries(make_sim_bag PRIVATE gmm_mcl_datasets_ros gmm_mcl_cli)
# Converts a 7-Scenes sequence (and its world-frame map) into such a bag: the data-set library's
# sequence reader (cmake/replay.cmake) and the accuracy protocol's odometry and attitude noise.
add_executable(make_7scenes_bag src/ros_tools/make_7scenes_bag.cpp)
target_link_libraries(make_7scenes_bag PRIVATE gmm_mcl_ros gmm_mcl_replay gmm_mcl_cli)
# Reads a recorded pose bag against ground truth: ATE and a plot (CSV + gnuplot/SVG).
add_executable(evaluate_pose_bag src/ros_tools/evaluate_pose_bag.cpp)
target_link_libraries(evaluate_pose_bag PRIVATE gmm_mcl_ros gmm_mcl_cli)
set_target_properties(gmm_mcl_node gmm_mcl_params make_sim_bag make_7scenes_bag evaluate_pose_bag PROPERTIES
  RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})

install(TARGETS gmm_mcl_ros LIBRARY DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(TARGETS gmm_mcl_node gmm_mcl_params make_sim_bag make_7scenes_bag evaluate_pose_bag
        RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(FILES nodelet_plugins.xml DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
install(DIRECTORY launch config rviz DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})

if(CATKIN_ENABLE_TESTING AND GMM_MCL_BUILD_TESTS)
  find_package(rostest REQUIRED)
  # Conversions, parameters: plain gtest, no master.
  add_executable(test_ros_conversions test/ros/test_conversions.cpp)
  target_link_libraries(test_ros_conversions PRIVATE gmm_mcl_ros gmm_mcl_sim GTest::gtest_main)
  add_test(NAME test_ros_conversions COMMAND test_ros_conversions)
  # The parameter tables against cfg/Localizer.cfg, docs/parameters.md and dynamic_reconfigure;
  # frame accounting, ~status and /diagnostics.
  add_executable(test_ros_params test/ros/test_ros_params.cpp)
  target_link_libraries(test_ros_params PRIVATE gmm_mcl_ros GTest::gtest_main)
  target_compile_definitions(test_ros_params PRIVATE GMM_MCL_SOURCE_DIR="${CMAKE_CURRENT_SOURCE_DIR}")
  add_test(NAME test_ros_params COMMAND test_ros_params)
  add_executable(test_node_status test/ros/test_node_status.cpp)
  target_link_libraries(test_node_status PRIVATE gmm_mcl_ros GTest::gtest_main)
  add_test(NAME test_node_status COMMAND test_node_status)
  # The nodelet library and the core it links hold the localizer only: no simulator (scenes,
  # meshes, BVH, renderer), no data-set reader, map builder or replay code defined in them (< 1 s).
  add_test(NAME test_nodelet_links_no_simulator
    COMMAND bash -c "p=$1; shift; for f; do s=$(nm -C --defined-only \"$f\") || exit 2; \
                     if grep -E \"$p\" <<< \"$s\"; then exit 1; fi; done" nm
            "gmm_mcl::(sim::|[A-Za-z]*Sequence::|fitGmm|runSevenScenesTrial|buildSevenScenesCloud)"
            $<TARGET_FILE:gmm_mcl_ros> $<TARGET_FILE:gmm_mcl_core>)

  # The synthetic bag and map the rostests play (small: 320x240, 240 frames).
  set(GMM_MCL_TEST_BAG ${CMAKE_CURRENT_BINARY_DIR}/ros_test/sim.bag)
  set(GMM_MCL_TEST_MAP ${CMAKE_CURRENT_BINARY_DIR}/ros_test/sim.gmm)
  add_custom_command(OUTPUT ${GMM_MCL_TEST_BAG} ${GMM_MCL_TEST_MAP}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_CURRENT_BINARY_DIR}/ros_test
    COMMAND $<TARGET_FILE:make_sim_bag> --frames 240 --width 320 --seed 3
            --bag ${GMM_MCL_TEST_BAG} --map ${GMM_MCL_TEST_MAP} --quiet
    DEPENDS make_sim_bag
    COMMENT "Writing the synthetic test bag")
  add_custom_target(gmm_mcl_ros_test_data ALL DEPENDS ${GMM_MCL_TEST_BAG} ${GMM_MCL_TEST_MAP})

  # Test nodes (gtest against a live master) and the rostests that launch them.
  foreach(name rostest_localization rostest_bad_inputs rostest_nodelet)
    add_executable(${name} test/ros/${name}.cpp)
    target_link_libraries(${name} PRIVATE gmm_mcl_ros gmm_mcl_sim GTest::gtest)
    set_target_properties(${name} PROPERTIES
      RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
    add_dependencies(${name} gmm_mcl_ros_test_data gmm_mcl_node)
  endforeach()
  # Deterministic on a loaded machine: the tests own /clock and feed the nodelet one frame at a
  # time, waiting for its output (test/ros/lockstep.h).
  foreach(launch localization_bag.test looped_bag.test nodelet.test bad_inputs.test bad_config.test)
    add_rostest(test/ros/${launch}
      ARGS dir:=${CMAKE_CURRENT_BINARY_DIR}/ros_test
      DEPENDENCIES rostest_localization rostest_bad_inputs rostest_nodelet gmm_mcl_ros)
  endforeach()
  # The launch files: documented arguments, a config's values not overridden by the
  # arguments' defaults (config:=tx2.yaml keeps backend: cuda), rviz:=true does not end with
  # the bag.
  add_test(NAME test_launch_files
    COMMAND ${CATKIN_ENV} python3 ${CMAKE_CURRENT_SOURCE_DIR}/test/ros/test_launch_files.py
            ${CMAKE_CURRENT_SOURCE_DIR})
  set_tests_properties(test_launch_files PROPERTIES TIMEOUT 120 LABELS "ros")
endif()
