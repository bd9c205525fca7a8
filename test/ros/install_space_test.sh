#!/usr/bin/env bash
# The package as deployed from an install space: installs a built tree into a temporary prefix
# and runs it from there in a fresh environment that sources only that prefix's setup.bash (the
# source tree and the build folder are nowhere on the paths):
#  - every tool and the core library resolve (each tool prints its usage; no missing shared
#    library), and the nodes are installed;
#  - a program on the umbrella header gmm_mcl/gmm_mcl.h compiles against the installed headers
#    alone and runs against the installed core; internal/ and private headers are not installed;
#  - localization.launch loads the nodelet from the install space into a manager, and its
#    services and messages answer from Python (rosservice call, rostopic type, rosmsg);
#  - replay.launch plays a bag written by the installed gmm_mcl_make_sim_bag, and removes
#    /use_sim_time from the master when it ends.
#   install_space_test.sh BUILD_DIR MAP.gmm
set -euo pipefail
BUILD="$1"
MAP="$2"
TMP="$(mktemp -d)"
# Installed under DESTDIR into the prefix the build was configured with: catkin writes its
# setup files to the configured CMAKE_INSTALL_PREFIX whatever `cmake --install --prefix` says
# (they would land in /usr/local), and setup.bash finds its own folder when sourced.
CONFIGURED_PREFIX="$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$BUILD/CMakeCache.txt")"
PREFIX="$TMP/root${CONFIGURED_PREFIX:-/usr/local}"
PIDS=()
cleanup() {
  for pid in "${PIDS[@]}"; do kill -TERM "$pid" 2> /dev/null || true; done
  for pid in "${PIDS[@]}"; do wait "$pid" 2> /dev/null || true; done
  rm -rf "$TMP"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*" >&2
  for f in "$TMP"/*.log; do echo "---- $f"; tail -30 "$f"; done >&2
  exit 1
}

DESTDIR="$TMP/root" cmake --install "$BUILD" > "$TMP/install.log" 2>&1 || fail "cmake --install"
if grep -v "^-- .*$TMP/root/" "$TMP/install.log" | grep -q "^-- \(Installing\|Up-to-date\)"; then
  fail "files installed outside the install space: $(grep -v "$TMP/root/" "$TMP/install.log" | head -3)"
fi
echo "installed into $PREFIX: $(find "$PREFIX" -type f | wc -l) files"

PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])')
# A clean environment: only the install space (and Debian's ROS in /usr).
run() {
  env -i HOME="$TMP" PATH=/usr/bin:/bin ROS_MASTER_URI="http://localhost:$PORT" \
    ROS_HOME="$TMP/ros_home" PREFIX="$PREFIX" MAP="$MAP" TMP="$TMP" \
    bash -c "set +u; source '$PREFIX/setup.bash'; set -u; $1"
}
# A long-running command in the background, its PID the command's own (so that TERM reaches
# it), its output unbuffered into LOG (the nodelet's start-up line is checked there).
start() {
  env -i HOME="$TMP" PATH=/usr/bin:/bin ROS_MASTER_URI="http://localhost:$PORT" \
    ROS_HOME="$TMP/ros_home" PREFIX="$PREFIX" MAP="$MAP" TMP="$TMP" PYTHONUNBUFFERED=1 \
    bash -c "set +u; source '$PREFIX/setup.bash'; set -u; exec stdbuf -oL -eL $2" > "$1" 2>&1 &
  PIDS+=($!)
}

# The environment points at the install space only.
run 'test "$(rospack find gmm_mcl)" = "$PREFIX/share/gmm_mcl"' ||
  fail "rospack find gmm_mcl is not the install space: $(run 'rospack find gmm_mcl' 2>&1)"
for lib in "$PREFIX"/lib/libgmm_mcl_*.so; do
  if run "ldd '$lib'" | grep -q "not found"; then fail "$lib: $(run "ldd '$lib'" | grep 'not found')"; fi
done
TOOLS=(gmm_mcl_fit gmm_mcl_inspect gmm_mcl_replay gmm_mcl_score gmm_mcl_bench gmm_mcl_kidnap
  gmm_mcl_render gmm_mcl_sim_demo gmm_mcl_figures gmm_mcl_params gmm_mcl_make_bag
  gmm_mcl_make_sim_bag gmm_mcl_make_7scenes_bag gmm_mcl_replay_bag gmm_mcl_evaluate_pose_bag)
for tool in "${TOOLS[@]}"; do
  run "rosrun gmm_mcl $tool --help" > "$TMP/$tool.log" 2>&1 || fail "rosrun gmm_mcl $tool --help"
done
# The nodes (they wait for a master): installed and executable.
for node in gmm_mcl_node gmm_mcl_ground_truth_odometry gmm_mcl_soak_publisher; do
  [ -x "$PREFIX/lib/gmm_mcl/$node" ] || fail "$node is not in the install space"
done
echo "tools: ${TOOLS[*]} run"

# The API (docs/architecture.md): the umbrella header compiles against the installed headers
# alone and a program on it links and runs against the installed core; internal/, the CUDA parts'
# headers and those of the static libraries are not installed.
[ -f "$PREFIX/include/gmm_mcl/gmm_mcl.h" ] || fail "include/gmm_mcl/gmm_mcl.h is not installed"
for private in internal backend/cuda_backend.h filter/cuda_particle_filter.h sim datasets cli; do
  [ ! -e "$PREFIX/include/gmm_mcl/$private" ] || fail "include/gmm_mcl/$private is installed"
done
cat > "$TMP/api.cpp" << 'CPP'
#include <gmm_mcl/gmm_mcl.h>

#include <cstdio>

int main() {
  using namespace gmm_mcl;
  std::vector<GaussianComponent> components(2);
  components[0].weight = components[1].weight = 0.5;
  components[1].mean_m = Eigen::Vector3d(1.0, 2.0, 0.5);
  const GmmMap map(components);
  const InitRegion bounds = mapBounds(map);
  LocalizerParams params;
  params.filter.num_particles = 100;
  Localizer localizer(params, map);
  std::printf("%s backend, %s filter, %zu parameters, map bounds centre %.2f %.2f %.2f\n",
              localizer.backend().name().c_str(), localizer.filterName().c_str(),
              localizerParamTable().size(), bounds.centre_m.x(), bounds.centre_m.y(),
              bounds.centre_m.z());
  return localizer.filter().size() == 100 ? 0 : 1;
}
CPP
run 'g++ -std=c++14 -DEIGEN_MAX_STATIC_ALIGN_BYTES=0 -I"$PREFIX/include" -I/usr/include/eigen3 \
     "$TMP/api.cpp" -o "$TMP/api" -L"$PREFIX/lib" -lgmm_mcl_core -Wl,-rpath,"$PREFIX/lib" && "$TMP/api"' \
  > "$TMP/api.log" 2>&1 || fail "a program on gmm_mcl/gmm_mcl.h against the install space: $(tail -5 "$TMP/api.log")"
echo "API: $(find "$PREFIX/include/gmm_mcl" -name '*.h' | wc -l) headers installed; gmm_mcl.h: $(cat "$TMP/api.log")"

start "$TMP/roscore.log" 'roscore -p "${ROS_MASTER_URI##*:}"'
for _ in $(seq 1 120); do run 'rosparam get /run_id' > /dev/null 2>&1 && break; sleep 0.5; done
run 'rosparam get /run_id' > /dev/null 2>&1 || fail "roscore did not start"

# The nodelet from the install space, in its manager.
start "$TMP/localization.log" 'roslaunch gmm_mcl localization.launch map:="$MAP"'
LAUNCH=${PIDS[-1]}
run 'timeout 120 rosservice call --wait /gmm_mcl/global_localization' > "$TMP/service.log" 2>&1 ||
  fail "rosservice call /gmm_mcl/global_localization (std_srvs from Python, the nodelet loaded)"
run 'rostopic type /gmm_mcl/status' | grep -q '^gmm_mcl/FilterStatus$' || fail "rostopic type /gmm_mcl/status"
run 'rosmsg show gmm_mcl/FilterStatus' | grep -q 'frames_received' || fail "rosmsg show gmm_mcl/FilterStatus"
run 'rosservice type /gmm_mcl/reload_map' | grep -q '^gmm_mcl/LoadMap$' || fail "rosservice type /gmm_mcl/reload_map"
grep -q "gmm_mcl: .* components from" "$TMP/localization.log" || fail "the nodelet did not start"
echo "localization.launch: the nodelet loaded from $PREFIX/lib and answered ~global_localization"
kill -TERM "$LAUNCH"
wait "$LAUNCH" || true

# replay.launch with a bag from the installed gmm_mcl_make_sim_bag, looped until the nodelet's
# poses reach the recorder (the test waits for them, not for a time: on a loaded machine the
# nodelet may start after a short bag has ended); /use_sim_time is gone after the launch ends.
run 'rosrun gmm_mcl gmm_mcl_make_sim_bag --bag "$TMP/short.bag" --map "$TMP/short.gmm" --frames 30 --width 160 --quiet' \
  > "$TMP/gmm_mcl_make_sim_bag.log" 2>&1 || fail "gmm_mcl_make_sim_bag"
start "$TMP/replay.log" 'roslaunch gmm_mcl replay.launch bag:="$TMP/short.bag" map:="$TMP/short.gmm" \
       overrides:="$PREFIX/share/gmm_mcl/config/sim_test.yaml" params:="$TMP/short_init.yaml" \
       loop:=true delay:=1 record:="$TMP/poses.bag"'
REPLAY=${PIDS[-1]}
# Poses published after the recorder has subscribed are in its bag.
run 'for _ in $(seq 1 480); do rostopic info /gmm_mcl/pose 2> /dev/null | grep -q "/recorder" && exit 0
     sleep 0.5; done; exit 1' || fail "the recorder of replay.launch never subscribed to /gmm_mcl/pose"
run 'timeout 300 rostopic echo -n 5 /gmm_mcl/pose' > "$TMP/poses.log" 2>&1 ||
  fail "replay.launch's nodelet published no pose"
kill -INT "$REPLAY"
wait "$REPLAY" || true
run 'rosbag info "$TMP/poses.bag"' | grep -q "/gmm_mcl/pose" || fail "no pose recorded by replay.launch"
if run 'rosparam get /use_sim_time' > /dev/null 2>&1; then
  fail "/use_sim_time is still set after replay.launch ended: $(run 'rosparam get /use_sim_time')"
fi
echo "replay.launch: poses recorded, /use_sim_time removed when it ended"
echo "install space test passed"
