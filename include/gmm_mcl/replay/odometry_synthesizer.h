// Odometry and attitude synthesised from ground truth, per the DESIGN.md accuracy protocol:
// odometry = true motion plus N(0, 0.005 m) per axis and N(0, 0.002 rad) in yaw per frame (it
// drifts), roll/pitch = truth plus N(0, 0.5 deg). Seeded; the replay, the bag converters and
// the ground-truth -> odometry node all draw from it, so one seed gives one noise sequence.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>

namespace gmm_mcl {

struct ProtocolNoise {
  double odom_sigma_m = 0.005;        // per frame, per axis
  double odom_sigma_yaw_rad = 0.002;  // per frame
  double attitude_sigma_rad = 0.5 * M_PI / 180.0;
};

class OdometrySynthesizer {
 public:
  OdometrySynthesizer(const ProtocolNoise& noise, uint64_t seed);

  // The odometry pose of the base for the next true pose T_world_base. The odometry frame
  // starts gravity-aligned at the first pose (its roll and pitch, zero yaw and position), as a
  // visual-inertial odometry's would. `frames` scales the noise variance of this step (the
  // interval in frames of the reference rate: 1 per frame; dt * 30 Hz for a pose stream).
  Eigen::Isometry3d next(const Eigen::Isometry3d& T_world_base, double frames = 1.0);
  // Noisy roll and pitch (REP-103) of a true pose.
  void attitude(const Eigen::Isometry3d& T_world_base, double* roll_rad, double* pitch_rad);
  // Forget the previous pose: the next call starts a new odometry frame.
  void restart() { started_ = false; }

 private:
  ProtocolNoise noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
  bool started_ = false;
  Eigen::Isometry3d last_truth_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d odom_ = Eigen::Isometry3d::Identity();
};

}  // namespace gmm_mcl
