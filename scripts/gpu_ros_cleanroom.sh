#!/usr/bin/env bash
# Tries the bundle of scripts/gpu_ros_bundle.sh here the way a GPU machine without ROS sees it:
# inside a Debian 13 (trixie) minimal root made once with debootstrap (/var/tmp/gmm_mcl_cleanroom:
# glibc 2.41, /usr/bin/python3 3.13, no ROS, no Eigen, none of this machine's /usr), with an
# empty environment (env -i) and the bundle folder bound in. There is no GPU here: the steps
# run with backend cpu (BACKEND=cuda shows the fallback: each step then fails). Root only
# (debootstrap, chroot, mounts in a private mount namespace).
#
#   scripts/gpu_ros_cleanroom.sh [BUNDLE_DIR]    # default .deps/gpuros
#   GPUROS_STEPS="info roscore rostests" BACKEND=cpu scripts/gpu_ros_cleanroom.sh
set -euo pipefail
source "$(dirname "$0")/common.sh"
BUNDLE="$(cd "${1:-$GMM_MCL_ROOT/.deps/gpuros}" && pwd)"
ROOTFS="${GMM_MCL_CLEANROOM:-/var/tmp/gmm_mcl_cleanroom}"
[[ -f "$BUNDLE/gpuros.tar.xz" ]] || { echo "error: no $BUNDLE/gpuros.tar.xz" >&2; exit 1; }
if [[ ! -x "$ROOTFS/usr/bin/python3" ]]; then
  ensure_packages debootstrap
  debootstrap --variant=minbase --include=python3,procps,xz-utils,iproute2 trixie "$ROOTFS" \
    http://deb.debian.org/debian
fi
mkdir -p "$ROOTFS/bundle" "$ROOTFS/out"
OUT_HOST="${OUT:-$GMM_MCL_ROOT/build/gpuros_cleanroom}"
mkdir -p "$OUT_HOST"
unshare -m bash -c '
  set -e
  mount --make-rprivate /
  mount --bind "$1" "$2/bundle"
  mount --bind "$3" "$2/out"
  mount -t proc proc "$2/proc"
  mount --rbind /dev "$2/dev"
  mount -t tmpfs tmpfs "$2/tmp"
  chroot "$2" /usr/bin/env -i HOME=/root PATH=/usr/bin:/bin OUT=/out \
    GPUROS_STEPS="$4" BACKEND="$5" DEMO_BACKENDS="$5" FRAMES="$6" LIVE_SECONDS="$7" \
    /bin/bash /bundle/gpu_ros_check.sh
' _ "$BUNDLE" "$ROOTFS" "$OUT_HOST" "${GPUROS_STEPS:-info roscore rostests demo live}" \
  "${BACKEND:-cpu}" "${FRAMES:-300}" "${LIVE_SECONDS:-30}"
