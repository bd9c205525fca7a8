# Reliability: the kidnapped-robot tool over the trials in gmm_mcl_experiments (cmake/figures.cmake).
gmm_mcl_add_tool(gmm_mcl_kidnap src/tools/kidnap_main.cpp LIBS gmm_mcl_experiments)
