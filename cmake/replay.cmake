# Offline replay: the filter run over a recorded sequence, the protocol's odometry/attitude
# noise, the accuracy protocol, the gmm_mcl_replay and gmm_mcl_score tools.
add_library(gmm_mcl_replay STATIC
  src/replay/odometry_synthesizer.cpp
  src/replay/evaluation.cpp
  src/replay/replay.cpp
)
target_link_libraries(gmm_mcl_replay PUBLIC gmm_mcl_datasets)
gmm_mcl_add_tool(gmm_mcl_replay_tool src/tools/replay_main.cpp OUTPUT_NAME gmm_mcl_replay
                 LIBS gmm_mcl_replay)
gmm_mcl_add_tool(gmm_mcl_score src/tools/score_main.cpp LIBS gmm_mcl_replay)
