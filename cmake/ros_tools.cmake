# The ROS tools: data-set converters (bags), the ground-truth -> odometry node, offline bag replay
# and evaluation, the soak publisher. Included by CMakeLists.txt when GMM_MCL_BUILD_ROS is ON,
# after cmake/ros.cmake (catkin, messages, gmm_mcl_ros) and the replay library.

# gmm_mcl_ros_tools (src/ros_tools, include/gmm_mcl/ros_tools): bag writing shared by the
# converters and sequence -> bag.
add_library(gmm_mcl_ros_tools STATIC
  src/ros_tools/bag_writer.cpp
  src/ros_tools/sequence_bag.cpp)
target_link_libraries(gmm_mcl_ros_tools PUBLIC gmm_mcl_ros gmm_mcl_replay)

# gmm_mcl_make_bag: 7-Scenes / TUM / Stanford folders or the synthetic scene -> bag.
add_executable(gmm_mcl_make_bag src/ros_tools/make_bag_main.cpp)
# gmm_mcl_make_sim_bag: the built-in synthetic scene as a bag (depth, CameraInfo, IMU, odometry,
# tf, truth) and its map.
add_executable(gmm_mcl_make_sim_bag src/ros_tools/make_sim_bag.cpp)
# gmm_mcl_make_7scenes_bag: a 7-Scenes sequence (and its world-frame map) as such a bag, with
# the accuracy protocol's odometry and attitude noise.
add_executable(gmm_mcl_make_7scenes_bag src/ros_tools/make_7scenes_bag.cpp)
# gmm_mcl_ground_truth_odometry: a ground-truth stream -> noisy odometry, IMU, truth (node).
add_executable(gmm_mcl_ground_truth_odometry src/ros_tools/ground_truth_odometry_node.cpp)
# gmm_mcl_replay_bag: a bag through the core localizer with the rosbag API, no master.
add_executable(gmm_mcl_replay_bag src/ros_tools/replay_bag_main.cpp)
# gmm_mcl_evaluate_pose_bag: a recorded pose bag against ground truth: ATE and a plot (CSV +
# gnuplot/SVG).
add_executable(gmm_mcl_evaluate_pose_bag src/ros_tools/evaluate_pose_bag.cpp)
# gmm_mcl_soak_publisher: the lockstep publisher of looped synthetic frames (docs/soak.md; the
# monitor is scripts/soak_monitor.py, which imports the Python messages: built with it).
add_executable(gmm_mcl_soak_publisher src/ros_tools/soak_publisher.cpp)
add_dependencies(gmm_mcl_soak_publisher ${PROJECT_NAME}_generate_messages)

set(GMM_MCL_ROS_TOOLS gmm_mcl_make_bag gmm_mcl_make_sim_bag gmm_mcl_make_7scenes_bag
    gmm_mcl_ground_truth_odometry gmm_mcl_replay_bag gmm_mcl_evaluate_pose_bag
    gmm_mcl_soak_publisher)
foreach(t ${GMM_MCL_ROS_TOOLS})
  target_link_libraries(${t} PRIVATE gmm_mcl_ros_tools gmm_mcl_cli)
endforeach()
