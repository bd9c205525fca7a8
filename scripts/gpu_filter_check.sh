#!/usr/bin/env bash
# The device particle filter on a GPU machine without ROS: its tests, the CUDA backend's parity
# tests, the whole-filter-step benchmark and a 7-Scenes replay with the particle set on the host
# and on the GPU, then compute-sanitizer on the new tests.
#
#   scripts/gpu_filter_check.sh bundle [DIR]   # here: build (nvcc, sm_$CUDA_ARCH, default 90),
#                                              # copy the tools, their shared libraries and the
#                                              # data into DIR (default .deps/gpufilter)
#   DIR/gpu_filter_check.sh run                # there: logs and a summary in $OUT
#
# Data: the 7-Scenes M=1000 map (scripts/build_map_7scenes.sh; GMM_MCL_MAP), its first 30 frames
# as a raw file for the benchmark and test_cuda_backend, and its first REPLAY_FRAMES (150) frames
# as a TUM folder reduced to the stride-8 grid for the replay. STEPS (run) picks from: tests bench
# replay memcheck racecheck.
set -uo pipefail
mode="${1:-run}"
# The device particle filter's suites (weights and resampling, sampling, likelihood and recovery).
filter_tests=(test_cuda_particle_filter_weights test_cuda_particle_filter_sampling
  test_cuda_particle_filter_likelihood)

if [[ "$mode" == bundle ]]; then
  set -e
  ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  source "$ROOT/scripts/common.sh"
  BUNDLE="${2:-$ROOT/.deps/gpufilter}"
  BUILD="${GMM_MCL_GPU_FILTER_BUILD:-$ROOT/build/gpufilter-tools}"
  MAP="${GMM_MCL_MAP:-$ROOT/build/maps/7scenes_redkitchen_m1000.gmm}"
  [[ -f "$MAP" ]] || { echo "no map at $MAP (scripts/build_map_7scenes.sh)" >&2; exit 1; }
  configure_gpu_tools "$BUILD" "${CUDA_ARCH:-90}" "$NVCC" -DGMM_MCL_BUILD_FIT=OFF
  tools=(gmm_mcl_bench gmm_mcl_replay test_cuda_backend "${filter_tests[@]}" test_cuda_localizer)
  cmake --build "$BUILD" -j2 --target gmm_mcl_bench gmm_mcl_replay_tool test_cuda_backend \
    "${filter_tests[@]}" test_cuda_localizer
  rm -rf "$BUNDLE"
  mkdir -p "$BUNDLE/data"
  bundle_binaries "$BUNDLE" "$BUILD" "${tools[@]}"
  cp "$MAP" "$BUNDLE/data/7scenes_m1000.gmm"
  "$BUNDLE/bin/gmm_mcl_bench" --map "$MAP" --frames-dir "$DATASETS/7scenes_redkitchen/data" \
    --frames 30 --export-frames "$BUNDLE/data/7scenes_frames30.bin" > /dev/null
  "$BUILD/gmm_mcl_replay" --format 7scenes --dataset "$DATASETS/7scenes_redkitchen/data" \
    --frames "${REPLAY_FRAMES:-150}" --convert tum "$BUNDLE/data/7scenes_tum8" \
    --convert-stride 8 > /dev/null
  cp "$ROOT/scripts/gpu_filter_check.sh" "$BUNDLE/"
  du -sh "$BUNDLE"
  exit 0
fi

# ---- run (on the GPU machine) ------------------------------------------------------------------
BUNDLE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
RESULTS="${OUT:-$BUNDLE/out}"
LOGS="$RESULTS/logs"
mkdir -p "$LOGS"
export LD_LIBRARY_PATH="$BUNDLE/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export GMM_MCL_MAP="$BUNDLE/data/7scenes_m1000.gmm"
export GMM_MCL_7SCENES_FRAMES="$BUNDLE/data/7scenes_frames30.bin"
SANITIZER="${COMPUTE_SANITIZER:-/usr/local/cuda/bin/compute-sanitizer}"
STEPS="${STEPS:-tests bench replay memcheck racecheck}"
SUMMARY="$RESULTS/summary.txt"
t0=$(date +%s)
note() { echo "$*" | tee -a "$SUMMARY"; }
elapsed() { echo "$(( $(date +%s) - t0 )) s"; }
bin="$BUNDLE/bin"
cd "$BUNDLE"
note "== $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>&1 | head -1)"

