// A 7-Scenes sequence folder (frame-NNNNNN.depth.png, frame-NNNNNN.pose.txt,
// camera-intrinsics.txt, optional gravity-direction.txt) as input for offline replay.
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/datasets/sequence_base.h"

namespace gmm_mcl {

class SevenScenesSequence : public Sequence {
 public:
  // Reads the intrinsics, every pose and the gravity direction; throws std::runtime_error
  // naming the file and the fault. Depth images are read on demand (needs libpng).
  explicit SevenScenesSequence(const std::string& data_dir, int max_frames = -1,
                               const SequenceOptions& options = SequenceOptions());

  double frameRateHz() const { return frame_rate_hz_; }
  // False when the folder has no gravity-direction.txt (and no option names one): then
  // R_aligned_world() is the identity.
  bool hasGravity() const { return gravity_source_ != "none"; }

 private:
  double frame_rate_hz_ = 30.0;
};

}  // namespace gmm_mcl
