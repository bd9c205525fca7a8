#!/usr/bin/env bash
# Every test: installs what is missing (apt), builds the core, backends, tools and tests, and
# runs them all with ctest. Data-set tests read ../shared/datasets (or $GMM_MCL_DATASETS) and
# skip with a printed reason when it is absent.
set -euo pipefail
source "$(dirname "$0")/common.sh"
ensure_packages "${CORE_PACKAGES[@]}" python3 python3-numpy python3-sklearn
BUILD="${GMM_MCL_BUILD_DIR:-$GMM_MCL_ROOT/build/test}"
mkdir -p "$BUILD"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON \
  -DCMAKE_BUILD_TYPE=Release > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
start=$(date +%s)
cmake --build "$BUILD" -j2
echo "== build took $(( $(date +%s) - start )) s"
cd "$BUILD"
start=$(date +%s)
ctest --output-on-failure --timeout 900
echo "== tests took $(( $(date +%s) - start )) s"
