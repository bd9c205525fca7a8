# Simulator (not the localizer's: the nodelet links none of it): gmm_mcl_sim from src/sim.
# Synthetic scenes and rendering: the analytic box scene, triangle meshes and the PLY reader,
# the BVH ray caster, the depth renderer with the structured-light sensor model, the procedural
# mesh scene, the procedural building world and walks through it, trajectories. Tests, tools and
# the synthetic data sets build on it.
add_library(gmm_mcl_sim STATIC
  src/sim/box_scene.cpp
  src/sim/mesh.cpp
  src/sim/ply_reader.cpp
  src/sim/mesh_bvh.cpp
  src/sim/sensor_noise.cpp
  src/sim/mesh_renderer.cpp
  src/sim/trajectory_io.cpp
  src/sim/mesh_scene.cpp
  src/sim/pose_scatter.cpp
  src/sim/building_scene.cpp
  src/sim/building_walk.cpp
)
target_link_libraries(gmm_mcl_sim PUBLIC gmm_mcl_core)
target_compile_options(gmm_mcl_sim PRIVATE -fno-trapping-math -fno-math-errno)

# The tools on the simulator.
# gmm_mcl_sim_demo: the synthetic scene through the localizer, offline; odometry and attitude
# noise from the replay library's OdometrySynthesizer (one implementation of the protocol's noise).
gmm_mcl_add_tool(gmm_mcl_sim_demo src/tools/sim_demo_main.cpp LIBS gmm_mcl_sim gmm_mcl_replay)

# gmm_mcl_render: mesh + trajectory -> TUM RGB-D folder (the data-set library writes the folder).
gmm_mcl_add_tool(gmm_mcl_render src/tools/render_main.cpp LIBS gmm_mcl_replay)
