// gmm_mcl_replay_bag: replays a bag through the core localizer directly (rosbag C++ API, no
// ROS master), as fast as it runs, seeded; the offline counterpart of replay.launch and
// cow_and_lady.launch. Inputs per depth frame (16UC1/32FC1 image + CameraInfo, or an organized
// PointCloud2): odometry from nav_msgs/Odometry, from tf odom -> base, or synthesised from the
// ground truth (DESIGN.md noise, as gmm_mcl_ground_truth_odometry); roll/pitch from the IMU
// (or synthesised from the truth); ground truth from a PoseStamped (base in map) or a
// TransformStamped (marker in world, with the marker -> camera calibration). Outputs as
// gmm_mcl_replay: TUM trajectories, per-frame CSV, the protocol's metrics.
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include "gmm_mcl/filter/stamped_buffer.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/ros/bag_writer.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/tools/command_line.h"

using namespace gmm_mcl;

namespace {

const char* kUsage =
      "usage: gmm_mcl_replay_bag BAG --map MAP.gmm [--out DIR] [--seed S] [--frames N]\n"
      "  [--particles N] [--stride PX] [--max-range-m M (4)] [--weighting paper|tempered]\n"
      "  [--init-half-extent M (2)] [--init-yaw-half-range RAD (pi/2)] (around the true start;\n"
      "   without ground truth the whole map)\n"
      "  [--depth-topic T (/camera/depth/image_raw)] [--info-topic T (.../camera_info)]\n"
      "  [--cloud-topic T] (organized PointCloud2 instead of the image)\n"
      "  [--imu-topic T (/imu/data)] [--odom-topic T (/odom)] [--truth-topic T (/ground_truth)]\n"
      "  [--odometry topic|tf|truth] (default: topic if present, else tf, else truth)\n"
      "  [--marker-to-camera x,y,z,qx,qy,qz,qw] (TransformStamped truth: marker -> camera)\n"
      "  [--odom-frame odom] [--base-frame base_link] [--quiet]\n"
      "  --cow-and-lady: --cloud-topic /camera/depth_registered/points --truth-topic\n"
      "                  /kinect/vrpn_client/estimated_transform --odometry truth\n"
      "Filter parameters: every one as --name-with-dashes (the list under --help).\n";

// Stamped tracks of the whole bag (no age limit), looked up as the nodelet looks up its
// buffers: interpolated between neighbours, else the nearest within a tolerance.
using PoseTrack = StampedPoseBuffer;
constexpr double kWholeBagS = 1e18;

}  // namespace

