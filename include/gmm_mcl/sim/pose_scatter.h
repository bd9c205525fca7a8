// Pose hypotheses scattered about a true pose, as a filter's particles spread before it has
// converged (the benchmark's workloads, the backend parity tests).
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {
namespace sim {

// n poses: T_true first, then poses uniform within +-spread_m per axis and +-spread_rad of yaw
// (about the map's z axis, through the camera centre) around it. Deterministic for a seed
// (std::mt19937_64; per pose the yaw, then x, y, z).
std::vector<RigidTransformF> scatterPoses(const Eigen::Isometry3d& T_true, int n, double spread_m,
                                          double spread_rad, unsigned seed);

}  // namespace sim
}  // namespace gmm_mcl
