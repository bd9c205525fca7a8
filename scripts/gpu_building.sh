#!/usr/bin/env bash
# The building-scale cost table (docs/building_scale.md) on a GPU machine: the CUDA backend's
# update and the localizer's tracking step and first update on one room's map and on the same
# room tiled into 3 x 3, 7 x 7 and 10 x 10 rooms, with the camera in the original room.
# Built and run there from the working tree and .deps/ (scripts/gpu_deps.sh, plus the tiled maps:
# `gmm_mcl_inspect MAP --tile N --out .deps/7scenes_tiled_NxN.gmm`); with BASE_SRC (a source tree
# of an earlier version whose .deps/ link points here) the same benchmark of that version first.
#
# With GLOBAL_MAP and GLOBAL_SEQS (TUM folders of a building, scripts/make_building.sh, reduced
# with `gmm_mcl_replay --convert tum --convert-stride 8`), global localization there: replay
# trials from a whole-map start (--init map, plus GLOBAL_ARGS) with the CUDA backend, GPU memory sampled by
# nvidia-smi, and the memory of 10^5 and 10^6 particles (MEMORY_ARGS, default one candidate per
# particle at the whole-map start: the particle set's own memory, in seconds).
#
#   scripts/gpu_building.sh                 # logs under $OUT (the device tool) or build-gpu/logs
#   BASE_SRC=.deps/base-src scripts/gpu_building.sh
#   VARIANTS="groups=--cuda-place-groups,true" scripts/gpu_building.sh   # and with those flags
#   STEPS=global GLOBAL_MAP=.deps/building/map.gmm GLOBAL_SEQS=".deps/building/walk1" \
#     scripts/gpu_building.sh
set -uo pipefail
source "$(dirname "$0")/gpu_common.sh"
cd "$ROOT"
LOGS="${OUT:-$ROOT/build-gpu/logs}"
mkdir -p "$LOGS"
MAPS="${MAPS:-$ROOT/.deps}"
FRAMES="${FRAMES:-$ROOT/.deps/7scenes_frames30.bin}"
ROOMS="${ROOMS:-redkitchen_m1000 tiled_3x3 tiled_7x7 tiled_10x10}"
TARGETS="test_cuda_backend test_cuda_localizer test_cuda_particle_filter_weights"
TARGETS+=" test_cuda_particle_filter_sampling test_cuda_particle_filter_likelihood gmm_mcl_bench"
TARGETS+=" gmm_mcl_replay_tool"
STEPS="${STEPS:-tests cost global}"
TRIALS="${TRIALS:-10}"
GLOBAL_FRAMES="${GLOBAL_FRAMES:-450}"

build() {  # SOURCE_ROOT TARGETS: scripts/gpu_check.sh's build step there (into its build-gpu)
  (cd "$1" && GPU_CHECK_STEPS=build GPU_CHECK_TARGETS="$2" OUT="$LOGS/build_$(basename "$1")" \
    bash scripts/gpu_check.sh)
}
bench() {  # LABEL BENCH MAP ARGS...
  local label="$1" bin="$2" map="$3"
  shift 3
  "$bin" --backend cuda --map "$map" --frames-raw "$FRAMES" --frames "${BENCH_FRAMES:-30}" --warmup 3 \
    --exact 0 "$@" \
    > "$LOGS/bench_${label}.txt" 2>&1
  grep -E "^\| (cuda|Localizer)" "$LOGS/bench_${label}.txt" | sed "s/^/$label /"
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
if [[ -n "${BASE_SRC:-}" ]]; then
  build "$BASE_SRC" "gmm_mcl_bench" &
fi
build "$ROOT" "$TARGETS"
wait
step tests && echo "== CUDA suites"
for t in $TARGETS; do
  step tests || break
  [[ "$t" == test_* ]] || continue
  "$ROOT/build-gpu/$t" > "$LOGS/$t.log" 2>&1
  echo "$t: rc=$? $(grep -E '^\[  (PASSED|FAILED)' "$LOGS/$t.log" | tr '\n' ' ')"
  grep -E -A6 "Failure" "$LOGS/$t.log" | head -40
done
step cost || ROOMS=""
for room in $ROOMS; do
  map="$MAPS/7scenes_$room.gmm"
  [[ -f "$map" ]] || { echo "no $map"; continue; }
  echo "== $room"
  if [[ -n "${BASE_SRC:-}" ]]; then
    bench "base_$room" "$BASE_SRC/build-gpu/gmm_mcl_bench" "$map" --workload paper,cpu
    bench "base_step_$room" "$BASE_SRC/build-gpu/gmm_mcl_bench" "$map" --workload cpu --step \
      --budget-s 5
  fi
  bench "new_$room" "$ROOT/build-gpu/gmm_mcl_bench" "$map" --workload paper,cpu
  bench "new_step_$room" "$ROOT/build-gpu/gmm_mcl_bench" "$map" --workload cpu --step --budget-s 5
  for v in ${VARIANTS:-}; do  # NAME=FLAG,VALUE[,FLAG,VALUE...]: the same with those flags
    IFS=, read -r -a args <<< "${v#*=}"
    bench "${v%%=*}_$room" "$ROOT/build-gpu/gmm_mcl_bench" "$map" --workload paper,cpu "${args[@]}"
    bench "${v%%=*}_step_$room" "$ROOT/build-gpu/gmm_mcl_bench" "$map" --workload cpu --step \
      --budget-s 5 "${args[@]}"
  done
done

if step global && [[ -n "${GLOBAL_MAP:-}" ]]; then
  echo "== global localization: $GLOBAL_MAP"
  for seq in ${GLOBAL_SEQS:-}; do
    name="$(basename "$seq")"
    nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 250 \
      > "$LOGS/memory_$name.txt" &
    smi=$!
    "$ROOT/build-gpu/gmm_mcl_replay" --format tum --dataset "$seq" --map "$GLOBAL_MAP" \
      --backend cuda --init map --trials "$TRIALS" --frames "$GLOBAL_FRAMES" --pixel-stride 8 \
      --out "$LOGS/global_$name" ${GLOBAL_ARGS:-} > "$LOGS/global_$name.txt" 2>&1
    echo "$name: rc=$?, GPU memory peak $(sort -n "$LOGS/memory_$name.txt" | tail -1) MiB"
    kill $smi 2> /dev/null
    grep -E "^trial|^\| [0-9]|mean|success" "$LOGS/global_$name.txt" | head -30
  done
  for n in ${MEMORY_RUNS-100000 1000000}; do
    seq="$(echo ${GLOBAL_SEQS:-} | cut -d' ' -f1)"
    [[ -n "$seq" ]] || break
    nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 100 > "$LOGS/memory_$n.txt" &
    smi=$!
    "$ROOT/build-gpu/gmm_mcl_replay" --format tum --dataset "$seq" --map "$GLOBAL_MAP" \
      --backend cuda --init map --trials 1 --frames "${MEMORY_FRAMES:-10}" --pixel-stride 8 \
      --num-particles "$n" --min-particles "$n" ${MEMORY_ARGS:---lost-candidates-per-particle 1} \
      --out "$LOGS/memory_run_$n" > "$LOGS/memory_run_$n.txt" 2>&1
    echo "$n particles: rc=$?, GPU memory peak $(sort -n "$LOGS/memory_$n.txt" | tail -1) MiB" \
      "(idle $(head -1 "$LOGS/memory_$n.txt") MiB), mean step" \
      "$(grep -o 'mean step [0-9.]* ms' "$LOGS/memory_run_$n.txt")"
    kill $smi 2> /dev/null
  done
fi
