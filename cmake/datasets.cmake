# Data sets: the recorded sequences behind one Sequence class (7-Scenes, TUM RGB-D / ICL-NUIM,
# Stanford, the synthetic scene) and the folder writers. Needs no ROS; reading and writing depth
# PNGs needs libpng.
add_library(gmm_mcl_datasets STATIC
  src/datasets/sequence_base.cpp
  src/datasets/seven_scenes_sequence.cpp
  src/datasets/tum_sequence.cpp
  src/datasets/stanford_sequence.cpp
  src/datasets/sim_sequence.cpp
  src/datasets/sequence_writer.cpp
)
target_link_libraries(gmm_mcl_datasets PUBLIC gmm_mcl_sim)
