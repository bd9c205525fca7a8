// The 7-Scenes map cloud (DESIGN.md "Accuracy protocol"): depth frames back-projected with their
// ground-truth camera-to-world poses, stitched and voxel-downsampled.
#pragma once

#include <string>

#include "gmm_mcl/fit/point_cloud.h"

namespace gmm_mcl {

struct SevenScenesCloudParams {
  int first_frame = 0;
  int last_frame = 990;  // inclusive
  int frame_step = 10;
  float min_depth_m = 0.1f;  // keep depth in (min_depth_m, max_depth_m]
  float max_depth_m = 4.0f;
  float voxel_m = 0.02f;  // voxel centroids; must be > 0
  int pixel_stride = 1;   // every pixel by default

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

struct SevenScenesCloudStats {
  int frames = 0;
  size_t points_back_projected = 0;
  size_t voxels = 0;
};

// Reads <data_dir>/camera-intrinsics.txt, frame-NNNNNN.depth.png (uint16 millimetres; 0 and
// 65535 = no measurement) and frame-NNNNNN.pose.txt (4x4 camera-to-world, metres). Throws
// FitError naming the file and the fault; needs libpng (GMM_MCL_HAVE_PNG).
PointCloud buildSevenScenesCloud(const std::string& data_dir, const SevenScenesCloudParams& params,
                                 SevenScenesCloudStats* stats = nullptr);

}  // namespace gmm_mcl
