#!/usr/bin/env bash
# The ROS nodelet with `backend: cuda` on a GPU machine that has no ROS (Ubuntu 24.04, CUDA 13,
# no network), from the bundle scripts/gpu_ros_bundle.sh packs (gpuros.tar.xz beside this
# script, or $GPUROS_ARCHIVE). Unpacks it into $GPUROS_WORK (default /tmp/gpuros_run), then runs
# the steps of $GPUROS_STEPS (default: all, in this order):
#   info       the GPU, the bundled interpreter, every bundled ELF file's libraries resolve
#   cudatests  the CUDA suites (backend parity, device particle filter, localizer with it)
#   roscore    a master starts, answers and stops
#   rostests   every rostest of the package, each with its nodelet's `backend` parameters set
#              to $BACKEND (default cuda): a copy of the test file with <param> overrides for
#              each .../backend parameter `roslaunch --dump-params` finds in it; a test passes
#              when rostest passes and, for cuda, no nodelet fell back to the CPU
#   demo       scripts/demo_ros.sh's job (synthetic bag -> replay.launch -> recorded pose ->
#              ATE) with each backend of $DEMO_BACKENDS (default "cuda cpu") on this machine;
#              per-frame times from ~status
#   live       a looped bag with $BACKEND; a ~global_localization call and a
#              dynamic_reconfigure change while it runs: the service answers, the parameter
#              reads back changed, the bag loops (stamps jump back) and the filter ends tracking
#              (20 of the last 30 steps ok), every step with $BACKEND
#   memcheck, racecheck
#              the demo (shorter) with the nodelet manager under compute-sanitizer
# Logs and a summary (summary.txt) go to $OUT (default $GPUROS_WORK/out). Exit status: the
# number of failed steps.
#   FRAMES (300), WIDTH (320), RATE (0.5): the demo bag and its playback rate, as demo_ros.sh;
#   SANITIZER_FRAMES (60), MEMCHECK_RATE (0.2), RACECHECK_RATE (0.03); LIVE_SECONDS (30);
#   ROS_PORT (11611).
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ARCHIVE="${GPUROS_ARCHIVE:-$HERE/gpuros.tar.xz}"
[[ -f "$ARCHIVE" ]] || ARCHIVE="$HERE/../.deps/gpuros/gpuros.tar.xz"
WORK="${GPUROS_WORK:-/tmp/gpuros_run}"
OUT="${OUT:-$WORK/out}"
STEPS="${GPUROS_STEPS:-info cudatests roscore rostests demo live memcheck racecheck}"
BACKEND="${BACKEND:-cuda}"
DEMO_BACKENDS="${DEMO_BACKENDS:-cuda cpu}"
FRAMES="${FRAMES:-300}"
WIDTH="${WIDTH:-320}"
RATE="${RATE:-0.5}"
SANITIZER_FRAMES="${SANITIZER_FRAMES:-60}"
MEMCHECK_RATE="${MEMCHECK_RATE:-0.2}"
RACECHECK_RATE="${RACECHECK_RATE:-0.03}"   # racecheck: about 0.5 s per update on an H100
SANITIZER_DELAY="${SANITIZER_DELAY:-45}"    # seconds between the nodelet's load and the bag
SANITIZER_EXIT_S="${SANITIZER_EXIT_S:-150}" # the longest wait for the manager under a tool to exit
LIVE_SECONDS="${LIVE_SECONDS:-30}"
SANITIZER="${COMPUTE_SANITIZER:-$(command -v compute-sanitizer || echo /usr/local/cuda/bin/compute-sanitizer)}"
mkdir -p "$WORK" "$OUT"
SUMMARY="$OUT/summary.txt"
: > "$SUMMARY"
failed=0
say() { echo "$*" | tee -a "$SUMMARY"; }
pass() { say "PASS $1: $2"; }
fail() { say "FAIL $1: $2"; failed=$((failed + 1)); }

