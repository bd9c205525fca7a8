# Shared by scripts/demo.sh and scripts/test.sh: PATH for ROS-era tools, idempotent apt installs.
# Debian 12's own python3 must come first (a pyenv python3 breaks catkin and the oracle tests).
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
GMM_MCL_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export GMM_MCL_ROOT
# The data sets: $GMM_MCL_DATASETS, else ../shared/datasets beside the package.
GMM_MCL_DATASETS_DIR="${GMM_MCL_DATASETS:-$GMM_MCL_ROOT/../shared/datasets}"
DATASETS="$GMM_MCL_DATASETS_DIR"
# nvcc: on PATH, else CUDA's default folder (it may not exist: callers check).
NVCC="$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)"

# apt_get ARGS...: apt-get (as root or through sudo) that waits for the apt/dpkg locks while
# another install holds them, up to APT_LOCK_TIMEOUT_S (600 s), instead of failing at once:
# DPkg::Lock::Timeout covers the dpkg frontend lock (install); apt-get update's lists lock is
# not covered by it, so a run that fails on a lock is tried again every 10 s until then.
apt_get() {
  local sudo="" timeout_s="${APT_LOCK_TIMEOUT_S:-600}" waited=0 rc err
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  err="$(mktemp)"
  while true; do
    rc=0
    DEBIAN_FRONTEND=noninteractive $sudo apt-get -o DPkg::Lock::Timeout="$timeout_s" "$@" \
      2> "$err" || rc=$?
    cat "$err" >&2
    if [ "$rc" -eq 0 ] || ! grep -qiE 'could not get lock|unable to acquire|is held by' "$err" \
        || [ "$waited" -ge "$timeout_s" ]; then
      rm -f "$err"
      return "$rc"
    fi
    echo "== apt-get $1: another install holds the apt lock; waiting (${waited} s so far)" >&2
    sleep 10
    waited=$((waited + 10))
  done
}

# ensure_packages PKG...: installs the Debian packages that are not installed yet (apt-get
# update once), as root or through sudo, waiting for another install's apt lock (apt_get).
ensure_packages() {
  local missing=()
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ "$(id -u)" -ne 0 ] && ! command -v sudo >/dev/null; then
    echo "need root or sudo to install: ${missing[*]}" >&2
    return 1
  fi
  echo "== installing: ${missing[*]}"
  apt_get update -qq
  apt_get install -y -qq --no-install-recommends "${missing[@]}"
}

# Build dependencies of the ROS-free core, tools and tests.
CORE_PACKAGES=(build-essential cmake libeigen3-dev libpng-dev libboost-program-options-dev libgtest-dev googletest python3-matplotlib)
# libFuzzer targets (scripts/fuzz.sh): clang, its sanitizer/fuzzer runtimes and OpenMP runtime.
FUZZ_PACKAGES=(clang libclang-rt-14-dev libomp-14-dev)

# find_tool NAME VAR: the path of a built gmm_mcl tool: $VAR if set, else the build folders that
# the scripts use (build-fit, build, the catkin devel folder of build/test), else PATH.
find_tool() {
  local name="$1" var="$2"
  if [[ -n "${!var:-}" ]]; then echo "${!var}"; return; fi
  local c
  for c in "$GMM_MCL_ROOT/build-fit/$name" "$GMM_MCL_ROOT/build/$name" \
           "$GMM_MCL_ROOT/build/test/devel/lib/gmm_mcl/$name" "$GMM_MCL_ROOT/build/test/$name" \
           "$(command -v "$name" || true)"; do
    if [[ -n "$c" && -x "$c" ]]; then echo "$c"; return; fi
  done
  echo "error: $name not found; build it (cmake --build <dir> --target $name) or set $var" >&2
  exit 1
}

