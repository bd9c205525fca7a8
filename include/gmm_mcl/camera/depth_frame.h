// Frame preparation: the used pixels of a depth image, back-projected into the camera optical
// frame and grouped by image patch, the layout every backend consumes.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

struct FrameParams {
  int pixel_stride = 4;      // use every stride-th pixel along u and v
  int patch_size_px = 32;    // square patches for component membership
  float min_range_m = 0.1f;  // valid depth window [min_range_m, max_range_m]
  float max_range_m = 4.0f;

  // Empty when valid, otherwise a description of every fault found.
  std::string validate() const;
};

// Regular patch grid over the image.
struct PatchGrid {
  int patch_size_px = 32;
  int cols = 0;
  int rows = 0;
  int count() const { return cols * rows; }
  // Centre of patch (col, row) in pixel coordinates (pixel centres at integers).
  float centreU(int col) const { return col * patch_size_px + 0.5f * (patch_size_px - 1); }
  float centreV(int row) const { return row * patch_size_px + 0.5f * (patch_size_px - 1); }
  static PatchGrid forImage(int width_px, int height_px, int patch_size_px);
};

// Back-projected points of one frame, structure of arrays, grouped by patch:
// the points of patch p are indices [patch_begin[p], patch_begin[p + 1]).
struct DepthFrame {
  Intrinsics intrinsics;
  PatchGrid grid;
  std::vector<float> x_m, y_m, z_m;  // camera optical frame
  std::vector<int> patch_begin;      // size grid.count() + 1
  int total_pixels_sampled = 0;      // pixels on the stride grid
  int invalid_pixels = 0;            // of those: no measurement (0, NaN, Inf, 65535)
  int out_of_range_pixels = 0;       // of those: valid but outside the range window
  // The far end of the range window it was prepared with (m): no used pixel is deeper, so the
  // view cull drops what lies beyond it (infinite for a frame built by hand: no such cull).
  float max_range_m = std::numeric_limits<float>::infinity();

  size_t size() const { return x_m.size(); }
  bool empty() const { return x_m.empty(); }
};

// Back-projects pixel (u, v) at depth z: x = (u - cx) z / fx, y = (v - cy) z / fy.
GMM_MCL_HD void backProject(const Intrinsics& K, float u, float v, float z_m, float p[3]) {
  p[0] = (u - K.cx_px) * z_m / K.fx_px;
  p[1] = (v - K.cy_px) * z_m / K.fy_px;
  p[2] = z_m;
}

// Builds the frame. Throws std::invalid_argument when the image and intrinsics disagree in size
// or the image layout is inconsistent; invalid pixels are counted, never an error.
DepthFrame prepareFrame(const DepthImage& image, const Intrinsics& intrinsics,
                        const FrameParams& params);

}  // namespace gmm_mcl