int main(int argc, char** argv) {
  std::string bag_path, map_path, out_dir, odometry_mode;
  std::string depth_topic = "/camera/depth/image_raw", info_topic, cloud_topic;
  std::string imu_topic = "/imu/data", odom_topic = "/odom", truth_topic = "/ground_truth";
  std::string odom_frame = "odom", base_frame = "base_link", marker_to_camera;
  int frames = -1, particles = kDefaultParticleCount, stride = 4;
  uint64_t seed = 1;
  double init_half_extent_m = 2.0, init_yaw_half_range_rad = 0.5 * M_PI;
  bool quiet = false;
  bool cow_and_lady = false;
  LocalizerParams lp;  // the filter parameters given on the command line
  cli::CommandLine cl("gmm_mcl_replay_bag", kUsage);
  cl.flags({{"bag", &bag_path}, {"map", &map_path}, {"out", &out_dir}, {"seed", &seed},
            {"frames", &frames}, {"particles", &particles}, {"stride", &stride},
            {"init-half-extent", &init_half_extent_m},
            {"init-yaw-half-range", &init_yaw_half_range_rad}, {"depth-topic", &depth_topic},
            {"info-topic", &info_topic}, {"cloud-topic", &cloud_topic}, {"imu-topic", &imu_topic},
            {"odom-topic", &odom_topic}, {"truth-topic", &truth_topic},
            {"odometry", &odometry_mode}, {"marker-to-camera", &marker_to_camera},
            {"odom-frame", &odom_frame}, {"base-frame", &base_frame}, {"quiet", &quiet},
            {"cow-and-lady", &cow_and_lady}});
  cl.addLocalizerParams(&lp, {"num_particles", "pixel_stride", "seed", "init_centre",
                              "init_half_extent", "init_yaw_centre", "init_yaw_half_range"});
  cl.alias("max-range", "max-range-m");
  cl.positional("bag");
  cl.parse(argc, argv);
  if (cow_and_lady) {
    cloud_topic = "/camera/depth_registered/points";
    truth_topic = "/kinect/vrpn_client/estimated_transform";
    odometry_mode = "truth";
  }
  if (bag_path.empty() || map_path.empty()) cl.fail("need BAG and --map");
  if (info_topic.empty()) info_topic = depth_topic.substr(0, depth_topic.rfind('/')) + "/camera_info";
  Eigen::Isometry3d T_marker_cam = Eigen::Isometry3d::Identity();
  if (!marker_to_camera.empty() && !ros_bag::parseTransform(marker_to_camera, &T_marker_cam)) {
    std::fprintf(stderr, "--marker-to-camera '%s' is not x,y,z,qx,qy,qz,qw\n", marker_to_camera.c_str());
    return 2;
  }
  if (!odometry_mode.empty() && odometry_mode != "topic" && odometry_mode != "tf" &&
      odometry_mode != "truth") {
    std::fprintf(stderr, "--odometry must be topic, tf or truth\n");
    return 2;
  }
  try {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    // Pass 1: everything but the depth, indexed by header stamp.
    PoseTrack odom_topic_track(kWholeBagS), odom_tf_track(kWholeBagS), truth_track(kWholeBagS);
    PoseTrack imu_track(kWholeBagS);  // roll and pitch
    std::map<double, sensor_msgs::CameraInfo> infos;
    Eigen::Isometry3d T_base_cam = opticalToBase();
    bool have_extrinsics = false;
    std::string camera_frame;
    {
      rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{
                                 imu_topic, odom_topic, truth_topic, info_topic, "/tf", "/tf_static"}));
      for (const rosbag::MessageInstance& m : view) {
        const std::string& topic = m.getTopic();
        if (topic == imu_topic) {
          auto imu = m.instantiate<sensor_msgs::Imu>();
          double r, p;
          if (imu && ros_conv::attitudeFromImu(*imu, &r, &p)) {
            imu_track.addAttitude(imu->header.stamp.toSec(), r, p);
          }
        } else if (topic == odom_topic) {
          if (auto od = m.instantiate<nav_msgs::Odometry>()) {
            odom_topic_track.add(od->header.stamp.toSec(), ros_conv::isometryFromPose(od->pose.pose));
          }
        } else if (topic == truth_topic) {
          if (auto ps = m.instantiate<geometry_msgs::PoseStamped>()) {
            truth_track.add(ps->header.stamp.toSec(), ros_conv::isometryFromPose(ps->pose));
          } else if (auto ts = m.instantiate<geometry_msgs::TransformStamped>()) {
            // The marker in the world; the base through the calibration (camera = base).
            truth_track.add(ts->header.stamp.toSec(), ros_conv::isometryFromTransform(ts->transform) *
                                                          T_marker_cam * opticalToBase().inverse());
          }
        } else if (topic == info_topic) {
          if (auto ci = m.instantiate<sensor_msgs::CameraInfo>()) infos[ci->header.stamp.toSec()] = *ci;
        } else if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
          for (const geometry_msgs::TransformStamped& t : tf->transforms) {
            if (t.header.frame_id == odom_frame && t.child_frame_id == base_frame) {
              odom_tf_track.add(t.header.stamp.toSec(), ros_conv::isometryFromTransform(t.transform));
            } else if (topic == "/tf_static" && t.header.frame_id == base_frame) {
              T_base_cam = ros_conv::isometryFromTransform(t.transform);
              camera_frame = t.child_frame_id;
              have_extrinsics = true;
            }
          }
        }
      }
    }
    if (odometry_mode.empty()) {
      odometry_mode = !odom_topic_track.empty() ? "topic" : !odom_tf_track.empty() ? "tf" : "truth";
    }
    const PoseTrack& odom_track = odometry_mode == "topic" ? odom_topic_track : odom_tf_track;
    if (odometry_mode != "truth" && odom_track.empty()) {
      throw std::runtime_error(bag_path + ": no odometry on " +
                               (odometry_mode == "topic" ? odom_topic : "tf " + odom_frame + " -> " + base_frame));
    }
    if (odometry_mode == "truth" && truth_track.empty()) {
      throw std::runtime_error(bag_path + ": no odometry and no ground truth on " + truth_topic +
                               " to make it from");
    }
    const bool synth_attitude = imu_track.empty();
    if (synth_attitude && truth_track.empty()) {
      throw std::runtime_error(bag_path + ": no IMU on " + imu_topic + " and no ground truth");
    }

    const GmmMap map = loadMap(map_path);
    lp.filter.num_particles = particles;
    lp.frame.pixel_stride = stride;
    lp.filter.seed = seed;
    lp.T_base_cam = T_base_cam;
    std::unique_ptr<Localizer> loc;
    OdometrySynthesizer synth(ProtocolNoise(), seed);
    TrialResult result;
    result.seed = seed;
    const std::string depth_source = cloud_topic.empty() ? depth_topic : cloud_topic;
    rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{depth_source}));
    const int total = frames > 0 ? std::min<int>(frames, view.size()) : static_cast<int>(view.size());
    std::printf("gmm_mcl_replay_bag: %s, %d depth frames on %s, odometry: %s, attitude: %s, "
                "ground truth: %zu poses on %s, extrinsics: %s; map %s (%zu components), %d "
                "particles, stride %d, seed %llu\n",
                bag_path.c_str(), total, depth_source.c_str(), odometry_mode.c_str(),
                synth_attitude ? "truth + noise" : imu_topic.c_str(), truth_track.size(),
                truth_topic.c_str(), have_extrinsics ? ("/tf_static " + camera_frame).c_str() : "camera = base",
                map_path.c_str(), map.size(), particles, stride, static_cast<unsigned long long>(seed));
    double last_t = -1.0;
    int skipped = 0;
    for (const rosbag::MessageInstance& m : view) {
      if (static_cast<int>(result.frames.size()) + skipped >= total) break;
      DepthImage depth;
      Intrinsics K;
      std::string why;
      double t = 0.0;
      bool ok = false;
      if (auto img = m.instantiate<sensor_msgs::Image>()) {
        t = img->header.stamp.toSec();
        const auto ci = infos.find(t);
        ok = ci != infos.end() && ros_conv::depthImageFromMsg(*img, &depth, &why) &&
             ros_conv::intrinsicsFromCameraInfo(ci->second, img->width, img->height, &K, &why);
        if (ci == infos.end()) why = "no CameraInfo with its stamp on " + info_topic;
      } else if (auto pc = m.instantiate<sensor_msgs::PointCloud2>()) {
        t = pc->header.stamp.toSec();
        ok = ros_conv::depthImageFromCloud(*pc, &depth, &K, &why);
      } else {
        why = "not an Image or PointCloud2";
      }
      Eigen::Isometry3d T_truth = Eigen::Isometry3d::Identity();
      const bool has_truth = truth_track.at(t, 0.05, &T_truth);
      StepInput in;
      in.stamp_s = t;
      if (odometry_mode == "truth") {
        in.has_odometry = has_truth;
        if (has_truth) {
          in.T_odom_base = synth.next(T_truth, last_t < 0 ? 1.0 : (t - last_t) * 30.0);
        }
      } else {
        in.has_odometry = odom_track.at(t, 0.05, &in.T_odom_base);
      }
      if (synth_attitude) {
        in.has_attitude = has_truth;
        if (has_truth) synth.attitude(T_truth, &in.roll_rad, &in.pitch_rad);
      } else {
        in.has_attitude = imu_track.attitudeAt(t, 0.05, &in.roll_rad, &in.pitch_rad);
      }
      if (!ok || !in.has_odometry) {
        if (!quiet) {
          std::fprintf(stderr, "frame at %.3f s skipped: %s\n", t,
                       ok ? "no odometry at its stamp" : why.c_str());
        }
        ++skipped;
        continue;
      }
      in.depth = &depth;
      in.intrinsics = K;
      if (!loc) {
        if (has_truth) {
          const Particle start = poseToParticle(T_truth);
          lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
          lp.init.half_extent_m.setConstant(init_half_extent_m);
          lp.init.yaw_centre_rad = start.yaw_rad;
          lp.init.yaw_half_range_rad = init_yaw_half_range_rad;
          loc.reset(new Localizer(lp, map));
        } else {
          loc.reset(new Localizer(lp, map));
          loc->reset(loc->mapBounds());
        }
      }
      const Particle truth = poseToParticle(T_truth);
      result.frames.push_back(makeReplayFrame(t, loc->step(in), has_truth ? &truth : nullptr));
      last_t = t;
      const ReplayFrame& rf = result.frames.back();
      const int f = static_cast<int>(result.frames.size()) + skipped - 1;
      if (!quiet && (f % 10 == 0 || f == total - 1)) {
        const int bar = 30, done = (f + 1) * bar / std::max(total, 1);
        std::fprintf(stderr, "\r  [%.*s%*s] %4d/%d  error %6.3f m  Neff %5.0f  %5.0f ms  ", done,
                     "==============================", bar - done, "", f + 1, total,
                     rf.has_truth ? rf.error.translation_m : NAN, rf.step.neff,
                     rf.step.timings.total_ms);
        if (f == total - 1) std::fprintf(stderr, "\n");
      }
    }
    finishTrial(EvaluationParams(), &result);
    if (result.frames.empty()) throw std::runtime_error(bag_path + ": no usable depth frame");
    if (!out_dir.empty()) {
      mkdir(out_dir.c_str(), 0755);
      writeTum(result, false, out_dir + "/estimate.tum");
      writeTum(result, true, out_dir + "/truth.tum");
      writeFrameCsv(result, out_dir + "/frames.csv");
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
    if (!out_dir.empty()) {
      std::printf("wrote %s/{estimate.tum,truth.tum,frames.csv}\n", out_dir.c_str());
    }
    return mt.frames == 0 || mt.success ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gmm_mcl_replay_bag: %s\n", e.what());
    return 1;
  }
}
