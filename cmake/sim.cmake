# Synthetic scenes and rendering (issue 4): triangle meshes and the PLY reader, the BVH ray
# caster, the depth renderer with the structured-light sensor model, the procedural mesh scene,
# trajectories and noisy odometry/attitude; the gmm_mcl_render tool and the tests. Part of the
# core library (no ROS, no external ray tracer).
target_sources(gmm_mcl_core PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/mesh.cpp
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/mesh_bvh.cpp
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/sensor_noise.cpp
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/mesh_renderer.cpp
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/trajectory_io.cpp
  ${CMAKE_CURRENT_LIST_DIR}/../src/sim/mesh_scene.cpp
)

if(GMM_MCL_BUILD_TESTS)
  set(GMM_MCL_SIM_TESTS
    test/sim/test_mesh.cpp
    test/sim/test_mesh_bvh.cpp
    test/sim/test_sensor_noise.cpp
    test/sim/test_replica_render.cpp
  )
  foreach(src ${GMM_MCL_SIM_TESTS})
    get_filename_component(name ${src} NAME_WE)
    add_executable(${name} ${src})
    target_link_libraries(${name} PRIVATE gmm_mcl_test_utils GTest::gtest_main)
    add_test(NAME ${name} COMMAND ${name})
  endforeach()
endif()

# The offline demo (defined in the top CMakeLists) draws odometry and attitude noise from the
# replay library's OdometrySynthesizer (one implementation of the protocol's noise).
target_link_libraries(gmm_mcl_sim_demo PRIVATE gmm_mcl_replay)
if(TARGET make_sim_bag)
  target_link_libraries(make_sim_bag PRIVATE gmm_mcl_replay)
endif()

# gmm_mcl_render: mesh + trajectory -> TUM RGB-D folder (the replay library writes the folder).
if(TARGET gmm_mcl_replay)
  add_executable(gmm_mcl_render src/tools/render_main.cpp)
  target_link_libraries(gmm_mcl_render PRIVATE gmm_mcl_replay gmm_mcl_cli)
  target_compile_options(gmm_mcl_render PRIVATE -Wall -Wextra)
endif()
