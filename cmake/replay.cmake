# Offline replay and evaluation: the data-set readers behind one Sequence interface (7-Scenes,
# TUM RGB-D / ICL-NUIM, Stanford, the synthetic scene), the folder writers, the protocol's
# odometry/attitude noise, the accuracy protocol, and the gmm_mcl_replay and gmm_mcl_score tools.
# Needs no ROS; reading and writing depth PNGs needs libpng.
add_library(gmm_mcl_replay STATIC
  src/replay/sequence_base.cpp
  src/replay/seven_scenes_sequence.cpp
  src/replay/tum_sequence.cpp
  src/replay/stanford_sequence.cpp
  src/replay/sim_sequence.cpp
  src/replay/sequence_writer.cpp
  src/replay/odometry_synthesizer.cpp
  src/replay/evaluation.cpp
  src/replay/replay.cpp
)
target_link_libraries(gmm_mcl_replay PUBLIC gmm_mcl_sim)
add_executable(gmm_mcl_replay_tool src/tools/replay_main.cpp)
set_target_properties(gmm_mcl_replay_tool PROPERTIES OUTPUT_NAME gmm_mcl_replay)
target_link_libraries(gmm_mcl_replay_tool PRIVATE gmm_mcl_replay gmm_mcl_cli)
add_executable(gmm_mcl_score src/tools/score_main.cpp)
target_link_libraries(gmm_mcl_score PRIVATE gmm_mcl_replay gmm_mcl_cli)
