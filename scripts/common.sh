# Shared by scripts/demo.sh and scripts/test.sh: PATH for ROS-era tools, idempotent apt installs.
# Debian 12's own python3 must come first (a pyenv python3 breaks catkin and the oracle tests).
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"
GMM_MCL_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export GMM_MCL_ROOT

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
