// The faults the fuzzing found in the camera input paths (intrinsics, clouds, image buffers, PNG,
// compressedDepth), each as a named case with its message (the fuzz_replay_* tests replay the
// raw reproducers; these say what each fix promises).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/map/gmm_map_io.h"  // crc32 (the PNG case repairs a chunk CRC)
#if defined(GMM_MCL_HAVE_PNG)
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace {

std::string intrinsicsError(const double K[9]) {
  try {
    makeIntrinsics(K, 64, 48);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(CameraInputValidationTest, CameraMatrixOutsideFloatRangeIsRejected) {
  const double good[9] = {525.0, 0.0, 31.5, 0.0, 525.0, 23.5, 0.0, 0.0, 1.0};
  EXPECT_EQ(intrinsicsError(good), "");
  double K[9];
  // fx = 1e300 would be an infinite float focal length; fy = 1e-300 passes "> 0" in double and
  // becomes 0 in float; cx = 3e38 fits a float but its back-projected points do not.
  for (const auto& c : {std::make_pair(0, 1e300), std::make_pair(4, 1e-300),
                        std::make_pair(2, 3e38), std::make_pair(5, -1e10)}) {
    std::memcpy(K, good, sizeof(K));
    K[c.first] = c.second;
    const std::string why = intrinsicsError(K);
    EXPECT_NE(why.find("out of range"), std::string::npos) << c.first << ": " << why;
  }
  // The existing faults keep their messages.
  std::memcpy(K, good, sizeof(K));
  K[0] = 0.0;
  EXPECT_NE(intrinsicsError(K).find("non-positive focal length"), std::string::npos);
  K[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(intrinsicsError(K).find("NaN or Inf"), std::string::npos);
}

TEST(CameraInputValidationTest, CameraInfoSizeBeyondIntIsAnError) {
  const double K[9] = {525.0, 0.0, 31.5, 0.0, 525.0, 23.5, 0.0, 0.0, 1.0};
  Intrinsics out;
  std::string why;
  EXPECT_TRUE(intrinsicsFromCameraMatrix(K, 64, 48, 64, 48, &out, &why)) << why;
  EXPECT_FALSE(intrinsicsFromCameraMatrix(K, 3000000000u, 48, 0, 0, &out, &why));
  EXPECT_NE(why.find("is empty"), std::string::npos) << why;
  const double zero[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  EXPECT_FALSE(intrinsicsFromCameraMatrix(zero, 64, 48, 64, 48, &out, &why));
  EXPECT_NE(why.find("uncalibrated"), std::string::npos) << why;
}

TEST(CameraInputValidationTest, HugePatchSizeAndStrideSampleTheImageOnce) {
  // Valid parameters near INT_MAX overflowed int in the patch grid and the stride grid.
  const double Kd[9] = {50.0, 0.0, 7.5, 0.0, 50.0, 5.5, 0.0, 0.0, 1.0};
  const Intrinsics K = makeIntrinsics(Kd, 16, 12);
  const DepthImage img = DepthImage::fromMetres(16, 12, std::vector<float>(16 * 12, 1.f));
  FrameParams p;
  p.patch_size_px = std::numeric_limits<int>::max();
  p.pixel_stride = 1;
  DepthFrame f = prepareFrame(img, K, p);
  EXPECT_EQ(f.grid.count(), 1);
  EXPECT_EQ(f.size(), 16u * 12u);
  p.patch_size_px = 5;
  p.pixel_stride = std::numeric_limits<int>::max();
  f = prepareFrame(img, K, p);
  EXPECT_EQ(f.total_pixels_sampled, 1);  // pixel (0, 0) only
  EXPECT_EQ(f.size(), 1u);
}

// An organized 4x4 cloud of a pinhole camera (f = 4, c = (1.5, 1.5)) at z = 1 + 0.1 u, x, y, z
// at bytes 0, 4, 8 of each point, and its layout.
std::vector<uint8_t> cloudData(uint32_t point_step, CloudLayout* layout) {
  layout->width = 4;
  layout->height = 4;
  layout->point_step = point_step;
  layout->row_step = 4 * point_step;
  layout->x_offset = 0;
  layout->y_offset = 4;
  layout->z_offset = 8;
  std::vector<uint8_t> d(point_step * 16, 0);
  for (int v = 0; v < 4; ++v) {
    for (int u = 0; u < 4; ++u) {
      const float z = 1.f + 0.1f * u;
      const float p[3] = {(u - 1.5f) * z / 4.f, (v - 1.5f) * z / 4.f, z};
      std::memcpy(&d[(v * 4 + u) * point_step], p, 12);
    }
  }
  return d;
}

TEST(CameraInputValidationTest, CloudFieldsMustFitThePointAndRowsMustNotWrap) {
  CloudLayout l;
  const std::vector<uint8_t> d = cloudData(16, &l);
  DepthImage img;
  Intrinsics K;
  std::string why;
  ASSERT_TRUE(depthImageFromCloudBuffer(l, d.data(), d.size(), &img, &K, &why)) << why;
  EXPECT_NEAR(K.fx_px, 4.f, 1e-3);
  EXPECT_NEAR(K.cx_px, 1.5f, 1e-3);
  // A z field at byte 13 of a 16-byte point reads past the last point.
  l.z_offset = 13;
  EXPECT_FALSE(depthImageFromCloudBuffer(l, d.data(), d.size(), &img, &K, &why));
  EXPECT_NE(why.find("field z at byte 13 does not fit the 16-byte point"), std::string::npos)
      << why;
  // width x point_step = 2^32 wrapped to 0 in 32 bits, so any row_step passed.
  l.z_offset = 8;
  l.width = 1u << 28;
  l.row_step = 16;
  EXPECT_FALSE(depthImageFromCloudBuffer(l, d.data(), d.size(), &img, &K, &why));
  EXPECT_NE(why.find("shorter than its declared layout"), std::string::npos) << why;
}

TEST(CameraInputValidationTest, ImageBufferChecksKeepTheirMessages) {
  const std::vector<uint8_t> d(4 * 3 * 2, 1);
  DepthImage img;
  std::string why;
  EXPECT_TRUE(depthImageFromBuffer("16UC1", 4, 3, 8, false, d.data(), d.size(), &img, &why));
  EXPECT_FALSE(depthImageFromBuffer("rgb8", 4, 3, 8, false, d.data(), d.size(), &img, &why));
  EXPECT_NE(why.find("unsupported depth encoding 'rgb8'"), std::string::npos) << why;
  EXPECT_FALSE(depthImageFromBuffer("16UC1", 4, 3, 7, false, d.data(), d.size(), &img, &why));
  EXPECT_NE(why.find("step 7 is shorter"), std::string::npos) << why;
  EXPECT_FALSE(depthImageFromBuffer("32FC1", 4, 3, 16, false, d.data(), d.size(), &img, &why));
  EXPECT_NE(why.find("data has 24 bytes, step x height = 48"), std::string::npos) << why;
  EXPECT_FALSE(depthImageFromBuffer("16UC1", 0, 3, 8, false, d.data(), d.size(), &img, &why));
  EXPECT_NE(why.find("empty depth image"), std::string::npos) << why;
}

#if defined(GMM_MCL_HAVE_PNG)
TEST(CameraInputValidationTest, PngLargerThanItsPayloadCanHoldIsRejectedBeforeAllocating) {
  std::vector<uint16_t> v(8 * 4, 1000);
  std::vector<uint8_t> png;
  encodePng16(8, 4, v, &png);
  int w = 0, h = 0;
  std::vector<uint16_t> back;
  decodePng16(png.data(), png.size(), &w, &h, &back);
  EXPECT_EQ(back, v);
  // IHDR width and height (PNG bytes 16 and 20, big-endian) set to 10^6, CRC (byte 29) fixed.
  for (size_t at : {size_t{16}, size_t{20}}) {
    const uint32_t n = 1000000;
    for (int k = 0; k < 4; ++k) png[at + k] = static_cast<uint8_t>(n >> (24 - 8 * k));
  }
  const uint32_t crc = crc32(&png[12], 17);
  for (int k = 0; k < 4; ++k) png[29 + k] = static_cast<uint8_t>(crc >> (24 - 8 * k));
  try {
    decodePng16(png.data(), png.size(), &w, &h, &back);
    FAIL() << "decoded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("PNG claims 1000000x1000000 pixels"), std::string::npos)
        << e.what();
  }
}

TEST(CameraInputValidationTest, CompressedDepthRoundTripThroughTheCore) {
  std::vector<uint16_t> mm = {0, 1000, 1234, 4000, 65535, 2};
  std::string format, why;
  std::vector<uint8_t> data;
  ASSERT_TRUE(encodeCompressedDepth(DepthImage::fromMillimetres(3, 2, mm), &format, &data, &why));
  EXPECT_EQ(format, "16UC1; compressedDepth png");
  DepthImage img;
  ASSERT_TRUE(decodeCompressedDepth(format, data.data(), data.size(), &img, &why)) << why;
  EXPECT_TRUE(std::isnan(img.depthMetres(0, 0)));  // 0: no measurement
  EXPECT_NEAR(img.depthMetres(1, 0), 1.0f, 1e-6);
  EXPECT_NEAR(img.depthMetres(0, 1), 4.0f, 1e-6);
  EXPECT_TRUE(std::isnan(img.depthMetres(1, 1)));  // 65535: no measurement
  EXPECT_NEAR(img.depthMetres(2, 1), 0.002f, 1e-7);
  EXPECT_FALSE(decodeCompressedDepth("16UC1; compressedDepth", data.data(), 12, &img, &why));
  EXPECT_EQ(why, "compressedDepth message shorter than its header");
}
#endif

}  // namespace
}  // namespace gmm_mcl
