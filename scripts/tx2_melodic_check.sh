#!/usr/bin/env bash
# Jetson TX2 proxy 4: what ROS Melodic on JetPack 4 (Ubuntu 18.04) differs in, checked where it
# can be here (docs/tx2.md lists each difference and what the package does about it):
#  - Python 2.7: Melodic runs ROS-side Python (the dynamic_reconfigure .cfg at build time, rospy
#    nodes) with python2; those files parse under a Python 2.7 interpreter, and a .cfg, which
#    Melodic's dynamic_reconfigure executes through its #! line, names `python`, not python3.
#  - Python 3.6 (Ubuntu 18.04's python3): every Python file of the package parses under it.
#  - CMake 3.10: no command, keyword or generator expression newer than 3.10 outside a
#    CMAKE_VERSION guard, no link to an OBJECT library (3.12), in the package's CMake files and
#    in the docs' TX2 build commands (no `cmake -S/-B`, 3.13; no `cmake --build -j`, 3.12).
#  - Eigen 3.3.4: no Eigen 3.4 API (slicing with seq/all/last, reshaped, the Vector<T, N>
#    alias templates, setUnit), and no CUDA kernel file includes Eigen
#    (Eigen 3.3.4's half-precision header does not compile under CUDA 10).
# Python 2.7 and 3.6 come from pyenv here (PYTHON27, PYTHON36 override); a check whose
# interpreter is missing says it skipped.
set -euo pipefail
source "$(dirname "$0")/common.sh"
cd "$GMM_MCL_ROOT"

find_python() {  # find_python VERSION: an interpreter of that version, or nothing
  local v="$1" c
  for c in "python$v" "$(pyenv root 2> /dev/null)/versions/$v"*/bin/"python$v" \
           "$HOME"/.pyenv/versions/"$v"*/bin/"python$v"; do
    if command -v "$c" > /dev/null 2>&1 && "$c" -c 'import sys' 2> /dev/null; then
      command -v "$c"; return
    fi
  done
}
PY27="${PYTHON27:-$(find_python 2.7)}"
PY36="${PYTHON36:-$(find_python 3.6)}"
failed=0
bad() { echo "FAIL: $*" >&2; failed=1; }

mapfile -t PY_FILES < <(git ls-files '*.py' '*.cfg')
# ROS-side Python: the dynamic_reconfigure definitions and the files that import rospy or rosbag.
mapfile -t ROS_PY < <(git ls-files '*.cfg'; git grep -lE '^(import|from) +(rospy|rosbag|dynamic_reconfigure)' -- '*.py')

parse_with() {  # parse_with PYTHON FILE...: each file compiles (syntax only)
  local py="$1"; shift
  "$py" - "$@" <<'EOF'
import sys
bad = 0
for f in sys.argv[1:]:
    try:
        compile(open(f).read(), f, "exec")
    except SyntaxError as e:
        print("%s:%s: %s" % (f, e.lineno, e.msg))
        bad = 1
sys.exit(bad)
EOF
}
if [[ -n "$PY27" ]]; then
  if parse_with "$PY27" "${ROS_PY[@]}"; then
    echo "== Python 2.7 ($PY27): ${#ROS_PY[@]} ROS-side files parse: ${ROS_PY[*]}"
  else
    bad "ROS-side Python that Python 2.7 cannot parse (above)"
  fi
else
  echo "== skipped: no Python 2.7 interpreter (set PYTHON27)"
fi
for f in $(git ls-files '*.cfg'); do
  head -1 "$f" | grep -qE '^#! */usr/bin/env python$' ||
    bad "$f: '$(head -1 "$f")' (Melodic runs a .cfg through its #! line: #!/usr/bin/env python)"
done
if [[ -n "$PY36" ]]; then
  if parse_with "$PY36" "${PY_FILES[@]}"; then
    echo "== Python 3.6 ($PY36): ${#PY_FILES[@]} files parse"
  else
    bad "Python that Python 3.6 cannot parse (above)"
  fi
else
  echo "== skipped: no Python 3.6 interpreter (set PYTHON36)"
fi

