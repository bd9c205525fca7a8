#!/usr/bin/env bash
# The offline job on the built-in default scene: installs what is missing, builds, runs the
# localizer on the synthetic room (a triangle mesh with box furniture and cylinders, depth ray
# cast through a BVH with a structured-light sensor model) from a uniform 4 m cube / pi yaw
# start and prints the error. Extra arguments go to gmm_mcl_sim_demo (--frames, --num-particles,
# --seed, --weighting, --scene mesh|box, --no-sensor-noise, ...).
set -euo pipefail
source "$(dirname "$0")/common.sh"
ensure_packages "${CORE_PACKAGES[@]}"
BUILD="${GMM_MCL_BUILD_DIR:-$GMM_MCL_ROOT/build/release}"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=OFF \
  -DCMAKE_BUILD_TYPE=Release > "$BUILD.cmake.log" 2>&1 || { cat "$BUILD.cmake.log"; exit 1; }
cmake --build "$BUILD" -j2 --target gmm_mcl_sim_demo
exec "$BUILD/gmm_mcl_sim_demo" "$@"
