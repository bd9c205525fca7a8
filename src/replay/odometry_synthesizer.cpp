#include "gmm_mcl/replay/odometry_synthesizer.h"

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {

OdometrySynthesizer::OdometrySynthesizer(const ProtocolNoise& noise, uint64_t seed)
    : noise_(noise), rng_(seed * 7919 + 17), gyro_rng_(seed * 104729 + 31) {}

Eigen::Isometry3d OdometrySynthesizer::next(const Eigen::Isometry3d& T_world_base, double frames) {
  if (!started_) {
    double roll, pitch, yaw;
    rpyFromRotation(T_world_base.linear(), &roll, &pitch, &yaw);
    odom_ = Eigen::Isometry3d::Identity();
    odom_.linear() = rotationFromRpy(roll, pitch, 0.0);
    started_ = true;
  } else {
    const double s = std::sqrt(std::max(frames, 0.0));
    Eigen::Isometry3d delta = last_truth_.inverse() * T_world_base;
    // Drawn z, y, x: the order in which GCC evaluated the former inline expression, so that
    // seeded replays repeat the numbers recorded before this class existed.
    const double nz = gauss_(rng_);
    const double ny = gauss_(rng_);
    const double nx = gauss_(rng_);
    delta.translation() += s * noise_.odom_sigma_m * Eigen::Vector3d(nx, ny, nz);
    delta.linear() =
        delta.linear() *
        Eigen::AngleAxisd(s * noise_.odom_sigma_yaw_rad * gauss_(rng_), Eigen::Vector3d::UnitZ())
            .toRotationMatrix();
    odom_ = odom_ * delta;
  }
  last_truth_ = T_world_base;
  return odom_;
}

void OdometrySynthesizer::attitude(const Eigen::Isometry3d& T_world_base, double* roll_rad,
                                   double* pitch_rad) {
  double yaw;
  rpyFromRotation(T_world_base.linear(), roll_rad, pitch_rad, &yaw);
  *roll_rad += noise_.attitude_sigma_rad * gauss_(rng_);
  *pitch_rad += noise_.attitude_sigma_rad * gauss_(rng_);
}

Eigen::Vector3d OdometrySynthesizer::gyroRate(const Eigen::Vector3d& true_rate_rad_s, double dt_s) {
  if (!rate_started_) {
    for (int a = 0; a < 3; ++a) {
      rate_bias_rad_s_[a] = noise_.gyro_bias_sigma_rad_s * gyro_gauss_(gyro_rng_);
    }
    rate_started_ = true;
  }
  Eigen::Vector3d rate = true_rate_rad_s + rate_bias_rad_s_;
  if (dt_s > 0.0 && std::isfinite(dt_s)) {
    const double sigma = noise_.gyro_noise_density_rad_s_sqrt_hz / std::sqrt(dt_s);
    for (int a = 0; a < 3; ++a) rate[a] += sigma * gyro_gauss_(gyro_rng_);
  }
  return rate;
}

double OdometrySynthesizer::gyroYaw(const Eigen::Isometry3d& T_world_base, double dt_s) {
  double roll, pitch, yaw;
  rpyFromRotation(T_world_base.linear(), &roll, &pitch, &yaw);
  if (!gyro_started_) {
    gyro_bias_rad_s_ = noise_.gyro_bias_sigma_rad_s * gyro_gauss_(gyro_rng_);
    gyro_yaw_rad_ = 0.0;
    gyro_started_ = true;
  } else {
    const double dt = std::max(dt_s, 0.0);
    gyro_yaw_rad_ +=
        wrapAngle(yaw - gyro_last_true_yaw_rad_) + gyro_bias_rad_s_ * dt +
        noise_.gyro_noise_density_rad_s_sqrt_hz * std::sqrt(dt) * gyro_gauss_(gyro_rng_);
  }
  gyro_last_true_yaw_rad_ = yaw;
  return gyro_yaw_rad_;
}

}  // namespace gmm_mcl
