#include "gmm_mcl/ros_tools/sequence_bag.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>

#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/ros_tools/bag_writer.h"

namespace gmm_mcl {
namespace ros_bag {

SequenceBagResult writeSequenceBag(const Sequence& seq, const GmmMap* map_world,
                                   const std::string& bag_path, const SequenceBagOptions& options) {
  if (options.layout != "image" && options.layout != "cow_and_lady") {
    throw std::runtime_error("unknown bag layout '" + options.layout + "' (image, cow_and_lady)");
  }
  const int n = options.max_frames > 0 ? std::min(options.max_frames, seq.size()) : seq.size();
  const std::string stem = bag_path.substr(0, bag_path.rfind('.'));
  SequenceBagResult result;
  result.frames = n;
  if (map_world) {
    result.map_path = stem + ".gmm";
    saveMap(rotateMap(*map_world, seq.R_aligned_world(), "map (gravity-aligned)"), result.map_path);
  }
  const std::vector<Eigen::Isometry3d> truth = alignedBaseTrajectory(seq, n);
  result.init_path = stem + "_init.yaml";
  writeInitRegionYaml(result.init_path,
                      "Initial region around the true start of " + bag_path + " (" + seq.format() +
                          ": " + seq.source() + ")",
                      poseToParticle(truth[0]), options.init_half_extent_m,
                      options.init_yaw_half_range_rad);

  const bool cow = options.layout == "cow_and_lady";
  BagLayout layout;
  if (cow) {
    layout.cloud_topic = kCowCloudTopic;
    layout.camera_frame = kCowCameraFrame;
  }
  SensorBagWriter writer(bag_path, "/gmm_mcl_make_bag", layout);
  const Eigen::Isometry3d T_base_cam = opticalToBase();
  const ros::Time t0(options.start_s);
  const double stamp0 = seq.stampS(0);
  if (!cow) writer.writeStaticTransform(t0, layout.base_frame, layout.camera_frame, T_base_cam);
  OdometrySynthesizer odometry(options.noise, options.seed);
  for (int f = 0; f < n; ++f) {
    const ros::Time t = t0 + ros::Duration(seq.stampS(f) - stamp0);
    const DepthImage depth = seq.loadDepth(f);
    if (cow) {
      // The motion-capture pose of the marker, slightly before the frame (as recorded), and
      // the organized cloud; the ground truth is the camera pose through the calibration.
      const Eigen::Isometry3d T_world_marker =
          truth[f] * T_base_cam * options.T_marker_cam.inverse();
      writer.writeTransformStamped(kCowTruthTopic, t, kCowWorldFrame, kCowMarkerFrame,
                                   T_world_marker);
      writer.writeCloud(t, depth, seq.intrinsics());
    } else {
      const ros::Time t_before = t - ros::Duration(0.002);
      const Eigen::Isometry3d T_odom_base = odometry.next(truth[f]);
      double roll, pitch;
      odometry.attitude(truth[f], &roll, &pitch);
      const double yaw = yawFromRotation(truth[f].linear());
      // The gyro: the true body rate over the interval ending at this frame (the first frame's
      // over the next interval), with a MEMS gyro's bias and white noise (ProtocolNoise).
      const int a = f > 0 ? f - 1 : 0, b = f > 0 ? f : std::min(1, n - 1);
      Eigen::Vector3d omega = Eigen::Vector3d::Zero();
      const double dt = seq.stampS(b) - seq.stampS(a);
      if (b > a && dt > 0.0) {
        const Eigen::AngleAxisd turn(truth[a].linear().transpose() * truth[b].linear());
        omega = turn.angle() / dt * turn.axis();
      }
      omega = odometry.gyroRate(omega, dt);
      writer.writeImu(t, t_before, roll, pitch, yaw, options.noise.attitude_sigma_rad, &omega);
      writer.writeOdometry(t, t_before, T_odom_base);
      writer.writeDepth(t, depth, seq.intrinsics());
      writer.writeGroundTruth(t, truth[f]);
    }
    if (options.progress) options.progress(f, n);
  }
  writer.close();
  result.duration_s = seq.stampS(n - 1) - stamp0;
  return result;
}

}  // namespace ros_bag
}  // namespace gmm_mcl
