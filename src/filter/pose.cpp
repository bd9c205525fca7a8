#include "gmm_mcl/filter/pose.h"

#include <cmath>
#include <sstream>

namespace gmm_mcl {

double wrapAngle(double a_rad) {
  const double two_pi = 2.0 * M_PI;
  double a = std::fmod(a_rad + M_PI, two_pi);
  if (a < 0.0) a += two_pi;
  return a - M_PI;
}

Eigen::Matrix3d rotationFromRpy(double roll_rad, double pitch_rad, double yaw_rad) {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void rpyFromRotation(const Eigen::Matrix3d& R, double* roll_rad, double* pitch_rad,
                     double* yaw_rad) {
  *yaw_rad = std::atan2(R(1, 0), R(0, 0));
  *pitch_rad = std::atan2(-R(2, 0), std::hypot(R(2, 1), R(2, 2)));
  *roll_rad = std::atan2(R(2, 1), R(2, 2));
}

double yawFromRotation(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

bool nearestRotation(const Eigen::Matrix3d& M, Eigen::Matrix3d* R, std::string* why) {
  const double det = M.determinant();
  const double ortho = (M.transpose() * M - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!std::isfinite(det) || !std::isfinite(ortho) || std::abs(det - 1.0) > 1e-2 || ortho > 1e-2) {
    if (why) {
      std::ostringstream msg;
      msg << "not a rotation (det " << det << ", |R^T R - I| " << ortho << ")";
      *why = msg.str();
    }
    return false;
  }
  *R = Eigen::Quaterniond(M).normalized().toRotationMatrix();
  return true;
}

Eigen::Isometry3d particleToPose(const Particle& p, double roll_rad, double pitch_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(roll_rad, pitch_rad, p.yaw_rad);
  T.translation() = Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
  return T;
}

Particle poseToParticle(const Eigen::Isometry3d& T_map_base) {
  Particle p;
  p.x_m = T_map_base.translation().x();
  p.y_m = T_map_base.translation().y();
  p.z_m = T_map_base.translation().z();
  p.yaw_rad = yawFromRotation(T_map_base.linear());
  return p;
}

RigidTransformF toRigidF(const Eigen::Isometry3d& T) {
  RigidTransformF out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.R[r * 3 + c] = static_cast<float>(T.linear()(r, c));
    out.t[r] = static_cast<float>(T.translation()(r));
  }
  return out;
}

PlanarDelta odometryDelta(const Eigen::Isometry3d& T_odom_prev,
                          const Eigen::Isometry3d& T_odom_cur) {
  const double yaw_prev = yawFromRotation(T_odom_prev.linear());
  const double yaw_cur = yawFromRotation(T_odom_cur.linear());
  PlanarDelta d;
  d.translation_m = Eigen::AngleAxisd(-yaw_prev, Eigen::Vector3d::UnitZ()) *
                    (T_odom_cur.translation() - T_odom_prev.translation());
  d.yaw_rad = wrapAngle(yaw_cur - yaw_prev);
  return d;
}

void applyDelta(const PlanarDelta& delta, Particle* p) {
  const double c = std::cos(p->yaw_rad), s = std::sin(p->yaw_rad);
  p->x_m += c * delta.translation_m.x() - s * delta.translation_m.y();
  p->y_m += s * delta.translation_m.x() + c * delta.translation_m.y();
  p->z_m += delta.translation_m.z();
  p->yaw_rad = wrapAngle(p->yaw_rad + delta.yaw_rad);
}

}  // namespace gmm_mcl
