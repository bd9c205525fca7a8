# Shared by the scripts that run on the GPU machine without ROS (gpu_check.sh, gpu_sweep.sh,
# gpu_building.sh). Unlike common.sh it leaves PATH alone: cmake and the CUDA tools there are
# wherever that machine has them.
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# gpu_build_dirs: BUILD, the CUDA build that gpu_check.sh makes (GMM_MCL_GPU_BUILD_DIR, default
# build-gpu), and LOGS (OUT, default BUILD/logs).
gpu_build_dirs() {
  BUILD="${GMM_MCL_GPU_BUILD_DIR:-$ROOT/build-gpu}"
  LOGS="${OUT:-$BUILD/logs}"
}

# step NAME: true when NAME is one of the words of STEPS.
step() { [[ " $STEPS " == *" $1 "* ]]; }
