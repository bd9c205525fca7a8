#!/usr/bin/env bash
# The paper's evaluation figures: builds gmm_mcl_figures, runs Fig. 2 (nll-sweep) and the
# Sensitivity Analysis (sensitivity), and plots both (scripts/plot_figures.py).
# On 7-Scenes redkitchen when the shared data is found ($GMM_MCL_DATASETS, else
# ../shared/datasets), else on the synthetic box scene.
#
# usage: scripts/figures.sh [OUT_DIR] [nll|sensitivity|all] [extra gmm_mcl_figures options...]
#   OUT_DIR   default build/figures_out (nll_sweep.* and sensitivity_* land there)
#   MAP       a 7-Scenes map in the world frame (scripts/build_map_7scenes.sh); default: the
#             map that script writes if it exists, else gmm_mcl_figures fits M=1000 itself
#   GMM_MCL_BUILD_DIR  build folder (default build/figures-release)
set -euo pipefail
source "$(dirname "$0")/common.sh"
OUT="${1:-$GMM_MCL_ROOT/build/figures_out}"
WHAT="${2:-all}"
shift $(( $# < 2 ? $# : 2 ))

ensure_packages "${CORE_PACKAGES[@]}"
BUILD="${GMM_MCL_BUILD_DIR:-$GMM_MCL_ROOT/build/figures-release}"
mkdir -p "$BUILD" "$OUT"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=OFF \
  -DCMAKE_BUILD_TYPE=Release > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
cmake --build "$BUILD" -j2 --target gmm_mcl_figures_tool
TOOL="$BUILD/gmm_mcl_figures"

MAP="${MAP:-${GMM_MCL_MAP_DIR:-$GMM_MCL_ROOT/build/maps}/7scenes_redkitchen_m1000.gmm}"
MAP_ARGS=()
[[ -f "$MAP" ]] && MAP_ARGS=(--map "$MAP")

cd "$GMM_MCL_ROOT"
if [[ "$WHAT" == "nll" || "$WHAT" == "all" ]]; then
  "$TOOL" nll-sweep "${MAP_ARGS[@]}" --out "$OUT" "$@"
fi
if [[ "$WHAT" == "sensitivity" || "$WHAT" == "all" ]]; then
  "$TOOL" sensitivity "${MAP_ARGS[@]}" --out "$OUT" "$@"
fi
/usr/bin/python3 "$GMM_MCL_ROOT/scripts/plot_figures.py" "$OUT"
