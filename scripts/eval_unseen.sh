#!/usr/bin/env bash
# The unseen-scene evaluation (DESIGN.md "Unseen scenes"; docs/unseen_scenes.md): scenes and
# maps the package was not tuned on.
#   - Replica office0: depth rendered along disjoint 600-frame segments of its trajectory (poses
#     0-599, 700-1299, 1400-1999) with a 640x480 camera (f = 525 px, unlike Replica's 1200x680,
#     f = 600), the structured-light sensor model and 2% random dropout; the map fitted to
#     250,000 points sampled on the mesh (never to the frames).
#   - 7-Scenes redkitchen with the map fitted to frames 5, 15, ..., 995 (disjoint from the
#     replayed frames' map frames 0, 10, ..., 990 of the DESIGN.md protocol), the DESIGN.md
#     protocol itself, and the same with an M=4000 map (the benchmark's `large` map: what the
#     map's resolution costs in accuracy).
# Protocols (PROTOCOLS, default all): start (the paper's 4 m cube / pi yaw start on every
# segment), map (uniform over the whole map's bounds, full yaw), kidnap (gmm_mcl_kidnap on the
# segments), 7s-disjoint, 7s, 7s-m4000 (not in the default list). Per run a folder with per-trial TUM files, per-frame CSVs and a
# summary; then a pooled table (scripts/unseen_table.py) in OUT/table.md.
#
# usage: scripts/eval_unseen.sh [OUT_DIR]          (default build/eval_unseen)
#   BACKEND=cpu|cuda  TRIALS (10)  FIRST_SEED (1)  FRAMES (600 per segment; 7-Scenes: all 1000)
#   SEGMENTS ("0 700 1400")  STRIDE (8)  PARTICLES / MIN_PARTICLES (the tools' defaults for the
#   backend)  EXTRA (more options for gmm_mcl_replay and gmm_mcl_kidnap)  JOBS (trials run as
#   this many processes at once, each with OMP threads THREADS; default 1 and all cores)
#   REPLAY_FRAMES (replay only the first N frames of each sequence: quick checks)
#   DEPTH_SCALE_ERROR (the Replica camera reports 1 + this times the depth: 0.004, 0.4% long)
#   GMM_MCL_DATASETS (../shared/datasets); SEVEN_TUM: the 7-Scenes sequence as a TUM folder
#   (scripts/gpu_bundle.sh makes one), read instead of the data set (its maps must then be in
#   OUT/maps already); GMM_FIT, GMM_MCL_RENDER, GMM_MCL_REPLAY, GMM_MCL_KIDNAP name the binaries
#   (default: the build folders, else PATH).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/common.sh"
OUT="${1:-$ROOT/build/eval_unseen}"
BACKEND="${BACKEND:-cpu}"
TRIALS="${TRIALS:-10}"
FIRST_SEED="${FIRST_SEED:-1}"
FRAMES="${FRAMES:-600}"
SEGMENTS="${SEGMENTS:-0 700 1400}"
STRIDE="${STRIDE:-8}"
PROTOCOLS="${PROTOCOLS:-start map kidnap 7s-disjoint 7s}"
JOBS="${JOBS:-1}"
export OMP_NUM_THREADS="${THREADS:-$(( $(nproc) / JOBS > 0 ? $(nproc) / JOBS : 1 ))}"
read -r -a EXTRA_ARGS <<< "${EXTRA:-}"
REPLAY_ARGS=()
[[ -n "${REPLAY_FRAMES:-}" ]] && REPLAY_ARGS+=(--frames "$REPLAY_FRAMES")
# DEPTH_SCALE_ERROR=E: the Replica segments rendered by a camera that reports (1 + E) times the
# depth (a miscalibrated stereo camera), in their own folders.
SEG_TAG=""
RENDER_ARGS=()
if [[ -n "${DEPTH_SCALE_ERROR:-}" ]]; then
  SEG_TAG="_scale_error$DEPTH_SCALE_ERROR"
  RENDER_ARGS+=(--depth-scale-error "$DEPTH_SCALE_ERROR")
fi
[[ -n "${PARTICLES:-}" ]] && EXTRA_ARGS+=(--num-particles "$PARTICLES")
[[ -n "${MIN_PARTICLES:-}" ]] && EXTRA_ARGS+=(--min-particles "$MIN_PARTICLES")
GMM_FIT="$(find_tool gmm_mcl_fit GMM_FIT)"
RENDER="$(find_tool gmm_mcl_render GMM_MCL_RENDER)"
REPLAY="$(find_tool gmm_mcl_replay GMM_MCL_REPLAY)"
KIDNAP="$(find_tool gmm_mcl_kidnap GMM_MCL_KIDNAP)"
REPLICA="$DATASETS/replica_office0"
SEVEN="$DATASETS/7scenes_redkitchen/data"
mkdir -p "$OUT/maps"
echo "== unseen-scene evaluation: backend $BACKEND, $TRIALS trials from seed $FIRST_SEED," \
     "stride $STRIDE, protocols: $PROTOCOLS; output $OUT"

