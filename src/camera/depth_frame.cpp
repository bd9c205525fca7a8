#include "gmm_mcl/camera/depth_frame.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>

namespace gmm_mcl {

std::string FrameParams::validate() const {
  std::ostringstream err;
  if (pixel_stride < 1) err << "pixel_stride must be >= 1 (got " << pixel_stride << "); ";
  if (patch_size_px < 1) err << "patch_size_px must be >= 1 (got " << patch_size_px << "); ";
  if (!(min_range_m > 0.f) || !std::isfinite(min_range_m)) {
    err << "min_range_m must be a positive number (got " << min_range_m << "); ";
  }
  if (!(max_range_m > min_range_m) || !std::isfinite(max_range_m)) {
    err << "max_range_m must be finite and greater than min_range_m (got " << max_range_m << "); ";
  }
  return err.str();
}

PatchGrid PatchGrid::forImage(int width_px, int height_px, int patch_size_px) {
  PatchGrid g;
  g.patch_size_px = patch_size_px;
  // 64-bit: width + patch_size - 1 overflows int for patch sizes near INT_MAX.
  g.cols = static_cast<int>((int64_t{width_px} + patch_size_px - 1) / patch_size_px);
  g.rows = static_cast<int>((int64_t{height_px} + patch_size_px - 1) / patch_size_px);
  return g;
}

DepthFrame prepareFrame(const DepthImage& image, const Intrinsics& intrinsics,
                        const FrameParams& params) {
  const std::string param_err = params.validate();
  if (!param_err.empty()) throw std::invalid_argument("frame parameters: " + param_err);
  const std::string layout_err = image.checkLayout();
  if (!layout_err.empty()) throw std::invalid_argument("depth image: " + layout_err);
  if (image.width_px != intrinsics.width_px || image.height_px != intrinsics.height_px) {
    std::ostringstream msg;
    msg << "depth image is " << image.width_px << "x" << image.height_px
        << " but the camera info says " << intrinsics.width_px << "x" << intrinsics.height_px;
    throw std::invalid_argument(msg.str());
  }
  DepthFrame f;
  f.intrinsics = intrinsics;
  f.max_range_m = params.max_range_m;
  f.grid = PatchGrid::forImage(image.width_px, image.height_px, params.patch_size_px);
  f.patch_begin.assign(f.grid.count() + 1, 0);
  // Pixel bounds in 64 bits: patch sizes and strides up to INT_MAX are valid parameters, and
  // (pr + 1) * ps or pc * ps + stride - 1 would overflow int.
  const int64_t ps = params.patch_size_px;
  const int64_t stride = params.pixel_stride;
  // Patch by patch so that each patch's points are contiguous.
  for (int pr = 0; pr < f.grid.rows; ++pr) {
    for (int pc = 0; pc < f.grid.cols; ++pc) {
      const int p = pr * f.grid.cols + pc;
      f.patch_begin[p] = static_cast<int>(f.x_m.size());
      // Stride grid anchored at the image origin, independent of the patch size.
      const int64_t v0 = ((pr * ps + stride - 1) / stride) * stride;
      const int64_t u0 = ((pc * ps + stride - 1) / stride) * stride;
      const int64_t v_end = std::min<int64_t>(image.height_px, (pr + 1) * ps);
      const int64_t u_end = std::min<int64_t>(image.width_px, (pc + 1) * ps);
      for (int64_t v = v0; v < v_end; v += stride) {
        for (int64_t u = u0; u < u_end; u += stride) {
          ++f.total_pixels_sampled;
          const float z = image.depthMetres(static_cast<int>(u), static_cast<int>(v));
          if (!std::isfinite(z)) {
            ++f.invalid_pixels;
            continue;
          }
          if (z < params.min_range_m || z > params.max_range_m) {
            ++f.out_of_range_pixels;
            continue;
          }
          float pt[3];
          backProject(intrinsics, static_cast<float>(u), static_cast<float>(v), z, pt);
          f.x_m.push_back(pt[0]);
          f.y_m.push_back(pt[1]);
          f.z_m.push_back(pt[2]);
        }
      }
    }
  }
  f.patch_begin[f.grid.count()] = static_cast<int>(f.x_m.size());
  return f;
}

}  // namespace gmm_mcl