# ---- unpack -------------------------------------------------------------------------------------
if [[ ! -f "$WORK/gpuros/env.sh" || "$ARCHIVE" -nt "$WORK/gpuros/env.sh" ]]; then
  [[ -f "$ARCHIVE" ]] || { echo "error: no bundle at $ARCHIVE (scripts/gpu_ros_bundle.sh)" >&2; exit 99; }
  rm -rf "$WORK/gpuros"
  start=$(date +%s)
  if command -v xz > /dev/null; then
    xz -dc "$ARCHIVE" | tar -C "$WORK" -xf -
  else
    python3 -c "import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2])" "$ARCHIVE" "$WORK"
  fi
  touch "$WORK/gpuros/env.sh"
  echo "== unpacked $ARCHIVE in $(( $(date +%s) - start )) s"
fi
export ROS_HOME="$WORK/ros_home"
export ROS_LOG_DIR="$WORK/ros_home/log"
# shellcheck disable=SC1091
source "$WORK/gpuros/env.sh"
export ROS_HOSTNAME=localhost
export ROS_MASTER_URI="http://localhost:${ROS_PORT:-11611}"
export PYTHONUNBUFFERED=1
SHARE="$GPUROS/ws/share/gmm_mcl"
BIN="$GPUROS/ws/lib/gmm_mcl"
NODELET="$GPUROS/usr/lib/nodelet/nodelet"

# A private roscore (ros_start_master, ros_stop_master): ros_common.sh lies beside this script
# in the checkout and in the bundle.
# shellcheck disable=SC1091
source "$HERE/ros_common.sh"
trap ros_stop_master EXIT

# status_stats BAG LABEL: per-frame figures from the recorded ~status messages.
status_stats() {
  python3 - "$1" "$2" <<'EOF'
import statistics, sys, rosbag
bag, label = sys.argv[1], sys.argv[2]
rows, backends, steps = [], {}, {}
for _, m, _ in rosbag.Bag(bag).read_messages(topics=["/gmm_mcl/status"]):
    backends[m.backend] = backends.get(m.backend, 0) + 1
    steps[m.step_status] = steps.get(m.step_status, 0) + 1
    if m.step_status == "ok":
        rows.append(m)
def med(f):
    v = [getattr(r, f) for r in rows]
    return statistics.median(v) if v else float("nan")
last = rows[-1] if rows else None
print("%s: %d status messages, backends %s, steps %s; per frame (median of %d ok steps): "
      "update %.2f ms (frame prep %.2f, projection+membership %.2f, likelihood %.2f), "
      "callback %.2f ms; particles %s; frames received %s, processed %s"
      % (label, sum(backends.values()), backends, steps, len(rows), med("total_ms"),
         med("frame_prep_ms"), med("projection_membership_ms"), med("likelihood_ms"),
         med("callback_ms"), last.particles if last else "-",
         last.frames_received if last else "-", last.frames_processed if last else "-"))
EOF
}

step_info() {
  {
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
    uname -a
    python3 -c "import sys; print('bundled python', sys.version.split()[0], sys.executable)"
    echo "system python3: $(PATH=/usr/bin:/bin python3 --version 2>&1)"
  } 2>&1 | tee "$OUT/info.log"
  local missing
  missing=$(find "$GPUROS" -type f \( -name '*.so*' -o -perm -u+x \) |
    while read -r f; do
      [[ "$(head -c 4 "$f")" == $'\x7fELF' ]] || continue
      ldd "$f" 2> /dev/null | grep -q "not found" && echo "$f"
    done)
  if [[ -n "$missing" ]]; then
    echo "$missing" > "$OUT/unresolved.txt"
    fail info "libraries not found for $(echo "$missing" | wc -l) files (unresolved.txt)"
  else
    pass info "$(head -1 "$OUT/info.log"); every bundled ELF file's libraries resolve"
  fi
}

step_roscore() {
  if ros_start_master "$OUT/roscore.log"; then
    local nodes
    nodes=$(rosnode list 2> /dev/null | tr '\n' ' ')
    ros_stop_master
    pass roscore "master answered on $ROS_MASTER_URI, nodes: $nodes"
  else
    ros_stop_master
    fail roscore "no answer (roscore.log)"
  fi
}

