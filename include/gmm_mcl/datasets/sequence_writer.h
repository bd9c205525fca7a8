// Writes any Sequence as a TUM RGB-D folder or a Stanford-layout folder: test fixtures from
// the synthetic scene, and format conversion. Each folder also gets intrinsics.txt
// ("fx fy cx cy width height") and gravity-direction.txt (down, world coordinates), which the
// readers pick up. Throws std::runtime_error naming the file that could not be written.
#pragma once

#include <string>

#include "gmm_mcl/datasets/sequence_base.h"

namespace gmm_mcl {

struct TumWriteOptions {
  // Ground truth is written at the depth stamps plus this offset (s): a real recording's
  // motion capture is not synchronised with the camera; association must bridge it.
  double truth_offset_s = 0.004;
  // Extra ground-truth poses between frames (motion capture runs faster than the camera);
  // interpolated linearly (position) and by slerp (rotation).
  int truth_per_frame = 3;
  int max_frames = -1;
  // Keep only the pixels on this stride's grid (u and v multiples of it; the others become "no
  // measurement"): the same input as the full frames for a filter of that stride (or a multiple
  // of it), in a fraction of the bytes, for carrying a data set to another machine. 1: all.
  int keep_stride_px = 1;
};

// dir/depth.txt, dir/depth/<stamp>.png (5000 units per metre), dir/groundtruth.txt.
void writeTumFolder(const Sequence& seq, const std::string& dir,
                    const TumWriteOptions& options = TumWriteOptions());

// dir/depth/NNNNNN.png (millimetres, numbered from 1) and dir/trajectory.log.
void writeStanfordFolder(const Sequence& seq, const std::string& dir, int max_frames = -1);

// Creates a folder and its parents (mkdir -p); throws naming it on failure.
void makeDirectories(const std::string& dir);

}  // namespace gmm_mcl
