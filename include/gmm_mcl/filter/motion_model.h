// The motion model of a step without odometry (docs/no_odometry.md): a constant velocity
// (body-frame x, y, z speeds and a yaw rate) estimated from the filter's own converged estimates,
// extrapolated over the time since the last step, with process noise that grows with that time.
#pragma once

#include <Eigen/Core>
#include <string>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {

// How a step predicted (StepResult::motion).
enum class MotionSource {
  kOdometry,          // the odometry delta since the previous step
  kConstantVelocity,  // ConstantVelocityModel (no odometry, or its first message)
  kStatic,            // no motion, the per-update noise only (no odometry and the model off)
};
const char* motionSourceName(MotionSource source);

struct ConstantVelocityParams {
  // Steps without odometry predict with the model; false: no motion and the fixed per-update
  // noise (sigma_translation_m, sigma_yaw_rad).
  bool enabled = true;
  // Weight of the newest velocity sample in the exponential smoothing (1 = the last one alone).
  double velocity_smoothing = 0.5;
  // Process noise: sigma = sigma_translation_m + sigma_speed_m_s * dt (and sigma_yaw_rad +
  // sigma_yaw_rate_rad_s * dt), dt the time since the previous step; twice the growth while no
  // velocity is known (the first frames, after a reset).
  double sigma_speed_m_s = 0.1;
  double sigma_yaw_rate_rad_s = 0.1;
  // A gap between steps (or between two converged estimates) longer than this forgets the
  // velocity: the motion over it is unknown, the noise alone covers it.
  double max_gap_s = 0.5;
  // A velocity sample faster than this is a jump of the estimate (a recovery, a wrong mode left):
  // the velocity restarts from zero.
  double max_speed_m_s = 3.0;

  std::string validate() const;
};

// The velocity lives in the body frame of the last estimate (forward, left, up and the yaw
// rate), so that a turning vehicle's motion turns with it, as an odometry delta does.
class ConstantVelocityModel {
 public:
  explicit ConstantVelocityModel(const ConstantVelocityParams& params = ConstantVelocityParams())
      : params_(params) {}
  void setParams(const ConstantVelocityParams& params) { params_ = params; }

  // The motion over dt_s with its process noise (sigmas from the base per-update noise). A gap
  // longer than max_gap_s (or a negative or non-finite one) forgets the velocity first.
  PlanarDelta predict(double dt_s, double sigma_translation_m, double sigma_yaw_rad);
  // An estimate of the base at stamp_s: a velocity sample against the previous one, smoothed
  // with velocity_smoothing x confidence (in (0, 1]: how far the estimate can be trusted).
  void observe(double stamp_s, const Particle& pose, double confidence = 1.0);
  // Forget the velocity and the last estimate (a reset, a lost redraw, time going back, a
  // belief that is not converged).
  void reset();

  bool hasVelocity() const { return have_velocity_; }
  // Body-frame x, y, z speeds (m/s) and the yaw rate (rad/s); zero when unknown.
  const Eigen::Vector4d& velocity() const { return velocity_; }

 private:
  void forgetVelocity();

  ConstantVelocityParams params_;
  bool have_pose_ = false;
  double last_stamp_s_ = 0.0;
  Particle last_pose_;
  bool have_velocity_ = false;
  Eigen::Vector4d velocity_ = Eigen::Vector4d::Zero();
};

}  // namespace gmm_mcl
