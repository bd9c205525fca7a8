#!/usr/bin/env bash
# Builds the 7-Scenes redkitchen map exactly as DESIGN.md's accuracy protocol says: every 10th
# frame (0, 10, ..., 990) back-projected with its camera-to-world pose (frame-*.pose.txt),
# depths in (0.1, 4.0] m, stitched, 2 cm voxel centroids, M=1000 full-covariance GMM.
#
# usage: scripts/build_map_7scenes.sh [DATASETS_DIR] [OUTPUT_MAP] [extra gmm_mcl_fit options...]
#   DATASETS_DIR  default $GMM_MCL_DATASETS, else ../shared/datasets (from the package root)
#   OUTPUT_MAP    default $GMM_MCL_MAP_DIR/7scenes_redkitchen_m1000.gmm (GMM_MCL_MAP_DIR
#                 defaults to build/maps); the stitched cloud is written next to it (.pcd)
#   GMM_FIT       the gmm_mcl_fit binary (default: build-fit/gmm_mcl_fit, build/gmm_mcl_fit, or on PATH)
# The benchmark's `large` workload map (M=4000 of the same frames; a later -m wins):
#   scripts/build_map_7scenes.sh "" build/maps/7scenes_redkitchen_m4000.gmm -m 4000
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DATASETS="${1:-${GMM_MCL_DATASETS:-$ROOT/../shared/datasets}}"
OUT="${2:-${GMM_MCL_MAP_DIR:-$ROOT/build/maps}/7scenes_redkitchen_m1000.gmm}"
shift $(( $# < 2 ? $# : 2 ))

source "$ROOT/scripts/common.sh"
GMM_FIT="$(find_tool gmm_mcl_fit GMM_FIT)"
GMM_INSPECT="$(find_tool gmm_mcl_inspect GMM_INSPECT)"

DATA="$DATASETS/7scenes_redkitchen/data"
if [[ ! -f "$DATA/camera-intrinsics.txt" ]]; then
  echo "error: 7-Scenes redkitchen not found at $DATA (pass DATASETS_DIR or set GMM_MCL_DATASETS)" >&2
  exit 1
fi
mkdir -p "$(dirname "$OUT")"
"$GMM_FIT" --7scenes "$DATA" --first 0 --last 990 --step 10 --min-depth 0.1 --max-depth 4.0 \
  --voxel 0.02 -m 1000 --seed 1 --save-cloud "${OUT%.gmm}.pcd" -o "$OUT" "$@"
"$GMM_INSPECT" "$OUT"
