// Converts a data-set Sequence (7-Scenes, TUM, Stanford, the synthetic scene) into a bag for
// the nodelet, following the DESIGN.md accuracy protocol: ground-truth base poses in the
// gravity-aligned frame, odometry and IMU attitude from OdometrySynthesizer (seeded).
// Layouts:
//  - image (replay.launch): depth 16UC1 + CameraInfo, /imu/data, /odom + tf odom -> base_link,
//    static base_link -> camera_depth_optical_frame, /ground_truth (PoseStamped).
//  - cow_and_lady (the voxblox data set, paper D2, as recorded): organized PointCloud2 on
//    /camera/depth_registered/points (camera_rgb_optical_frame) and the motion-capture pose of
//    the camera's marker as TransformStamped on /kinect/vrpn_client/estimated_transform
//    (world -> kinect); no odometry, IMU or tf: gmm_mcl_ground_truth_odometry makes them.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <string>

#include "gmm_mcl/datasets/sequence_base.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"

namespace gmm_mcl {
namespace ros_bag {

struct SequenceBagOptions {
  std::string layout = "image";  // "image" or "cow_and_lady"
  uint64_t seed = 1;             // odometry and attitude noise
  ProtocolNoise noise;
  double start_s = 1000.0;  // bag time of the first frame (stamps keep their spacing)
  int max_frames = -1;
  // cow_and_lady: marker (kinect body) -> camera optical frame, the fixed calibration.
  Eigen::Isometry3d T_marker_cam = Eigen::Isometry3d::Identity();
  // Initial region written to <bag stem>_init.yaml (the paper's 4 m cube, yaw range pi).
  double init_half_extent_m = 2.0;
  double init_yaw_half_range_rad = 0.5 * M_PI;
  std::function<void(int frame, int total)> progress;
};

struct SequenceBagResult {
  int frames = 0;
  double duration_s = 0.0;
  std::string map_path;   // <stem>.gmm when a map was given
  std::string init_path;  // <stem>_init.yaml
};

// Writes bag_path, <stem>_init.yaml and, when map_world is not null, <stem>.gmm (the map
// rotated into the gravity-aligned frame). Throws std::runtime_error.
SequenceBagResult writeSequenceBag(const Sequence& seq, const GmmMap* map_world,
                                   const std::string& bag_path, const SequenceBagOptions& options);

// The cow_and_lady layout's names.
constexpr const char* kCowCloudTopic = "/camera/depth_registered/points";
constexpr const char* kCowCameraFrame = "camera_rgb_optical_frame";
constexpr const char* kCowTruthTopic = "/kinect/vrpn_client/estimated_transform";
constexpr const char* kCowWorldFrame = "world";
constexpr const char* kCowMarkerFrame = "kinect";

}  // namespace ros_bag
}  // namespace gmm_mcl
