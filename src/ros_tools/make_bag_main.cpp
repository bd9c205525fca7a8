// gmm_mcl_make_bag: converts a data-set folder (7-Scenes, TUM RGB-D / ICL-NUIM, Stanford) or the
// synthetic scene into a bag for the nodelet (layout: sequence_bag.h), plus the map in the
// gravity-aligned frame and the initial-region parameter file.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/cli/sequence_flags.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros_tools/bag_writer.h"
#include "gmm_mcl/ros_tools/sequence_bag.h"

namespace gmm_mcl {

namespace {

const char* kUsage =
    "usage: gmm_mcl_make_bag --format 7scenes|tum|stanford DIR OUT.bag [--map WORLD_MAP.gmm]\n"
    "       gmm_mcl_make_bag --format sim OUT.bag [--width PX] (map: the scene's own)\n"
    "  [--frames N] [--seed S] [--layout image|cow_and_lady]\n"
    "  [--marker-to-camera x,y,z,qx,qy,qz,qw] (cow_and_lady calibration, default identity)\n"
    "  [--init-half-extent M (2)] [--init-yaw-half-range RAD (pi/2)] [--start-time S (1000)]\n"
    "  folder options: [--intrinsics fr1|fr2|fr3|icl|kinect|fx,fy,cx,cy|FILE]\n"
    "  [--depth-scale UNITS_PER_M] [--tolerance S] [--gravity z-up|first-camera|gx,gy,gz]\n"
    "  [--trajectory FILE.log] [--rate HZ] [--quiet]\n"
    "Writes OUT.bag, OUT_init.yaml and, with a map, OUT.gmm (gravity-aligned).\n"
    "image layout: /camera/depth/image_raw (16UC1) + camera_info, /imu/data, /odom, /tf,\n"
    "/tf_static, /ground_truth (replay.launch). cow_and_lady layout: organized cloud on\n"
    "/camera/depth_registered/points and TransformStamped on\n"
    "/kinect/vrpn_client/estimated_transform (cow_and_lady.launch).\n";

}  // namespace

int run(int argc, char** argv) {
  std::string format, dir, bag_path, map_path, marker_to_camera;
  SequenceOptions so;
  ros_bag::SequenceBagOptions bo;
  int width = 320;
  bool quiet = false;
  int frames = -1;
  std::vector<std::string> paths;
  cli::CommandLine cl("gmm_mcl_make_bag", kUsage);
  // clang-format off
  cl.flags({{"format", &format}, {"map", &map_path}, {"frames", &frames}, {"seed", &bo.seed},
           {"layout", &bo.layout}, {"marker-to-camera", &marker_to_camera},
           {"init-half-extent", &bo.init_half_extent_m},
           {"init-yaw-half-range", &bo.init_yaw_half_range_rad}, {"start-time", &bo.start_s},
           {"width", &width}, {"quiet", &quiet}, {"paths", &paths}});
  // clang-format on
  cli::addSequenceFlags(&cl, &so);
  cl.positional("paths", 2);
  cl.parse(argc, argv);
  if (cl.given("frames")) so.max_frames = bo.max_frames = frames;
  const size_t wanted = format == "sim" ? 1 : 2;
  if (format.empty() || paths.size() != wanted) {
    cl.fail(format == "sim" ? "--format sim needs OUT.bag" : "need --format, DIR and OUT.bag");
  }
  if (wanted == 2) dir = paths[0];
  bag_path = paths.back();
  if (!marker_to_camera.empty() && !ros_bag::parseTransform(marker_to_camera, &bo.T_marker_cam)) {
    std::fprintf(stderr, "--marker-to-camera '%s' is not x,y,z,qx,qy,qz,qw (unit quaternion)\n",
                 marker_to_camera.c_str());
    return 2;
  }
  return cli::reportErrors("gmm_mcl_make_bag", [&] {
    std::unique_ptr<Sequence> seq;
    std::unique_ptr<GmmMap> map;
    if (format == "sim") {
      SimSequenceParams sp;
      sp.frames = so.max_frames > 0 ? so.max_frames : 240;
      sp.width_px = width;
      sp.seed = bo.seed;
      std::unique_ptr<SimSequence> sim = std::make_unique<SimSequence>(sp);
      if (map_path.empty()) map = std::make_unique<GmmMap>(sim->map());
      seq = std::move(sim);
    } else {
      seq = openSequence(format, dir, so);
    }
    if (!map_path.empty()) map = std::make_unique<GmmMap>(loadMap(map_path));
    if (!quiet) {
      bo.progress = [](int f, int total) {
        if (f % 30 == 0 || f == total - 1) {
          std::fprintf(stderr, "\r  frame %d/%d  ", f + 1, total);
          if (f == total - 1) std::fprintf(stderr, "\n");
        }
      };
    }
    const ros_bag::SequenceBagResult r = ros_bag::writeSequenceBag(*seq, map.get(), bag_path, bo);
    const Intrinsics& K = seq->intrinsics();
    std::printf("wrote %s (%s layout, %d frames %dx%d from %s %s, %.1f s; gravity: %s)%s%s, %s\n",
                bag_path.c_str(), bo.layout.c_str(), r.frames, K.width_px, K.height_px,
                seq->format(), seq->source().c_str(), r.duration_s, seq->gravitySource().c_str(),
                r.map_path.empty() ? "" : ", map ", r.map_path.c_str(), r.init_path.c_str());
    return 0;
  });
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
