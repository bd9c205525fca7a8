// Camera trajectories and cameras of mesh data sets (Replica / NICE-SLAM layout).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {
namespace sim {

// One camera-to-world pose per line: a row-major 4x4 matrix (16 numbers; Replica's traj.txt).
// Rotations within 1e-3 of orthonormal are re-orthonormalised. Throws std::runtime_error naming
// the file, the line and the fault (field count, non-finite, last row not 0 0 0 1, not a
// rotation, no poses).
std::vector<Eigen::Isometry3d> readMatrixTrajectory(const std::string& path);

// Replica's cam_params.json: {"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}} (scale =
// depth PNG units per metre). Throws std::runtime_error naming the file and the missing or
// bad key.
void readReplicaCamera(const std::string& path, Intrinsics* K, double* depth_units_per_m);

// Writes a TUM trajectory: '#' lines (the comment's lines, then the field names), then
// "t tx ty tz qx qy qz qw" per pose (stamps 6 decimals, the rest 9), which readTumTrajectory and
// gmm_mcl_render --trajectory read back. Throws std::runtime_error naming the file when it
// cannot be written, or when the counts differ.
void writeTumTrajectory(const std::string& path, const std::vector<double>& stamps_s,
                        const std::vector<Eigen::Isometry3d>& T_world_frame,
                        const std::string& comment = "");

}  // namespace sim
}  // namespace gmm_mcl
