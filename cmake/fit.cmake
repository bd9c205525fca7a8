# Map builder (issue 3): the gmm_mcl_fit library (point-cloud I/O, EM fitter, 7-Scenes stitching,
# map inspection), the gmm_fit and gmm_inspect tools, and their tests. Included by the top-level
# CMakeLists.txt after gmm_mcl_core is defined; needs no ROS.
add_library(gmm_mcl_fit STATIC
  src/fit/point_cloud_io.cpp
  src/fit/cloud_filter.cpp
  src/fit/em_fitter.cpp
  src/fit/em_init.cpp
  src/fit/em_prune_grid.cpp
  src/fit/seven_scenes_cloud.cpp
  src/fit/map_inspect.cpp
)
# The 7-Scenes cloud reads the sequence through the data-set reader (cmake/replay.cmake); the PLY
# reader and the mesh type are the simulator's (gmm_mcl_datasets links gmm_mcl_sim).
target_link_libraries(gmm_mcl_fit PUBLIC gmm_mcl_datasets)
target_compile_options(gmm_mcl_fit PRIVATE -Wall -Wextra)

add_executable(gmm_fit src/tools/gmm_fit_main.cpp)
target_link_libraries(gmm_fit PRIVATE gmm_mcl_fit gmm_mcl_cli)
add_executable(gmm_inspect src/tools/gmm_inspect_main.cpp)
target_link_libraries(gmm_inspect PRIVATE gmm_mcl_fit gmm_mcl_cli)

if(GMM_MCL_BUILD_TESTS)
  foreach(src test/fit/test_point_cloud_io.cpp test/fit/test_em_fitter.cpp
              test/fit/test_map_inspect.cpp)
    get_filename_component(name ${src} NAME_WE)
    gmm_mcl_add_gtest(${name} ${src} gmm_mcl_fit)
  endforeach()
  # Data-set tests read $GMM_MCL_DATASETS, else ../shared/datasets, and skip when absent.
  target_compile_definitions(test_point_cloud_io PRIVATE
    GMM_MCL_TEST_DATASETS="${CMAKE_CURRENT_SOURCE_DIR}/../shared/datasets")
  # Agreement with scikit-learn (Debian python3-sklearn is the oracle). Exit code 77 = skipped
  # (no /usr/bin/python3 with sklearn), reported by ctest as a skip, not a pass.
  set(GMM_MCL_ORACLE_PYTHON /usr/bin/python3 CACHE FILEPATH
      "Python with numpy and scikit-learn for the map-builder oracle test")
  add_test(NAME test_fit_sklearn_agreement
           COMMAND ${CMAKE_CURRENT_LIST_DIR}/../test/fit/run_sklearn_agreement.sh
                   ${GMM_MCL_ORACLE_PYTHON} $<TARGET_FILE:gmm_fit>
                   ${CMAKE_CURRENT_BINARY_DIR}/fit_sklearn_agreement)
  set_tests_properties(test_fit_sklearn_agreement PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 600)
  # scikit-learn GaussianMixture -> scripts/sklearn_to_gmm_csv.py -> gmm_fit --import.
  add_test(NAME test_sklearn_import
           COMMAND ${GMM_MCL_ORACLE_PYTHON} ${CMAKE_CURRENT_LIST_DIR}/../test/fit/sklearn_import.py
                   $<TARGET_FILE:gmm_fit> $<TARGET_FILE:gmm_inspect>
                   ${CMAKE_CURRENT_BINARY_DIR}/sklearn_import)
  set_tests_properties(test_sklearn_import PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 300)
endif()
