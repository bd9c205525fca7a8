# Benchmark tool (both backends; CPU only when GMM_MCL_WITH_CUDA=OFF) and its data helpers.
add_library(gmm_mcl_bench_data STATIC src/bench/frame_set.cpp)
target_include_directories(gmm_mcl_bench_data PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/src)
target_link_libraries(gmm_mcl_bench_data PUBLIC gmm_mcl_datasets)

gmm_mcl_add_tool(gmm_mcl_bench src/tools/bench_main.cpp src/tools/bench_workload.cpp
                 src/tools/bench_step.cpp LIBS gmm_mcl_bench_data gmm_mcl_replay)
