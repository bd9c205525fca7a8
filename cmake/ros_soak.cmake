# Soak test (issue 7): the lockstep publisher of looped synthetic frames; the monitor is
# scripts/soak_monitor.py and the driver scripts/soak.sh (docs/soak.md). Included by the
# top-level CMakeLists.txt when GMM_MCL_BUILD_ROS is ON, after cmake/ros.cmake (catkin,
# messages, gmm_mcl_ros).
add_executable(gmm_mcl_soak_publisher src/ros_tools/soak_publisher.cpp)
target_link_libraries(gmm_mcl_soak_publisher PRIVATE gmm_mcl_datasets_ros gmm_mcl_cli)
target_compile_options(gmm_mcl_soak_publisher PRIVATE -Wall -Wextra)
# The monitor imports the Python messages (FilterStatus): build them with the publisher.
add_dependencies(gmm_mcl_soak_publisher ${PROJECT_NAME}_generate_messages)
set_target_properties(gmm_mcl_soak_publisher PROPERTIES
  RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
install(TARGETS gmm_mcl_soak_publisher RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(PROGRAMS scripts/soak_monitor.py DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING AND GMM_MCL_BUILD_TESTS)
  # Short soak in CI: 2,000 frames through the nodelet in its manager (own roscore on a free
  # port): every frame accounted for, no gap in map -> odom, no NaN. RSS growth is printed but
  # not checked at this length (warm-up effects dominate; the 50,000-frame run checks it).
  add_test(NAME soak_short
    COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/scripts/soak.sh --frames 2000 --warmup 500
            --no-rss-check --no-build --build ${CMAKE_BINARY_DIR}
            --out ${CMAKE_BINARY_DIR}/soak_short)
  set_tests_properties(soak_short PROPERTIES TIMEOUT 300 LABELS "ros;soak")
endif()
