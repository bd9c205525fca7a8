#!/usr/bin/env bash
# Every test: installs what is missing (apt), builds the core, the backends, the tools, the ROS
# nodelet and all tests, and runs them with ctest (gtest suites and rostests); then compiles the
# CUDA backend with nvcc (its tests skip without a GPU). Data-set tests read ../shared/datasets
# (or $GMM_MCL_DATASETS) and skip with a printed reason when it is absent.
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
ensure_packages "${CORE_PACKAGES[@]}" "${ROS_PACKAGES[@]}" python3 python3-numpy python3-sklearn

BUILD="${GMM_MCL_BUILD_DIR:-$GMM_MCL_ROOT/build/test}"
mkdir -p "$BUILD"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DGMM_MCL_BUILD_TESTS=ON \
  -DCMAKE_BUILD_TYPE=Release > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
start=$(date +%s)
cmake --build "$BUILD" -j2
echo "== build took $(( $(date +%s) - start )) s"
start=$(date +%s)
export ROS_HOME="$BUILD/ros_home"  # rostest logs stay in the build folder
(cd "$BUILD" && ctest --output-on-failure --timeout 1200) | tee "$BUILD/ctest.log"
echo "== tests took $(( $(date +%s) - start )) s"

# CUDA backend: compiled with nvcc (one architecture); its tests skip without a GPU.
NVCC="$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)"
if [ -x "$NVCC" ]; then
  CUDA_BUILD="${GMM_MCL_CUDA_BUILD_DIR:-$GMM_MCL_ROOT/build/test-cuda}"
  mkdir -p "$CUDA_BUILD"
  cmake -S "$GMM_MCL_ROOT" -B "$CUDA_BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON \
    -DGMM_MCL_BUILD_FIT=OFF -DGMM_MCL_WITH_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=75 \
    -DCMAKE_CUDA_COMPILER="$NVCC" -DCMAKE_BUILD_TYPE=Release > "$CUDA_BUILD/cmake.log" 2>&1 \
    || { cat "$CUDA_BUILD/cmake.log"; exit 1; }
  start=$(date +%s)
  cmake --build "$CUDA_BUILD" -j2 --target test_cuda_backend gmm_mcl_bench
  echo "== CUDA build took $(( $(date +%s) - start )) s"
  (cd "$CUDA_BUILD" && ctest --output-on-failure -R test_cuda_backend) | tee "$CUDA_BUILD/ctest.log"
else
  echo "== nvcc not found: CUDA backend not compiled"
fi

# One closing line over both ctest runs (set -e has already stopped on any failure).
passed=0
skipped=0
for log in "$BUILD/ctest.log" "${CUDA_BUILD:-/nonexistent}/ctest.log"; do
  [ -f "$log" ] || continue
  passed=$((passed + $(grep -cE 'Test +#[0-9]+: .* Passed' "$log" || true)))
  skipped=$((skipped + $(grep -cE 'Test +#[0-9]+: .*\*\*\*Skipped' "$log" || true)))
done
echo "${passed} passed, 0 failed, ${skipped} skipped"
