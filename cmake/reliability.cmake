# Reliability: the kidnapped-robot trials (library and the gmm_mcl_kidnap tool). The 7-Scenes
# source needs the replay library (libpng).
add_library(gmm_mcl_reliability STATIC src/reliability/kidnap.cpp)
target_link_libraries(gmm_mcl_reliability PUBLIC gmm_mcl_replay)
add_executable(gmm_mcl_kidnap src/tools/kidnap_main.cpp)
target_link_libraries(gmm_mcl_kidnap PRIVATE gmm_mcl_reliability gmm_mcl_cli)
