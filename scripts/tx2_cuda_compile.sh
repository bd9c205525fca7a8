#!/usr/bin/env bash
# Jetson TX2 proxy 2: the CUDA backend (kernels and host code) compiled by nvcc 11.8 for sm_62
# (the TX2's GPU) as C++14, through the project's CMake (cmake/cuda_backend.cmake with
# CMAKE_CUDA_ARCHITECTURES=62), every nvcc warning an error; then the backend's test and the
# benchmark linked against CUDA 11.8's runtime. nvcc 11.8 is Debian 12's nvidia-cuda-toolkit
# (non-free), unpacked into /opt/gmm_mcl/cuda-11.8 when missing (scripts/tx2_common.sh says why
# not apt-get install), with g++-11 as the host compiler. Builds into build/tx2-cuda
# (GMM_MCL_TX2_CUDA_BUILD_DIR).
#
#   scripts/tx2_cuda_compile.sh                  # installs what is missing, compiles, links
#   scripts/tx2_cuda_compile.sh --if-installed   # CI: compiles only (no link), or says it skipped
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/tx2_common.sh"

IF_INSTALLED="$(tx2_switch --if-installed "$@")"

if [[ "$IF_INSTALLED" -eq 1 ]]; then
  if ! tx2_cuda_toolkit_present; then
    echo "== skipped: nvcc 11.8 not installed ($TX2_NVCC; scripts/tx2_cuda_compile.sh installs it)"
    exit 0
  fi
else
  ensure_packages "${CORE_PACKAGES[@]}"
  ensure_cuda_toolkit_11
fi

BUILD="${GMM_MCL_TX2_CUDA_BUILD_DIR:-$GMM_MCL_ROOT/build/tx2-cuda}"
mkdir -p "$BUILD"
# -Werror all-warnings: nvcc's own warnings (deprecated architectures or features, host/device
# mismatches, ...) fail the build. GMM_MCL_NATIVE_ARCH=OFF: the TX2's compile has no x86 flags.
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_BUILD_TESTS=ON \
  -DGMM_MCL_BUILD_FIT=OFF -DGMM_MCL_NATIVE_ARCH=OFF -DGMM_MCL_WITH_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES=62 -DCMAKE_CUDA_COMPILER="$TX2_NVCC" \
  -DCMAKE_CUDA_HOST_COMPILER="$TX2_CUDA_HOST_CXX" -DCMAKE_CUDA_FLAGS="-Werror all-warnings" \
  -DCMAKE_BUILD_TYPE=Release > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
grep -q "CUDA backend for architectures 62" "$BUILD/cmake.log" ||
  { echo "error: the CUDA backend was not configured for sm_62" >&2; exit 1; }
targets=(gmm_mcl_cuda gmm_mcl_cuda_sort)
[[ "$IF_INSTALLED" -eq 1 ]] || targets+=(test_cuda_backend gmm_mcl_bench)
start=$(date +%s)
cmake --build "$BUILD" -j2 --target "${targets[@]}"
# The objects hold sm_62 machine code.
for o in "$BUILD"/CMakeFiles/gmm_mcl_cuda{,_sort}.dir/src/{backend,filter}/cuda/*.cu.o; do
  [[ -e "$o" ]] || continue
  "$TX2_CUDA_PREFIX/usr/bin/cuobjdump" --list-elf "$o" | grep -q "sm_62" ||
    { echo "error: $o has no sm_62 code" >&2; exit 1; }
done
echo "== nvcc $("$TX2_NVCC" --version | sed -n 's/.*release \([0-9.]*\).*/\1/p') -std=c++14 sm_62:" \
  "${targets[*]} built in $(( $(date +%s) - start )) s"
