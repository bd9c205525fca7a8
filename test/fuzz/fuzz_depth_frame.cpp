// libFuzzer target: depth input as the nodelet receives it, as bytes, then the core's frame
// preparation. Mode 0: a sensor_msgs/Image's fields (encoding 16UC1/mono16/32FC1/others, size,
// step, byte order, data) and a CameraInfo's K and size (zero, NaN, Inf, huge, tiny values from
// a table or raw bits); mode 1: an organized PointCloud2's layout and data. Frame parameters
// (stride, patch size, range window) come from the input too. Whatever is accepted must give a
// consistent frame: every sampled pixel counted once, points finite and inside the window,
// patches contiguous; whatever is rejected must say why.
#include <cmath>
#include <stdexcept>
#include <string>

#include "fuzz_input.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {
namespace {

// Ranges beyond this may overflow float in the back-projection for any intrinsics.
constexpr float kFiniteRangeLimitM = 1e20f;

std::string encodingFrom(fuzz::Reader* in) {
  return in->nameOrString({"16UC1", "mono16", "32FC1", "8UC1", "", "32FC1 "}, 32);
}

FrameParams frameParamsFrom(fuzz::Reader* in) {
  FrameParams p;
  p.pixel_stride = in->i32();
  p.patch_size_px = in->i32();
  p.min_range_m = static_cast<float>(in->number());
  p.max_range_m = static_cast<float>(in->number());
  return p;
}

int64_t ceilDiv(int64_t a, int64_t b) { return (a + b - 1) / b; }

// prepareFrame on an image and intrinsics that agree: throws only for bad parameters, and the
// frame it builds is consistent.
void checkFrame(const DepthImage& image, const Intrinsics& K, const FrameParams& params) {
  FUZZ_CHECK(image.checkLayout().empty());
  DepthFrame f;
  try {
    f = prepareFrame(image, K, params);
  } catch (const std::invalid_argument& e) {
    FUZZ_CHECK(!params.validate().empty());
    FUZZ_CHECK(std::string(e.what()).find("frame parameters") == 0);
    return;
  }
  FUZZ_CHECK(params.validate().empty());
  const int64_t stride = params.pixel_stride;
  FUZZ_CHECK(f.total_pixels_sampled ==
             ceilDiv(image.width_px, stride) * ceilDiv(image.height_px, stride));
  FUZZ_CHECK(static_cast<int64_t>(f.size()) + f.invalid_pixels + f.out_of_range_pixels ==
             f.total_pixels_sampled);
  FUZZ_CHECK(f.x_m.size() == f.y_m.size() && f.y_m.size() == f.z_m.size());
  FUZZ_CHECK(f.grid.cols == ceilDiv(image.width_px, params.patch_size_px));
  FUZZ_CHECK(f.grid.rows == ceilDiv(image.height_px, params.patch_size_px));
  FUZZ_CHECK(f.patch_begin.size() == static_cast<size_t>(f.grid.count()) + 1);
  FUZZ_CHECK(f.patch_begin.front() == 0);
  FUZZ_CHECK(f.patch_begin.back() == static_cast<int>(f.size()));
  for (size_t p = 0; p + 1 < f.patch_begin.size(); ++p) {
    FUZZ_CHECK(f.patch_begin[p] <= f.patch_begin[p + 1]);
  }
  for (size_t i = 0; i < f.size(); ++i) {
    FUZZ_CHECK(f.z_m[i] >= params.min_range_m && f.z_m[i] <= params.max_range_m);
    if (params.max_range_m <= kFiniteRangeLimitM) {
      FUZZ_CHECK(std::isfinite(f.x_m[i]) && std::isfinite(f.y_m[i]));
    }
  }
}

void checkIntrinsics(const Intrinsics& K, int width, int height) {
  FUZZ_CHECK(K.fx_px > 0.f && K.fy_px > 0.f);
  FUZZ_CHECK(std::isfinite(K.fx_px) && std::isfinite(K.fy_px));
  FUZZ_CHECK(std::isfinite(K.cx_px) && std::isfinite(K.cy_px));
  FUZZ_CHECK(K.width_px == width && K.height_px == height);
}

void fuzzImage(fuzz::Reader* in) {
  const std::string encoding = encodingFrom(in);
  const uint32_t width = in->u32(), height = in->u32(), step = in->u32();
  const bool big_endian = (in->u8() & 1) != 0;
  double K[9];
  for (double& k : K) k = in->number();
  const uint32_t info_width = in->u32(), info_height = in->u32();
  const FrameParams params = frameParamsFrom(in);
  DepthImage image;
  std::string error;
  if (!depthImageFromBuffer(encoding, width, height, step, big_endian, in->rest(), in->restSize(),
                            &image, &error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  FUZZ_CHECK(image.checkLayout().empty());
  FUZZ_CHECK(static_cast<uint32_t>(image.width_px) == width);
  FUZZ_CHECK(static_cast<uint32_t>(image.height_px) == height);
  // Every pixel reads as NaN or a positive finite depth.
  for (int v = 0; v < image.height_px; ++v) {
    for (int u = 0; u < image.width_px; ++u) {
      const float z = image.depthMetres(u, v);
      FUZZ_CHECK(std::isnan(z) || (std::isfinite(z) && z > 0.f));
    }
  }
  Intrinsics intrinsics;
  if (!intrinsicsFromCameraMatrix(K, info_width, info_height, image.width_px, image.height_px,
                                  &intrinsics, &error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  checkIntrinsics(intrinsics, image.width_px, image.height_px);
  checkFrame(image, intrinsics, params);
}

void fuzzCloud(fuzz::Reader* in) {
  CloudLayout layout;
  layout.width = in->u32();
  layout.height = in->u32();
  layout.point_step = in->u32();
  layout.row_step = in->u32();
  layout.big_endian = (in->u8() & 1) != 0;
  layout.x_offset = in->i32();
  layout.y_offset = in->i32();
  layout.z_offset = in->i32();
  const FrameParams params = frameParamsFrom(in);
  DepthImage image;
  Intrinsics K;
  std::string error;
  if (!depthImageFromCloudBuffer(layout, in->rest(), in->restSize(), &image, &K, &error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  FUZZ_CHECK(image.encoding == DepthEncoding::kFloat32Metres);
  FUZZ_CHECK(static_cast<uint32_t>(image.width_px) == layout.width);
  FUZZ_CHECK(static_cast<uint32_t>(image.height_px) == layout.height);
  checkIntrinsics(K, image.width_px, image.height_px);
  checkFrame(image, K, params);
}

}  // namespace
}  // namespace gmm_mcl

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace gmm_mcl;
  fuzz::Reader in(data, size);
  if ((in.u8() & 1) == 0) {
    fuzzImage(&in);
  } else {
    fuzzCloud(&in);
  }
  return 0;
}
