# Map builder: the gmm_mcl_fit library (point-cloud I/O, EM fitter, 7-Scenes stitching, map
# inspection, the fit of a cloud given as the map and its cache) and the gmm_mcl_fit,
# gmm_mcl_inspect and gmm_mcl_load_map tools. Needs no ROS; the nodelet links it for clouds
# given as ~map (cmake/ros.cmake).
add_library(gmm_mcl_fit STATIC
  src/fit/point_cloud_io.cpp
  src/fit/cloud_filter.cpp
  src/fit/em_fitter.cpp
  src/fit/em_init.cpp
  src/fit/em_prune_grid.cpp
  src/fit/block_fitter.cpp
  src/fit/seven_scenes_cloud.cpp
  src/fit/map_inspect.cpp
  src/fit/fit_on_load.cpp
)
# The 7-Scenes cloud reads the sequence through the data-set reader (cmake/datasets.cmake); the PLY
# reader and the mesh type are the simulator's (gmm_mcl_datasets links gmm_mcl_sim).
target_link_libraries(gmm_mcl_fit PUBLIC gmm_mcl_datasets)

# The tool's target has another name than the library's; the program is gmm_mcl_fit.
gmm_mcl_add_tool(gmm_mcl_fit_tool src/tools/gmm_fit_main.cpp OUTPUT_NAME gmm_mcl_fit LIBS gmm_mcl_fit)
gmm_mcl_add_tool(gmm_mcl_inspect src/tools/gmm_inspect_main.cpp LIBS gmm_mcl_fit)
gmm_mcl_add_tool(gmm_mcl_load_map src/tools/load_map_main.cpp LIBS gmm_mcl_fit)
