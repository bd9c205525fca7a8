# ROS 1 layer: messages, catkin_package(), the localization nodelet, its standalone node and the
# parameter printer. Included by CMakeLists.txt when GMM_MCL_BUILD_ROS is ON, before any target
# (catkin_package() sets the output folders). Nothing here is compiled into the core: the core
# stays ROS-free. The ROS tools are in cmake/ros_tools.cmake, the rostests in test/CMakeLists.txt.
set(GMM_MCL_ROS_COMPONENTS
  roscpp nodelet pluginlib std_msgs sensor_msgs geometry_msgs nav_msgs std_srvs
  visualization_msgs diagnostic_msgs diagnostic_updater tf2 tf2_ros tf2_eigen tf2_geometry_msgs
  image_transport message_filters dynamic_reconfigure rosbag message_generation)
find_package(catkin REQUIRED COMPONENTS ${GMM_MCL_ROS_COMPONENTS})

add_message_files(DIRECTORY msg FILES FilterStatus.msg CameraStatus.msg)
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
  src/ros/frame_sets.cpp
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
# A point cloud or mesh given as ~map is fitted on load by the map builder's library
# (fit/fit_on_load.h; static, so its code is inside the nodelet's library). Without the map
# builder (GMM_MCL_BUILD_FIT=OFF) such a map is refused with a message naming gmm_mcl_fit.
if(GMM_MCL_BUILD_FIT)
  target_link_libraries(gmm_mcl_ros PRIVATE gmm_mcl_fit)
  target_compile_definitions(gmm_mcl_ros PRIVATE GMM_MCL_HAVE_FIT_ON_LOAD)
endif()
add_dependencies(gmm_mcl_ros ${PROJECT_NAME}_generate_messages_cpp ${PROJECT_NAME}_gencfg)

# Standalone node: the same nodelet, loaded in-process.
add_executable(gmm_mcl_node src/ros/localization_node.cpp)
target_link_libraries(gmm_mcl_node PRIVATE gmm_mcl_ros)
# Prints what the parameter tables generate (cfg/Localizer.cfg, docs/parameters.md, defaults).
add_executable(gmm_mcl_params src/ros_tools/params_main.cpp)
target_link_libraries(gmm_mcl_params PRIVATE gmm_mcl_ros)
set_target_properties(gmm_mcl_node gmm_mcl_params PROPERTIES
  RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
