#!/usr/bin/env bash
# Tuning sweep on the GPU machine (after scripts/gpu_check.sh has built build-gpu): the CUDA
# benchmark under likelihood shapes (--cuda-likelihood-shape GROUPSxPX), band sizes
# (--cuda-band-patches; both parameters of the table, docs/parameters.md) and, when SWEEP_MINBLOCKS is set, a second build whose likelihood kernel
# is compiled for that many resident blocks per SM. Prints one line per run.
#   SWEEP="paper:32x2:10 paper:16x4:10 cpu:8x2:10" scripts/gpu_sweep.sh
set -uo pipefail
source "$(dirname "$0")/gpu_common.sh"
cd "$ROOT"
gpu_build_dirs
mkdir -p "$LOGS"
args=(--backend cuda --frames 100 --warmup 3 --budget-s "${BENCH_BUDGET_S:-2}")
[[ -f .deps/7scenes_redkitchen_m1000.gmm ]] && args+=(--map .deps/7scenes_redkitchen_m1000.gmm)
[[ -f .deps/7scenes_frames30.bin ]] && args+=(--frames-raw .deps/7scenes_frames30.bin)
builds=("$BUILD")
if [[ -n "${SWEEP_MINBLOCKS:-}" ]]; then
  B2="$BUILD-mb$SWEEP_MINBLOCKS"
  cmake -S "$ROOT" -B "$B2" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_WITH_CUDA=ON -DGMM_MCL_BUILD_FIT=OFF \
    -DGMM_MCL_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release -DGMM_MCL_EIGEN_DIR="$ROOT/.deps/eigen3" \
    -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}" \
    -DCMAKE_CUDA_FLAGS="-DGMM_MCL_LIKELIHOOD_MIN_BLOCKS=$SWEEP_MINBLOCKS" > "$LOGS/cmake_mb.log" 2>&1 &&
    cmake --build "$B2" -j"$(nproc)" --target gmm_mcl_bench > "$LOGS/build_mb.log" 2>&1 &&
    builds+=("$B2")
fi
for b in "${builds[@]}"; do
  for run in ${SWEEP:-paper:32x2:10}; do
    IFS=: read -r wl shape band <<< "$run"
    line=$("$b/gmm_mcl_bench" "${args[@]}" --cuda-likelihood-shape "$shape" \
      --cuda-band-patches "$band" --workload "$wl" 2>/dev/null | grep "^| cuda")
    echo "$(basename "$b") $wl $shape band $band: $(echo "$line" | awk -F'|' '{print "upd/s",$9,"memb",$11,"lik",$12,"update",$14,"peak",$17}')"
  done
done
