#!/usr/bin/env bash
# Soak test of the ROS nodelet (docs/soak.md): N synthetic frames (default 50,000,
# 160x120, looped ping-pong) through gmm_mcl/LocalizationNodelet in a nodelet manager (100
# particles, pixel stride 8, one OpenMP thread), in lockstep with the nodelet (the next frame
# when the previous frame's ~status arrives, 2 s timeout). Prints one table: frames sent /
# received / processed / dropped, frames/s, the manager's VmRSS at the end of warm-up and at
# the end, the largest map -> odom gaps, NaN counts. Exits non-zero when a target is missed.
#
#   scripts/soak.sh [--frames N] [--warmup N] [--particles N] [--stride PX] [--build DIR]
#                   [--no-build] [--port P] [--out DIR] [--no-rss-check]
#
# Builds what it needs in build/soak (ROS on); a private roscore on a free port (or --port).
set -euo pipefail
SCRIPT_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
source "$SCRIPT_DIR/common.sh"
source "$SCRIPT_DIR/ros_common.sh"

FRAMES=50000
WARMUP=""
PARTICLES=100
STRIDE=8
BUILD="$GMM_MCL_ROOT/build/soak"
DO_BUILD=1
PORT=""
OUT=""
RSS_CHECK=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --frames) FRAMES="$2"; shift 2 ;;
    --warmup) WARMUP="$2"; shift 2 ;;
    --particles) PARTICLES="$2"; shift 2 ;;
    --stride) STRIDE="$2"; shift 2 ;;
    --build) BUILD="$2"; shift 2 ;;
    --no-build) DO_BUILD=0; shift ;;
    --port) PORT="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --no-rss-check) RSS_CHECK=(--no-rss-check); shift ;;
    -h|--help) sed -n 2,12p "$0"; exit 0 ;;
    *) echo "unknown argument: $1" >&2; exit 2 ;;
  esac
done
# Warm-up: the first 5,000 frames, or a tenth of a shorter run.
[[ -z "$WARMUP" ]] && WARMUP=$(( FRAMES >= 50000 ? 5000 : FRAMES / 10 ))
OUT="${OUT:-$BUILD/soak_run}"
mkdir -p "$OUT"

# The monitor's Python messages (python3-tf2-msgs is not among ROS_PACKAGES).
SOAK_PACKAGES=(python3-rospy python3-tf2-msgs python3-diagnostic-msgs python3-geometry-msgs
  python3-std-msgs)
ensure_packages "${SOAK_PACKAGES[@]}"
if [[ $DO_BUILD -eq 1 ]]; then
  ensure_packages "${CORE_PACKAGES[@]}" "${ROS_PACKAGES[@]}"
  echo "== building in $BUILD (log: $BUILD/soak_build.log)"
  mkdir -p "$BUILD"
  {
    cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DGMM_MCL_BUILD_TESTS=ON \
      -DCMAKE_BUILD_TYPE=Release &&
    cmake --build "$BUILD" -j2 --target gmm_mcl_soak_publisher gmm_mcl_ros
  } > "$BUILD/soak_build.log" 2>&1 || { tail -30 "$BUILD/soak_build.log"; exit 1; }
fi
PUBLISHER="$BUILD/devel/lib/gmm_mcl/gmm_mcl_soak_publisher"
[[ -x "$PUBLISHER" ]] || { echo "no $PUBLISHER: build first" >&2; exit 1; }
# setup.bash puts the source tree on ROS_PACKAGE_PATH (launch files, nodelet plugin) and the
# generated Python messages on PYTHONPATH; it reads unset variables.
set +u
source "$BUILD/devel/setup.bash"
set -u

if [[ -z "$PORT" ]]; then
  PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])')
fi
export ROS_MASTER_URI="http://localhost:$PORT"
# One OpenMP thread in the manager: on a shared 2-core machine two spinning OpenMP threads
# compete with every other process (measured: 4-7x slower steps). Override from outside.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
export ROS_HOME="$OUT/ros_home"
mkdir -p "$ROS_HOME"

MANAGER_PID=""
LAUNCH_PID=""
PUB_PID=""
cleanup() {
  local p
  for p in "$PUB_PID" "$LAUNCH_PID" "$MANAGER_PID"; do
    if [[ -n "$p" ]] && kill -0 "$p" 2> /dev/null; then
      kill -INT "$p" 2> /dev/null || true
      for _ in $(seq 1 20); do kill -0 "$p" 2> /dev/null || break; sleep 0.25; done
      kill -KILL "$p" 2> /dev/null || true
    fi
  done
  ros_stop_master
}
trap cleanup EXIT

"$PUBLISHER" --write-map "$OUT/soak.gmm" --write-params "$OUT/soak_init.yaml"
echo "== roscore on port $PORT; logs in $OUT"
ros_start_master "$OUT/roscore.log"
# The manager on its own, so that its pid is the process whose memory is sampled.
rosrun nodelet nodelet manager __name:=soak_manager > "$OUT/manager.log" 2>&1 &
MANAGER_PID=$!
# By path: other copies of the source tree on ROS_PACKAGE_PATH make "gmm_mcl soak.launch" ambiguous.
roslaunch --wait "$GMM_MCL_ROOT/launch/soak.launch" map:="$OUT/soak.gmm" init:="$OUT/soak_init.yaml" \
  manager:=soak_manager particles:="$PARTICLES" stride:="$STRIDE" > "$OUT/launch.log" 2>&1 &
LAUNCH_PID=$!
# rosrun execs the binary: the pid becomes the manager's once rosrun has found it.
for _ in $(seq 1 120); do
  [[ "$(cat /proc/$MANAGER_PID/comm 2> /dev/null)" == nodelet ]] && break
  sleep 0.25
done
[[ "$(cat /proc/$MANAGER_PID/comm 2> /dev/null)" == nodelet ]] ||
  { echo "the nodelet manager did not start (see $OUT/manager.log)" >&2; exit 1; }

echo "== soak: $FRAMES frames, N=$PARTICLES particles, stride $STRIDE, warm-up $WARMUP frames"
uptime
START=$(date +%s)
"$PUBLISHER" --frames "$FRAMES" > "$OUT/publisher.log" 2>&1 &
PUB_PID=$!
set +e
python3 "$GMM_MCL_ROOT/scripts/soak_monitor.py" --pid "$MANAGER_PID" --frames "$FRAMES" \
  --warmup "$WARMUP" --out "$OUT" "${RSS_CHECK[@]}" --timeout $(( 600 + FRAMES / 2 )) \
  --publisher-pid "$PUB_PID"
RC=$?
wait "$PUB_PID" 2> /dev/null
PUB_RC=$?
PUB_PID=""
set -e
tail -1 "$OUT/publisher.log"
echo "== wall $(( $(date +%s) - START )) s; $(uptime)"
if [[ $PUB_RC -ne 0 && $RC -eq 0 ]]; then
  echo "== the publisher failed ($PUB_RC): $OUT/publisher.log" >&2
  RC=1
fi
exit $RC
