// A 7-Scenes sequence folder (frame-NNNNNN.depth.png, frame-NNNNNN.pose.txt,
// camera-intrinsics.txt, optional gravity-direction.txt) as input for offline replay.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

class SevenScenesSequence {
 public:
  // Reads the intrinsics, every pose and the gravity direction; throws std::runtime_error
  // naming the file and the fault. Depth images are read on demand (needs libpng).
  explicit SevenScenesSequence(const std::string& data_dir, int max_frames = -1);

  int size() const { return static_cast<int>(T_world_cam_.size()); }
  const Intrinsics& intrinsics() const { return intrinsics_; }
  double frameRateHz() const { return 30.0; }
  // Camera-to-world pose of frame i (optical frame).
  const Eigen::Isometry3d& T_world_cam(int i) const { return T_world_cam_[i]; }
  // Rotation taking world coordinates into a gravity-aligned frame (z up); identity when the
  // folder has no gravity-direction.txt.
  const Eigen::Matrix3d& R_aligned_world() const { return R_aligned_world_; }
  bool hasGravity() const { return has_gravity_; }
  DepthImage loadDepth(int i) const;
  std::string depthPath(int i) const;

 private:
  std::string dir_;
  Intrinsics intrinsics_;
  std::vector<Eigen::Isometry3d> T_world_cam_;
  Eigen::Matrix3d R_aligned_world_ = Eigen::Matrix3d::Identity();
  bool has_gravity_ = false;
};

// Rotation R with R * down = (0, 0, -1), keeping the x axis as close to world x as possible.
Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& down_world);

}  // namespace gmm_mcl
