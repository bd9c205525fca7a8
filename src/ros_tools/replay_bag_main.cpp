// gmm_mcl_replay_bag: replays a bag through the core localizer directly (rosbag C++ API, no
// ROS master), as fast as it runs, seeded; the offline counterpart of replay.launch and
// cow_and_lady.launch. Inputs per depth frame (16UC1/32FC1 image + CameraInfo, or an organized
// PointCloud2): odometry from nav_msgs/Odometry, from tf odom -> base, synthesised from the
// ground truth (DESIGN.md noise, as gmm_mcl_ground_truth_odometry), or none (the localizer's
// constant-velocity model, turned by the IMU gyro's heading when the IMU carries its rates, as
// the nodelet without ~odom_topic: docs/no_odometry.md); roll/pitch from the IMU
// (or synthesised from the truth); ground truth from a PoseStamped (base in map) or a
// TransformStamped (marker in world, with the marker -> camera calibration). Outputs as
// gmm_mcl_replay: TUM trajectories, per-frame CSV, the protocol's metrics.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <sys/stat.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/filter/stamped_buffer.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros_tools/bag_writer.h"

namespace gmm_mcl {
namespace {

const char* kUsage =
    "usage: gmm_mcl_replay_bag BAG --map MAP.gmm [--out DIR] [--seed S] [--frames N]\n"
    "  [--num-particles N] [--pixel-stride PX] [--max-range-m M (4)] [--weighting paper|tempered]\n"
    "  [--init-half-extent M (2)] [--init-yaw-half-range RAD (pi/2)] (around the true start;\n"
    "   without ground truth the whole map)\n"
    "  [--depth-topic T (/camera/depth/image_raw)] [--info-topic T (.../camera_info)]\n"
    "  [--cloud-topic T] (organized PointCloud2 instead of the image)\n"
    "  [--imu-topic T (/imu/data)] [--odom-topic T (/odom)] [--truth-topic T (/ground_truth)]\n"
    "  [--odometry topic|tf|truth|none] (default: topic if present, else tf, else truth)\n"
    "  [--marker-to-camera x,y,z,qx,qy,qz,qw] (TransformStamped truth: marker -> camera)\n"
    "  [--odom-frame odom] [--base-frame base_link] [--quiet]\n"
    "  --cow-and-lady: --cloud-topic /camera/depth_registered/points --truth-topic\n"
    "                  /kinect/vrpn_client/estimated_transform --odometry truth\n"
    "Filter parameters: every one as --name-with-dashes (the list under --help).\n";

// Stamped tracks of the whole bag (no age limit), looked up as the nodelet looks up its
// buffers: interpolated between neighbours, else the nearest within a tolerance.
using PoseTrack = StampedPoseBuffer;
constexpr double kWholeBagS = 1e18;

struct Options {
  std::string bag_path, map_path, out_dir, odometry_mode;
  std::string depth_topic = "/camera/depth/image_raw", info_topic, cloud_topic;
  std::string imu_topic = "/imu/data", odom_topic = "/odom", truth_topic = "/ground_truth";
  std::string odom_frame = "odom", base_frame = "base_link", marker_to_camera;
  int frames = -1;
  uint64_t seed = 1;
  double init_half_extent_m = 2.0, init_yaw_half_range_rad = 0.5 * M_PI;
  bool quiet = false;
  LocalizerParams lp;  // the filter parameters given on the command line
  Eigen::Isometry3d T_marker_cam = Eigen::Isometry3d::Identity();
};

// The command line, checked: a usage error exits with status 2.
Options parseOptions(int argc, char** argv) {
  Options o;
  bool cow_and_lady = false;
  cli::CommandLine cl("gmm_mcl_replay_bag", kUsage);
  // clang-format off
  cl.flags({{"bag", &o.bag_path}, {"map", &o.map_path}, {"out", &o.out_dir}, {"seed", &o.seed},
            {"frames", &o.frames},
            {"init-half-extent", &o.init_half_extent_m},
            {"init-yaw-half-range", &o.init_yaw_half_range_rad}, {"depth-topic", &o.depth_topic},
            {"info-topic", &o.info_topic}, {"cloud-topic", &o.cloud_topic},
            {"imu-topic", &o.imu_topic}, {"odom-topic", &o.odom_topic},
            {"truth-topic", &o.truth_topic}, {"odometry", &o.odometry_mode},
            {"marker-to-camera", &o.marker_to_camera}, {"odom-frame", &o.odom_frame},
            {"base-frame", &o.base_frame}, {"quiet", &o.quiet}, {"cow-and-lady", &cow_and_lady}});
  // clang-format on
  cl.addLocalizerParams(
      &o.lp, {"seed", "init_centre", "init_half_extent", "init_yaw_centre", "init_yaw_half_range"});
  cl.alias("max-range", "max-range-m");
  cl.alias("stride", "pixel-stride");
  cl.alias("particles", "num-particles");
  cl.positional("bag");
  cl.parse(argc, argv);
  if (cow_and_lady) {
    o.cloud_topic = "/camera/depth_registered/points";
    o.truth_topic = "/kinect/vrpn_client/estimated_transform";
    o.odometry_mode = "truth";
  }
  if (o.bag_path.empty() || o.map_path.empty()) cl.fail("need BAG and --map");
  if (o.info_topic.empty()) {
    o.info_topic = o.depth_topic.substr(0, o.depth_topic.rfind('/')) + "/camera_info";
  }
  if (!o.marker_to_camera.empty() &&
      !ros_bag::parseTransform(o.marker_to_camera, &o.T_marker_cam)) {
    std::fprintf(stderr, "--marker-to-camera '%s' is not x,y,z,qx,qy,qz,qw\n",
                 o.marker_to_camera.c_str());
    std::exit(2);
  }
  if (!o.odometry_mode.empty() && o.odometry_mode != "topic" && o.odometry_mode != "tf" &&
      o.odometry_mode != "truth" && o.odometry_mode != "none") {
    std::fprintf(stderr, "--odometry must be topic, tf, truth or none\n");
    std::exit(2);
  }
  return o;
}

// Everything in the bag but the depth, indexed by header stamp.
struct BagTracks {
  PoseTrack odom_topic{kWholeBagS}, odom_tf{kWholeBagS}, truth{kWholeBagS};
  PoseTrack imu{kWholeBagS};     // roll and pitch
  GyroHeading gyro{kWholeBagS};  // the heading the IMU's rates turned (when it carries them)
  std::map<double, sensor_msgs::CameraInfo> infos;
  Eigen::Isometry3d T_base_cam = opticalToBase();
  bool have_extrinsics = false;
  std::string camera_frame;
};

void addTf(const rosbag::MessageInstance& m, const Options& o, BagTracks* tracks) {
  auto tf = m.instantiate<tf2_msgs::TFMessage>();
  if (!tf) return;
  for (const geometry_msgs::TransformStamped& t : tf->transforms) {
    if (t.header.frame_id == o.odom_frame && t.child_frame_id == o.base_frame) {
      tracks->odom_tf.add(t.header.stamp.toSec(), ros_conv::isometryFromTransform(t.transform));
    } else if (m.getTopic() == "/tf_static" && t.header.frame_id == o.base_frame) {
      tracks->T_base_cam = ros_conv::isometryFromTransform(t.transform);
      tracks->camera_frame = t.child_frame_id;
      tracks->have_extrinsics = true;
    }
  }
}

// Pass 1 over the bag: IMU, odometry, ground truth, CameraInfo and tf.
void readTracks(rosbag::Bag& bag, const Options& o, BagTracks* tracks) {
  rosbag::View view(
      bag, rosbag::TopicQuery(std::vector<std::string>{o.imu_topic, o.odom_topic, o.truth_topic,
                                                       o.info_topic, "/tf", "/tf_static"}));
  for (const rosbag::MessageInstance& m : view) {
    const std::string& topic = m.getTopic();
    if (topic == o.imu_topic) {
      auto imu = m.instantiate<sensor_msgs::Imu>();
      double r, p;
      if (imu && ros_conv::attitudeFromImu(*imu, &r, &p)) {
        tracks->imu.addAttitude(imu->header.stamp.toSec(), r, p);
        Eigen::Vector3d omega;
        if (ros_conv::angularVelocityFromImu(*imu, &omega)) {
          tracks->gyro.add(imu->header.stamp.toSec(), omega, r, p);
        }
      }
    } else if (topic == o.odom_topic) {
      if (auto od = m.instantiate<nav_msgs::Odometry>()) {
        tracks->odom_topic.add(od->header.stamp.toSec(), ros_conv::isometryFromPose(od->pose.pose));
      }
    } else if (topic == o.truth_topic) {
      if (auto ps = m.instantiate<geometry_msgs::PoseStamped>()) {
        tracks->truth.add(ps->header.stamp.toSec(), ros_conv::isometryFromPose(ps->pose));
      } else if (auto ts = m.instantiate<geometry_msgs::TransformStamped>()) {
        // The marker in the world; the base through the calibration (camera = base).
        tracks->truth.add(ts->header.stamp.toSec(), ros_conv::isometryFromTransform(ts->transform) *
                                                        o.T_marker_cam * opticalToBase().inverse());
      }
    } else if (topic == o.info_topic) {
      if (auto ci = m.instantiate<sensor_msgs::CameraInfo>()) {
        tracks->infos[ci->header.stamp.toSec()] = *ci;
      }
    } else {
      addTf(m, o, tracks);
    }
  }
}

// The odometry source (*mode: given, else topic, tf or truth, whichever the bag has) and its
// track; throws when the bag lacks what the replay needs.
const PoseTrack& chooseOdometry(const BagTracks& tracks, const Options& o, std::string* mode) {
  if (mode->empty()) {
    *mode = !tracks.odom_topic.empty() ? "topic" : !tracks.odom_tf.empty() ? "tf" : "truth";
  }
  const PoseTrack& odom_track = *mode == "topic" ? tracks.odom_topic : tracks.odom_tf;
  if (*mode != "truth" && *mode != "none" && odom_track.empty()) {
    throw std::runtime_error(
        o.bag_path + ": no odometry on " +
        (*mode == "topic" ? o.odom_topic : "tf " + o.odom_frame + " -> " + o.base_frame));
  }
  if (*mode == "truth" && tracks.truth.empty()) {
    throw std::runtime_error(o.bag_path + ": no odometry and no ground truth on " + o.truth_topic +
                             " to make it from");
  }
  if (tracks.imu.empty() && tracks.truth.empty()) {
    throw std::runtime_error(o.bag_path + ": no IMU on " + o.imu_topic + " and no ground truth");
  }
  return odom_track;
}

// One depth message as an image with its intrinsics and stamp; false with why.
bool decodeDepth(const rosbag::MessageInstance& m, const BagTracks& tracks, const Options& o,
                 DepthImage* depth, Intrinsics* K, double* t, std::string* why) {
  if (auto img = m.instantiate<sensor_msgs::Image>()) {
    *t = img->header.stamp.toSec();
    const auto ci = tracks.infos.find(*t);
    const bool ok = ci != tracks.infos.end() && ros_conv::depthImageFromMsg(*img, depth, why) &&
                    ros_conv::intrinsicsFromCameraInfo(ci->second, img->width, img->height, K, why);
    if (ci == tracks.infos.end()) *why = "no CameraInfo with its stamp on " + o.info_topic;
    return ok;
  }
  if (auto pc = m.instantiate<sensor_msgs::PointCloud2>()) {
    *t = pc->header.stamp.toSec();
    return ros_conv::depthImageFromCloud(*pc, depth, K, why);
  }
  *why = "not an Image or PointCloud2";
  return false;
}

// The localizer at the first usable frame: around the true start, else over the whole map.
std::unique_ptr<Localizer> startLocalizer(LocalizerParams lp, const GmmMap& map, bool has_truth,
                                          const Eigen::Isometry3d& T_truth, const Options& o) {
  if (!has_truth) {
    auto loc = std::make_unique<Localizer>(lp, map);
    loc->reset(loc->mapBounds());
    return loc;
  }
  const Particle start = poseToParticle(T_truth);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.half_extent_m.setConstant(o.init_half_extent_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  lp.init.yaw_half_range_rad = o.init_yaw_half_range_rad;
  return std::make_unique<Localizer>(lp, map);
}

void printProgress(int f, int total, const ReplayFrame& rf) {
  if (f % 10 != 0 && f != total - 1) return;
  const int bar = 30, done = (f + 1) * bar / std::max(total, 1);
  std::fprintf(stderr, "\r  [%.*s%*s] %4d/%d  error %6.3f m  Neff %5.0f  %5.0f ms  ", done,
               "==============================", bar - done, "", f + 1, total,
               rf.has_truth ? rf.error.translation_m : NAN, rf.step.neff, rf.step.timings.total_ms);
  if (f == total - 1) std::fprintf(stderr, "\n");
}

// The files and the summary line; the exit status (1: the protocol's failure).
int report(const TrialResult& result, int skipped, const Options& o) {
  if (!o.out_dir.empty()) {
    mkdir(o.out_dir.c_str(), 0755);
    writeTum(result, false, o.out_dir + "/estimate.tum");
    writeTum(result, true, o.out_dir + "/truth.tum");
    writeFrameCsv(result, o.out_dir + "/frames.csv");
  }
  const TrialMetrics& mt = result.metrics;
  std::printf("%zu frames used, %d skipped; mean step %.0f ms", result.frames.size(), skipped,
              result.mean_step_ms);
  if (mt.frames > 0) {
    std::printf("; %s, converged at %.2f s, ATE %.2f cm / %.2f deg, final error %.2f cm",
                mt.success ? "success" : "FAILURE", mt.converged ? mt.converge_time_s : NAN,
                100 * mt.ate_translation_m, mt.ate_yaw_rad * 180 / M_PI,
                100 * result.frames.back().error.translation_m);
  }
  std::printf("\n");
  if (!o.out_dir.empty()) {
    std::printf("wrote %s/{estimate.tum,truth.tum,frames.csv}\n", o.out_dir.c_str());
  }
  return mt.frames == 0 || mt.success ? 0 : 1;
}

int run(const Options& o) {
  rosbag::Bag bag(o.bag_path, rosbag::bagmode::Read);
  BagTracks tracks;
  readTracks(bag, o, &tracks);
  std::string odometry_mode = o.odometry_mode;
  const PoseTrack& odom_track = chooseOdometry(tracks, o, &odometry_mode);
  const bool synth_attitude = tracks.imu.empty();
  const bool no_odometry = odometry_mode == "none";
  if (no_odometry) {
    odometry_mode = tracks.gyro.added() == 0 ? "none (constant velocity)"
                                             : "none (constant velocity, gyro heading)";
  }

  const GmmMap map = loadMap(o.map_path);
  LocalizerParams lp = o.lp;
  lp.filter.seed = o.seed;
  lp.T_base_cam = tracks.T_base_cam;
  std::unique_ptr<Localizer> loc;
  OdometrySynthesizer synth(ProtocolNoise(), o.seed);
  TrialResult result;
  result.seed = o.seed;
  const std::string depth_source = o.cloud_topic.empty() ? o.depth_topic : o.cloud_topic;
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{depth_source}));
  const int total =
      o.frames > 0 ? std::min<int>(o.frames, view.size()) : static_cast<int>(view.size());
  std::printf(
      "gmm_mcl_replay_bag: %s, %d depth frames on %s, odometry: %s, attitude: %s, "
      "ground truth: %zu poses on %s, extrinsics: %s; map %s (%zu components), %d "
      "particles, stride %d, seed %llu\n",
      o.bag_path.c_str(), total, depth_source.c_str(), odometry_mode.c_str(),
      synth_attitude ? "truth + noise" : o.imu_topic.c_str(), tracks.truth.size(),
      o.truth_topic.c_str(),
      tracks.have_extrinsics ? ("/tf_static " + tracks.camera_frame).c_str() : "camera = base",
      o.map_path.c_str(), map.size(), lp.filter.num_particles, lp.frame.pixel_stride,
      static_cast<unsigned long long>(o.seed));
  double last_t = -1.0;
  int skipped = 0;
  for (const rosbag::MessageInstance& m : view) {
    if (static_cast<int>(result.frames.size()) + skipped >= total) break;
    DepthImage depth;
    Intrinsics K;
    std::string why;
    double t = 0.0;
    const bool ok = decodeDepth(m, tracks, o, &depth, &K, &t, &why);
    Eigen::Isometry3d T_truth = Eigen::Isometry3d::Identity();
    const bool has_truth = tracks.truth.at(t, 0.05, &T_truth);
    StepInput in;
    in.stamp_s = t;
    if (odometry_mode == "truth") {
      in.has_odometry = has_truth;
      if (has_truth) in.T_odom_base = synth.next(T_truth, last_t < 0 ? 1.0 : (t - last_t) * 30.0);
    } else if (no_odometry) {
      // The gyro's heading and its segment of samples (as the nodelet's).
      in.has_gyro_yaw =
          gyroHeadingForStep(tracks.gyro, t, 0.05, &in.gyro_segment, &in.gyro_yaw_rad);
    } else {
      in.has_odometry = odom_track.at(t, 0.05, &in.T_odom_base);
    }
    if (synth_attitude) {
      in.has_attitude = has_truth;
      if (has_truth) synth.attitude(T_truth, &in.roll_rad, &in.pitch_rad);
    } else {
      in.has_attitude = tracks.imu.attitudeAt(t, 0.05, &in.roll_rad, &in.pitch_rad);
    }
    if (!ok || (!in.has_odometry && !no_odometry)) {
      if (!o.quiet) {
        std::fprintf(stderr, "frame at %.3f s skipped: %s\n", t,
                     ok ? "no odometry at its stamp" : why.c_str());
      }
      ++skipped;
      continue;
    }
    in.depth = &depth;
    in.intrinsics = K;
    if (!loc) loc = startLocalizer(lp, map, has_truth, T_truth, o);
    const Particle truth = poseToParticle(T_truth);
    result.frames.push_back(makeReplayFrame(t, loc->step(in), has_truth ? &truth : nullptr));
    last_t = t;
    if (!o.quiet) {
      printProgress(static_cast<int>(result.frames.size()) + skipped - 1, total,
                    result.frames.back());
    }
  }
  finishTrial(EvaluationParams(), &result);
  if (result.frames.empty()) throw std::runtime_error(o.bag_path + ": no usable depth frame");
  return report(result, skipped, o);
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  const gmm_mcl::Options o = gmm_mcl::parseOptions(argc, argv);
  try {
    return gmm_mcl::run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gmm_mcl_replay_bag: %s\n", e.what());
    return 1;
  }
}
