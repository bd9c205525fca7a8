# The tools on the simulator (gmm_mcl_sim and its tests are in the top-level CMakeLists.txt).
# The offline demo (defined in the top CMakeLists) draws odometry and attitude noise from the
# replay library's OdometrySynthesizer (one implementation of the protocol's noise).
target_link_libraries(gmm_mcl_sim_demo PRIVATE gmm_mcl_replay)

# gmm_mcl_render: mesh + trajectory -> TUM RGB-D folder (the data-set library writes the folder).
if(TARGET gmm_mcl_replay)
  add_executable(gmm_mcl_render src/tools/render_main.cpp)
  target_link_libraries(gmm_mcl_render PRIVATE gmm_mcl_replay gmm_mcl_cli)
  target_compile_options(gmm_mcl_render PRIVATE -Wall -Wextra)
endif()
