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
  // The IMU gyro's heading (StepInput::gyro_yaw_rad): the true yaw change plus a constant bias
  // per trial, N(0, gyro_bias_sigma_rad_s), and white noise of this density. A MEMS gyro after
  // its start-up calibration has a residual bias of about 0.1 deg/s (0.0017 rad/s) and a noise
  // density of 0.014 deg/s/sqrt(Hz) (0.00024 rad/s/sqrt(Hz), Bosch BMI088 datasheet): these
  // are three and twelve times that.
  double gyro_bias_sigma_rad_s = 0.005;
  double gyro_noise_density_rad_s_sqrt_hz = 0.003;
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
  // The gyro's heading at the next true pose, dt_s after the previous call's (0 at the first
  // call). Its own random numbers: the odometry and attitude sequences of a seed are the same
  // whether or not it is called.
  double gyroYaw(const Eigen::Isometry3d& T_world_base, double dt_s);
  // The gyro's rate sample (sensor_msgs/Imu angular_velocity, the body frame) for a true body
  // rate averaged over dt_s: plus a constant bias per axis and trial, N(0,
  // gyro_bias_sigma_rad_s), and white noise N(0, gyro_noise_density / sqrt(dt_s)) per axis (none
  // for dt_s <= 0). The same random numbers as gyroYaw: a caller uses one or the other.
  Eigen::Vector3d gyroRate(const Eigen::Vector3d& true_rate_rad_s, double dt_s);
  // Forget the previous pose: the next call starts a new odometry frame.
  void restart() { started_ = false; }

 private:
  ProtocolNoise noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
  bool started_ = false;
  Eigen::Isometry3d last_truth_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d odom_ = Eigen::Isometry3d::Identity();
  std::mt19937_64 gyro_rng_;  // with its own distribution (a normal_distribution caches draws)
  std::normal_distribution<double> gyro_gauss_{0.0, 1.0};
  bool gyro_started_ = false;
  double gyro_bias_rad_s_ = 0.0, gyro_yaw_rad_ = 0.0, gyro_last_true_yaw_rad_ = 0.0;
  bool rate_started_ = false;
  Eigen::Vector3d rate_bias_rad_s_ = Eigen::Vector3d::Zero();
};

}  // namespace gmm_mcl