if [[ " $STEPS " == *" tests "* ]]; then
  for t in "${filter_tests[@]}" test_cuda_localizer test_cuda_backend; do
    timeout "${TEST_TIMEOUT:-240}" "$bin/$t" > "$LOGS/$t.log" 2>&1
    note "== $t: exit $? at $(elapsed)"
    grep -hE "measured|FAILED|Failure|PASSED|skipped" "$LOGS/$t.log" | tee -a "$SUMMARY"
  done
fi

if [[ " $STEPS " == *" bench "* ]]; then
  timeout "${BENCH_TIMEOUT:-300}" "$bin/gmm_mcl_bench" --backend cuda --workload scale,cpu --step \
    --map "$GMM_MCL_MAP" --frames-raw "$GMM_MCL_7SCENES_FRAMES" --frames 20 --warmup 3 \
    --budget-s 8 > "$LOGS/bench_step.log" 2> "$LOGS/bench_step.err"
  note "== bench --step: exit $? at $(elapsed)"
  grep -E "^\||^#" "$LOGS/bench_step.log" | tee -a "$SUMMARY"
fi

if [[ " $STEPS " == *" replay "* ]]; then
  for filter in device host; do
    extra=()
    [[ "$filter" == host ]] && extra=(--host-filter)
    timeout "${REPLAY_TIMEOUT:-200}" "$bin/gmm_mcl_replay" --map "$GMM_MCL_MAP" --format tum \
      --dataset "$BUNDLE/data/7scenes_tum8" --backend cuda --pixel-stride 8 --trials "${TRIALS:-2}" \
      --quiet --out "$LOGS/replay_$filter" "${extra[@]}" > "$LOGS/replay_$filter.log" 2>&1
    note "== replay, particle set on the $filter: exit $? at $(elapsed)"
    grep -E "^gmm_mcl replay|^trial|^\|" "$LOGS/replay_$filter.log" | tee -a "$SUMMARY"
  done
fi

if [[ " $STEPS " == *" memcheck "* ]]; then
  for t in "${filter_tests[@]}"; do
    timeout "${SAN_TIMEOUT:-200}" "$SANITIZER" --tool memcheck --leak-check full \
      --error-exitcode 3 "$bin/$t" > "$LOGS/memcheck_$t.log" 2>&1
    note "== memcheck $t: exit $? at $(elapsed)"
  done
  timeout "${SAN_TIMEOUT:-200}" "$SANITIZER" --tool memcheck --error-exitcode 3 \
    "$bin/test_cuda_localizer" \
    --gtest_filter='*Reproducible*:*TwoLocalizers*:*FallsBack*:*ThreadsDrive*' \
    > "$LOGS/memcheck_localizer.log" 2>&1
  note "== memcheck test_cuda_localizer (threads, fallback): exit $? at $(elapsed)"
  grep -hE "ERROR SUMMARY|LEAK SUMMARY|PASSED|FAILED" "$LOGS"/memcheck_*.log | tee -a "$SUMMARY"
fi

if [[ " $STEPS " == *" racecheck "* ]]; then
  # The filter's own kernels (block reductions in shared memory); the backend's membership and
  # likelihood kernels ran through racecheck with test_cuda_backend before.
  for t in "${filter_tests[@]}"; do
    timeout "${SAN_TIMEOUT:-200}" "$SANITIZER" --tool racecheck --racecheck-report all \
      --error-exitcode 3 "$bin/$t" \
      --gtest_filter='-*Likelihood*:*Screening*' > "$LOGS/racecheck_$t.log" 2>&1
    note "== racecheck $t (filter kernels): exit $? at $(elapsed)"
    timeout 120 "$SANITIZER" --tool synccheck --error-exitcode 3 "$bin/$t" \
      --gtest_filter='-*Likelihood*:*Screening*' > "$LOGS/synccheck_$t.log" 2>&1
    note "== synccheck $t (filter kernels): exit $? at $(elapsed)"
  done
  grep -hE "ERROR SUMMARY|RACECHECK SUMMARY|hazard|PASSED|FAILED" "$LOGS"/racecheck_*.log \
    "$LOGS"/synccheck_*.log | head -20 | tee -a "$SUMMARY"
fi

(cd "$RESULTS" && tar czf logs.tgz logs && rm -rf logs)
note "== done at $(elapsed)"
