#!/usr/bin/env bash
# Builds the Replica office0 map: 250,000 points sampled area-uniformly on office0_mesh.ply
# (101 m^2 of surface: about one point per 4 cm^2, the density of 2 cm voxels), M=1000
# full-covariance GMM.
#
# usage: scripts/build_map_replica.sh [DATASETS_DIR] [OUTPUT_MAP] [extra gmm_mcl_fit options...]
#   DATASETS_DIR  default $GMM_MCL_DATASETS, else ../shared/datasets (from the package root)
#   OUTPUT_MAP    default $GMM_MCL_MAP_DIR/replica_office0_m1000.gmm (GMM_MCL_MAP_DIR defaults
#                 to build/maps)
#   GMM_FIT       the gmm_mcl_fit binary (default: build-fit/gmm_fit, build/gmm_fit, or on PATH)
# Extra options replace the defaults they name (-m 4000: M = 4000).
#
# With GMM_MCL_REPLICA_SEQUENCE=DIR it also renders a depth sequence from the same mesh along
# Replica's traj.txt with cam_params.json (1200x680) into DIR, in TUM RGB-D layout, with the
# structured-light sensor model (gmm_mcl_render; GMM_MCL_REPLICA_FRAMES poses, default 300,
# every GMM_MCL_REPLICA_STRIDE-th, default 1; GMM_MCL_RENDER names the binary). The Replica
# world is z up. The map and the sequence together are a localization test case.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
map_builder_args replica_office0_m1000.gmm "$@"
shift "$MAP_ARGS_USED"

MESH="$DATASETS/replica_office0/office0_mesh.ply"
require_input "$MESH" "Replica office0 mesh"
mkdir -p "$(dirname "$OUT")"
fit_options --mesh-samples 250000 -m 1000 --seed 1 -- "$@"
"$GMM_FIT" "$MESH" -o "$OUT" "${FIT_OPTIONS[@]}"
"$GMM_INSPECT" "$OUT"

if [[ -n "${GMM_MCL_REPLICA_SEQUENCE:-}" ]]; then
  GMM_MCL_RENDER="$(find_tool gmm_mcl_render GMM_MCL_RENDER)"
  "$GMM_MCL_RENDER" --mesh "$MESH" --trajectory "$DATASETS/replica_office0/traj.txt" \
    --camera "$DATASETS/replica_office0/cam_params.json" \
    --frames "${GMM_MCL_REPLICA_FRAMES:-300}" --stride "${GMM_MCL_REPLICA_STRIDE:-1}" \
    --seed 1 --out "$GMM_MCL_REPLICA_SEQUENCE"
fi
