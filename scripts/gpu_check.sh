#!/usr/bin/env bash
# On a machine with a CUDA GPU and no ROS: builds the ROS-free part with the CUDA backend, runs
# the CPU-vs-CUDA parity tests, compute-sanitizer (memcheck, racecheck) on them, and the
# benchmark. Logs go to $OUT (default build-gpu/logs).
#
#   scripts/gpu_check.sh            # everything
#   GPU_CHECK_STEPS="build test bench" scripts/gpu_check.sh
#   GPU_CHECK_STEPS="build ncu" scripts/gpu_check.sh   # Nsight Compute counters of the kernels
#
# Inputs (optional, else the synthetic scene): $GMM_MCL_MAP (7-Scenes M=1000 map),
# $GMM_MCL_LARGE_MAP (the M=4000 map of the `large` workload) and $GMM_MCL_7SCENES_FRAMES (raw
# frames from `gmm_mcl_bench --export-frames`); by default the files
# .deps/7scenes_redkitchen_m1000.gmm, .deps/7scenes_redkitchen_m4000.gmm and
# .deps/7scenes_frames30.bin when present. Eigen and googletest are taken from .deps/eigen3 and
# .deps/googletest when the system has none, boost::program_options from .deps/boost whenever it
# is there (scripts/gpu_deps.sh puts them and those inputs there). Prebuilt binaries: GMM_MCL_GPU_BUILD_DIR=DIR and
# the steps without `build`.
set -uo pipefail
source "$(dirname "$0")/gpu_common.sh"
cd "$ROOT"
gpu_build_dirs
STEPS="${GPU_CHECK_STEPS:-build test memcheck racecheck bench}"
JOBS="${JOBS:-$(nproc)}"
mkdir -p "$BUILD" "$LOGS"
status=0

nvidia-smi --query-gpu=name,compute_cap,driver_version,clocks.max.sm --format=csv 2>&1 | tee "$LOGS/gpu.txt"
ARCH="${CUDA_ARCH:-$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d ' .')}"
ARCH="${ARCH:-75}"
[[ -z "${GMM_MCL_MAP:-}" && -f .deps/7scenes_redkitchen_m1000.gmm ]] && export GMM_MCL_MAP="$ROOT/.deps/7scenes_redkitchen_m1000.gmm"
[[ -z "${GMM_MCL_LARGE_MAP:-}" && -f .deps/7scenes_redkitchen_m4000.gmm ]] && export GMM_MCL_LARGE_MAP="$ROOT/.deps/7scenes_redkitchen_m4000.gmm"
[[ -z "${GMM_MCL_7SCENES_FRAMES:-}" && -f .deps/7scenes_frames30.bin ]] && export GMM_MCL_7SCENES_FRAMES="$ROOT/.deps/7scenes_frames30.bin"

if step build; then
  extra=()
  [[ -d .deps/eigen3 && ! -d /usr/include/eigen3 ]] && extra+=(-DGMM_MCL_EIGEN_DIR="$ROOT/.deps/eigen3")
  [[ -d .deps/googletest && ! -d /usr/src/googletest ]] && extra+=(-DGMM_MCL_GTEST_SRC="$ROOT/.deps/googletest")
  # Boost: a system may have the headers and not the library (the H100 machine); a carried copy
  # is always used.
  [[ -d .deps/boost ]] && extra+=(-DGMM_MCL_BOOST_DIR="$ROOT/.deps/boost")
  [[ -d .deps/png && ! -f /usr/include/png.h ]] && extra+=(-DPNG_PNG_INCLUDE_DIR="$ROOT/.deps/png/include" \
    -DPNG_LIBRARY="$ROOT/.deps/png/lib/libpng16.so" -DZLIB_INCLUDE_DIR="$ROOT/.deps/png/include" \
    -DZLIB_LIBRARY="$ROOT/.deps/png/lib/libz.so")
  cmake -S "$ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_WITH_CUDA=ON -DGMM_MCL_BUILD_FIT=OFF \
    -DCMAKE_CUDA_ARCHITECTURES="$ARCH" -DCMAKE_BUILD_TYPE=Release "${extra[@]}" > "$LOGS/cmake.log" 2>&1 \
    || { cat "$LOGS/cmake.log"; exit 1; }
  start=$(date +%s)
  cmake --build "$BUILD" -j"$JOBS" --target ${GPU_CHECK_TARGETS:-test_cuda_backend gmm_mcl_bench} \
    > "$LOGS/build.log" 2>&1 || { tail -50 "$LOGS/build.log"; exit 1; }
  echo "== build (sm_$ARCH) took $(( $(date +%s) - start )) s"
fi

if step test; then
  echo "== parity tests"
  "$BUILD/test_cuda_backend" 2>&1 | tee "$LOGS/test_cuda_backend.log" | grep -E "measured|OK|FAIL|SKIP|PASSED|Failure|error" || true
  [[ ${PIPESTATUS[0]} -eq 0 ]] || { echo "parity tests FAILED"; status=1; }
fi

SAN_FILTER="${SAN_FILTER:-CudaBackendTest.SyntheticSceneMatchesCpu:CudaBackendTest.GpuFramePreparationMatchesHost:CudaBackendTest.EmptyAndDegenerateInputs}"
for tool in memcheck racecheck; do
  step $tool || continue
  echo "== compute-sanitizer --tool $tool"
  start=$(date +%s)
  compute-sanitizer --tool $tool --error-exitcode 9 "$BUILD/test_cuda_backend" \
    --gtest_filter="$SAN_FILTER" > "$LOGS/sanitizer_$tool.log" 2>&1
  rc=$?
  grep -E "ERROR SUMMARY|RACECHECK SUMMARY|PASSED|FAILED|Skipped" "$LOGS/sanitizer_$tool.log" | head -5
  echo "   rc=$rc, $(( $(date +%s) - start )) s"
  [[ $rc -eq 0 ]] || status=1
