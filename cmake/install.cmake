# The install space (cmake --install, or a catkin/bloom package): everything that a deployment
# from it runs. Included by the top-level CMakeLists.txt last, when GMM_MCL_BUILD_ROS is ON
# (the core library and the tools are defined by then). The nodelet library, its tools, launch
# files and configs are installed by cmake/ros.cmake; this adds the core library they link,
# the public headers, the offline tools and the plot scripts.
install(TARGETS gmm_mcl_core
        LIBRARY DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION}
        ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(DIRECTORY include/gmm_mcl/ DESTINATION ${CATKIN_PACKAGE_INCLUDE_DESTINATION})
set(GMM_MCL_INSTALLED_TOOLS gmm_fit gmm_inspect gmm_mcl_replay_tool gmm_mcl_bench gmm_mcl_score
    gmm_mcl_kidnap gmm_mcl_render gmm_mcl_sim_demo)
foreach(tool ${GMM_MCL_INSTALLED_TOOLS})
  if(TARGET ${tool})
    install(TARGETS ${tool} RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
  endif()
endforeach()
install(PROGRAMS scripts/plot_replay.py scripts/plot_figures.py scripts/sklearn_to_gmm_csv.py
                 scripts/restore_wall_time.py
        DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(FILES scripts/sklearn_common.py DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING AND GMM_MCL_BUILD_TESTS)
  # Installs the package into a temporary prefix and runs it from there alone (a fresh shell
  # that sources only the install space): the nodelet loads in a manager and answers its
  # services, the tools and Python messages resolve, replay.launch leaves /use_sim_time unset.
  add_test(NAME ros_install_space
    COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test/ros/install_space_test.sh ${CMAKE_BINARY_DIR}
            ${CMAKE_BINARY_DIR}/ros_test/sim.gmm)
  set_tests_properties(ros_install_space PROPERTIES TIMEOUT 300 LABELS "ros")
endif()
