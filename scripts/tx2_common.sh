# Shared by the Jetson TX2 proxies (scripts/tx2_*.sh): the Debian packages each needs, installed
# when missing (idempotent, as root or through sudo). Sourced after scripts/common.sh.

# Debian's GNU cross compiler for 64-bit Arm, user-mode emulation, and the arm64 multiarch
# libraries the core links (libpng) and tests with (googletest). Eigen is architecture-free
# (CORE_PACKAGES has it); libgomp comes with the cross compiler.
TX2_CROSS_PACKAGES=(g++-aarch64-linux-gnu qemu-user libpng-dev:arm64 zlib1g-dev:arm64 libgtest-dev:arm64)

# tx2_switch FLAG ARGS...: prints 1 when ARGS is FLAG, 0 when empty; anything else is a usage
# error (exit 2). Each TX2 script takes one optional switch.
tx2_switch() {
  local flag="$1"
  shift
  case "$*" in
    "") echo 0 ;;
    "$flag") echo 1 ;;
    *) echo "usage: $(basename "$0") [$flag]" >&2; exit 2 ;;
  esac
}

tx2_sudo() {
  if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

# ensure_arm64_packages: adds the arm64 architecture to dpkg (once) and installs
# TX2_CROSS_PACKAGES.
ensure_arm64_packages() {
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then
    echo "== dpkg --add-architecture arm64"
    tx2_sudo dpkg --add-architecture arm64
    apt_get update -qq
  fi
  ensure_packages "${TX2_CROSS_PACKAGES[@]}"
}

# ensure_nonfree: adds Debian's non-free component to the apt sources of the main archive
# (deb822 .sources files and the one-line sources.list format alike), once, then apt-get update.
ensure_nonfree() {
  local changed=0 f
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    # Stanzas whose URIs end in /debian (not debian-security) and whose Components lack non-free.
    if awk 'BEGIN{RS=""} /URIs:[^\n]*\/debian\/?(\n|$)/ && /Components:/ && !/Components:[^\n]*[ \t]non-free([ \t]|\n|$)/ {found=1} END{exit !found}' "$f"; then
      tx2_sudo cp "$f" "$f.bak-before-non-free"
      awk 'BEGIN{RS=""; ORS="\n\n"} {
             if ($0 ~ /URIs:[^\n]*\/debian\/?(\n|$)/ && $0 !~ /Components:[^\n]*[ \t]non-free([ \t]|\n|$)/)
               sub(/Components:[^\n]*/, "& non-free");
             print }' "$f.bak-before-non-free" | tx2_sudo tee "$f" > /dev/null
      echo "== added non-free to $f (previous version: $f.bak-before-non-free)"
      changed=1
    fi
  done
  if [ -f /etc/apt/sources.list ] &&
     grep -qE '^deb +[^ ]*/debian/? +[a-z-]+ .*main' /etc/apt/sources.list &&
     ! grep -qE '^deb +[^ ]*/debian/? +[a-z-]+ .*[ ]non-free( |$)' /etc/apt/sources.list; then
    tx2_sudo sed -i.bak-before-non-free -E \
      '/^deb +[^ ]*\/debian\/? +[a-z-]+ .*main/{/ non-free( |$)/!s/$/ non-free/}' /etc/apt/sources.list
    echo "== added non-free to /etc/apt/sources.list"
    changed=1
  fi
  if [ "$changed" -eq 1 ]; then apt_get update -qq; fi
}

# Debian 12's CUDA 11.8 (nvidia-cuda-toolkit, non-free): the newest CUDA that still compiles for
# sm_62 (the TX2's Pascal GPU) and the nearest to JetPack 4's CUDA 10.2. apt cannot install the
# package on a machine without an NVIDIA driver short of the driver's user space (libcuda1 from
# contrib, GLX diversions), which a compile needs nothing of: ensure_cuda_toolkit_11 downloads
# the compiler's packages with apt-get download and unpacks them with dpkg -x into
# $TX2_CUDA_PREFIX (default /opt/gmm_mcl/cuda-11.8, outside any checkout so that every clone
# finds it), keeping nvcc, its tools, the headers and the CUDA runtime, and writes an
# nvcc.profile for that place. Host compiler: g++-11 (nvcc 11.8 takes GCC <= 11; Debian's
# package wires the same through its g++ wrapper). Idempotent: a finished unpack is kept.
TX2_CUDA_PREFIX="${TX2_CUDA_PREFIX:-/opt/gmm_mcl/cuda-11.8}"
TX2_NVCC="$TX2_CUDA_PREFIX/usr/lib/nvidia-cuda-toolkit/bin/nvcc"
TX2_CUDA_HOST_CXX=g++-11