step_rostests() {
  local data="$WORK/data" line test args name copy log t0 n_ok=0 n=0
  mkdir -p "$data"
  # The rostests' data, written by the package's tools as the build writes it.
  while read -r line; do
    line="${line//@DATA@/$data}"
    line="${line//@BIN@/$BIN}"
    bash -c "$line" < /dev/null >> "$OUT/test_data.log" 2>&1 || { fail rostests "test data: $line (test_data.log)"; return; }
  done < "$GPUROS/test_data_commands.txt"
  while read -r test args; do
    [[ -n "$test" ]] || continue
    n=$((n + 1))
    args="${args//@DATA@/$data}"
    name="$(basename "$test" .test)"
    # Beside the original: rostest takes the package from the test file's place.
    copy="$SHARE/$(dirname "$test")/${name}_backend_$BACKEND.test"
    log="$OUT/rostest_$name.log"
    # The nodelet's backend parameters in this test, set to $BACKEND after everything else.
    # shellcheck disable=SC2086
    python3 - "$SHARE/$test" "$copy" "$BACKEND" $args <<'EOF'
import subprocess, sys, yaml
src, dst, backend, args = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
dump = subprocess.run(["roslaunch", "--dump-params", src] + args, capture_output=True, text=True,
                      stdin=subprocess.DEVNULL)
if dump.returncode != 0:
    sys.exit("roslaunch --dump-params failed: " + dump.stderr)
keys = sorted(k for k in (yaml.safe_load(dump.stdout) or {}) if k.endswith("/backend"))
text = open(src).read()
cut = text.rindex("</launch>")
extra = "".join('  <param name="%s" value="%s"/>\n' % (k, backend) for k in keys)
open(dst, "w").write(text[:cut] + extra + text[cut:])
print(" ".join(keys))
EOF
    t0=$(date +%s)
    # shellcheck disable=SC2086
    rostest --text "$copy" $args < /dev/null > "$log" 2>&1
    local rc=$? secs=$(( $(date +%s) - t0 ))
    local ready fallback
    ready=$(grep -c "components from .*, $BACKEND backend" "$log")
    fallback=$(grep -c "CUDA backend unavailable\|CUDA backend not built" "$log")
    if [[ $rc -eq 0 && $fallback -eq 0 ]]; then
      n_ok=$((n_ok + 1))
      pass "rostest $name" "$secs s, $ready nodelet start(s) with the $BACKEND backend"
    else
      fail "rostest $name" "rostest exit $rc, $fallback CPU fallback(s), $secs s ($log)"
      grep -E "FAILURE|Failure|FAILED|ERROR|\[ERROR\]" "$log" | head -10
    fi
  done < "$GPUROS/rostests.txt"
  say "rostests: $n_ok of $n passed with backend $BACKEND"
}

# make_demo_bag DIR FRAMES: the synthetic bag, map and initial region (gmm_mcl_make_sim_bag).
make_demo_bag() {
  mkdir -p "$1"
  [[ -f "$1/sim.bag" ]] || "$BIN/gmm_mcl_make_sim_bag" --bag "$1/sim.bag" --frames "$2" --width "$WIDTH" --quiet
}

# run_replay DIR BACKEND RATE LABEL [ARGS...]: replay.launch until the bag ends, pose recorded.
run_replay() {
  local d="$1" b="$2" rate="$3" label="$4"
  shift 4
  rm -f "$d/poses_$label.bag"
  roslaunch --wait gmm_mcl replay.launch bag:="$d/sim.bag" map:="$d/sim.gmm" \
    overrides:="$SHARE/config/sim_test.yaml" params:="$d/sim_init.yaml" rate:="$rate" \
    record:="$d/poses_$label.bag" backend:="$b" "$@" > "$OUT/roslaunch_$label.log" 2>&1
}

