#!/usr/bin/env bash
# Prepares, on this machine, what a GPU machine without ROS, Eigen, libpng-dev or network needs to
# run the offline tools with the CUDA backend: the tools built here (nvcc, sm_90 by default;
# x86-64 with AVX2/FMA instead of -march=native, which is this machine's CPU), the shared
# libraries they need beyond glibc, the Replica mesh and trajectory, the maps of
# scripts/eval_unseen.sh, and the 7-Scenes sequence as a TUM folder reduced to the stride-8 pixel
# grid (the same input as the full frames for a stride-8 filter; 9 MB instead of 80 MB), and the
# rendered Replica segments likewise when they exist here (GMM_MCL_EVAL_SEGMENTS).
# Everything goes to $BUNDLE (default .deps/gpu, git-ignored); scripts/gpu_eval.sh runs it there.
#
#   scripts/gpu_bundle.sh            # CUDA_ARCH=90, GMM_MCL_DATASETS=../shared/datasets
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
BUNDLE="${BUNDLE:-$GMM_MCL_ROOT/.deps/gpu}"
BUILD="${GMM_MCL_GPU_TOOLS_BUILD:-$GMM_MCL_ROOT/build/gpu-tools}"
ARCH="${CUDA_ARCH:-90}"
TOOLS=(gmm_mcl_replay gmm_mcl_kidnap gmm_mcl_render gmm_mcl_fit gmm_mcl_bench test_cuda_backend)
ensure_packages "${CORE_PACKAGES[@]}"

configure_gpu_tools "$BUILD" "$ARCH" "$NVCC"
cmake --build "$BUILD" -j2 --target gmm_mcl_replay_tool gmm_mcl_kidnap gmm_mcl_render gmm_mcl_fit_tool \
  gmm_mcl_bench test_cuda_backend

rm -rf "$BUNDLE"
mkdir -p "$BUNDLE/data/maps" "$BUNDLE/data/replica_office0"
bundle_binaries "$BUNDLE" "$BUILD" "${TOOLS[@]}"

# Data: the Replica mesh and trajectory, the maps, the reduced 7-Scenes sequence.
cp "$DATASETS/replica_office0/office0_mesh.ply" "$DATASETS/replica_office0/traj.txt" \
  "$BUNDLE/data/replica_office0/"
MAPS="${GMM_MCL_EVAL_MAPS:-$GMM_MCL_ROOT/build/eval_unseen/maps}"
mkdir -p "$MAPS"
SEVEN="$DATASETS/7scenes_redkitchen/data"
[[ -f "$MAPS/replica_office0_m1000.gmm" ]] || "$BUILD/gmm_mcl_fit" \
  "$DATASETS/replica_office0/office0_mesh.ply" --mesh-samples 250000 -m 1000 --seed 1 \
  -o "$MAPS/replica_office0_m1000.gmm" -q
for f0 in 0 5; do
  m="$MAPS/7scenes_redkitchen_m1000_first$f0.gmm"
  [[ -f "$m" ]] || "$BUILD/gmm_mcl_fit" --7scenes "$SEVEN" --first $f0 --last $((990 + f0)) --step 10 \
    --min-depth 0.1 --max-depth 4.0 --voxel 0.02 -m 1000 --seed 1 -o "$m" -q
done
# The M=4000 map of the DESIGN.md protocol's frames (the benchmark's `large` workload; the
# 7s-m4000 protocol of scripts/eval_unseen.sh).
[[ -f "$MAPS/7scenes_redkitchen_m4000.gmm" ]] || "$BUILD/gmm_mcl_fit" --7scenes "$SEVEN" --first 0 \
  --last 990 --step 10 --min-depth 0.1 --max-depth 4.0 --voxel 0.02 -m 4000 --seed 1 \
  -o "$MAPS/7scenes_redkitchen_m4000.gmm" -q
cp "$MAPS"/*.gmm "$BUNDLE/data/maps/"
"$BUILD/gmm_mcl_replay" --format 7scenes --dataset "$SEVEN" --convert tum \
  "$BUNDLE/data/7scenes_tum8" --convert-stride 8 > /dev/null
# The Replica segments of scripts/eval_unseen.sh, reduced likewise, when already rendered here
# (GMM_MCL_EVAL_SEGMENTS: the folder holding replica_seg<first>; default the evaluation's).
SEGS="${GMM_MCL_EVAL_SEGMENTS:-$GMM_MCL_ROOT/build/eval_unseen}"
for first in 0 700 1400; do
  [[ -f "$SEGS/replica_seg$first/depth.txt" ]] || continue
  "$BUILD/gmm_mcl_replay" --format tum --dataset "$SEGS/replica_seg$first" --convert tum \
    "$BUNDLE/data/replica_seg${first}_tum8" --convert-stride 8 > /dev/null
done
du -sh "$BUNDLE"
