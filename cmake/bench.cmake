# Benchmark (src/bench): the frame sets it measures on (gmm_mcl_bench_data, header
# include/gmm_mcl/bench; the CUDA parity tests read them too) and the gmm_mcl_bench tool (both
# backends; CPU only when GMM_MCL_WITH_CUDA=OFF).
add_library(gmm_mcl_bench_data STATIC src/bench/frame_set.cpp)
target_link_libraries(gmm_mcl_bench_data PUBLIC gmm_mcl_datasets)

gmm_mcl_add_tool(gmm_mcl_bench src/bench/bench_main.cpp src/bench/bench_workload.cpp
                 src/bench/bench_step.cpp LIBS gmm_mcl_bench_data gmm_mcl_replay)