# runs COMMAND... for seeds FIRST_SEED.. in JOBS processes (one trial each) or in one process.
# $1: the output folder; the command gets --first-seed/--trials appended.
run_trials() {
  local dir="$1"; shift
  mkdir -p "$dir"
  if [[ "$JOBS" -le 1 ]]; then
    "$@" --first-seed "$FIRST_SEED" --trials "$TRIALS" > "$dir/log.txt" 2>&1 || true
    return
  fi
  local s pids=()
  for ((s = FIRST_SEED; s < FIRST_SEED + TRIALS; ++s)); do
    "$@" --first-seed "$s" --trials 1 > "$dir/log_$s.txt" 2>&1 &
    pids+=($!)
    if (( ${#pids[@]} >= JOBS )); then wait "${pids[0]}" || true; pids=("${pids[@]:1}"); fi
  done
  for p in "${pids[@]}"; do wait "$p" || true; done
  cat "$dir"/log_*.txt > "$dir/log.txt"
}

needs_replica=0
for p in $PROTOCOLS; do [[ "$p" == start || "$p" == map || "$p" == kidnap ]] && needs_replica=1; done
if (( needs_replica )); then
  [[ -f "$REPLICA/office0_mesh.ply" ]] || { echo "error: $REPLICA/office0_mesh.ply not found" >&2; exit 1; }
  MAP="$OUT/maps/replica_office0_m1000.gmm"
  [[ -f "$MAP" ]] || "$GMM_FIT" "$REPLICA/office0_mesh.ply" --mesh-samples 250000 -m 1000 --seed 1 \
    -o "$MAP" -q
  for first in $SEGMENTS; do
    seg="$OUT/replica_seg$first$SEG_TAG"
    [[ -f "$seg/depth.txt" ]] && [[ $(grep -vc '^#' "$seg/depth.txt") -ge $FRAMES ]] && continue
    rm -rf "$seg"
    OMP_NUM_THREADS="$(nproc)" "$RENDER" --mesh "$REPLICA/office0_mesh.ply" --trajectory "$REPLICA/traj.txt" \
      --camera 525,525,319.5,239.5,640,480 --first "$first" --frames "$FRAMES" --dropout 0.02 \
      --seed 1 --out "$seg" --quiet "${RENDER_ARGS[@]}"
  done
fi
for p in $PROTOCOLS; do
  case "$p" in
    start)
      for first in $SEGMENTS; do
        run_trials "$OUT/start_seg$first" "$REPLAY" --format tum --dataset "$OUT/replica_seg$first$SEG_TAG" \
          --map "$MAP" --pixel-stride "$STRIDE" --backend "$BACKEND" --out "$OUT/start_seg$first" --quiet \
          "${REPLAY_ARGS[@]}" "${EXTRA_ARGS[@]}"
      done ;;
    map)
      first="${SEGMENTS%% *}"
      run_trials "$OUT/map_seg$first" "$REPLAY" --format tum --dataset "$OUT/replica_seg$first$SEG_TAG" \
        --map "$MAP" --init map --pixel-stride "$STRIDE" --backend "$BACKEND" --out "$OUT/map_seg$first" \
        --quiet "${REPLAY_ARGS[@]}" "${EXTRA_ARGS[@]}" ;;
    kidnap)
      for first in $SEGMENTS; do
        run_trials "$OUT/kidnap_seg$first" "$KIDNAP" --scene tum --dataset "$OUT/replica_seg$first$SEG_TAG" \
          --map "$MAP" --pixel-stride "$STRIDE" --backend "$BACKEND" --out "$OUT/kidnap_seg$first" \
          "${EXTRA_ARGS[@]}"
      done ;;
    7s-disjoint|7s|7s-m4000)
      if [[ "$p" == 7s-disjoint ]]; then f0=5; f1=995; else f0=0; f1=990; fi
      if [[ "$p" == 7s-m4000 ]]; then m=4000; else m=1000; fi
      if [[ "$m" == 1000 ]]; then map7="$OUT/maps/7scenes_redkitchen_m1000_first$f0.gmm"
      else map7="$OUT/maps/7scenes_redkitchen_m$m.gmm"; fi
      if [[ ! -f "$map7" ]]; then
        [[ -f "$SEVEN/frame-000000.depth.png" ]] || { echo "error: $SEVEN not found" >&2; exit 1; }
        "$GMM_FIT" --7scenes "$SEVEN" --first $f0 --last $f1 --step 10 --min-depth 0.1 \
          --max-depth 4.0 --voxel 0.02 -m $m --seed 1 -o "$map7" -q
      fi
      if [[ -n "${SEVEN_TUM:-}" ]]; then source7=(--format tum --dataset "$SEVEN_TUM")
      else source7=(--dataset "$SEVEN"); fi
      run_trials "$OUT/$p" "$REPLAY" "${source7[@]}" --map "$map7" --pixel-stride "$STRIDE" \
        --backend "$BACKEND" --out "$OUT/$p" --quiet "${REPLAY_ARGS[@]}" "${EXTRA_ARGS[@]}" ;;
    *) echo "unknown protocol '$p'" >&2; exit 2 ;;
  esac
done
python3 "$ROOT/scripts/unseen_table.py" "$OUT" | tee "$OUT/table.md"
