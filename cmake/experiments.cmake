# Experiments (src/experiments/{figures,reliability}, include/gmm_mcl/experiments): gmm_mcl_experiments
# and its tools. Paper-figure tools: Fig. 2 (NLL vs displacement, approximate vs exact) and the Sensitivity
# Analysis (KL-divergence variance vs N and M) as gmm_mcl_figures. Needs no ROS; the component
# sweep needs the map builder (gmm_mcl_fit), 7-Scenes depth needs libpng.
set(GMM_MCL_FIGURES_SOURCES
  src/experiments/figures/nll_sweep.cpp
  src/experiments/figures/gaussian_kl.cpp
  src/experiments/figures/scenario.cpp
  src/experiments/figures/sensitivity.cpp
)
if(TARGET gmm_mcl_fit)
  list(APPEND GMM_MCL_FIGURES_SOURCES src/experiments/figures/map_series.cpp)
endif()
# The experiments: the paper's figures (src/experiments/figures) and the reliability trials (src/experiments/reliability:
# kidnapped robot, global localisation), drivers over the core, the data sets and the replay.
add_library(gmm_mcl_experiments STATIC ${GMM_MCL_FIGURES_SOURCES} src/experiments/reliability/kidnap.cpp)
target_link_libraries(gmm_mcl_experiments PUBLIC gmm_mcl_replay gmm_mcl_core)
if(TARGET gmm_mcl_fit)
  target_link_libraries(gmm_mcl_experiments PUBLIC gmm_mcl_fit)
  target_compile_definitions(gmm_mcl_experiments PUBLIC GMM_MCL_FIGURES_HAVE_FIT=1)
endif()

gmm_mcl_add_tool(gmm_mcl_figures_tool src/tools/figures_main.cpp OUTPUT_NAME gmm_mcl_figures
                 LIBS gmm_mcl_experiments)
# Reliability: the kidnapped-robot and whole-map trials.
gmm_mcl_add_tool(gmm_mcl_kidnap src/tools/kidnap_main.cpp LIBS gmm_mcl_experiments)
