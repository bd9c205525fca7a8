#!/usr/bin/env bash
# Builds the 7-Scenes redkitchen map exactly as DESIGN.md's accuracy protocol says: every 10th
# frame (0, 10, ..., 990) back-projected with its camera-to-world pose (frame-*.pose.txt),
# depths in (0.1, 4.0] m, stitched, 2 cm voxel centroids, M=1000 full-covariance GMM.
#
# usage: scripts/build_map_7scenes.sh [DATASETS_DIR] [OUTPUT_MAP] [extra gmm_mcl_fit options...]
#   DATASETS_DIR  default $GMM_MCL_DATASETS, else ../shared/datasets (from the package root)
#   OUTPUT_MAP    default $GMM_MCL_MAP_DIR/7scenes_redkitchen_m1000.gmm (GMM_MCL_MAP_DIR
#                 defaults to build/maps); the stitched cloud is written next to it (.pcd)
#   GMM_FIT       the gmm_mcl_fit binary (default: build-fit/gmm_fit, build/gmm_fit, or on PATH)
# Extra options replace the defaults they name. The benchmark's `large` workload map (M=4000 of
# the same frames):
#   scripts/build_map_7scenes.sh "" build/maps/7scenes_redkitchen_m4000.gmm -m 4000
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
map_builder_args 7scenes_redkitchen_m1000.gmm "$@"
shift "$MAP_ARGS_USED"

DATA="$DATASETS/7scenes_redkitchen/data"
require_input "$DATA/camera-intrinsics.txt" "7-Scenes redkitchen" "$DATA"
mkdir -p "$(dirname "$OUT")"
fit_options --first 0 --last 990 --step 10 --min-depth 0.1 --max-depth 4.0 --voxel 0.02 \
  -m 1000 --seed 1 -- "$@"
"$GMM_FIT" --7scenes "$DATA" --save-cloud "${OUT%.gmm}.pcd" -o "$OUT" "${FIT_OPTIONS[@]}"
"$GMM_INSPECT" "$OUT"
