#!/usr/bin/env bash
# Jetson TX2 proxy 3: the C++ sources of the core (the CPU backend included), the CUDA backend's
# host code and the ROS nodelet (--all: the tools, the map builder, replay and figures too)
# compiled as strict ISO C++14:
# -std=c++14 -pedantic-errors, syntax only (JetPack 4 / ROS Melodic: GCC 7, C++14). Reads the
# compile commands of a configured build (include paths, definitions, catkin's generated
# message headers) and re-runs each with -fsyntax-only; a C++17 construct (if constexpr,
# structured bindings, inline variables, nested namespace definitions, std::optional, ...) or a
# GNU extension is an error there. Also checks that every source is compiled with the same
# Eigen definitions (EIGEN_MAX_STATIC_ALIGN_BYTES=0: one object layout across the package).
#
#   scripts/tx2_cxx14_check.sh [--all] [BUILD_DIR]
#
# BUILD_DIR: a build configured with -DCMAKE_EXPORT_COMPILE_COMMANDS=ON whose generated headers
# exist (scripts/test.sh passes build/test after building it). Without one, configures
# build/cxx14 (ROS on when catkin is installed, CUDA on when nvcc is found) and builds only the
# generated headers.
set -euo pipefail
source "$(dirname "$0")/common.sh"

SCOPE=core
if [[ "${1:-}" == "--all" ]]; then SCOPE=all; shift; fi
BUILD="${1:-}"
if [[ -z "$BUILD" ]]; then
  BUILD="$GMM_MCL_ROOT/build/cxx14"
  ros=OFF
  [[ -f /usr/share/catkin/cmake/catkinConfig.cmake ]] && ros=ON
  cuda=()
  NVCC="${NVCC:-/usr/local/cuda/bin/nvcc}"
  [[ -x "$NVCC" ]] && cuda=(-DGMM_MCL_WITH_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=75 -DCMAKE_CUDA_COMPILER="$NVCC")
  mkdir -p "$BUILD"
  cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=$ros -DGMM_MCL_BUILD_TESTS=ON \
    "${cuda[@]}" -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DCMAKE_BUILD_TYPE=Release \
    > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
  if [[ "$ros" == ON ]]; then
    cmake --build "$BUILD" --target gmm_mcl_generate_messages_cpp gmm_mcl_gencfg > /dev/null
  fi
fi
DB="$BUILD/compile_commands.json"
[[ -f "$DB" ]] || { echo "error: $DB not found (configure with -DCMAKE_EXPORT_COMPILE_COMMANDS=ON)" >&2; exit 1; }

# One shell command per source (not the tests, not the CUDA kernels:
# nvcc's own C++14 compile is scripts/tx2_cuda_compile.sh), as the build ran it, with the
# object output replaced by -fsyntax-only and the C++14 flags appended (they override any
# earlier -std).
start=$(date +%s)
/usr/bin/python3 - "$DB" "$GMM_MCL_ROOT" "$SCOPE" "$BUILD/cxx14_built_strict.txt" \
  > "$BUILD/cxx14_commands.txt" <<'EOF'
import json, os, shlex, sys
db, root, everything = sys.argv[1], os.path.realpath(sys.argv[2]), sys.argv[3] == "all"
# The core (with the CPU backend), the CUDA backend's host code, the ROS nodelet and ROS tools.
CORE_DIRS = ("map", "camera", "measurement", "backend", "filter", "sim", "ros", "ros_tools")
seen = set()
eigen_defs = {}
strict = open(sys.argv[4], "w")
for e in json.load(open(db)):
    src = os.path.realpath(os.path.join(e["directory"], e["file"]))
    rel = os.path.relpath(src, root)
    core = rel.startswith(tuple("src/%s/" % d for d in CORE_DIRS))
    if rel.endswith(".cu") or not (core or (everything and rel.startswith("src/"))):
        continue
    if rel in seen:
        continue
    seen.add(rel)
    args = e["arguments"] if "arguments" in e else shlex.split(e["command"])
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a in ("-o", "-MF", "-MT", "-MQ"):
            skip = True
            continue
        if a in ("-c", "-MD", "-MMD") or a.startswith("-march") or "ccache" in os.path.basename(a):
            continue
        out.append(a)
    eigen_defs[rel] = tuple(sorted(a for a in out if a.startswith("-DEIGEN_")))
    # A build configured with GMM_MCL_STRICT_CXX14 compiled it so already: nothing to re-run.
    stds = [a for a in out if a.startswith("-std=")]
    if "-pedantic-errors" in out and stds and stds[-1] == "-std=c++14":
        strict.write(rel + "\n")
        continue
    out += ["-std=c++14", "-pedantic-errors", "-fsyntax-only"]
    print("cd %s && %s" % (shlex.quote(e["directory"]), " ".join(shlex.quote(a) for a in out)))
# Eigen's layout (EIGEN_MAX_STATIC_ALIGN_BYTES, ...) must be the same in every translation unit:
# objects cross them (an Isometry3d passed by reference, a std::vector of fixed-size members).
if len(set(eigen_defs.values())) > 1:
    for rel, d in sorted(eigen_defs.items()):
        sys.stderr.write("%s: %s\n" % (rel, " ".join(d) or "(no EIGEN_ definitions)"))
    sys.exit("error: the package's sources are compiled with different Eigen definitions (above)")
EOF
rerun=$(wc -l < "$BUILD/cxx14_commands.txt")
built=$(wc -l < "$BUILD/cxx14_built_strict.txt")
n=$((rerun + built))
[[ "$n" -gt 0 ]] || { echo "error: no package sources in $DB" >&2; exit 1; }
fail=0
if [[ "$rerun" -gt 0 ]]; then
  tr '\n' '\0' < "$BUILD/cxx14_commands.txt" | xargs -0 -P 2 -I{} bash -c '{}' \
    2> "$BUILD/cxx14_errors.log" || fail=1
fi
if [[ "$fail" -ne 0 ]]; then
  cat "$BUILD/cxx14_errors.log"
  echo "error: sources that are not ISO C++14 (above)" >&2
  exit 1
fi
ros_n=$(cat "$BUILD/cxx14_commands.txt" "$BUILD/cxx14_built_strict.txt" | grep -c 'src/ros/' || true)
echo "== C++14 -pedantic-errors: $n sources ($ros_n of them the ROS nodelet's; scope $SCOPE) compile" \
  "($built of them compiled so by the build, GMM_MCL_STRICT_CXX14), $(( $(date +%s) - start )) s"
