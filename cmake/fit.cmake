# Map builder: the gmm_mcl_fit library (point-cloud I/O, EM fitter, 7-Scenes stitching, map
# inspection) and the gmm_mcl_fit and gmm_mcl_inspect tools. Needs no ROS.
add_library(gmm_mcl_fit STATIC
  src/fit/point_cloud_io.cpp
  src/fit/cloud_filter.cpp
  src/fit/em_fitter.cpp
  src/fit/em_init.cpp
  src/fit/em_prune_grid.cpp
  src/fit/block_fitter.cpp
  src/fit/seven_scenes_cloud.cpp
  src/fit/map_inspect.cpp
)
# The 7-Scenes cloud reads the sequence through the data-set reader (cmake/datasets.cmake); the PLY
# reader and the mesh type are the simulator's (gmm_mcl_datasets links gmm_mcl_sim).
target_link_libraries(gmm_mcl_fit PUBLIC gmm_mcl_datasets)

# The tool's target has another name than the library's; the program is gmm_mcl_fit.
gmm_mcl_add_tool(gmm_mcl_fit_tool src/tools/gmm_fit_main.cpp OUTPUT_NAME gmm_mcl_fit LIBS gmm_mcl_fit)
gmm_mcl_add_tool(gmm_mcl_inspect src/tools/gmm_inspect_main.cpp LIBS gmm_mcl_fit)
