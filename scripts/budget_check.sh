#!/usr/bin/env bash
# The frame-rate budget on real data: the 7-Scenes redkitchen bag played in real time (30 Hz)
# through the nodelet with the CPU backend and the budget on, then the same bag in lockstep with
# the budget off, every frame used (the reference), then real time again from the true pose. Prints, per run, the
# frames sent / received / used, the stride and particle cap the budget settled on, the ATE of
# ~pose against the ground truth, and the machine's load average during the run.
# Not part of CI (about 15 minutes on this 2-core machine under load). Options (environment):
#   GMM_MCL_ROS_BUILD_DIR (build/ros)   the ROS build to use (configured and built here)
#   GMM_MCL_DATASETS (../shared/datasets), MAP (build/maps/7scenes_redkitchen_m1000.gmm; made
#   by scripts/build_map_7scenes.sh when missing), FRAMES (1000), CONFIG (config/desktop.yaml),
#   REF_RATE (lockstep: each frame waits for the last one's ~status; or a rosbag play rate),
#   SKIP (5: seconds before the ATE counts), RUNS ("budget reference budget_pose";
#   budget_pose and reference_pose start from the true pose instead of the uniform 4 m region),
#   ROS_PORT (11517), OUT ($BUILD/budget_check).
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
BUILD="${GMM_MCL_ROS_BUILD_DIR:-$GMM_MCL_ROOT/build/ros}"
MAP="${MAP:-$GMM_MCL_ROOT/build/maps/7scenes_redkitchen_m1000.gmm}"
FRAMES="${FRAMES:-1000}"
CONFIG="${CONFIG:-$GMM_MCL_ROOT/config/desktop.yaml}"
REF_RATE="${REF_RATE:-lockstep}"
SKIP="${SKIP:-5}"
RUNS="${RUNS:-budget reference budget_pose}"
OUT="${OUT:-$BUILD/budget_check}"
export ROS_MASTER_URI="http://localhost:${ROS_PORT:-11517}"
export ROS_HOME="${ROS_HOME:-$BUILD/ros_home}"
export PATH="/usr/bin:$PATH"

if [ ! -d "$DATASETS/7scenes_redkitchen/data" ]; then
  echo "skipped: no 7-Scenes redkitchen under $DATASETS" >&2
  exit 0
fi
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$BUILD" -j2 --target gmm_mcl_ros gmm_mcl_make_7scenes_bag gmm_mcl_evaluate_pose_bag \
  gmm_mcl_generate_messages gmm_mcl_gencfg
[ -f "$MAP" ] || "$GMM_MCL_ROOT/scripts/build_map_7scenes.sh" "$DATASETS" "$MAP"
set +u
source "$BUILD/devel/setup.bash"
set -u
mkdir -p "$OUT"
BAG="$OUT/7s.bag"
if [ ! -f "$BAG" ]; then
  "$BUILD/devel/lib/gmm_mcl/gmm_mcl_make_7scenes_bag" "$DATASETS/7scenes_redkitchen/data" --map "$MAP" \
    --bag "$BAG" --frames "$FRAMES"
fi
SENT=$(python3 -c "import rosbag,sys; b=rosbag.Bag(sys.argv[1]); print(b.get_message_count('/camera/depth/image_raw'))" "$BAG")

ros_start_master "$OUT/roscore.log"
LOAD_PID=""
cleanup() {
  [ -n "$LOAD_PID" ] && kill "$LOAD_PID" 2> /dev/null || true
  ros_stop_master
}
trap cleanup EXIT

