// The Stanford lounge/copyroom layout (Zhou and Koltun; paper D1): depth/NNNNNN.png in
// millimetres and a .log trajectory, per frame a line "id id frame_index" and a 4x4
// camera-to-world matrix (four lines). frame_index k is the depth image numbered k. No stamps:
// frames are 1 / frame_rate_hz apart (by frame index). Intrinsics 525/525/319.5/239.5.
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/replay/sequence_base.h"

namespace gmm_mcl {

class StanfordSequence : public Sequence {
 public:
  // Trajectory: options.trajectory, else the folder's only *.log. Intrinsics: options, else
  // the folder's intrinsics.txt, else "kinect". Gravity: options, else gravity-direction.txt,
  // else the first camera's +y is down. Throws std::runtime_error naming file and fault.
  explicit StanfordSequence(const std::string& dir,
                            const SequenceOptions& options = SequenceOptions());

  const char* format() const override { return "stanford"; }
  const std::string& source() const override { return dir_; }
  int size() const override { return static_cast<int>(T_world_cam_.size()); }
  const Intrinsics& intrinsics() const override { return intrinsics_; }
  double stampS(int i) const override { return stamps_s_[i]; }
  const Eigen::Isometry3d& T_world_cam(int i) const override { return T_world_cam_[i]; }
  const Eigen::Matrix3d& R_aligned_world() const override { return R_aligned_world_; }
  std::string gravitySource() const override { return gravity_source_; }
  DepthImage loadDepth(int i) const override;
  std::string depthPath(int i) const override { return depth_paths_[i]; }
  const std::string& trajectoryPath() const { return log_path_; }

 private:
  std::string dir_;
  std::string log_path_;
  Intrinsics intrinsics_;
  double units_per_m_ = 1000.0;
  std::vector<double> stamps_s_;
  std::vector<std::string> depth_paths_;
  std::vector<Eigen::Isometry3d> T_world_cam_;
  Eigen::Matrix3d R_aligned_world_ = Eigen::Matrix3d::Identity();
  std::string gravity_source_;
};

// One entry of a .log trajectory.
struct LogEntry {
  long frame_index = 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
};
// Reads a .log trajectory (blocks of 5 lines); throws naming the file, the line and the fault.
std::vector<LogEntry> readLogTrajectory(const std::string& path);

}  // namespace gmm_mcl