done

if step ncu; then
  # Hardware counters of every kernel of one update per workload (NCU_WORKLOADS; NCU_COUNT
  # launches after the first NCU_SKIP, i.e. after the warm-up), Nsight Compute's raw page:
  # duration, registers, issue activity, warps active, threads per instruction, DRAM and L2
  # traffic, shared-memory bank conflicts, the FP32 instructions actually executed
  # (ncu_flops.txt: the measured FP32 FLOP rate, FFMA counting 2), the warp instructions per pipe
  # and the pipes' utilisation (scripts/jetson_projection.py projects each kernel to the Jetsons
  # from these). Counters the profiler does not know on this chip are left out and listed in
  # ncu_dropped.txt. NCU_BENCH_ARGS: more gmm_mcl_bench options (--no-depth-noise).
  metrics=(gpu__time_duration.sum sm__inst_executed.sum smsp__inst_executed.sum
    smsp__issue_active.avg.pct_of_peak_sustained_active sm__warps_active.avg.pct_of_peak_sustained_active
    smsp__thread_inst_executed_per_inst_executed.ratio sm__sass_thread_inst_executed_op_ffma_pred_on.sum
    sm__sass_thread_inst_executed_op_fadd_pred_on.sum sm__sass_thread_inst_executed_op_fmul_pred_on.sum
    sm__cycles_elapsed.avg.per_second sm__cycles_elapsed.max dram__bytes_read.sum dram__bytes_write.sum
    lts__t_bytes.sum launch__registers_per_thread launch__grid_size launch__block_size
    launch__shared_mem_per_block_static launch__shared_mem_per_block_dynamic
    l1tex__data_bank_conflicts_pipe_lsu_mem_shared.sum device__attribute_multiprocessor_count
    dram__throughput.avg.pct_of_peak_sustained_elapsed)
  for p in fma fmaheavy alu xu lsu fp16 adu cbu uniform; do
    metrics+=(smsp__inst_executed_pipe_$p.sum sm__inst_executed_pipe_$p.avg.pct_of_peak_sustained_active)
  done
  metrics+=(sm__pipe_fma_cycles_active.avg.pct_of_peak_sustained_active
    sm__pipe_alu_cycles_active.avg.pct_of_peak_sustained_active
    sm__pipe_shared_cycles_active.avg.pct_of_peak_sustained_active)
  ncu --query-metrics > "$LOGS/ncu_query.txt" 2>&1
  keep=() ; : > "$LOGS/ncu_dropped.txt"
  for m in "${metrics[@]}"; do
    # launch__ and device__ attributes are not listed by --query-metrics but always known.
    if [[ $m == launch__* || $m == device__* ]] || grep -q "^${m%%.*} " "$LOGS/ncu_query.txt"; then
      keep+=("$m")
    else
      echo "$m" >> "$LOGS/ncu_dropped.txt"
    fi
  done
  [[ -s "$LOGS/ncu_dropped.txt" ]] && echo "counters not on this chip: $(tr '\n' ' ' < "$LOGS/ncu_dropped.txt")"
  list=$(IFS=,; echo "${keep[*]}")
  : > "$LOGS/ncu_flops.txt"
  for wl in ${NCU_WORKLOADS:-paper cpu full scale large}; do
    echo "== ncu ($wl)"
    args=(--backend cuda --workload "$wl" --frames 6 --warmup 3 --min-timed 1 --exact 0 ${NCU_BENCH_ARGS:-})
    [[ -n "${GMM_MCL_MAP:-}" ]] && args+=(--map "$GMM_MCL_MAP")
    [[ -n "${GMM_MCL_LARGE_MAP:-}" ]] && args+=(--large-map "$GMM_MCL_LARGE_MAP")
    [[ -n "${GMM_MCL_7SCENES_FRAMES:-}" ]] && args+=(--frames-raw "$GMM_MCL_7SCENES_FRAMES")
    timeout 300 ncu --clock-control none --kernel-name regex:Kernel --launch-skip "${NCU_SKIP:-24}" \
      --launch-count "${NCU_COUNT:-16}" --metrics "$list" --page raw --csv "$BUILD/gmm_mcl_bench" "${args[@]}" \
      > "$LOGS/ncu_$wl.csv" 2> "$LOGS/ncu_$wl.err" || { echo "ncu failed"; tail -5 "$LOGS/ncu_$wl.err"; }
    python3 "$ROOT/scripts/jetson_projection.py" --flops "$LOGS/ncu_$wl.csv" | tee -a "$LOGS/ncu_flops.txt"
  done
fi

if step bench; then
  echo "== benchmark"
  args=(--backend "${BENCH_BACKEND:-cuda}" --workload "${BENCH_WORKLOAD:-all}" --frames "${BENCH_FRAMES:-100}"
        --warmup 3 --budget-s "${BENCH_BUDGET_S:-10}")
  [[ -n "${GMM_MCL_MAP:-}" ]] && args+=(--map "$GMM_MCL_MAP")
  [[ -n "${GMM_MCL_LARGE_MAP:-}" ]] && args+=(--large-map "$GMM_MCL_LARGE_MAP")
  [[ -n "${GMM_MCL_7SCENES_FRAMES:-}" ]] && args+=(--frames-raw "$GMM_MCL_7SCENES_FRAMES")
  "$BUILD/gmm_mcl_bench" "${args[@]}" 2>&1 | tee "$LOGS/bench.txt"
  [[ ${PIPESTATUS[0]} -eq 0 ]] || status=1
fi
exit $status
