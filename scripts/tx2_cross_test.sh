#!/usr/bin/env bash
# Jetson TX2 proxy 1: the core, the CPU backend and their unit tests cross-compiled for 64-bit
# Arm (aarch64, the TX2's CPU) with Debian's g++-aarch64-linux-gnu and arm64 multiarch
# libraries (cmake/toolchains/aarch64-linux-gnu.cmake), no -march=native and so none of the
# x86 AVX2/FMA paths, and run under qemu-aarch64 (user-mode emulation). Installs what is missing
# (apt: the cross compiler, qemu-user, libpng-dev:arm64, libgtest-dev:arm64; adds the arm64
# architecture to dpkg once). Builds into build/aarch64 (GMM_MCL_AARCH64_BUILD_DIR).
#
#   scripts/tx2_cross_test.sh        # every case of every core unit test (hours under qemu)
#   scripts/tx2_cross_test.sh --ci   # the same less eleven long cases, test_pose_refinement not built (scripts/test.sh runs this)
#
# The --ci filter leaves out the cases that take minutes emulated (qemu emulates their double
# precision references and OpenMP loops slowly; docs/tx2.md has the measured times):
# LocalizerTest.ConvergesFromAUniformFourMetreCube (200 frames x 1068 particles at stride 4:
# 3 min natively on this 2-core machine), MembershipTest.FastTableEqualsBruteForceAtRandomPoses
# and .ApproximateLikelihoodWithinOnePercentOfExact, LikelihoodTest.FloatKernelAgreesWith-
# DoubleReferencePerPixel, BackendThreadsTest.SameLikelihoodsForEveryThreadCount,
# LocalizerTest.AWideStartSearchesAroundItsBestCandidates (48,000 candidates scored twice per
# seed: 7 s natively, minutes emulated), LocalizerTest.AWideStartFollowsItsPlacesAndTheBest-
# SeedsTheParticles (two runs of 30 frames with 3000 particles: 12 s natively; the places'
# own code runs in test_start_hypotheses' cases in the sanitizer stage). The same kernels run
# emulated in the other membership, likelihood, depth-noise and localizer cases. test_pose_refinement
# is not built: each of its cases refines in double precision over whole frames (the first three
# took over 10 min emulated together, the two localizer depth-scale cases 3 min), and the C++14
# and sanitizer stages cover it. Two programs at a time (ctest -j2): each is one emulated process.
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/tx2_common.sh"

CI_MODE="$(tx2_switch --ci "$@")"

ensure_packages "${CORE_PACKAGES[@]}"
ensure_arm64_packages

BUILD="${GMM_MCL_AARCH64_BUILD_DIR:-$GMM_MCL_ROOT/build/aarch64}"
TESTS=(test_gmm_map test_depth_frame test_projection test_membership test_likelihood
  test_depth_noise test_params test_resampling test_particle_filter test_localizer
  test_lost_detector test_backend_threads test_camera_input_validation
  test_map_input_validation
  fuzz_replay_map_loader fuzz_replay_depth_frame fuzz_replay_compressed_depth)
SLOW_CASES="LocalizerTest.ConvergesFromAUniformFourMetreCube:MembershipTest.FastTableEqualsBruteForceAtRandomPoses"
SLOW_CASES+=":MembershipTest.ApproximateLikelihoodWithinOnePercentOfExact"
SLOW_CASES+=":LikelihoodTest.FloatKernelAgreesWithDoubleReferencePerPixel"
SLOW_CASES+=":BackendThreadsTest.SameLikelihoodsForEveryThreadCount"
SLOW_CASES+=":LocalizerTest.BackendFailureFallsBackToTheCpuBackendKeepingTheParticles"
SLOW_CASES+=":LocalizerTest.SetParamsKeepsTheBelief:LocalizerTest.SetMapKeepsTheParticles"
SLOW_CASES+=":LocalizerTest.PerFrameExtrinsicsEnterWithoutTouchingTheBelief"
SLOW_CASES+=":LocalizerTest.AWideStartSearchesAroundItsBestCandidates"
SLOW_CASES+=":LocalizerTest.AWideStartFollowsItsPlacesAndTheBestSeedsTheParticles"
SLOW_CASES+=":LocalizerTest.ARivalPlaceThatScoresBetterTakesTheParticles"
SLOW_CASES+=":LocalizerTest.ASetAtTheTruthKeepsItsPlaceAgainstRivals"
# Static archives of what the tests link (libgomp.a comes with the cross compiler, libpng.a and
# libz.a with libpng-dev:arm64 and zlib1g-dev:arm64).
GOMP_A="$(aarch64-linux-gnu-g++ -print-file-name=libgomp.a)"

launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
mkdir -p "$BUILD"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" \
  -DCMAKE_TOOLCHAIN_FILE="$GMM_MCL_ROOT/cmake/toolchains/aarch64-linux-gnu.cmake" \
  -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON -DGMM_MCL_BUILD_FIT=OFF \
  -DGMM_MCL_NATIVE_ARCH=OFF -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" \
  -DCMAKE_EXE_LINKER_FLAGS=-static -DOpenMP_gomp_LIBRARY="$GOMP_A" \
  -DPNG_LIBRARY_RELEASE=/usr/lib/aarch64-linux-gnu/libpng.a \
  -DZLIB_LIBRARY_RELEASE=/usr/lib/aarch64-linux-gnu/libz.a \
  > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
start=$(date +%s)
cmake --build "$BUILD" -j2 --target "${TESTS[@]}"
echo "== aarch64 build took $(( $(date +%s) - start )) s"

# What was built is static Arm code, and the x86 vector paths were not compiled in.
for t in "${TESTS[@]}"; do
  machine=$(readelf -h "$BUILD/$t" | sed -n 's/^ *Machine: *//p')
  [[ "$machine" == "AArch64" ]] || { echo "error: $t is built for '$machine', not AArch64" >&2; exit 1; }
  if readelf -d "$BUILD/$t" | grep -q NEEDED; then
    echo "error: $t is linked dynamically (qemu-aarch64 hangs on its exceptions)" >&2; exit 1
  fi
done
if aarch64-linux-gnu-g++ -dM -E -x c++ /dev/null | grep -qE '__(AVX|SSE)'; then
  echo "error: the aarch64 compiler defines x86 vector macros" >&2; exit 1
fi
echo "== ${#TESTS[@]} test programs built for AArch64 ($(aarch64-linux-gnu-g++ -dumpfullversion)); $(qemu-aarch64 --version | head -1)"

# ctest runs each through qemu-aarch64 (CMAKE_CROSSCOMPILING_EMULATOR). libgomp's idle threads
# sleep instead of spinning: spinning emulated threads take the cores from the working ones.
filter=""
timeout_s=21600
[[ "$CI_MODE" -eq 1 ]] && { filter="-$SLOW_CASES"; timeout_s=600; }
regex="^($(IFS='|'; echo "${TESTS[*]}"))\$"
start=$(date +%s)
(cd "$BUILD" && env OMP_WAIT_POLICY=passive ${filter:+GTEST_FILTER="$filter"} \
  ctest -j2 --output-on-failure --timeout "$timeout_s" -R "$regex") | tee "$BUILD/ctest.log"
echo "== aarch64 tests under qemu took $(( $(date +%s) - start )) s${filter:+ (left out: ${SLOW_CASES//:/, })}"
