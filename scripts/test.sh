#!/usr/bin/env bash
# Every test: installs what is missing (apt), builds the core, the backends, the tools, the ROS
# nodelet and all tests, and runs them with ctest (gtest suites, rostests, the sources'
# clang-format check, the package installed into a temporary prefix and run from there, fuzz
# corpus replays);
# then compiles the CUDA backend with nvcc (its tests skip without a GPU); then the Jetson TX2
# proxies (docs/tx2.md); then builds the core's unit tests with ASan and UBSan in their own
# folder and runs them. Data-set tests read
# ../shared/datasets (or $GMM_MCL_DATASETS) and skip with a printed reason when it is absent.
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
ensure_packages "${CORE_PACKAGES[@]}" "${ROS_PACKAGES[@]}" python3 python3-numpy python3-sklearn \
  clang-format

BUILD="${GMM_MCL_BUILD_DIR:-$GMM_MCL_ROOT/build/test}"
mkdir -p "$BUILD"
# Strict ISO C++14 (-pedantic-errors), the Jetson TX2 proxy below: the build is the check.
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DGMM_MCL_BUILD_TESTS=ON \
  -DGMM_MCL_STRICT_CXX14=ON -DCMAKE_BUILD_TYPE=Release -DCMAKE_EXPORT_COMPILE_COMMANDS=ON \
  > "$BUILD/cmake.log" 2>&1 \
  || { cat "$BUILD/cmake.log"; exit 1; }
start=$(date +%s)
cmake --build "$BUILD" -j2
echo "== build took $(( $(date +%s) - start )) s"
start=$(date +%s)
export ROS_HOME="$BUILD/ros_home"  # rostest logs stay in the build folder
# Two at a time for the tests without ROS (seeded, on the data's own time: a second test beside
# them changes only how long they take; the longest start first, cmake/test_costs.cmake), then
# the rostests and the install space two at a time (each rostest on its own master, rostest's
# free port, in lockstep with a clock its test owns or a bag it waits for), then the soak beside
# nothing else. Passive OpenMP threads: two tests' spinning pools would take each other's cores.
ROS_TESTS='rostest|soak|install_space'
(cd "$BUILD" && OMP_WAIT_POLICY=passive ctest -j2 --output-on-failure --timeout 1200 \
  -E "$ROS_TESTS") | tee "$BUILD/ctest.log"
echo "== tests without ROS took $(( $(date +%s) - start )) s"
ros_start=$(date +%s)
(cd "$BUILD" && OMP_WAIT_POLICY=passive ctest -j2 --output-on-failure --timeout 1200 \
  -R 'rostest|install_space') | tee -a "$BUILD/ctest.log"
(cd "$BUILD" && ctest --output-on-failure --timeout 1200 -R soak) | tee -a "$BUILD/ctest.log"
echo "== ROS tests took $(( $(date +%s) - ros_start )) s"
echo "== tests took $(( $(date +%s) - start )) s"

# CUDA backend: compiled with nvcc (one architecture); its tests skip without a GPU. (The
# benchmark, whose code is the same with and without CUDA, is built with CUDA by the GPU
# machine's scripts, scripts/gpu_check.sh.)
if [ -x "$NVCC" ]; then
  CUDA_BUILD="${GMM_MCL_CUDA_BUILD_DIR:-$GMM_MCL_ROOT/build/test-cuda}"
  mkdir -p "$CUDA_BUILD"
  cmake -S "$GMM_MCL_ROOT" -B "$CUDA_BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON \
    -DGMM_MCL_BUILD_FIT=OFF -DGMM_MCL_WITH_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=75 \
    -DCMAKE_CUDA_COMPILER="$NVCC" -DCMAKE_BUILD_TYPE=Release > "$CUDA_BUILD/cmake.log" 2>&1 \
    || { cat "$CUDA_BUILD/cmake.log"; exit 1; }
  start=$(date +%s)
  cmake --build "$CUDA_BUILD" -j2 --target test_cuda_backend test_cuda_particle_filter_weights \
    test_cuda_particle_filter_sampling test_cuda_particle_filter_likelihood test_cuda_localizer
  echo "== CUDA build took $(( $(date +%s) - start )) s"
  (cd "$CUDA_BUILD" && ctest --output-on-failure -R 'test_cuda_(backend|particle_filter|localizer)') \
    | tee "$CUDA_BUILD/ctest.log"
else
  echo "== nvcc not found: CUDA backend not compiled"
fi

# Jetson TX2 proxies (docs/tx2.md): every package source as strict C++14 (the main build's
# compile commands: it compiled them so, GMM_MCL_STRICT_CXX14), the ROS Melodic checks, the CUDA backend by nvcc 11.8 for sm_62 when
# scripts/tx2_cuda_compile.sh has installed it, and the core's unit tests cross-built for
# aarch64 and run under qemu (less the cases that take minutes emulated).
start=$(date +%s)
"$GMM_MCL_ROOT/scripts/tx2_cxx14_check.sh" "$BUILD"
"$GMM_MCL_ROOT/scripts/tx2_melodic_check.sh"
"$GMM_MCL_ROOT/scripts/tx2_cuda_compile.sh" --if-installed
echo "== TX2 compile checks took $(( $(date +%s) - start )) s"
AARCH64_BUILD="${GMM_MCL_AARCH64_BUILD_DIR:-${BUILD}-aarch64}"
start=$(date +%s)
GMM_MCL_AARCH64_BUILD_DIR="$AARCH64_BUILD" "$GMM_MCL_ROOT/scripts/tx2_cross_test.sh" --ci
echo "== TX2 aarch64 stage took $(( $(date +%s) - start )) s"

