#!/usr/bin/env bash
# Builds the building test world (docs/sim.md "The building world"; DESIGN.md "Building
# scale"): the procedural building of one seed (60 x 56 m, 36 rooms of ten kinds, corridors,
# doors, furniture) as a mesh and as its analytic GMM map (about 100,000 flat Gaussians tiling
# the visible surfaces), and sequences that fly from room to room through doors and along
# corridors, rendered through the structured-light sensor model into TUM RGB-D folders.
# Idempotent: what is already there is skipped (a sequence counts once its folder is complete:
# each is rendered into NAME.partial and moved into place at the end).
#
# usage: scripts/make_building.sh [OUT_DIR]
#   OUT_DIR                  default $GMM_MCL_BUILDING_DIR, else build/building
#   GMM_MCL_BUILDING_SEED    the building's seed (default 1)
#   GMM_MCL_BUILDING_WALKS   the walks' seeds (default "1 7 12": three rooms each, through doors;
#                            7 and 12 along corridors too); walk W is rendered with sensor
#                            noise seed W
#   GMM_MCL_BUILDING_FRAMES  frames per walk, 30 Hz (default 900: 30 s)
#   GMM_MCL_BUILDING_WIDTH   image width (default 640; 4:3, f = 585 px at 640)
#   GMM_MCL_RENDER           the gmm_mcl_render binary (default: the build folders, or PATH)
#
# Writes, for building seed S and walk W:
#   OUT_DIR/building_sS.ply        the mesh (visible surfaces only; binary PLY)
#   OUT_DIR/building_sS.gmm        its map (tileBuilding: 0.375 m tiles, 1.5 cm normal sigma)
#   OUT_DIR/building_sS_walkW/     depth/, depth.txt, groundtruth.txt, intrinsics.txt,
#                                  gravity-direction.txt (gmm_mcl_replay --format tum reads it)
#   OUT_DIR/building_sS_walkW.txt  the walk: the camera's poses rendered (TUM trajectory)
# For example:
#   gmm_mcl_replay --map OUT_DIR/building_s1.gmm --format tum --dataset OUT_DIR/building_s1_walk1
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

OUT_DIR="${1:-${GMM_MCL_BUILDING_DIR:-$GMM_MCL_ROOT/build/building}}"
SEED="${GMM_MCL_BUILDING_SEED:-1}"
WALKS="${GMM_MCL_BUILDING_WALKS:-1 7 12}"
FRAMES="${GMM_MCL_BUILDING_FRAMES:-900}"
WIDTH="${GMM_MCL_BUILDING_WIDTH:-640}"
RENDER="$(find_tool gmm_mcl_render GMM_MCL_RENDER)"
mkdir -p "$OUT_DIR"

world="$OUT_DIR/building_s$SEED"
if [[ -s "$world.ply" && -s "$world.gmm" ]]; then
  echo "== $world.ply and .gmm: already there"
else
  echo "== building seed $SEED: mesh and map"
  "$RENDER" --building "$SEED" --save-mesh "$world.partial.ply" --save-map "$world.partial.gmm"
  mv "$world.partial.ply" "$world.ply"
  mv "$world.partial.gmm" "$world.gmm"
fi

for walk in $WALKS; do
  seq="${world}_walk$walk"
  if [[ -f "$seq/groundtruth.txt" && -f "$seq.txt" ]]; then
    echo "== $seq: already there"
    continue
  fi
  echo "== building seed $SEED, walk $walk: $FRAMES frames"
  rm -rf "$seq.partial" "$seq.partial.txt"
  "$RENDER" --building "$SEED" --walk "$walk" --frames "$FRAMES" --width "$WIDTH" \
    --seed "$walk" --out "$seq.partial" --save-trajectory "$seq.partial.txt"
  rm -rf "$seq"
  mv "$seq.partial" "$seq"
  mv "$seq.partial.txt" "$seq.txt"
done
names=""
for walk in $WALKS; do names="$names $(basename "$world")_walk$walk"; done
echo "== $OUT_DIR: map $(basename "$world").gmm, sequences:$names"
