# The install space (cmake --install, or a catkin/bloom package): everything that a deployment
# from it runs. Included by CMakeLists.txt after every library and tool is defined.
#   ROS build: catkin's folders (lib/gmm_mcl for the programs, rosrun finds them there);
#   without ROS: bin/, lib/, include/ under CMAKE_INSTALL_PREFIX.
if(GMM_MCL_BUILD_ROS)
  set(GMM_MCL_INSTALL_BIN ${CATKIN_PACKAGE_BIN_DESTINATION})
  set(GMM_MCL_INSTALL_LIB ${CATKIN_PACKAGE_LIB_DESTINATION})
  set(GMM_MCL_INSTALL_INCLUDE ${CATKIN_PACKAGE_INCLUDE_DESTINATION})
else()
  include(GNUInstallDirs)
  set(GMM_MCL_INSTALL_BIN ${CMAKE_INSTALL_BINDIR})
  set(GMM_MCL_INSTALL_LIB ${CMAKE_INSTALL_LIBDIR})
  set(GMM_MCL_INSTALL_INCLUDE ${CMAKE_INSTALL_INCLUDEDIR}/gmm_mcl)
endif()

install(TARGETS gmm_mcl_core
        LIBRARY DESTINATION ${GMM_MCL_INSTALL_LIB}
        ARCHIVE DESTINATION ${GMM_MCL_INSTALL_LIB})
# The API's headers (docs/architecture.md "API"): the umbrella gmm_mcl.h and the core's parts,
# with ROS the nodelet's. Not internal/ (the core's private helpers, included by its sources
# only) nor the headers of the static libraries that are not installed (sim, datasets, fit,
# replay, bench, experiments, cli, ros_tools); the CUDA parts' headers are beside their sources.
install(FILES include/gmm_mcl/gmm_mcl.h DESTINATION ${GMM_MCL_INSTALL_INCLUDE})
foreach(part map camera measurement backend filter common)
  install(DIRECTORY include/gmm_mcl/${part} DESTINATION ${GMM_MCL_INSTALL_INCLUDE})
endforeach()
if(GMM_MCL_BUILD_ROS)
  install(DIRECTORY include/gmm_mcl/ros DESTINATION ${GMM_MCL_INSTALL_INCLUDE})
endif()

# The offline tools (those this configuration defines: the map builder may be off; without
# boost program_options none is built, and none is installed).
if(TARGET gmm_mcl_cli)
  set(GMM_MCL_INSTALLED_TOOLS gmm_mcl_fit_tool gmm_mcl_inspect gmm_mcl_load_map gmm_mcl_replay_tool
      gmm_mcl_score gmm_mcl_bench gmm_mcl_kidnap gmm_mcl_render gmm_mcl_sim_demo gmm_mcl_figures_tool)
  foreach(tool ${GMM_MCL_INSTALLED_TOOLS})
    if(TARGET ${tool})
      install(TARGETS ${tool} RUNTIME DESTINATION ${GMM_MCL_INSTALL_BIN})
    endif()
  endforeach()
endif()
install(PROGRAMS scripts/plot_replay.py scripts/plot_figures.py scripts/sklearn_to_gmm_csv.py
                 scripts/restore_wall_time.py
        DESTINATION ${GMM_MCL_INSTALL_BIN})
install(FILES scripts/sklearn_common.py scripts/plot_common.py DESTINATION ${GMM_MCL_INSTALL_BIN})

# The nodelet (the pluginlib export names its library), its node, the ROS tools, the soak
# monitor, launch files, configs and rviz layouts.
if(GMM_MCL_BUILD_ROS)
  install(TARGETS gmm_mcl_ros LIBRARY DESTINATION ${GMM_MCL_INSTALL_LIB})
  install(TARGETS gmm_mcl_node gmm_mcl_params ${GMM_MCL_ROS_TOOLS}
          RUNTIME DESTINATION ${GMM_MCL_INSTALL_BIN})
  install(PROGRAMS scripts/soak_monitor.py DESTINATION ${GMM_MCL_INSTALL_BIN})
  install(FILES nodelet_plugins.xml DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
  install(DIRECTORY launch config rviz DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
endif()