# Sanitizers: the core's gtest suites (map, camera, measurement, filter), the input-validation
# cases and the fuzz corpus replays, built with -fsanitize=address,undefined
# (cmake/sanitize.cmake) in their own folder, ROS and the map builder off, and run. Not here:
# the rostests (ROS), the 7-Scenes regression (minutes even without ASan), the map builder's and
# the replay tools' suites (their libraries would double the build), and three cases:
# LocalizerTest.ConvergesFromAUniformFourMetreCube (200 frames x 1068 particles: over 10 min
# under ASan; the CPU backend's OpenMP path runs in test_backend_threads, its kernels in
# test_membership and test_likelihood, and the other LocalizerTest cases run the localizer's
# step on bad frames, time and odometry jumps) and the camera rig's two runs (the corridor, two
# 80-step runs of 1500 particles; the room loop, two 150-step runs; the other
# LocalizerCamerasTest cases run the rig's code paths), and the localizer's depth-scale cases
# (DepthScaleTest: 30-frame runs; PoseRefinementTest runs the same estimate's code, one camera
# and a rig), and the wide starts in the synthetic room: the places followed (two 30-frame runs
# of 3000 particles; test_start_hypotheses runs the places' code) and the local stage (six first
# updates of 3000 particles, 3 minutes under ASan; ParticleFilterTest runs its draws around the
# best candidates). Two programs at a time, their OpenMP threads passive.
#  - detect_leaks=1: LeakSanitizer at exit (the default on x86-64 Linux, stated).
#  - halt_on_error/abort_on_error: the first report ends the test with a non-zero status.
#  - libgomp is not instrumented; the CPU backend's OpenMP loops (1-3 threads) run under ASan
#    without reports (its thread pool stays reachable at exit, so LeakSanitizer does not count
#    it), and no suppression file is needed.
SAN_BUILD="${GMM_MCL_SANITIZE_BUILD_DIR:-${BUILD}-asan}"
SANITIZE_TESTS=(test_gmm_map test_depth_frame test_projection test_membership test_likelihood
  test_depth_noise test_params test_resampling test_particle_filter test_localizer test_localizer_cameras test_pose_refinement test_lost_detector test_backend_threads
  test_parameter_table test_stamped_buffer test_pose_reset test_building_scale test_motion_model
  test_start_hypotheses
  test_camera_input_validation test_map_input_validation fuzz_replay_map_loader fuzz_replay_depth_frame fuzz_replay_compressed_depth)
mkdir -p "$SAN_BUILD"
# -O1 without NDEBUG: a third less compile time than -O3 (most of this stage), and assert()
# and Eigen's index checks stay on.
cmake -S "$GMM_MCL_ROOT" -B "$SAN_BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON \
  -DGMM_MCL_BUILD_FIT=OFF -DGMM_MCL_SANITIZE=ON -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS_RELEASE="-O1" > "$SAN_BUILD/cmake.log" 2>&1 \
  || { cat "$SAN_BUILD/cmake.log"; exit 1; }
# Only the listed targets that this tree defines (a part may be configured out).
targets=$(cmake --build "$SAN_BUILD" --target help | sed -n 's/^\.\.\. \([A-Za-z0-9_]*\).*/\1/p')
san_targets=()
for t in "${SANITIZE_TESTS[@]}"; do
  grep -qx "$t" <<< "$targets" && san_targets+=("$t")
done
start=$(date +%s)
cmake --build "$SAN_BUILD" -j2 --target "${san_targets[@]}"
echo "== sanitizer build took $(( $(date +%s) - start )) s"
start=$(date +%s)
regex="^($(IFS='|'; echo "${san_targets[*]}"))\$"
(cd "$SAN_BUILD" && OMP_WAIT_POLICY=passive \
  ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=1:strict_string_checks=1" \
  UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1" \
  GTEST_FILTER="-LocalizerTest.ConvergesFromAUniformFourMetreCube:LocalizerCamerasTest.ADownwardCameraResolvesTheCorridorTheForwardCameraCannot:LocalizerCamerasTest.ACameraWithMorePixelsAddsToTheFirstOneAndMayDropOut:DepthScaleTest.*:LocalizerTest.AWideStartFollowsItsPlacesAndTheBestSeedsTheParticles:LocalizerTest.AWideStartSearchesAroundItsBestCandidates:LocalizerTest.ASetAtTheTruthKeepsItsPlaceAgainstRivals" \
  ctest -j2 --output-on-failure --timeout 600 -R "$regex") | tee "$SAN_BUILD/ctest.log"
echo "== sanitizer tests took $(( $(date +%s) - start )) s"

# One closing line over all ctest runs (set -e has already stopped on any failure).
passed=0
skipped=0
for log in "$BUILD/ctest.log" "${CUDA_BUILD:-/nonexistent}/ctest.log" "$AARCH64_BUILD/ctest.log" \
           "$SAN_BUILD/ctest.log"; do
  [ -f "$log" ] || continue
  passed=$((passed + $(grep -cE 'Test +#[0-9]+: .* Passed' "$log" || true)))
  skipped=$((skipped + $(grep -cE 'Test +#[0-9]+: .*\*\*\*Skipped' "$log" || true)))
done
echo "${passed} passed, 0 failed, ${skipped} skipped"
