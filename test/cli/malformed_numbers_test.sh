#!/usr/bin/env bash
# Every tool given a malformed number must stop with an error that names the flag and a
# non-zero exit status (not run with 0 or a default in its place).
#   malformed_numbers_test.sh TOOL=PATH ...   (the tools that were built; others are skipped)
set -u
declare -A path
for a in "$@"; do path["${a%%=*}"]="${a#*=}"; done

# tool | arguments | the flag the error must name
cases=(
  "gmm_mcl_replay|--map x.gmm --trials abc|--trials"
  "gmm_mcl_replay|--map x.gmm --lost-margin-nats 1.5x|--lost-margin-nats"
  "gmm_mcl_replay|--map x.gmm --particles 1e3x|--num-particles"
  "gmm_mcl_kidnap|--trials 3.5|--trials"
  "gmm_mcl_kidnap|--lost-margin-nats abc|--lost-margin-nats"
  "gmm_mcl_bench|--frames abc|--frames"
  "gmm_mcl_bench|--cuda-band-patches abc|--cuda-band-patches"
  "gmm_mcl_score|--map x.gmm --pixel-stride 8px|--pixel-stride"
  "gmm_mcl_score|--map x.gmm --stride 8px|--pixel-stride"
  "gmm_mcl_score|--map x.gmm --max-range-m far|--max-range-m"
  "gmm_mcl_sim_demo|--frames 1e|--frames"
  "gmm_mcl_sim_demo|--temperature hot|--temperature"
  "gmm_mcl_figures|nll-sweep --range-m wide|--range-m"
  "gmm_mcl_render|--out OUT --frames abc|--frames"
  "gmm_mcl_fit|cloud.ply -o x.gmm -m abc|--components"
  "gmm_mcl_fit|cloud.ply -o x.gmm --crop-box -1 -1 0 1 1 x|--crop-box"
  "gmm_mcl_inspect|x.gmm --sigma abc|--sigma"
  "gmm_mcl_make_sim_bag|--bag x.bag --frames abc|--frames"
  "gmm_mcl_make_7scenes_bag|DIR --map x.gmm --bag x.bag --frames abc|--frames"
  "gmm_mcl_evaluate_pose_bag|x.bag --skip abc|--skip"
  "gmm_mcl_make_bag|--format sim x.bag --frames abc|--frames"
  "gmm_mcl_replay_bag|x.bag --map x.gmm --num-particles abc|--num-particles"
  "gmm_mcl_replay_bag|x.bag --map x.gmm --particles abc|--num-particles"
  "gmm_mcl_replay_bag|x.bag --map x.gmm --max-range 4m|--max-range-m"
  "gmm_mcl_soak_publisher|--frames abc|--frames"
)

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
failed=0 checked=0
for c in "${cases[@]}"; do
  IFS='|' read -r tool args flag <<< "$c"
  exe="${path[$tool]:-}"
  if [[ -z "$exe" ]]; then
    echo "[ skipped ] $tool (not built)"
    continue
  fi
  # shellcheck disable=SC2086
  err="$(timeout 60 "$exe" $args 2>&1 > /dev/null)"
  rc=$?
  checked=$((checked + 1))
  first="$(printf '%s\n' "$err" | head -1)"
  if [[ $rc -eq 0 || $rc -eq 124 ]] || ! grep -q -- "$flag'\?\( \|:\|$\)" <<< "$first"; then
    echo "[ FAILED  ] $tool $args: exit $rc, first line: $first"
    failed=1
  else
    echo "[ ok      ] $tool $args: exit $rc, $first"
  fi
done
echo "$checked cases checked"
[[ $checked -gt 0 && $failed -eq 0 ]]
