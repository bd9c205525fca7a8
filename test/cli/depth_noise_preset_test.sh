#!/usr/bin/env bash
# gmm_mcl_replay's --depth-noise-preset (docs/measurement_model.md "Sensor presets"): listed by
# --help; a preset's numbers are the ones the replay runs with (its settings line); a number
# given beside it overrides it; without one the default model is unchanged; an unknown name
# stops the tool (status 2) with an error naming the flag and the valid names.
#   depth_noise_preset_test.sh PATH_TO_gmm_mcl_replay
set -u
tool="$1"
source "$(dirname "${BASH_SOURCE[0]}")/cli_test_common.sh"

"$tool" --help | grep -q -- "--depth-noise-preset" || fail "--help does not list --depth-noise-preset"

"$tool" --make-fixture tum "$work/tum" --frames 6 --width 80 --seed 3 > /dev/null ||
  { echo "[ FAILED  ] --make-fixture"; exit 1; }
replay() {
  "$tool" --format tum --dataset "$work/tum" --map "$work/tum/map.gmm" --trials 1 \
    --num-particles 50 --hold-frames 2 --tail-frames 3 --quiet --out "$work/out" "$@" 2>&1
}
# Each case: the arguments | what the settings line must say about the depth noise.
cases=(
  "|depth noise 0.0012 + 0.0019 (z - 0.4)^2 m"
  "--depth-noise-preset custom|depth noise 0.0012 + 0.0019 (z - 0.4)^2 m"
  "--depth-noise-preset realsense_d435_848x480|depth noise 0 + 0.003774 (z - 0)^2 m"
  "--depth-noise-preset realsense_d435_848x480 --depth-noise-a-m 0.002|depth noise 0.002 + 0.003774 (z - 0)^2 m"
  "--depth-noise 0.001,0.002,0.5 --depth-noise-preset kinect_v2|depth noise 0.001 + 0.002 (z - 0.5)^2 m"
  "--depth-noise-preset kinect_v2|depth noise 0.001292 + 0.0003 (z - 0.83)^2 m"
)
for c in "${cases[@]}"; do
  IFS='|' read -r args expected <<< "$c"
  # shellcheck disable=SC2086
  out="$(replay $args)"
  rc=$?
  # 0 or 1 (six frames need not converge: the trial may count as failed); 2: a refused flag.
  if [[ $rc -gt 1 ]] || ! grep -qF -- "$expected" <<< "$out"; then
    fail "'$args': exit $rc, expected '$expected' in: $(head -3 <<< "$out")"
  else
    echo "[ ok      ] '$args': $expected"
  fi
done

err="$(replay --depth-noise-preset realsense_d999)"
rc=$?
first="$(head -1 <<< "$err")"
if [[ $rc -ne 2 ]] || ! grep -q -- "--depth-noise-preset" <<< "$first" ||
   ! grep -q "realsense_d435_848x480" <<< "$first"; then
  fail "unknown preset: exit $rc, first line: $first"
else
  echo "[ ok      ] unknown preset: exit 2, $first"
fi
[[ $failed -eq 0 ]]
