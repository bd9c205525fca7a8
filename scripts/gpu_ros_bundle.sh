#!/usr/bin/env bash
# Packs, on this machine, a self-contained ROS 1 runtime with the nodelet built for the CUDA
# backend, for a GPU machine that has no ROS, no Eigen and no network (Ubuntu 24.04, glibc 2.39,
# CUDA 13): scripts/gpu_ros_check.sh unpacks it there and runs roscore, the rostests and the
# demo with `backend: cuda`.
#
#   scripts/gpu_ros_bundle.sh        # -> .deps/gpuros/{gpuros.tar.xz,gpu_ros_check.sh}
#   BUNDLE=/other/place scripts/gpu_ros_bundle.sh
#
# What goes in (gpuros.tar.xz, one folder gpuros/):
#  - ws/: the package as a catkin workspace: the nodelet library, its executables and test
#    nodes (built here in build/gpuros: ROS on, CUDA on for CUDA_ARCHS, default "75;90", nvcc
#    from /usr/local/cuda; x86-64 with AVX2/FMA instead of -march=native), the generated
#    Python messages, and share/gmm_mcl with package.xml, launch/, config/, test/ros/;
#  - usr/, etc/ros/: the files of the Debian packages that roscore, roslaunch, rostest, rosbag,
#    rosservice and dynamic_reconfigure's dynparam need (their Depends closure, -dev packages
#    and base packages left out), Debian's Python 3.11 interpreter and standard library (the
#    ROS modules are Debian's Python 3.11 ones; 3.12 has no distutils, which roslaunch imports),
#    every ROS package.xml of this machine (rospack resolves dependencies through them), and
#    each shared library any of these ELF files needs beyond the C library and the C++ runtime
#    (the GPU machine's are newer);
#  - rostests.txt: one line per rostest (test file, arguments, @DATA@ for the build folder);
#    test_data_commands.txt: the commands that write their data (build/…/ros_test_data_commands.txt,
#    with the package's own tools), run there: the bags stay here;
#  - env.sh: PATH, LD_LIBRARY_PATH, PYTHONHOME, ROS_PACKAGE_PATH, CMAKE_PREFIX_PATH for it.
# Scripts' #!/usr/bin/python3 lines become #!/usr/bin/env python3, resolved to the bundled
# interpreter by PATH. scripts/gpu_ros_check.sh and the ros_common.sh it sources are copied
# beside the archive, since the GPU machine gets the main checkout, which may not have them yet.
set -euo pipefail
source "$(dirname "$0")/common.sh"
source "$(dirname "$0")/ros_common.sh"
ensure_packages "${CORE_PACKAGES[@]}" "${ROS_PACKAGES[@]}" xz-utils

BUILD="${GMM_MCL_GPUROS_BUILD:-$GMM_MCL_ROOT/build/gpuros}"
BUNDLE="${BUNDLE:-$GMM_MCL_ROOT/.deps/gpuros}"
ARCHS="${CUDA_ARCHS:-75;90}"
NVCC="${NVCC:-/usr/local/cuda/bin/nvcc}"
[[ -x "$NVCC" ]] || NVCC="$(command -v nvcc)"

# ---- build ------------------------------------------------------------------------------------
launchers=()
command -v ccache > /dev/null &&
  launchers=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache)
mkdir -p "$BUILD"
cmake -S "$GMM_MCL_ROOT" -B "$BUILD" -DGMM_MCL_BUILD_ROS=ON -DGMM_MCL_WITH_CUDA=ON \
  -DGMM_MCL_BUILD_TESTS=ON -DGMM_MCL_NATIVE_ARCH=OFF -DCMAKE_CXX_FLAGS="-mavx2 -mfma" \
  -DCMAKE_CUDA_ARCHITECTURES="$ARCHS" -DCMAKE_CUDA_COMPILER="$NVCC" -DCMAKE_BUILD_TYPE=Release \
  "${launchers[@]}" > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
# The nodelet, the demo's tools, every gmm_mcl executable a launch or test file names, and the
# targets that write the rostests' data.
targets=(gmm_mcl_ros gmm_mcl_node gmm_mcl_make_sim_bag gmm_mcl_evaluate_pose_bag)
# The CUDA suites (the backend, the device particle filter, the localizer with it).
targets+=(test_cuda_backend test_cuda_particle_filter_weights test_cuda_particle_filter_sampling
  test_cuda_particle_filter_likelihood test_cuda_localizer)
