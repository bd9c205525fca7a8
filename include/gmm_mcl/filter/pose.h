// 4-DoF particle state (x, y, z, yaw of the base in the map) and rotation helpers.
// Roll and pitch come from the attitude input and are shared by all particles (DESIGN.md).
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

struct Particle {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double yaw_rad = 0.0;
};

// Wraps an angle into [-pi, pi).
double wrapAngle(double a_rad);
// R = Rz(yaw) * Ry(pitch) * Rx(roll) (REP-103 fixed-axis roll, pitch, yaw).
Eigen::Matrix3d rotationFromRpy(double roll_rad, double pitch_rad, double yaw_rad);
// Inverse of rotationFromRpy (pitch in [-pi/2, pi/2]).
void rpyFromRotation(const Eigen::Matrix3d& R, double* roll_rad, double* pitch_rad,
                     double* yaw_rad);
double yawFromRotation(const Eigen::Matrix3d& R);

// The rotation nearest to a matrix read from text (poses carry rounding): false, with *why,
// when it is far from a rotation (|det - 1| or |M^T M - I| over 1e-2, or not finite). Every
// reader of text poses (data sets, the map builder) goes through it, so they agree.
bool nearestRotation(const Eigen::Matrix3d& M, Eigen::Matrix3d* R, std::string* why);

// Full 6-DoF base pose of a particle with the shared roll and pitch.
Eigen::Isometry3d particleToPose(const Particle& p, double roll_rad, double pitch_rad);
Particle poseToParticle(const Eigen::Isometry3d& T_map_base);

RigidTransformF toRigidF(const Eigen::Isometry3d& T);

// Motion between two odometry poses expressed in the gravity-aligned frame of the first
// (rotated by its yaw only), so that it applies to a particle regardless of roll and pitch.
struct PlanarDelta {
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  double yaw_rad = 0.0;
  // The process noise of this step; negative: the filter's sigma_translation_m / sigma_yaw_rad.
  double sigma_translation_m = -1.0;
  double sigma_yaw_rad = -1.0;
};
PlanarDelta odometryDelta(const Eigen::Isometry3d& T_odom_prev,
                          const Eigen::Isometry3d& T_odom_cur);
// Moves a pose by a delta without noise (the delta's translation turned by the pose's yaw).
void applyDelta(const PlanarDelta& delta, Particle* p);

}  // namespace gmm_mcl
