#!/usr/bin/env bash
# The DESIGN.md benchmark on this machine: builds gmm_mcl_bench (CPU backend; CUDA too when
# GMM_MCL_WITH_CUDA=ON is passed in CMAKE_ARGS) and runs it on the 7-Scenes M=1000 map and frames
# (falls back to the synthetic scene when they are absent). Extra arguments go to the tool, e.g.
#   scripts/bench.sh --workload paper,cpu --frames 20
# The map: $GMM_MCL_MAP, else build/maps/7scenes_redkitchen_m1000.gmm (scripts/build_map_7scenes.sh).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${GMM_MCL_BENCH_BUILD_DIR:-$ROOT/build/bench}"
mkdir -p "$BUILD"
cmake -S "$ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=OFF -DGMM_MCL_BUILD_FIT=OFF \
  -DCMAKE_BUILD_TYPE=Release ${CMAKE_ARGS:-} > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
cmake --build "$BUILD" -j"${JOBS:-2}" --target gmm_mcl_bench > "$BUILD/build.log" 2>&1 \
  || { tail -40 "$BUILD/build.log"; exit 1; }
cd "$ROOT"
exec "$BUILD/gmm_mcl_bench" "$@"
