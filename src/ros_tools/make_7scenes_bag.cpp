// Converts a 7-Scenes sequence into a bag for the nodelet (DESIGN.md accuracy protocol); the
// former command line of what is now `gmm_mcl_make_bag --format 7scenes` (sequence_bag.h):
// depth 16UC1 + CameraInfo, IMU roll/pitch = truth + N(0, 0.5 deg), odometry = truth motion
// plus drifting noise (0.005 m, 0.002 rad per frame) as /odom and tf, the static base -> camera
// tf, /ground_truth; the map rotated into the gravity-aligned frame; the initial region.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros_tools/sequence_bag.h"

namespace gmm_mcl {

int run(int argc, char** argv) {
  std::string data_dir, map_in, bag_path;
  int frames = -1;
  ros_bag::SequenceBagOptions bo;
  cli::CommandLine cl(
      "gmm_mcl_make_7scenes_bag",
      "usage: gmm_mcl_make_7scenes_bag DATA_DIR --map WORLD_MAP.gmm --bag OUT.bag [--frames N]\n"
      "                                [--seed S] [--init-half-extent M (2)]\n"
      "                                [--init-yaw-half-range RAD (pi/2)]\n"
      "Writes OUT.bag, OUT.gmm (the map in the gravity-aligned frame) and OUT_init.yaml.\n"
      "Same as: gmm_mcl_make_bag --format 7scenes DATA_DIR OUT.bag --map WORLD_MAP.gmm\n");
  // clang-format off
  cl.flags({{"data-dir", &data_dir}, {"map", &map_in}, {"bag", &bag_path}, {"frames", &frames},
           {"seed", &bo.seed}, {"init-half-extent", &bo.init_half_extent_m},
           {"init-yaw-half-range", &bo.init_yaw_half_range_rad}});
  // clang-format on
  cl.positional("data-dir");
  cl.parse(argc, argv);
  if (data_dir.empty() || map_in.empty() || bag_path.empty()) {
    cl.fail("need DATA_DIR, --map and --bag");
  }
  return cli::reportErrors("gmm_mcl_make_7scenes_bag", [&] {
    const SevenScenesSequence seq(data_dir, frames);
    const GmmMap map = loadMap(map_in);
    const ros_bag::SequenceBagResult r = ros_bag::writeSequenceBag(seq, &map, bag_path, bo);
    std::printf("wrote %s (%d frames, %.1f s), %s (%zu components, gravity-aligned), %s\n",
                bag_path.c_str(), r.frames, r.duration_s + 1.0 / seq.frameRateHz(),
                r.map_path.c_str(), map.size(), r.init_path.c_str());
    return 0;
  });
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