# CMake 3.10.
/usr/bin/python3 - CMakeLists.txt cmake/*.cmake test/CMakeLists.txt docs/tx2.md docs/cuda_backend.md README.md <<'EOF' || bad "CMake newer than 3.10 (above)"
import re, sys
# (pattern, what, version)
NEWER = [
    (r"\badd_link_options\s*\(", "add_link_options", "3.13"),
    (r"\btarget_link_options\s*\(", "target_link_options", "3.13"),
    (r"\btarget_link_directories\s*\(", "target_link_directories", "3.13"),
    (r"\btarget_precompile_headers\s*\(", "target_precompile_headers", "3.16"),
    (r"\bcmake_language\s*\(", "cmake_language", "3.18"),
    (r"\bcmake_path\s*\(", "cmake_path", "3.20"),
    (r"\bFetchContent", "FetchContent", "3.11"),
    (r"\blist\s*\(\s*(TRANSFORM|PREPEND|POP_BACK|POP_FRONT|JOIN|SUBLIST)\b", "list(TRANSFORM/PREPEND/POP_*/JOIN/SUBLIST)", "3.12"),
    (r"\bstring\s*\(\s*(JOIN|REPEAT|HEX)\b", "string(JOIN/REPEAT/HEX)", "3.12"),
    (r"\bfile\s*\(\s*(CREATE_LINK|SIZE|READ_SYMLINK|REAL_PATH|ARCHIVE_CREATE|ARCHIVE_EXTRACT|CONFIGURE|CHMOD)\b", "file(CREATE_LINK/SIZE/...)", "3.14"),
    (r"\bIN\s+ZIP_LISTS\b", "foreach(IN ZIP_LISTS)", "3.17"),
    (r"\$<(TARGET_EXISTS|GENEX_EVAL|TARGET_GENEX_EVAL|IN_LIST)\b", "$<TARGET_EXISTS/GENEX_EVAL/IN_LIST>", "3.12"),
    (r"\$<(REMOVE_DUPLICATES|FILTER|COMPILE_LANG_AND_ID|LINK_LANG_AND_ID|LINK_LANGUAGE|DEVICE_LINK|HOST_LINK)\b", "$<REMOVE_DUPLICATES/FILTER/...>", "3.15"),
    (r"\bfind_package\s*\(\s*(CUDAToolkit)\b", "find_package(CUDAToolkit)", "3.17"),
    (r"\bfind_package\s*\(\s*(Python3?)\b", "find_package(Python/Python3)", "3.12"),
    (r"\bCOMMAND_EXPAND_LISTS\b", "COMMAND_EXPAND_LISTS", "3.8"),
]
DOC = [
    (r"\bcmake\s+(-S|-B)\b[^\n]*", "cmake -S/-B", "3.13"),
    (r"\bcmake\s+--build\b[^\n]*\s(-j\s*\d*|--parallel)", "cmake --build -j/--parallel", "3.12"),
]
bad = 0
for path in sys.argv[1:]:
    try:
        text = open(path).read()
    except FileNotFoundError:
        continue
    lines = text.splitlines()
    if path.endswith(".md"):
        # Only the TX2's own build commands: fenced blocks after a heading naming the TX2.
        in_tx2, fence = False, False
        for i, line in enumerate(lines, 1):
            if line.startswith("#"):
                in_tx2 = "TX2" in line or "Jetson" in line
            if line.startswith("```"):
                fence = not fence
                continue
            if in_tx2 and fence and "3.10" not in line:
                for pat, what, ver in DOC:
                    if re.search(pat, line):
                        print("%s:%d: %s needs CMake %s: %s" % (path, i, what, ver, line.strip()))
                        bad = 1
        continue
    # Guarded blocks: lines inside if(... CMAKE_VERSION VERSION_{GREATER_EQUAL,LESS} X) branches
    # that only CMake >= X takes are allowed.
    guard = []  # stack of (is_new_branch)
    objects = set(re.findall(r"add_library\s*\(\s*(\w+)\s+OBJECT\b", text))
    for i, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0]
        m = re.match(r"\s*if\s*\((.*)\)", line)
        if m:
            cond = m.group(1)
            new = bool(re.search(r"CMAKE_VERSION\s+VERSION_(GREATER_EQUAL|GREATER)\s+3\.(1[1-9]|[2-9]\d)", cond))
            old = bool(re.search(r"CMAKE_VERSION\s+VERSION_LESS\s+3\.(1[1-9]|[2-9]\d)", cond))
            guard.append("new" if new else ("old" if old else ""))
            continue
        if re.match(r"\s*else\s*\(", line) and guard:
            guard[-1] = {"new": "old", "old": "new"}.get(guard[-1], "")
            continue
        if re.match(r"\s*endif\s*\(", line) and guard:
            guard.pop()
            continue
        if "new" in guard:
            continue
        for pat, what, ver in NEWER:
            if re.search(pat, line):
                print("%s:%d: %s needs CMake %s" % (path, i, what, ver))
                bad = 1
        for o in objects:
            if re.search(r"\btarget_link_libraries\s*\(\s*%s\b" % o, line):
                print("%s:%d: target_link_libraries on the OBJECT library %s needs CMake 3.12" % (path, i, o))
                bad = 1
sys.exit(bad)
EOF
echo "== CMake 3.10: CMakeLists.txt, cmake/*.cmake, test/CMakeLists.txt and the docs' TX2 build commands checked"

# Eigen 3.3.4.
if git grep -nE 'Eigen::(seqN?|placeholders|all|last|lastN|indexing)\b|\.reshaped(<[^>]*>)?\(|Eigen::(Row)?Vector[234]?<|Eigen::(Matrix|Array)[234]X?<|\bsetUnit\(' \
     -- include src test ':!test/fuzz/corpus' ':!test/fuzz/regressions'; then
  bad "Eigen 3.4 API (above); Melodic has Eigen 3.3.4"
fi
NVCC="${NVCC:-/usr/local/cuda/bin/nvcc}"
if [[ -x "$NVCC" ]]; then
  for f in src/backend/cuda/*.cu src/filter/cuda/*.cu; do
    if "$NVCC" -std=c++14 -I include -I src/backend -I src/filter -I /usr/include/eigen3 -M "$f" 2> /dev/null | grep -q 'eigen3'; then
      bad "$f includes Eigen (Eigen 3.3.4 does not compile under nvcc 10.2)"
    fi
  done
  echo "== Eigen 3.3.4: no 3.4 API; no CUDA kernel file includes Eigen ($(ls src/backend/cuda/*.cu src/filter/cuda/*.cu | wc -l) .cu files)"
else
  echo "== Eigen 3.3.4: no 3.4 API (skipped the .cu include check: no nvcc)"
fi
[[ "$failed" -eq 0 ]] || exit 1
echo "== ROS Melodic checks passed"
