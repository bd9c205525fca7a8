// The Stanford lounge/copyroom layout (Zhou and Koltun; paper D1): depth/NNNNNN.png in
// millimetres and a .log trajectory, per frame a line "id id frame_index" and a 4x4
// camera-to-world matrix (four lines). frame_index k is the depth image numbered k. No stamps:
// frames are 1 / frame_rate_hz apart (by frame index). Intrinsics 525/525/319.5/239.5.
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/datasets/sequence_base.h"

namespace gmm_mcl {

class StanfordSequence : public Sequence {
 public:
  // Trajectory: options.trajectory, else the folder's only *.log. Intrinsics: options, else
  // the folder's intrinsics.txt, else "kinect". Gravity: options, else gravity-direction.txt,
  // else the first camera's +y is down. Throws std::runtime_error naming file and fault.
  explicit StanfordSequence(const std::string& dir,
                            const SequenceOptions& options = SequenceOptions());

  const std::string& trajectoryPath() const { return log_path_; }

 private:
  std::string log_path_;
};

// One entry of a .log trajectory.
struct LogEntry {
  long frame_index = 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
};
// Reads a .log trajectory (blocks of 5 lines); throws naming the file, the line and the fault.
std::vector<LogEntry> readLogTrajectory(const std::string& path);

}  // namespace gmm_mcl
