#!/usr/bin/env bash
# The host side of the GPU scripts, which nothing else runs here (their GPU side needs a GPU
# machine): every script parses, and the rostest data commands that scripts/gpu_ros_bundle.sh
# carries (BUILD/ros_test_data_commands.txt, written by test/CMakeLists.txt) run as
# scripts/gpu_ros_check.sh runs them there, with @BIN@ the package's programs and @DATA@ a fresh
# folder, and write every file the rostests read. A restructure that moves a program, a build
# rule or an argument fails here instead of on the GPU machine.
#
# usage: gpu_bundle_host_test.sh SOURCE_DIR BUILD_DIR BIN_DIR
set -euo pipefail
SRC="$1"
BUILD="$2"
BIN="$3"
fail() { echo "FAIL: $*" >&2; exit 1; }

for s in "$SRC"/scripts/gpu_*.sh "$SRC"/scripts/ros_common.sh "$SRC"/scripts/common.sh; do
  bash -n "$s" || fail "$s does not parse"
done
echo "ok   $(ls "$SRC"/scripts/gpu_*.sh | wc -l) GPU scripts parse"

COMMANDS="$BUILD/ros_test_data_commands.txt"
[[ -s "$COMMANDS" ]] || fail "$COMMANDS missing or empty (test/CMakeLists.txt writes it)"
grep -q 'cp "$BUILD/ros_test_data_commands.txt"' "$SRC/scripts/gpu_ros_bundle.sh" ||
  fail "scripts/gpu_ros_bundle.sh no longer carries ros_test_data_commands.txt"
# The bundle refuses any command but these two kinds; so does this test.
if grep -vE '^(mkdir -p|@BIN@/)' "$COMMANDS"; then fail "a command above is neither kind"; fi
DATA="$(mktemp -d)"
trap 'rm -rf "$DATA"' EXIT
n=0
while read -r line; do
  [[ -n "$line" ]] || continue
  cmd="${line//@BIN@/$BIN}"
  cmd="${cmd//@DATA@/$DATA}"
  prog="$(cut -d' ' -f1 <<< "$cmd")"
  [[ "$prog" == mkdir || -x "$prog" ]] || fail "no program $prog (from: $line)"
  eval "$cmd" > /dev/null || fail "command failed: $line"
  n=$((n + 1))
done < "$COMMANDS"
# Every file the rostests name under the data folder exists now.
for f in ros_test/sim.bag ros_test/sim.gmm ros_test/sim_init.yaml ros_test/sim_building.gmm \
         ros_test_datasets/sim_cow.bag; do
  [[ -s "$DATA/$f" ]] || fail "the data commands did not write $f"
done
echo "ok   $n data commands ran and wrote the rostests' files"
