#!/usr/bin/env bash
# scripts/build_map_7scenes.sh and scripts/build_map_replica.sh give gmm_mcl_fit their defaults
# (-m 1000, --seed 1, ...) unless the user's extra options name them: `-m 4000` (or
# `--components 4000`, `--components=4000`) replaces the default instead of repeating the
# option, which gmm_mcl_fit refuses ("cannot be specified more than once"). A stand-in for
# gmm_mcl_fit records the arguments; every option must come once, with the expected value.
#   map_scripts_test.sh PACKAGE_ROOT
set -u
root="$1"
source "$(dirname "${BASH_SOURCE[0]}")/cli_test_common.sh"
printf '#!/usr/bin/env bash\nprintf "%%s\\n" "$@" > "$FIT_ARGS_OUT"\n' > "$work/fit"
printf '#!/bin/sh\nexit 0\n' > "$work/inspect"
chmod +x "$work/fit" "$work/inspect"
mkdir -p "$work/data/7scenes_redkitchen/data" "$work/data/replica_office0"
touch "$work/data/7scenes_redkitchen/data/camera-intrinsics.txt"
touch "$work/data/replica_office0/office0_mesh.ply"
export GMM_FIT="$work/fit" GMM_INSPECT="$work/inspect" FIT_ARGS_OUT="$work/args"

# values OPTION [ALIAS]: the values given to OPTION in the recorded arguments, one per line.
values() {
  awk -v a="$1" -v b="${2:-$1}" '
    take { print; take = 0; next }
    $0 == a || $0 == b { take = 1; next }
    index($0, a "=") == 1 { print substr($0, length(a) + 2) }' "$work/args"
}
# check SCRIPT COMPONENTS SEED EXTRA...: the script run with EXTRA gives gmm_mcl_fit one
# component count (COMPONENTS), one seed (SEED) and no option twice.
check() {
  local script="$1" m="$2" seed="$3" got before="$failed"
  failed=0
  shift 3
  rm -f "$work/args"
  if ! bash "$root/scripts/$script" "$work/data" "$work/map.gmm" "$@" > "$work/log" 2>&1; then
    fail "$script $*: exit status $?: $(cat "$work/log")"
    return
  fi
  got="$(values --components -m | tr '\n' ' ')"
  [[ "$got" == "$m " ]] || fail "$script $*: components given as '$got', expected '$m '"
  got="$(values --seed | tr '\n' ' ')"
  [[ "$got" == "$seed " ]] || fail "$script $*: seed given as '$got', expected '$seed '"
  got="$(grep -E '^-' "$work/args" | sed 's/=.*//; s/^-m$/--components/' | sort | uniq -d)"
  [[ -z "$got" ]] || fail "$script $*: options given twice: $got"
  [[ "$failed" == 0 ]] && echo "[       OK ] $script $* -> $(tr '\n' ' ' < "$work/args")"
  [[ "$before" == 0 ]] || failed=1
}
for script in build_map_7scenes.sh build_map_replica.sh; do
  check "$script" 1000 1
  check "$script" 4000 1 -m 4000
  check "$script" 2000 1 --components 2000
  check "$script" 3000 7 --components=3000 --seed 7
done
exit "$failed"