# run NAME RATE BUDGET(true|false) QUEUE [START]: the reference queues frames (queue_size) so
# that none is dropped while an update runs. START pose: a single-pose start (initial_pose_*) at
# the bag's true start, 0.1 m / 0.1 rad standard deviation, instead of the uniform region.
run() {
  local name="$1" rate="$2" budget="$3" queue="$4" start="${5:-region}"
  printf 'update_budget: %s\nqueue_size: %s\n' "$budget" "$queue" > "$OUT/$name.yaml"
  if [ "$start" = pose ]; then
    python3 - "$OUT/7s_init.yaml" >> "$OUT/$name.yaml" << 'PY'
import sys, yaml
p = yaml.safe_load(open(sys.argv[1]))
x, y, z = p["init_centre"]
print("initial_pose_x: %r\ninitial_pose_y: %r\ninitial_pose_z: %r\ninitial_pose_yaw: %r" % (x, y, z, p["init_yaw_centre"]))
print("initial_cov_xx: 0.01\ninitial_cov_yy: 0.01\ninitial_cov_zz: 0.01\ninitial_cov_yawyaw: 0.01")
PY
  fi
  rm -f "$OUT/$name.bag"
  rosparam delete /gmm_mcl > /dev/null 2>&1 || true  # no pose saved by an earlier run
  (while true; do uptime; sleep 5; done) > "$OUT/$name.load" &
  LOAD_PID=$!
  local t0=$SECONDS
  echo "== $name: $( [ "$rate" = lockstep ] && echo "lockstep playback" || echo "rosbag play -r $rate"), update_budget $budget ($(uptime | sed 's/.*load/load/'))"
  if [ "$rate" = lockstep ]; then
    # Every frame, however long an update takes: each depth frame waits for the last one's status.
    rosparam set /use_sim_time true
    roslaunch --wait gmm_mcl localization.launch map:="$OUT/7s.gmm" config:="$CONFIG" \
      overrides:="$OUT/$name.yaml" params:="$OUT/7s_init.yaml" > "$OUT/$name.log" 2>&1 &
    local launch_pid=$!
    rosbag record -O "$OUT/$name.bag" /gmm_mcl/pose /gmm_mcl/status /ground_truth /tf \
      > "$OUT/$name.record.log" 2>&1 &
    local record_pid=$!
    python3 "$GMM_MCL_ROOT/scripts/lockstep_play.py" "$BAG" | tee -a "$OUT/$name.play.log" || true
    sleep 2
    kill -INT "$record_pid" "$launch_pid" 2> /dev/null || true
    wait "$record_pid" "$launch_pid" 2> /dev/null || true
    rosparam delete /use_sim_time > /dev/null 2>&1 || true
  else
    roslaunch --wait gmm_mcl replay.launch bag:="$BAG" map:="$OUT/7s.gmm" config:="$CONFIG" \
      overrides:="$OUT/$name.yaml" params:="$OUT/7s_init.yaml" rate:="$rate" \
      record:="$OUT/$name.bag" > "$OUT/$name.log" 2>&1 || true
  fi
  kill "$LOAD_PID" 2> /dev/null || true
  LOAD_PID=""
  local load
  load=$(sed 's/.*load average: //' "$OUT/$name.load" | awk -F', ' '{s+=$1; if ($1>m) m=$1; n++} END {printf "%.2f mean, %.2f max (1-min average, %d samples)", s/n, m, n}')
  echo "   wall $((SECONDS - t0)) s; load $load"
  grep -E "update budget" "$OUT/$name.log" | sed 's/^.*gmm_mcl: /   /' | tail -n 8 || true
  python3 "$GMM_MCL_ROOT/scripts/budget_status.py" "$OUT/$name.bag" "$SENT" | tee "$OUT/$name.summary"
  "$BUILD/devel/lib/gmm_mcl/gmm_mcl_evaluate_pose_bag" "$OUT/$name.bag" --skip "$SKIP" --out "$OUT/$name" \
    | tee "$OUT/$name.ate"
}

for r in $RUNS; do
  case "$r" in
    budget) run budget 1.0 true 1 ;;
    reference) run reference "$REF_RATE" false 100 ;;
    budget_pose) run budget_pose 1.0 true 1 pose ;;
    reference_pose) run reference_pose "$REF_RATE" false 100 pose ;;
    *) echo "unknown run $r (budget, reference, budget_pose, reference_pose)" >&2; exit 2 ;;
  esac
done
