#!/usr/bin/env bash
# The full ROS path on the built-in synthetic scene: builds the nodelet (catkin, plain cmake
# build), writes the synthetic bag (gmm_mcl_make_sim_bag), starts a roscore, runs the nodelet in a
# manager via roslaunch (replay.launch: rosbag play --clock, use_sim_time), records the pose
# output, then prints the ATE against the ground truth and writes a plot (SVG) and a CSV.
# Options (environment): FRAMES (300), WIDTH (320), RATE (0.5), CONFIG (sim_test overrides),
# GMM_MCL_ROS_BUILD_DIR (build-ros), ROS_PORT (11511), RVIZ (false), RIG (unset; `both`: the
# camera rig's corridor with its forward and downward cameras, `forward`: the same bag with the
# forward camera alone; docs/multi_camera.md).
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
ensure_packages "${CORE_PACKAGES[@]}" "${ROS_PACKAGES[@]}"
BUILD="${GMM_MCL_ROS_BUILD_DIR:-$GMM_MCL_ROOT/build-ros}"
FRAMES="${FRAMES:-300}"
WIDTH="${WIDTH:-320}"
RATE="${RATE:-0.5}"
OVERRIDES="${CONFIG:-$GMM_MCL_ROOT/config/sim_test.yaml}"
export ROS_MASTER_URI="http://localhost:${ROS_PORT:-11511}"
export ROS_HOME="${ROS_HOME:-$BUILD/ros_home}"

mkdir -p "$BUILD"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DCMAKE_BUILD_TYPE=Release \
  > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
# The nodelet, its tools, and the generated messages and services (C++ and Python: rostopic,
# rosservice and rqt read the Python ones).
cmake --build "$BUILD" -j2 --target gmm_mcl_ros gmm_mcl_node gmm_mcl_make_sim_bag gmm_mcl_evaluate_pose_bag \
  gmm_mcl_generate_messages gmm_mcl_gencfg
set +u
source "$BUILD/devel/setup.bash"
set -u
OUT="$BUILD/demo"
mkdir -p "$OUT"
rig_bag=()
rig_launch=()
case "${RIG:-}" in
  "") ;;
  both) rig_bag=(--rig); rig_launch=(more_cameras:="[down]" second_camera:=down) ;;
  forward) rig_bag=(--rig) ;;
  *) echo "RIG: both or forward" >&2; exit 2 ;;
esac
"$BUILD/devel/lib/gmm_mcl/gmm_mcl_make_sim_bag" --bag "$OUT/sim.bag" --frames "$FRAMES" --width "$WIDTH" \
  --quiet "${rig_bag[@]}"

ros_start_master "$OUT/roscore.log"
trap ros_stop_master EXIT
echo "== roslaunch gmm_mcl replay.launch (rate $RATE, $FRAMES frames at ${WIDTH}px)"
rm -f "$OUT/poses.bag"
roslaunch --wait gmm_mcl replay.launch bag:="$OUT/sim.bag" map:="$OUT/sim.gmm" \
  overrides:="$OVERRIDES" params:="$OUT/sim_init.yaml" rate:="$RATE" \
  record:="$OUT/poses.bag" rviz:="${RVIZ:-false}" "${rig_launch[@]}" > "$OUT/roslaunch.log" 2>&1 || true
grep -E "gmm_mcl:" "$OUT/roslaunch.log" | head -5 || true
"$BUILD/devel/lib/gmm_mcl/gmm_mcl_evaluate_pose_bag" "$OUT/poses.bag" --skip 2 --out "$OUT/demo"
