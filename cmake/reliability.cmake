# Reliability: the kidnapped-robot tool over the trials in gmm_mcl_experiments (cmake/figures.cmake).
add_executable(gmm_mcl_kidnap src/tools/kidnap_main.cpp)
target_link_libraries(gmm_mcl_kidnap PRIVATE gmm_mcl_experiments gmm_mcl_cli)
