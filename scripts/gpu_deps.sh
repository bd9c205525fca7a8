#!/usr/bin/env bash
# Fills .deps/ (git-ignored), on this machine, with what scripts/gpu_check.sh builds and runs
# with on a GPU machine that has CUDA and CMake but no Eigen, googletest or Boost and no network
# (the H100 machine: Ubuntu 24.04, CUDA 13):
#   .deps/eigen3        Eigen's headers (libeigen3-dev)
#   .deps/googletest    googletest's sources (googletest)
#   .deps/boost         boost::program_options: the headers it includes and its library
#                       (libboost-program-options-dev; about 3.5 MB)
#   .deps/png           libpng and zlib, headers and libraries (about 0.4 MB)
# and the 7-Scenes inputs of the parity test and the benchmark, when the maps are built here
# (scripts/build_map_7scenes.sh):
#   .deps/7scenes_redkitchen_m1000.gmm, .deps/7scenes_redkitchen_m4000.gmm   (from build/maps)
#   .deps/7scenes_frames30.bin   the first 30 frames (gmm_mcl_bench --export-frames; GMM_MCL_BENCH)
# Then copy the working tree with .deps/ there and run scripts/gpu_check.sh.
#
#   scripts/gpu_deps.sh              # DEPS=.deps, MAPS=build/maps
set -euo pipefail
source "$(dirname "$0")/common.sh"
ensure_packages "${CORE_PACKAGES[@]}"
DEPS="${DEPS:-$GMM_MCL_ROOT/.deps}"
MAPS="${MAPS:-$GMM_MCL_ROOT/build/maps}"
mkdir -p "$DEPS"

rm -rf "$DEPS/eigen3" "$DEPS/googletest" "$DEPS/boost"
cp -r /usr/include/eigen3 "$DEPS/eigen3"
cp -r /usr/src/googletest "$DEPS/googletest"
mkdir -p "$DEPS/boost/include" "$DEPS/boost/lib"
echo '#include <boost/program_options.hpp>' | g++ -x c++ -M - | tr ' \\' '\n\n' |
  sed -n 's|^/usr/include/\(boost/.*\)|\1|p' | sort -u | while read -r h; do
    mkdir -p "$DEPS/boost/include/$(dirname "$h")"
    cp "/usr/include/$h" "$DEPS/boost/include/$h"
  done
# Plain files, no links: the library under its soname (what programs load) and its link name.
lib="$(readlink -f "$(g++ -print-file-name=libboost_program_options.so)")"
cp "$lib" "$DEPS/boost/lib/"
cp "$lib" "$DEPS/boost/lib/libboost_program_options.so"
echo "== $DEPS: eigen3, googletest, boost ($(du -sh "$DEPS/boost" | cut -f1))"
# libpng and zlib (headers and libraries): the data-set readers and the tools that read depth
# PNGs (replay, kidnap, render) build there too.
rm -rf "$DEPS/png"
mkdir -p "$DEPS/png/include" "$DEPS/png/lib"
cp /usr/include/png.h /usr/include/pngconf.h /usr/include/pnglibconf.h /usr/include/zlib.h \
  /usr/include/zconf.h "$DEPS/png/include/"
for l in libpng16.so libz.so; do
  real="$(readlink -f "$(g++ -print-file-name=$l)")"
  cp "$real" "$DEPS/png/lib/$l"
  cp "$real" "$DEPS/png/lib/$(objdump -p "$real" | sed -n 's/^ *SONAME *//p')"
done
echo "== $DEPS/png: libpng, zlib"

for m in 7scenes_redkitchen_m1000.gmm 7scenes_redkitchen_m4000.gmm; do
  if [[ -f "$MAPS/$m" ]]; then
    cp "$MAPS/$m" "$DEPS/$m"
    echo "== $DEPS/$m"
  else
    echo "== no $MAPS/$m (scripts/build_map_7scenes.sh builds it): gpu_check.sh falls back"
  fi
done
if [[ -f "$DEPS/7scenes_redkitchen_m1000.gmm" ]]; then
  BENCH="$(find_tool gmm_mcl_bench GMM_MCL_BENCH)"
  "$BENCH" --map "$DEPS/7scenes_redkitchen_m1000.gmm" --frames 30 \
    --export-frames "$DEPS/7scenes_frames30.bin"
  echo "== $DEPS/7scenes_frames30.bin"
fi
