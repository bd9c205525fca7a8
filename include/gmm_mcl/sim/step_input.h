// The localizer's input for one frame of a simulated run: odometry, the IMU's roll and pitch and
// a depth image.
#pragma once

#include <Eigen/Geometry>

#include "gmm_mcl/filter/localizer.h"

namespace gmm_mcl {
namespace sim {

// `depth` must outlive the returned input (it keeps a pointer).
inline StepInput frameInput(double stamp_s, const Eigen::Isometry3d& T_odom_base, double roll_rad,
                            double pitch_rad, const DepthImage& depth, const Intrinsics& K) {
  StepInput in;
  in.stamp_s = stamp_s;
  in.has_odometry = true;
  in.T_odom_base = T_odom_base;
  in.has_attitude = true;
  in.roll_rad = roll_rad;
  in.pitch_rad = pitch_rad;
  in.depth = &depth;
  in.intrinsics = K;
  return in;
}

}  // namespace sim
}  // namespace gmm_mcl