step_demo() {
  local d="$WORK/demo" b
  make_demo_bag "$d" "$FRAMES"
  ros_start_master "$OUT/roscore_demo.log" || { fail demo "no master"; return; }
  for b in $DEMO_BACKENDS; do
    local t0 secs
    t0=$(date +%s)
    run_replay "$d" "$b" "$RATE" "demo_$b"
    secs=$(( $(date +%s) - t0 ))
    if [[ ! -f "$d/poses_demo_$b.bag" ]]; then
      fail "demo $b" "no pose bag (roslaunch_demo_$b.log)"
      continue
    fi
    "$BIN/gmm_mcl_evaluate_pose_bag" "$d/poses_demo_$b.bag" --skip 2 --out "$OUT/demo_$b" > "$OUT/ate_$b.txt" 2>&1
    local ate stats
    ate=$(grep -E "ATE" "$OUT/ate_$b.txt" | tail -1)
    stats=$(status_stats "$d/poses_demo_$b.bag" "$b" 2>&1 | tail -1)
    echo "$stats" > "$OUT/stats_demo_$b.txt"
    if [[ -n "$ate" ]] && grep -q "backends {'$b'" <<< "$stats"; then
      pass "demo $b" "$ate; $stats; $secs s"
    else
      fail "demo $b" "$(tail -3 "$OUT/ate_$b.txt" | tr '\n' ' ') $stats"
    fi
  done
  ros_stop_master
}

step_live() {
  local d="$WORK/demo"
  make_demo_bag "$d" "$FRAMES"
  ros_start_master "$OUT/roscore_live.log" || { fail live "no master"; return; }
  rm -f "$d/poses_live.bag"
  roslaunch gmm_mcl replay.launch bag:="$d/sim.bag" map:="$d/sim.gmm" \
    overrides:="$SHARE/config/sim_test.yaml" params:="$d/sim_init.yaml" rate:=1.0 loop:=true \
    record:="$d/poses_live.bag" backend:="$BACKEND" > "$OUT/roslaunch_live.log" 2>&1 &
  local launch_pid=$!
  # Until the nodelet publishes (or a minute).
  timeout 60 rostopic echo -n 1 /gmm_mcl/status > /dev/null 2>&1 < /dev/null
  sleep 4
  local gl dr get
  gl=$(timeout 20 rosservice call /gmm_mcl/global_localization 2>&1); local gl_rc=$?
  sleep 3
  dr=$(timeout 20 "$GPUROS/usr/lib/dynamic_reconfigure/dynparam" set /gmm_mcl sigma_translation_m 0.031 2>&1); local dr_rc=$?
  get=$(timeout 20 "$GPUROS/usr/lib/dynamic_reconfigure/dynparam" get /gmm_mcl 2>&1)
  sleep "$LIVE_SECONDS"
  kill -INT "$launch_pid" 2> /dev/null
  wait "$launch_pid" 2> /dev/null
  ros_stop_master
  echo "global_localization: rc $gl_rc $gl" > "$OUT/live_calls.txt"
  echo "dynparam set: rc $dr_rc $dr" >> "$OUT/live_calls.txt"
  echo "dynparam get: $get" >> "$OUT/live_calls.txt"
  local stats
  stats=$(python3 - "$d/poses_live.bag" "$BACKEND" <<'EOF' 2>&1
import sys, rosbag
msgs = [m for _, m, _ in rosbag.Bag(sys.argv[1]).read_messages(topics=["/gmm_mcl/status"])]
if not msgs:
    sys.exit("no status recorded")
# The bag orders by simulated time, which jumps back at each loop: the nodelet's order instead.
msgs.sort(key=lambda m: m.frames_processed)
stamps = [m.header.stamp.to_sec() for m in msgs]
loops = sum(1 for a, b in zip(stamps, stamps[1:]) if b < a)
resets = [m.resets for m in msgs]
ok_tail = sum(1 for m in msgs[-30:] if m.step_status == "ok")
print("%d status messages, backends %s, %d loop(s) (stamp back), resets counter %s, "
      "ok in the last 30: %d, frames processed %d"
      % (len(msgs), sorted(set(m.backend for m in msgs)), loops,
         " ".join(str(r) for i, r in enumerate(resets) if i == 0 or r != resets[i - 1]),
         ok_tail, msgs[-1].frames_processed))
sys.exit(0 if set(m.backend for m in msgs) == {sys.argv[2]} and loops >= 1 and ok_tail >= 20
         else 1)
EOF
)
  local stats_rc=$?
  if [[ $gl_rc -eq 0 && $dr_rc -eq 0 && $stats_rc -eq 0 ]] &&
     grep -q "sigma_translation_m.*0.031" <<< "$get"; then
    pass live "looped bag, /gmm_mcl/global_localization answered, dynparam set took (sigma_translation_m 0.031); $stats"
  else
    fail live "service rc $gl_rc, dynparam rc $dr_rc; $stats (live_calls.txt, roslaunch_live.log)"
  fi
}

