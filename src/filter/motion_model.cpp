#include "gmm_mcl/filter/motion_model.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "gmm_mcl/common/enum_names.h"

namespace gmm_mcl {

namespace {

const EnumName<MotionSource> kMotionSourceNames[] = {
    {"odometry", MotionSource::kOdometry},
    {"constant_velocity", MotionSource::kConstantVelocity},
    {"static", MotionSource::kStatic}};

}  // namespace

const char* motionSourceName(MotionSource source) { return enumNameOf(source, kMotionSourceNames); }

std::string ConstantVelocityParams::validate() const {
  std::ostringstream err;
  if (!(velocity_smoothing > 0.0 && velocity_smoothing <= 1.0))
    err << "cv_velocity_smoothing must be in (0, 1]; ";
  if (!(sigma_speed_m_s >= 0.0) || !std::isfinite(sigma_speed_m_s))
    err << "cv_sigma_speed_m_s must be finite and >= 0; ";
  if (!(sigma_yaw_rate_rad_s >= 0.0) || !std::isfinite(sigma_yaw_rate_rad_s))
    err << "cv_sigma_yaw_rate_rad_s must be finite and >= 0; ";
  if (!(vertical_time_constant_s >= 0.0) || !std::isfinite(vertical_time_constant_s))
    err << "cv_vertical_time_constant_s must be finite and >= 0; ";
  if (!(max_gap_s > 0.0)) err << "cv_max_gap_s must be positive; ";
  if (!(max_speed_m_s > 0.0)) err << "cv_max_speed_m_s must be positive; ";
  if (!(gyro_sigma_yaw_rate_rad_s >= 0.0) || !std::isfinite(gyro_sigma_yaw_rate_rad_s))
    err << "cv_gyro_sigma_yaw_rate_rad_s must be finite and >= 0; ";
  return err.str();
}

void ConstantVelocityModel::forgetVelocity() {
  have_velocity_ = false;
  velocity_.setZero();
  world_velocity_.setZero();
}

void ConstantVelocityModel::reset() {
  forgetVelocity();
  have_pose_ = false;
}

PlanarDelta ConstantVelocityModel::predict(double dt_s, double sigma_translation_m,
                                           double sigma_yaw_rad, const double* gyro_yaw_delta_rad,
                                           bool* turned_by_gyro) {
  if (!std::isfinite(dt_s) || dt_s < 0.0) dt_s = 0.0;
  if (dt_s > params_.max_gap_s) forgetVelocity();
  PlanarDelta d;
  d.translation_m = velocity_.head<3>() * dt_s;
  const bool gyro = params_.use_gyro && gyro_yaw_delta_rad && std::isfinite(*gyro_yaw_delta_rad);
  if (turned_by_gyro) *turned_by_gyro = gyro;
  if (gyro && params_.world_velocity) {  // into the last estimate's body frame
    const double c = std::cos(last_pose_.yaw_rad), s = std::sin(last_pose_.yaw_rad);
    const Eigen::Vector3d& w = world_velocity_;
    d.translation_m = Eigen::Vector3d(c * w.x() + s * w.y(), -s * w.x() + c * w.y(), w.z()) * dt_s;
  }
  d.yaw_rad = velocity_[3] * dt_s;
  const double growth = have_velocity_ ? 1.0 : 2.0;
  d.sigma_translation_m = sigma_translation_m + growth * params_.sigma_speed_m_s * dt_s;
  d.sigma_yaw_rad = sigma_yaw_rad + growth * params_.sigma_yaw_rate_rad_s * dt_s;
  if (gyro) {
    d.yaw_rad = *gyro_yaw_delta_rad;
    d.sigma_yaw_rad = sigma_yaw_rad + params_.gyro_sigma_yaw_rate_rad_s * dt_s;
  }
  return d;
}

void ConstantVelocityModel::observe(double stamp_s, const Particle& pose, double confidence) {
  const double dt = stamp_s - last_stamp_s_;
  const bool usable = have_pose_ && dt > 0.0 && dt <= params_.max_gap_s;
  const Particle prev = last_pose_;
  have_pose_ = true;
  last_pose_ = pose;
  last_stamp_s_ = stamp_s;
  if (!usable) {
    forgetVelocity();
    return;
  }
  // The displacement in the previous estimate's gravity-aligned body frame.
  const double c = std::cos(prev.yaw_rad), s = std::sin(prev.yaw_rad);
  const double dx = pose.x_m - prev.x_m, dy = pose.y_m - prev.y_m;
  Eigen::Vector4d sample(c * dx + s * dy, -s * dx + c * dy, pose.z_m - prev.z_m,
                         wrapAngle(pose.yaw_rad - prev.yaw_rad));
  sample /= dt;
  if (!sample.allFinite() || sample.head<3>().norm() > params_.max_speed_m_s) {
    forgetVelocity();
    return;
  }
  // From zero at the first sample: one noisy sample (the frame the filter converged) moves the
  // prediction only by the smoothing weight.
  const double trust = std::min(1.0, std::max(0.0, confidence));
  const double gain = params_.velocity_smoothing * trust;
  const double tau = params_.vertical_time_constant_s;
  const double gain_z = tau > 0.0 ? (1.0 - std::exp(-dt / tau)) * trust : gain;
  const Eigen::Vector4d gains(gain, gain, gain_z, gain);  // forward, left, up, yaw rate
  velocity_ += gains.cwiseProduct(sample - velocity_);
  world_velocity_ += gains.head<3>().cwiseProduct(
      Eigen::Vector3d(dx, dy, pose.z_m - prev.z_m) / dt - world_velocity_);
  have_velocity_ = true;
}

}  // namespace gmm_mcl
