#!/usr/bin/env bash
# Screenshot of rviz (particles, pose, map ellipsoids, debug image) while the nodelet replays the
# synthetic bag, under Xvfb: for the README. Run scripts/demo_ros.sh first (it builds and writes
# build-ros/demo/sim.bag). Usage: scripts/ros_rviz_screenshot.sh [OUTPUT.png] [SECONDS]
# Another bag: BAG=... MAP=... PARAMS=... [OVERRIDES=...] (e.g. from gmm_mcl_make_7scenes_bag).
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
ensure_packages rviz xvfb imagemagick
BUILD="${GMM_MCL_ROS_BUILD_DIR:-$GMM_MCL_ROOT/build-ros}"
OUT_PNG="${1:-$BUILD/demo/rviz.png}"
WAIT_S="${2:-25}"
DEMO="$BUILD/demo"
BAG="${BAG:-$DEMO/sim.bag}"
MAP="${MAP:-${BAG%.bag}.gmm}"
PARAMS="${PARAMS:-${BAG%.bag}_init.yaml}"
OVERRIDES="${OVERRIDES:-$GMM_MCL_ROOT/config/sim_test.yaml}"
[ -f "$BAG" ] || { echo "no $BAG: run scripts/demo_ros.sh first" >&2; exit 1; }
set +u
source "$BUILD/devel/setup.bash"
set -u
export ROS_MASTER_URI="http://localhost:${ROS_PORT:-11512}"
export ROS_HOME="${ROS_HOME:-$BUILD/ros_home}"
DISPLAY_NUM="${XVFB_DISPLAY:-:97}"
Xvfb "$DISPLAY_NUM" -screen 0 1280x800x24 > "$DEMO/xvfb.log" 2>&1 &
XVFB_PID=$!
LAUNCH_PID=""
cleanup() {
  [ -n "$LAUNCH_PID" ] && kill -INT "$LAUNCH_PID" 2> /dev/null && wait "$LAUNCH_PID" 2> /dev/null || true
  ros_stop_master
  kill "$XVFB_PID" 2> /dev/null || true
}
trap cleanup EXIT
export DISPLAY="$DISPLAY_NUM"
ros_start_master "$DEMO/roscore_rviz.log"
roslaunch --wait gmm_mcl replay.launch bag:="$BAG" map:="$MAP" \
  overrides:="$OVERRIDES" params:="$PARAMS" rate:=0.3 \
  loop:=true rviz:=true > "$DEMO/roslaunch_rviz.log" 2>&1 &
LAUNCH_PID=$!
sleep "$WAIT_S"
import -display "$DISPLAY_NUM" -window root "$OUT_PNG"
echo "wrote $OUT_PNG"
