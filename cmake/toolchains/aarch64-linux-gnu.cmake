# Cross-compiling for 64-bit Arm Linux (the Jetson TX2's CPU) with Debian's GNU cross compilers
# (g++-aarch64-linux-gnu) and arm64 multiarch libraries (dpkg --add-architecture arm64;
# libpng-dev:arm64, libgtest-dev:arm64), for scripts/tx2_cross_test.sh:
#
#   cmake -S . -B build/aarch64 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchains/aarch64-linux-gnu.cmake \
#         -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_NATIVE_ARCH=OFF
#
# The tests then run under qemu-aarch64 (ctest uses CMAKE_CROSSCOMPILING_EMULATOR). Eigen is
# header-only (libeigen3-dev is architecture-independent); OpenMP's libgomp comes with the cross
# compiler.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(GMM_MCL_CROSS_TRIPLE aarch64-linux-gnu)

set(CMAKE_C_COMPILER ${GMM_MCL_CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${GMM_MCL_CROSS_TRIPLE}-g++)
# Multiarch: arm64 libraries live in /usr/lib/aarch64-linux-gnu, their headers in /usr/include
# beside the build machine's; the cross compiler's own runtime in /usr/aarch64-linux-gnu.
set(CMAKE_LIBRARY_ARCHITECTURE ${GMM_MCL_CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH /usr/${GMM_MCL_CROSS_TRIPLE} /)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
# Never the build machine's x86-64 libraries.
set(CMAKE_IGNORE_PATH /usr/lib/x86_64-linux-gnu /lib/x86_64-linux-gnu
    /usr/lib/x86_64-linux-gnu/cmake)

# ctest runs the test programs through user-mode emulation; QEMU_LD_PREFIX points the
# emulated loader at the arm64 C library (the multiarch libraries are found through it).
find_program(GMM_MCL_QEMU_AARCH64 qemu-aarch64)
if(GMM_MCL_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${GMM_MCL_QEMU_AARCH64} -L /usr/${GMM_MCL_CROSS_TRIPLE})
endif()