targets+=($(grep -ohE 'pkg="gmm_mcl" +type="[A-Za-z0-9_]+"' "$GMM_MCL_ROOT"/launch/*.launch \
  "$GMM_MCL_ROOT"/test/ros/*.test | sed -E 's/.*type="([^"]+)"/\1/' | sort -u))
targets+=($(cmake --build "$BUILD" --target help | sed -n 's/^\.\.\. \([A-Za-z0-9_]*_test_data\)$/\1/p'))
start=$(date +%s)
cmake --build "$BUILD" -j2 --target "${targets[@]}"
echo "== build took $(( $(date +%s) - start )) s (${#targets[@]} targets, CUDA $ARCHS)"

# ---- stage ------------------------------------------------------------------------------------
STAGE="$BUILD/bundle_stage"
R="$STAGE/gpuros"
rm -rf "$STAGE"
mkdir -p "$R/ws/lib/gmm_mcl" "$R/ws/share/gmm_mcl" "$R/ws/lib/python3/dist-packages" "$R/bin"

# Debian packages: the Depends closure of these roots, less base and -dev packages.
ROOTS=(python3-rostest python3-roslaunch python3-rosbag python3-rosservice python3-rostopic
  python3-rosnode python3-rosparam python3-rosmsg python3-dynamic-reconfigure python3-distutils
  rosout libnodeletlib-tools libimage-transport0d python3-std-srvs python3-geometry-msgs
  python3-sensor-msgs python3-nav-msgs python3-diagnostic-msgs python3-tf2-msgs
  python3-visualization-msgs libpython3.11)
/usr/bin/python3 - "$R" "${ROOTS[@]}" <<'EOF'
import os, re, shutil, subprocess, sys
dest, roots = sys.argv[1], sys.argv[2:]
skip_pkg = re.compile(r"^(libc6|libc-bin|libstdc\+\+6|libgcc-s1|gcc-\d+-base|tzdata|debconf.*|dpkg|"
                      r"perl.*|base-files|media-types|mime-support|readline-common|ca-certificates|"
                      r"netbase|sensible-utils|init-system-helpers|lsb-base|libcuda1|.*-dev|"
                      r"python3-numpy|python3-matplotlib|python3-sklearn.*|python3-scipy|"
                      # GnuPG and what it brings (rosbag's Python imports python-gnupg, which
                      # calls gpg only for encrypted bags), catkin_pkg's changelog parser.
                      r"gnupg.*|gpg.*|dirmngr|pinentry.*|libsasl2.*|libldap.*|libpam.*|"
                      r"libkrb5.*|libgssapi.*|libtirpc.*|libnsl.*|libsqlite3.*|libdb5.3|"
                      r"python3-docutils)$")
skip_file = re.compile(r"^/usr/(share/(doc|man|info|lintian|locale|bash-completion|zoneinfo)|include)/"
                       r"|\.a$|/__pycache__/|/cmake/|/pkgconfig/"
                       r"|^/usr/lib/python3\.11/(test|idlelib|tkinter|turtledemo|ensurepip|lib2to3/tests|"
                       r"config-3\.11-[^/]*|pydoc_data)/"
                       r"|^/usr/lib/python3\.11/lib-dynload/(_sqlite3|_dbm|_gdbm|nis|_curses|readline|_tkinter"
                       r"|_test|_ctypes_test|xxlimited)")
# Breadth first, one apt-cache call per level (each call reads the whole package cache).
seen, level = set(), set(roots)
while level:
    level = {p for p in level if p not in seen and not skip_pkg.match(p)}
    if not level:
        break
    seen |= level
    out = subprocess.run(["apt-cache", "depends", "--installed", "--no-recommends", "--no-suggests",
                          "--no-conflicts", "--no-breaks", "--no-replaces", "--no-enhances"]
                         + sorted(level), capture_output=True, text=True).stdout
    level = set()
    for line in out.splitlines():
        m = re.match(r"\s*\|?(Pre)?Depends:\s+<?([^\s>]+)>?", line)
        if m:
            level.add(m.group(2).split(":")[0])
n = 0
for p in sorted(seen):
    r = subprocess.run(["dpkg", "-L", p], capture_output=True, text=True)
    if r.returncode != 0:
        continue
    for f in r.stdout.splitlines():
        if skip_file.search(f) or not os.path.lexists(f) or (os.path.isdir(f) and not os.path.islink(f)):
            continue
        t = dest + f
        os.makedirs(os.path.dirname(t), exist_ok=True)
        if os.path.islink(f):
            if not os.path.lexists(t):
                os.symlink(os.readlink(f), t)
        else:
            shutil.copy2(f, t)
        n += 1
open(os.path.join(dest, "debian_packages.txt"), "w").write("\n".join(sorted(seen)) + "\n")
print("== %d Debian packages, %d files" % (len(seen), n))
EOF

# Every ROS package's package.xml and its top-level plugin descriptions (rospack and pluginlib
# read them), roslaunch's roscore.xml and logging configuration.
for x in /usr/share/*/package.xml; do
  d="$(dirname "$x")"
  mkdir -p "$R$d"
  cp "$x" "$R$d/"
  find "$d" -maxdepth 1 -name '*.xml' -exec cp {} "$R$d/" \;
done
mkdir -p "$R/etc"
cp -r /etc/ros "$R/etc/"
# Debian's pluginlib looks for plugin libraries under each CMAKE_PREFIX_PATH entry's lib/, then
# in the fixed /usr/${LIB}/ros/ where Debian installs them: links from usr/lib/ to those.
for f in "$R"/usr/lib/x86_64-linux-gnu/ros/*.so; do
  ln -sf "x86_64-linux-gnu/ros/$(basename "$f")" "$R/usr/lib/$(basename "$f")"
done
# Catkin workspace markers: roslib finds nodes under <prefix>/lib/<package>.
touch "$R/usr/.catkin" "$R/ws/.catkin"
ln -s ../usr/bin/python3.11 "$R/bin/python3"
ln -s ../usr/bin/python3.11 "$R/bin/python"

# The package: executables, libraries, Python messages, share.
DEVEL="$BUILD/devel"
cp -P "$DEVEL"/lib/libgmm_mcl*.so* "$R/ws/lib/"
find "$DEVEL/lib/gmm_mcl" -maxdepth 1 -type f -perm -u+x -exec cp {} "$R/ws/lib/gmm_mcl/" \;
# The launch files' Python nodes (catkin installs them beside the executables).
install -m 755 "$GMM_MCL_ROOT/scripts/restore_wall_time.py" "$R/ws/lib/gmm_mcl/"
cp -r "$DEVEL/lib/python3/dist-packages/gmm_mcl" "$R/ws/lib/python3/dist-packages/"
cp "$GMM_MCL_ROOT/package.xml" "$GMM_MCL_ROOT/nodelet_plugins.xml" "$R/ws/share/gmm_mcl/"
cp -r "$GMM_MCL_ROOT/launch" "$GMM_MCL_ROOT/config" "$R/ws/share/gmm_mcl/"
mkdir -p "$R/ws/share/gmm_mcl/test"
cp -r "$GMM_MCL_ROOT/test/ros" "$R/ws/share/gmm_mcl/test/"
rm -f "$R"/ws/share/gmm_mcl/test/ros/*.cpp
[[ -d "$DEVEL/share/gmm_mcl" ]] && cp -rn "$DEVEL/share/gmm_mcl/." "$R/ws/share/gmm_mcl/"
rm -rf "$R/ws/share/gmm_mcl/cmake"
find "$R/ws" -type f \( -name '*.so*' -o -perm -u+x \) -exec strip --strip-unneeded {} + 2> /dev/null || true

# Scripts run by the bundled interpreter.
grep -rlIE '^#!(/usr/bin/python3|/usr/bin/env python3?)( |$)' "$R/usr/bin" "$R/usr/lib" \
  "$R/ws/lib/gmm_mcl" 2> /dev/null | while read -r f; do
  [[ "$(head -c 2 "$f")" == "#!" ]] && sed -i '1s|^#!.*python3\?\( .*\)\?$|#!/usr/bin/env python3|' "$f"
done

# Shared libraries: the closure of every ELF file's needs, less the C library, the C++ runtime
# and the CUDA driver (the GPU machine has them, newer).
skip_lib='^(linux-vdso|ld-linux-x86-64|libc|libm|libpthread|libdl|librt|libresolv|libutil|libstdc\+\+|libgcc_s|libcuda|libnvidia-.*)\.so'
LIBDIR="$R/usr/lib/x86_64-linux-gnu"
for _ in 1 2; do
  find "$R" -type f \( -name '*.so*' -o -perm -u+x \) -print0 |
    xargs -0 file -N | sed -n 's/^\([^:]*\): *ELF.*dynamically linked.*/\1/p' |
    while read -r f; do ldd "$f" 2> /dev/null | awk '/=> \// {print $1, $3}'; done |
    sort -u | while read -r name path; do
      [[ "$name" =~ $skip_lib ]] && continue
      [[ -e "$LIBDIR/$name" || -e "$R/ws/lib/$name" ]] && continue
      cp -L "$path" "$LIBDIR/$name"
    done
done

# Rostests: test file and arguments, as the build registered them, the build folder written
# @DATA@; and the commands that write their data (the package's own tools under @BIN@), which
# test/CMakeLists.txt writes beside its rules, run on the GPU machine instead of carrying the bags.
(cd "$BUILD" && ctest -N -V) | sed -n 's/.*rostest --pkgdir=[^ ]* --package=gmm_mcl .* \(\/[^ ]*\.test\)\(.*\)"$/\1\2/p' |
  sed -e "s|^$GMM_MCL_ROOT/||" -e "s|$BUILD|@DATA@|g" > "$R/rostests.txt"
cp "$BUILD/ros_test_data_commands.txt" "$R/test_data_commands.txt"
if grep -vE '^(mkdir -p|@BIN@/)' "$R/test_data_commands.txt"; then
  echo "error: a test data command above uses something the bundle does not have" >&2; exit 1
fi
[[ -s "$R/rostests.txt" ]] || { echo "error: no rostest registered in $BUILD" >&2; exit 1; }

cat > "$R/env.sh" <<'EOF'
# Source this: the bundled ROS 1 runtime and the gmm_mcl workspace.
GPUROS="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export GPUROS
export PATH="$GPUROS/bin:$GPUROS/usr/bin:$PATH"
export LD_LIBRARY_PATH="$GPUROS/ws/lib:$GPUROS/usr/lib/x86_64-linux-gnu:$GPUROS/usr/lib/x86_64-linux-gnu/ros:$GPUROS/usr/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PYTHONHOME="$GPUROS/usr"        # the interpreter, and the one librospack embeds
export PYTHONPATH="$GPUROS/ws/lib/python3/dist-packages"
export PYTHONNOUSERSITE=1
export ROS_PACKAGE_PATH="$GPUROS/ws/share:$GPUROS/usr/share"
export CMAKE_PREFIX_PATH="$GPUROS/ws:$GPUROS/usr"
export ROS_ETC_DIR="$GPUROS/etc/ros"
export ROS_ROOT="$GPUROS/usr/share/ros"
export ROS_PYTHON_VERSION=3
export ROS_DISTRO=debian
export ROS_HOME="${ROS_HOME:-$GPUROS/../ros_home}"
EOF

cp "$GMM_MCL_ROOT/scripts/gpu_ros_check.sh" "$GMM_MCL_ROOT/scripts/ros_common.sh" "$R/"
echo "== staged $(du -sh "$R" | cut -f1) in $R ($(wc -l < "$R/rostests.txt") rostests)"

# ---- pack ---------------------------------------------------------------------------------------
mkdir -p "$BUNDLE"
start=$(date +%s)
tar -C "$STAGE" -cf - gpuros | xz -T2 -6 > "$BUNDLE/gpuros.tar.xz.partial"
mv "$BUNDLE/gpuros.tar.xz.partial" "$BUNDLE/gpuros.tar.xz"
# The staged copy goes: inside the package's folder, roslaunch finds its launch files as
# duplicates of the package's own ("multiple files named [replay.launch] in package [gmm_mcl]").
rm -rf "$STAGE"
cp "$GMM_MCL_ROOT/scripts/gpu_ros_check.sh" "$GMM_MCL_ROOT/scripts/ros_common.sh" "$BUNDLE/"
echo "== $BUNDLE: $(du -sh "$BUNDLE" | cut -f1) (xz took $(( $(date +%s) - start )) s)"
