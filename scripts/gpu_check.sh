#!/usr/bin/env bash
# On a machine with a CUDA GPU and no ROS: builds the ROS-free part with the CUDA backend, runs
# the CPU-vs-CUDA parity tests, compute-sanitizer (memcheck, racecheck) on them, and the
# benchmark. Logs go to $OUT (default build-gpu/logs).
#
#   scripts/gpu_check.sh            # everything
#   GPU_CHECK_STEPS="build test bench" scripts/gpu_check.sh
#
# Inputs (optional, else the synthetic scene): $GMM_MCL_MAP (7-Scenes M=1000 map) and
# $GMM_MCL_7SCENES_FRAMES (raw frames from `gmm_mcl_bench --export-frames`); by default the
# files .deps/7scenes_redkitchen_m1000.gmm and .deps/7scenes_frames30.bin when present. Eigen and
# googletest are taken from .deps/eigen3 and .deps/googletest when the system has none.
set -uo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
BUILD="${GMM_MCL_GPU_BUILD_DIR:-$ROOT/build-gpu}"
LOGS="${OUT:-$BUILD/logs}"
STEPS="${GPU_CHECK_STEPS:-build test memcheck racecheck bench}"
JOBS="${JOBS:-$(nproc)}"
mkdir -p "$BUILD" "$LOGS"
status=0
step() { [[ " $STEPS " == *" $1 "* ]]; }

nvidia-smi --query-gpu=name,compute_cap,driver_version,clocks.max.sm --format=csv 2>&1 | tee "$LOGS/gpu.txt"
ARCH="${CUDA_ARCH:-$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d ' .')}"
ARCH="${ARCH:-75}"
[[ -z "${GMM_MCL_MAP:-}" && -f .deps/7scenes_redkitchen_m1000.gmm ]] && export GMM_MCL_MAP="$ROOT/.deps/7scenes_redkitchen_m1000.gmm"
[[ -z "${GMM_MCL_7SCENES_FRAMES:-}" && -f .deps/7scenes_frames30.bin ]] && export GMM_MCL_7SCENES_FRAMES="$ROOT/.deps/7scenes_frames30.bin"

if step build; then
  extra=()
  [[ -d .deps/eigen3 && ! -d /usr/include/eigen3 ]] && extra+=(-DGMM_MCL_EIGEN_DIR="$ROOT/.deps/eigen3")
  [[ -d .deps/googletest && ! -d /usr/src/googletest ]] && extra+=(-DGMM_MCL_GTEST_SRC="$ROOT/.deps/googletest")
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

if step bench; then
  echo "== benchmark"
  args=(--backend "${BENCH_BACKEND:-cuda}" --workload "${BENCH_WORKLOAD:-all}" --frames "${BENCH_FRAMES:-100}"
        --warmup 3 --budget-s "${BENCH_BUDGET_S:-10}")
  [[ -n "${GMM_MCL_MAP:-}" ]] && args+=(--map "$GMM_MCL_MAP")
  [[ -n "${GMM_MCL_7SCENES_FRAMES:-}" ]] && args+=(--frames-raw "$GMM_MCL_7SCENES_FRAMES")
  "$BUILD/gmm_mcl_bench" "${args[@]}" 2>&1 | tee "$LOGS/bench.txt"
  [[ ${PIPESTATUS[0]} -eq 0 ]] || status=1
fi
exit $status
