// The motion model of a step without odometry (docs/no_odometry.md): a constant velocity (x, y,
// z speeds in the map or the body frame and a yaw rate, or the gyro's turn) estimated from the
// filter's own converged estimates, extrapolated over the time since the last step, with process
// noise that grows with that time.
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
  // The vertical speed learns over this time instead: each sample moves it by
  // 1 - exp(-dt / vertical_time_constant_s) (x the sample's confidence), dt the time since the
  // previous estimate; 0: velocity_smoothing as the other axes. A forward-looking camera pins its
  // height least (walls are vertical), and a climb read from the set's own slide, learned with a
  // per-frame weight, moves the set further: at 30 Hz it swung 1.1-1.3 m up and down on Replica
  // (docs/no_odometry.md). A time constant damps that loop at every frame rate.
  double vertical_time_constant_s = 0.5;
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
  // A step that carries the IMU gyro's heading (StepInput::has_gyro_yaw) takes its yaw change
  // from it instead of the yaw rate above: the rate of a fast turn itself, which a constant
  // velocity lags. Its noise: sigma_yaw_rad + gyro_sigma_yaw_rate_rad_s x the time since the
  // last step (a gyro's bias after calibration and its white noise, with margin).
  bool use_gyro = true;
  double gyro_sigma_yaw_rate_rad_s = 0.02;
  // On a step that turns by the gyro's heading, the translation velocity held in the
  // gravity-aligned map frame instead of the body frame: a drone or a hand-held camera moves the
  // same way whichever way it faces, where a body-frame velocity swings with every turn of the
  // head (a car's turns with its heading). Without the gyro the body frame, whose turn is the
  // learned yaw rate's (docs/no_odometry.md: the map frame there tracked a synthetic loop worse
  // and, with few particles, ran away).
  bool world_velocity = true;

  std::string validate() const;
};

// The velocity is kept both in the body frame of the last estimate (forward, left, up and the
// yaw rate: a turning vehicle's motion turns with it, as an odometry delta does) and in the map
// frame (x, y, z); world_velocity says which predicts the translation of a gyro-turned step.
class ConstantVelocityModel {
 public:
  explicit ConstantVelocityModel(const ConstantVelocityParams& params = ConstantVelocityParams())
      : params_(params) {}
  void setParams(const ConstantVelocityParams& params) { params_ = params; }

  // The motion over dt_s with its process noise (sigmas from the base per-update noise). A gap
  // longer than max_gap_s (or a negative or non-finite one) forgets the velocity first. With
  // gyro_yaw_delta_rad (the heading the IMU's gyro turned over dt_s; null: none) and use_gyro,
  // the yaw change is that, with the gyro's noise, and the translation the map-frame velocity's
  // (world_velocity). *turned_by_gyro (when given): whether the gyro's turn was used.
  PlanarDelta predict(double dt_s, double sigma_translation_m, double sigma_yaw_rad,
                      const double* gyro_yaw_delta_rad = nullptr, bool* turned_by_gyro = nullptr);
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
  Eigen::Vector3d world_velocity_ = Eigen::Vector3d::Zero();  // map frame (world_velocity)
};

}  // namespace gmm_mcl
