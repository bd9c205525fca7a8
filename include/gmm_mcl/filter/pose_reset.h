// What a requested pose (an initial pose topic, rviz's 2D Pose Estimate, a reset service, a
// stored pose at start-up) resets the filter to: a Gaussian around a particle. The policy lives
// here, not in the ROS layer: sigmas from the covariance (at least a minimum each), a stale
// stamp carried forward by odometry, and a planar tool's pose keeping the current height.
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "gmm_mcl/filter/particle_filter.h"

namespace gmm_mcl {

struct PoseResetRequest {
  Eigen::Isometry3d T_map_base = Eigen::Isometry3d::Identity();  // already in the map frame
  // ROS order (x, y, z, roll, pitch, yaw); the diagonal gives the sigmas.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // From a planar tool (rviz's 2D Pose Estimate sends z = 0): its z means nothing, the height
  // is kept from the current estimate. See isPlanarPose().
  bool planar = false;
  // Odometry at the request's stamp and at the last update: a stamp older than the last update
  // is carried forward by the motion between the two.
  bool carry_forward = false;
  Eigen::Isometry3d T_odom_base_then = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_odom_base_now = Eigen::Isometry3d::Identity();
  double age_s = 0.0;  // last update's stamp - the request's (for the message)
};

struct PoseReset {
  bool ok = false;
  Particle pose;
  Eigen::Vector4d sigma = Eigen::Vector4d::Zero();  // x, y, z, yaw
  std::string message;                              // what was done, or why not
};

// A pose with z = 0, a pure yaw rotation and no z variance: what planar tools send.
bool isPlanarPose(const Eigen::Isometry3d& T_map_base,
                  const Eigen::Matrix<double, 6, 6>& covariance);

// The reset for a request. `current`: the filter's estimate (nullptr before the first update:
// a planar pose then takes fallback_z_m, e.g. the initial region's centre, and its z spread from
// default_sigma). default_sigma (x, y, z, yaw) stands in where the covariance gives no spread
// (zero, negative or not finite). Not ok when the pose is not finite.
PoseReset resolvePoseReset(const PoseResetRequest& request, const PoseEstimate* current,
                           double fallback_z_m, const Eigen::Vector4d& default_sigma);

// Measurement updates only after the robot has moved (amcl's update_min_d / update_min_a):
// while hovering, frames are not used and the estimate follows odometry. Thresholds of 0
// update on every frame.
class MotionGate {
 public:
  MotionGate(double min_translation_m = 0.0, double min_yaw_rad = 0.0)
      : min_d_m_(min_translation_m), min_a_rad_(min_yaw_rad) {}
  void setThresholds(double min_translation_m, double min_yaw_rad) {
    min_d_m_ = min_translation_m;
    min_a_rad_ = min_yaw_rad;
  }
  // True for the first frame, after force(), without odometry, with both thresholds 0, or once
  // the odometry moved farther (3-D) or turned more (yaw) than a threshold since the last update
  // (as amcl: a threshold of 0 lets any motion of its kind through).
  bool shouldUpdate(bool has_odometry, const Eigen::Isometry3d& T_odom_base) const;
  // A frame updated the filter with this odometry.
  void updated(bool has_odometry, const Eigen::Isometry3d& T_odom_base);
  // The next frame updates (a reset, a time jump, another map).
  void force() { have_last_ = false; }

 private:
  double min_d_m_, min_a_rad_;
  bool have_last_ = false;
  Eigen::Isometry3d last_ = Eigen::Isometry3d::Identity();
};

}  // namespace gmm_mcl
