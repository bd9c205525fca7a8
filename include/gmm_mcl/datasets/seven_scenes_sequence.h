// A 7-Scenes sequence folder (frame-NNNNNN.depth.png, frame-NNNNNN.pose.txt,
// camera-intrinsics.txt, optional gravity-direction.txt) as input for offline replay.
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/replay/sequence_base.h"

namespace gmm_mcl {

class SevenScenesSequence : public Sequence {
 public:
  // Reads the intrinsics, every pose and the gravity direction; throws std::runtime_error
  // naming the file and the fault. Depth images are read on demand (needs libpng).
  explicit SevenScenesSequence(const std::string& data_dir, int max_frames = -1,
                               const SequenceOptions& options = SequenceOptions());

  const char* format() const override { return "7scenes"; }
  const std::string& source() const override { return dir_; }
  int size() const override { return static_cast<int>(T_world_cam_.size()); }
  const Intrinsics& intrinsics() const override { return intrinsics_; }
  double frameRateHz() const { return frame_rate_hz_; }
  double stampS(int i) const override { return i / frame_rate_hz_; }
  const Eigen::Isometry3d& T_world_cam(int i) const override { return T_world_cam_[i]; }
  // Identity when the folder has no gravity-direction.txt (and no option names one).
  const Eigen::Matrix3d& R_aligned_world() const override { return R_aligned_world_; }
  std::string gravitySource() const override { return gravity_source_; }
  bool hasGravity() const { return gravity_source_ != "none"; }
  DepthImage loadDepth(int i) const override;
  std::string depthPath(int i) const override;

 private:
  std::string dir_;
  Intrinsics intrinsics_;
  double frame_rate_hz_ = 30.0;
  std::vector<Eigen::Isometry3d> T_world_cam_;
  Eigen::Matrix3d R_aligned_world_ = Eigen::Matrix3d::Identity();
  std::string gravity_source_ = "none";
};

}  // namespace gmm_mcl