# The CUDA suites as built for the bundle (exit 77: no device).
step_cudatests() {
  local t rc
  for t in test_cuda_backend test_cuda_particle_filter_weights test_cuda_particle_filter_sampling \
    test_cuda_particle_filter_likelihood test_cuda_localizer; do
    "$BIN/$t" > "$OUT/$t.log" 2>&1
    rc=$?
    if [[ $rc -eq 0 ]]; then
      pass "$t" "$(grep -E '^\[  PASSED  \]' "$OUT/$t.log")"
    else
      fail "$t" "exit $rc ($t.log)"
      grep -E "FAILED|Failure" "$OUT/$t.log" | head -10
    fi
  done
}

step_sanitizer() {
  local tool="$1" d="$WORK/sanitizer"
  [[ -x "$SANITIZER" ]] || { fail "$tool" "compute-sanitizer not found"; return; }
  make_demo_bag "$d" "$SANITIZER_FRAMES"
  ros_start_master "$OUT/roscore_$tool.log" || { fail "$tool" "no master"; return; }
  "$SANITIZER" --tool "$tool" --log-file "$OUT/$tool.log" --print-limit 50 \
    "$NODELET" manager __name:=sanitized_manager > "$OUT/manager_$tool.log" 2>&1 &
  local san_pid=$!
  sleep 3
  local t0=$(date +%s)
  local rate="$MEMCHECK_RATE"
  [[ "$tool" == racecheck ]] && rate="$RACECHECK_RATE"
  # The nodelet's CUDA start-up under the sanitizer takes tens of seconds: the bag waits for it.
  # Another name than the launch file's own manager (gmm_mcl_manager), which the launch would
  # start beside it, replacing the instrumented one on the master.
  run_replay "$d" cuda "$rate" "$tool" manager:=sanitized_manager delay:="$SANITIZER_DELAY"
  local secs=$(( $(date +%s) - t0 ))
  rosnode kill /sanitized_manager > /dev/null 2>&1
  # The summary is written when the manager exits on its own (the tool's teardown is slow).
  for _ in $(seq 1 "$SANITIZER_EXIT_S"); do kill -0 "$san_pid" 2> /dev/null || break; sleep 1; done
  kill -INT "$san_pid" 2> /dev/null
  wait "$san_pid" 2> /dev/null
  ros_stop_master
  local summary steps
  summary=$(grep -E "ERROR SUMMARY|RACECHECK SUMMARY|LEAK SUMMARY" "$OUT/$tool.log" | tr '\n' ' ')
  steps=$(status_stats "$d/poses_$tool.bag" "$tool" 2>&1 | tail -1)
  if grep -qE "(ERROR|RACECHECK) SUMMARY: 0 (errors|hazards)" "$OUT/$tool.log" &&
     grep -q "backends {'cuda'" <<< "$steps"; then
    pass "$tool" "$summary; $steps; $secs s"
  else
    fail "$tool" "${summary:-no summary} ($tool.log); $steps"
  fi
}

for s in $STEPS; do
  echo "== step $s"
  case "$s" in
    info) step_info ;;
    roscore) step_roscore ;;
    rostests) step_rostests ;;
    demo) step_demo ;;
    live) step_live ;;
    cudatests) step_cudatests ;;
    memcheck | racecheck) step_sanitizer "$s" ;;
    *) fail "$s" "unknown step" ;;
  esac
done
echo "== summary ($OUT/summary.txt)"
cat "$SUMMARY"
exit "$failed"
