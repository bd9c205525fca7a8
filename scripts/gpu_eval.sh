#!/usr/bin/env bash
# On the GPU machine, with the bundle of scripts/gpu_bundle.sh (.deps/gpu): the CUDA parity
# tests, then scripts/eval_unseen.sh with the bundled tools and data. Results: the tables and a
# tarball of every run's per-trial files in $OUT (default build/gpu_eval).
#   VARIANTS="name:BACKEND:PROTOCOLS:EXTRA ..." runs several configurations one after another
#   (EXTRA with commas for spaces), each into its own folder; default one run of everything with
#   the CUDA backend. JOBS (trials at once, default 8), TRIALS, FRAMES, SEGMENTS as there.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUNDLE="${BUNDLE:-$ROOT/.deps/gpu}"
RESULTS="${OUT:-$ROOT/build/gpu_eval}"
WORK="${WORK:-/tmp/gmm_mcl_gpu_eval}"
mkdir -p "$RESULTS" "$WORK/maps"
export LD_LIBRARY_PATH="$BUNDLE/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export GMM_FIT="$BUNDLE/bin/gmm_fit" GMM_MCL_RENDER="$BUNDLE/bin/gmm_mcl_render"
export GMM_MCL_REPLAY="$BUNDLE/bin/gmm_mcl_replay" GMM_MCL_KIDNAP="$BUNDLE/bin/gmm_mcl_kidnap"
export GMM_MCL_DATASETS="$BUNDLE/data" SEVEN_TUM="$BUNDLE/data/7scenes_tum8"
export JOBS="${JOBS:-8}"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$RESULTS/gpu.txt"
if [[ "${PARITY:-1}" == 1 ]]; then
  GMM_MCL_MAP="$BUNDLE/data/maps/7scenes_redkitchen_m1000_first0.gmm" \
    "$BUNDLE/bin/test_cuda_backend" > "$RESULTS/parity.log" 2>&1
  echo "parity: exit $? ($(grep -cE '^\[       OK' "$RESULTS/parity.log") passed)"; grep -E "measured|FAIL" "$RESULTS/parity.log" | head -20
fi
for v in ${VARIANTS:-cuda:cuda:start,map,kidnap,7s-disjoint,7s:}; do
  IFS=: read -r name backend protocols extra <<< "$v"
  dir="$WORK/$name"
  mkdir -p "$dir/maps"
  cp -n "$BUNDLE/data/maps/"*.gmm "$dir/maps/"
  [[ -d "$WORK/segments" ]] && for s in "$WORK"/segments/replica_seg*; do ln -sfn "$s" "$dir/"; done
  start=$(date +%s)
  BACKEND="$backend" PROTOCOLS="${protocols//,/ }" EXTRA="${extra//,/ }" \
    bash "$ROOT/scripts/eval_unseen.sh" "$dir" > "$dir.log" 2>&1
  echo "== $name ($backend; ${protocols}; ${extra}): $(( $(date +%s) - start )) s"
  # Rendered segments are shared by later variants.
  if [[ ! -d "$WORK/segments" ]] && ls -d "$dir"/replica_seg* > /dev/null 2>&1; then
    mkdir -p "$WORK/segments"
    for s in "$dir"/replica_seg*; do mv "$s" "$WORK/segments/" && ln -sfn "$WORK/segments/$(basename "$s")" "$dir/"; done
  fi
  sed -n '1,12p' "$dir/table.md" 2>/dev/null || tail -5 "$dir.log"
  cp "$dir/table.md" "$RESULTS/table_$name.md" 2>/dev/null
done
(cd "$WORK" && tar czf "$RESULTS/runs.tgz" --exclude='replica_seg*' --exclude='segments' \
  --exclude='*.tum' --exclude='maps' .) 2>/dev/null
ls -la "$RESULTS"
