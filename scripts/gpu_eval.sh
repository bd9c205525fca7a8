#!/usr/bin/env bash
# On the GPU machine, with the bundle of scripts/gpu_bundle.sh (.deps/gpu): optionally the CUDA
# parity tests, then scripts/eval_unseen.sh with the bundled tools and data (the Replica
# segments and 7-Scenes as TUM folders reduced to the stride-8 grid, so nothing is rendered
# there). Per configuration a tarball of its per-trial files and table in $OUT (default
# build/gpu_eval); the tables are printed as they finish.
#   VARIANTS="name:BACKEND:PROTOCOLS:EXTRA:SECONDS ..." (EXTRA with commas for spaces; each run
#   stopped after SECONDS, its finished trials kept). JOBS (trials at once, default 8), THREADS
#   (per trial, default 2), TRIALS, REPLAY_FRAMES as in eval_unseen.sh; PARITY=1 runs
#   test_cuda_backend first.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUNDLE="${BUNDLE:-$ROOT/.deps/gpu}"
RESULTS="${OUT:-$ROOT/build/gpu_eval}"
WORK="${WORK:-/tmp/gmm_mcl_gpu_eval}"
mkdir -p "$RESULTS" "$WORK"
export LD_LIBRARY_PATH="$BUNDLE/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export GMM_FIT="$BUNDLE/bin/gmm_mcl_fit" GMM_MCL_RENDER="$BUNDLE/bin/gmm_mcl_render"
export GMM_MCL_REPLAY="$BUNDLE/bin/gmm_mcl_replay" GMM_MCL_KIDNAP="$BUNDLE/bin/gmm_mcl_kidnap"
export GMM_MCL_DATASETS="$BUNDLE/data" SEVEN_TUM="$BUNDLE/data/7scenes_tum8"
export JOBS="${JOBS:-8}" THREADS="${THREADS:-2}"
t0=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$RESULTS/gpu.txt"
if [[ "${PARITY:-0}" == 1 ]]; then
  GMM_MCL_MAP="$BUNDLE/data/maps/7scenes_redkitchen_m1000_first0.gmm" \
    "$BUNDLE/bin/test_cuda_backend" > "$RESULTS/parity.log" 2>&1
  echo "parity: exit $?"; grep -E "measured|FAIL" "$RESULTS/parity.log" | head -20
fi
for v in ${VARIANTS:-cuda:cuda:start,map,kidnap,7s-disjoint,7s::500}; do
  IFS=: read -r name backend protocols extra seconds <<< "$v"
  dir="$WORK/$name"
  mkdir -p "$dir/maps"
  cp "$BUNDLE/data/maps/"*.gmm "$dir/maps/"
  for s in "$BUNDLE"/data/replica_seg*_tum8; do
    b=$(basename "$s")
    ln -sfn "$s" "$dir/${b%_tum8}"
  done
  echo "== $name ($backend; $protocols; $extra) from $(( $(date +%s) - t0 )) s"
  BACKEND="$backend" PROTOCOLS="${protocols//,/ }" EXTRA="${extra//,/ }" \
    timeout "${seconds:-300}" bash "$ROOT/scripts/eval_unseen.sh" "$dir" > "$dir.log" 2>&1
  echo "   exit $? at $(( $(date +%s) - t0 )) s"
  python3 "$ROOT/scripts/unseen_table.py" "$dir" > "$dir/table.md" 2>&1
  head -8 "$dir/table.md"
  (cd "$WORK" && tar czf "$RESULTS/runs_$name.tgz" --exclude='replica_seg*' --exclude='maps' \
    --exclude='*.tum' "$name" "$name.log")
done
