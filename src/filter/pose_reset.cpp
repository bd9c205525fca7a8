#include "gmm_mcl/filter/pose_reset.h"

#include <cmath>
#include <sstream>

namespace gmm_mcl {

bool isPlanarPose(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& cov) {
  const Eigen::Vector3d z_axis = T.linear().col(2);
  return T.translation().z() == 0.0 && cov(2, 2) == 0.0 &&
         (z_axis - Eigen::Vector3d::UnitZ()).norm() < 1e-9;
}

PoseReset resolvePoseReset(const PoseResetRequest& r, const PoseEstimate* current,
                           double fallback_z_m, const Eigen::Vector4d& default_sigma) {
  PoseReset out;
  if (!r.T_map_base.matrix().allFinite() || !r.covariance.diagonal().allFinite()) {
    out.message = "pose not finite: ignored";
    return out;
  }
  std::ostringstream m;
  Eigen::Isometry3d T = r.T_map_base;
  if (r.carry_forward) {
    T = T * r.T_odom_base_then.inverse() * r.T_odom_base_now;
    m << "carried forward " << r.age_s << " s by odometry; ";
  }
  out.pose = poseToParticle(T);
  const int idx[4] = {0, 1, 2, 5};
  for (int k = 0; k < 4; ++k) {
    const double var = r.covariance(idx[k], idx[k]);
    out.sigma[k] = std::isfinite(var) && var > 0.0 ? std::sqrt(var) : default_sigma[k];
  }
  if (r.planar) {
    out.pose.z_m = current ? current->mean.z_m : fallback_z_m;
    if (current) out.sigma[2] = std::sqrt(current->covariance(2, 2));
    m << "planar pose: height " << out.pose.z_m << " m kept from the "
      << (current ? "current estimate" : "initial region") << "; ";
  }
  out.ok = true;
  m << "reset to (" << out.pose.x_m << ", " << out.pose.y_m << ", " << out.pose.z_m << ", yaw "
    << out.pose.yaw_rad << ") sigma (" << out.sigma.transpose() << ")";
  out.message = m.str();
  return out;
}

bool MotionGate::shouldUpdate(bool has_odometry, const Eigen::Isometry3d& T) const {
  if (!has_odometry || !have_last_ || (min_d_m_ <= 0.0 && min_a_rad_ <= 0.0)) return true;
  const Eigen::Isometry3d d = last_.inverse() * T;
  const double yaw = std::abs(std::atan2(d.linear()(1, 0), d.linear()(0, 0)));
  return d.translation().norm() > min_d_m_ || yaw > min_a_rad_;
}

void MotionGate::updated(bool has_odometry, const Eigen::Isometry3d& T) {
  have_last_ = has_odometry;
  last_ = T;
}

}  // namespace gmm_mcl
