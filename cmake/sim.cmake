# The tools on the simulator (the gmm_mcl_sim library is in CMakeLists.txt).
# gmm_mcl_sim_demo: the synthetic scene through the localizer, offline; odometry and attitude
# noise from the replay library's OdometrySynthesizer (one implementation of the protocol's noise).
gmm_mcl_add_tool(gmm_mcl_sim_demo src/tools/sim_demo_main.cpp LIBS gmm_mcl_sim gmm_mcl_replay)

# gmm_mcl_render: mesh + trajectory -> TUM RGB-D folder (the data-set library writes the folder).
gmm_mcl_add_tool(gmm_mcl_render src/tools/render_main.cpp LIBS gmm_mcl_replay)
