// A TUM RGB-D folder (also ICL-NUIM in TUM format, and gmm_mcl_render's output): depth.txt
// ("timestamp path" lines, '#' comments), depth PNGs (5000 units per metre), groundtruth.txt
// ("timestamp tx ty tz qx qy qz qw", camera-to-world of the optical frame). Each depth frame is
// paired with the ground-truth pose nearest in time, within a tolerance; depth frames without
// one are skipped and counted. See https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/datasets/sequence_base.h"

namespace gmm_mcl {

class TumSequence : public Sequence {
 public:
  // Intrinsics: options.intrinsics, else the folder's intrinsics.txt, else fr1/fr2/fr3 from a
  // "freiburgN" folder name; otherwise an error. Gravity: options.gravity, else the folder's
  // gravity-direction.txt, else z up (the motion-capture world). Throws std::runtime_error.
  explicit TumSequence(const std::string& dir, const SequenceOptions& options = SequenceOptions());

  // Depth frames listed in depth.txt but dropped for want of a ground-truth pose in tolerance.
  int unassociatedFrames() const { return unassociated_; }
  // Where the intrinsics came from.
  const std::string& intrinsicsSource() const { return intrinsics_source_; }

 private:
  std::string intrinsics_source_;
  int unassociated_ = 0;
};

// A TUM trajectory file: one pose per line "t tx ty tz qx qy qz qw" ('#' comments); throws
// naming the file, the line and the fault (field count, non-finite, zero quaternion, stamps
// not increasing).
struct StampedPose {
  double stamp_s = 0.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
};
std::vector<StampedPose> readTumTrajectory(const std::string& path);
// Index of the pose nearest to t (poses sorted by stamp), -1 when none is within tolerance_s.
int nearestPose(const std::vector<StampedPose>& poses, double t_s, double tolerance_s);

}  // namespace gmm_mcl
