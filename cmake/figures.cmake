# Paper-figure tools (issue 4): Fig. 2 (NLL vs displacement, approximate vs exact) and the
# Sensitivity Analysis (KL-divergence variance vs N and M) as gmm_mcl_figures, plus the tests of
# the figure library and of the plot scripts. Needs no ROS; the component sweep needs the map
# builder (gmm_mcl_fit), 7-Scenes depth needs libpng.
set(GMM_MCL_FIGURES_SOURCES
  src/figures/nll_sweep.cpp
  src/figures/gaussian_kl.cpp
  src/figures/scenario.cpp
  src/figures/sensitivity.cpp
)
if(TARGET gmm_mcl_fit)
  list(APPEND GMM_MCL_FIGURES_SOURCES src/figures/map_series.cpp)
endif()
# The experiments: the paper's figures (src/figures) and the reliability trials (src/reliability:
# kidnapped robot, global localisation), drivers over the core, the data sets and the replay.
add_library(gmm_mcl_experiments STATIC ${GMM_MCL_FIGURES_SOURCES} src/reliability/kidnap.cpp)
target_link_libraries(gmm_mcl_experiments PUBLIC gmm_mcl_replay gmm_mcl_core)
if(TARGET gmm_mcl_fit)
  target_link_libraries(gmm_mcl_experiments PUBLIC gmm_mcl_fit)
  target_compile_definitions(gmm_mcl_experiments PUBLIC GMM_MCL_FIGURES_HAVE_FIT=1)
endif()
target_compile_options(gmm_mcl_experiments PRIVATE -Wall -Wextra)

add_executable(gmm_mcl_figures_tool src/tools/figures_main.cpp)
set_target_properties(gmm_mcl_figures_tool PROPERTIES OUTPUT_NAME gmm_mcl_figures)
target_link_libraries(gmm_mcl_figures_tool PRIVATE gmm_mcl_experiments gmm_mcl_cli)
target_compile_options(gmm_mcl_figures_tool PRIVATE -Wall -Wextra)

if(GMM_MCL_BUILD_TESTS)
  foreach(src test/figures/test_nll_sweep.cpp test/figures/test_gaussian_kl.cpp
              test/figures/test_sensitivity.cpp)
    get_filename_component(name ${src} NAME_WE)
    gmm_mcl_add_gtest(${name} ${src} gmm_mcl_experiments gmm_mcl_test_utils)
  endforeach()
  # The plot scripts on fixture folders they write themselves; exit code 77 = skipped (no
  # /usr/bin/python3 with matplotlib), shown by ctest as a skip.
  set(GMM_MCL_PLOT_PYTHON /usr/bin/python3 CACHE FILEPATH "Python with matplotlib for the plots")
  add_test(NAME test_plot_scripts
           COMMAND ${GMM_MCL_PLOT_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/../test/figures/test_plot_scripts.py
                   ${CMAKE_CURRENT_BINARY_DIR}/figures_plot_test)
  set_tests_properties(test_plot_scripts PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 120)
endif()