# map_builder_args NAME [DATASETS_DIR] [OUTPUT_MAP]: the map-building scripts' arguments:
# DATASETS (default GMM_MCL_DATASETS_DIR), OUT (default $GMM_MCL_MAP_DIR/NAME, GMM_MCL_MAP_DIR
# defaulting to build/maps), MAP_ARGS_USED (how many of the two were given: the caller shifts
# them off) and the tools GMM_FIT and GMM_INSPECT.
map_builder_args() {
  local name="$1"
  shift
  DATASETS="${1:-$GMM_MCL_DATASETS_DIR}"
  OUT="${2:-${GMM_MCL_MAP_DIR:-$GMM_MCL_ROOT/build/maps}/$name}"
  MAP_ARGS_USED=$(( $# < 2 ? $# : 2 ))
  GMM_FIT="$(find_tool gmm_mcl_fit GMM_FIT)"
  GMM_INSPECT="$(find_tool gmm_mcl_inspect GMM_INSPECT)"
}

# fit_options DEFAULT... -- EXTRA...: FIT_OPTIONS = the map-building scripts' default gmm_mcl_fit
# options (each an option and its value) that EXTRA (the user's extra options) does not give
# itself, then EXTRA: a user's `-m 4000` replaces the default `-m 1000` (gmm_mcl_fit refuses an
# option given twice). -m and --components are one option, as are --name VALUE and --name=VALUE.
fit_options() {
  local -a defaults=()
  while [[ $# -gt 0 && "$1" != "--" ]]; do
    defaults+=("$1")
    shift
  done
  [[ $# -gt 0 ]] && shift
  FIT_OPTIONS=()
  local i a given
  for ((i = 0; i < ${#defaults[@]}; i += 2)); do
    given=0
    for a in "$@"; do
      [[ "$(fit_option_name "${a%%=*}")" == "$(fit_option_name "${defaults[i]}")" ]] && given=1
    done
    [[ $given == 1 ]] || FIT_OPTIONS+=("${defaults[i]}" "${defaults[i + 1]}")
  done
  FIT_OPTIONS+=("$@")
}
fit_option_name() {
  case "$1" in
    -m) echo --components ;;
    -o) echo --output ;;
    *) echo "$1" ;;
  esac
}

# require_input FILE WHAT [WHERE]: exits with an error naming WHAT and WHERE (default FILE)
# unless FILE exists.
require_input() {
  if [[ ! -f "$1" ]]; then
    echo "error: $2 not found at ${3:-$1} (pass DATASETS_DIR or set GMM_MCL_DATASETS)" >&2
    exit 1
  fi
}


# configure_gpu_tools BUILD ARCH NVCC [CMAKE_ARGS...]: configures BUILD (Release, no ROS, the
# CUDA backend for ARCH, the tests) for a GPU machine: x86-64 with AVX2/FMA instead of
# -march=native, which is this machine's CPU. Shows the log and exits on failure.
configure_gpu_tools() {
  local build="$1" arch="$2" nvcc="$3"
  shift 3
  cmake -S "$GMM_MCL_ROOT" -B "$build" -DGMM_MCL_BUILD_ROS=OFF -DGMM_MCL_WITH_CUDA=ON \
    -DGMM_MCL_BUILD_TESTS=ON -DGMM_MCL_NATIVE_ARCH=OFF -DCMAKE_CXX_FLAGS="-mavx2 -mfma" \
    -DCMAKE_CUDA_ARCHITECTURES="$arch" -DCMAKE_CUDA_COMPILER="$nvcc" \
    -DCMAKE_BUILD_TYPE=Release "$@" > "$build.cmake.log" 2>&1 \
    || { cat "$build.cmake.log"; exit 1; }
}

# bundle_binaries BUNDLE BUILD TOOL...: the tools of BUILD into BUNDLE/bin (stripped) and the
# shared libraries they need beyond the C library and the loader into BUNDLE/lib (the GPU
# machine has a newer glibc).
bundle_binaries() {
  local bundle="$1" build="$2" t
  shift 2
  mkdir -p "$bundle/bin" "$bundle/lib"
  for t in "$@"; do cp "$build/$t" "$bundle/bin/"; done
  strip "$bundle"/bin/*
  for t in "$bundle"/bin/*; do ldd "$t" | awk '/=> \// {print $3}'; done | sort -u \
    | grep -vE '/(libc|libm|libpthread|libdl|librt|ld-linux[^/]*)\.so' \
    | while read -r lib; do cp -L "$lib" "$bundle/lib/"; done
}