tx2_cuda_toolkit_present() {
  [ -x "$TX2_NVCC" ] && [ -f "$TX2_CUDA_PREFIX/.complete" ] &&
    [ -f "$TX2_CUDA_PREFIX/usr/include/cub/cub.cuh" ] && command -v "$TX2_CUDA_HOST_CXX" > /dev/null
}

ensure_cuda_toolkit_11() {
  ensure_packages "$TX2_CUDA_HOST_CXX"
  tx2_cuda_toolkit_present && return 0
  ensure_nonfree
  local tmp p
  tmp="$(mktemp -d)"
  echo "== downloading Debian's CUDA 11.8 compiler packages (about 870 MB) into $tmp"
  # libcub-dev: the device filter's sorts and scans (src/filter/cuda/filter_sort.cu); Debian keeps cub apart.
  (cd "$tmp" && apt-get download -qq nvidia-cuda-toolkit nvidia-cuda-dev libcudart11.0 libnvvm4 \
     libcub-dev libthrust-dev)
  tx2_sudo rm -rf "$TX2_CUDA_PREFIX.partial"
  tx2_sudo mkdir -p "$TX2_CUDA_PREFIX.partial"
  for p in "$tmp"/*.deb; do tx2_sudo dpkg -x "$p" "$TX2_CUDA_PREFIX.partial"; done
  rm -rf "$tmp"
  # Keep the runtime; leave out the math libraries, static archives and debugger (2.5 GB).
  (cd "$TX2_CUDA_PREFIX.partial/usr/lib/x86_64-linux-gnu" &&
   tx2_sudo find . -mindepth 1 -maxdepth 1 ! -name 'libcudart*' ! -name 'libcudadevrt.a' \
     ! -name 'libnvvm*' ! -name stubs -exec rm -rf {} +)
  # CMake expects one toolkit root (bin/, include/, lib64/, nvvm/libdevice): Debian's
  # /usr/lib/cuda is that root in part; complete it with relative links.
  local root="$TX2_CUDA_PREFIX.partial/usr/lib/cuda" nv="$TX2_CUDA_PREFIX/usr/lib/nvidia-cuda-toolkit"
  tx2_sudo rm -rf "$root/include" "$root/lib64"
  tx2_sudo ln -s ../../include "$root/include"
  tx2_sudo ln -s ../x86_64-linux-gnu "$root/lib64"
  for p in nvlink fatbinary ptxas cudafe++ bin2c nvprune cuobjdump; do
    tx2_sudo ln -sf "../../../bin/$p" "$root/bin/$p"
  done
  tx2_sudo rm -f "$TX2_CUDA_PREFIX.partial/usr/lib/nvidia-cuda-toolkit/bin/nvcc.profile"
  tx2_sudo tee "$TX2_CUDA_PREFIX.partial/usr/lib/nvidia-cuda-toolkit/bin/nvcc.profile" > /dev/null <<PROFILE
# Written by scripts/tx2_common.sh for Debian's nvidia-cuda-toolkit unpacked in $TX2_CUDA_PREFIX.
TOP = $TX2_CUDA_PREFIX/usr/lib/cuda
NVVMIR_LIBRARY_DIR = $TX2_CUDA_PREFIX/usr/lib/cuda/nvvm/libdevice
PATH += $nv/bin:$TX2_CUDA_PREFIX/usr/bin:
INCLUDES += "-I$TX2_CUDA_PREFIX/usr/include" \$(_SPACE_)
LIBRARIES =+ \$(_SPACE_) -L$TX2_CUDA_PREFIX/usr/lib/x86_64-linux-gnu/stubs -L$TX2_CUDA_PREFIX/usr/lib/x86_64-linux-gnu
PROFILE
  tx2_sudo rm -rf "$TX2_CUDA_PREFIX"
  tx2_sudo mv "$TX2_CUDA_PREFIX.partial" "$TX2_CUDA_PREFIX"
  tx2_sudo touch "$TX2_CUDA_PREFIX/.complete"
  echo "== CUDA 11.8 compiler in $TX2_CUDA_PREFIX ($(du -sh "$TX2_CUDA_PREFIX" | cut -f1))"
}
