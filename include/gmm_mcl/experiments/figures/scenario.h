// The frames the figure tools run on: a 7-Scenes sequence (gravity-aligned as the replay does)
// or the synthetic box scene, with ground truth, depth images and the protocol's synthesised
// odometry and attitude (DESIGN.md), identical for every filter run that shares a data seed.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace figures {

struct Scenario {
  std::string name;
  Intrinsics intrinsics;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();  // optical frame in base
  float max_range_m = 4.0f;  // depth window of the filter (7-Scenes map: 4 m)
  double frame_rate_hz = 30.0;
  std::vector<Eigen::Isometry3d> T_map_base;  // ground truth per frame (map frame, z up)
  std::vector<DepthImage> depth;
  // Rotation from the data set's world frame into the map frame (maps built in the world
  // frame, e.g. by build_map_7scenes.sh, are rotated by it).
  Eigen::Matrix3d R_map_world = Eigen::Matrix3d::Identity();
  std::string dataset_dir;  // 7-Scenes folder; empty for the synthetic scene

  int size() const { return static_cast<int>(T_map_base.size()); }
};

// `frames` frames of a 7-Scenes folder from first_frame on. Throws std::runtime_error.
Scenario sevenScenesScenario(const std::string& data_dir, int first_frame, int frames);

// The synthetic box scene (sim::makeDefaultScene) along sim::makeTrajectory (30 Hz), frames
// first_frame .. first_frame + frames - 1, depth rendered at width_px (7-Scenes camera scaled,
// f = 585 px at 640) with the demo's noise (1.5 mm at 1 m, 2% dropout) seeded by noise_seed.
Scenario syntheticScenario(int first_frame, int frames, int width_px, uint64_t noise_seed);

// The synthetic scene's analytic map: every surface tiled with flat Gaussians (spacing, normal
// sigma), about 1100 components at the defaults (the test fixtures' map).
GmmMap syntheticTiledMap(double spacing_m = 0.4, double normal_sigma_m = 0.015);

// $GMM_MCL_DATASETS/7scenes_redkitchen/data, else ../shared/datasets/... relative to the working
// directory, else relative to `exe_dir/../..`; empty when none has camera-intrinsics.txt.
std::string findSevenScenes(const std::string& exe_dir);

// The protocol's sensor inputs: odometry = true frame-to-frame motion plus N(0, odom_sigma_m)
// per axis and N(0, odom_sigma_yaw_rad) in yaw per frame (drifting), roll/pitch = truth plus
// N(0, attitude_sigma_rad).
struct SensorInputs {
  std::vector<Eigen::Isometry3d> T_odom_base;
  std::vector<double> roll_rad, pitch_rad;
};
struct SensorNoise {
  double odom_sigma_m = 0.005;
  double odom_sigma_yaw_rad = 0.002;
  double attitude_sigma_rad = 0.5 * M_PI / 180.0;
};
SensorInputs synthesiseInputs(const Scenario& scenario, const SensorNoise& noise, uint64_t seed);

}  // namespace figures
}  // namespace gmm_mcl
