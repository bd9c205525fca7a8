#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "gmm_mcl/camera/depth_frame.h"
#include "test_utils/synthetic_fixtures.h"

#if defined(GMM_MCL_HAVE_PNG)
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace {

TEST(DepthFrameTest, BothEncodingsGiveTheSamePoints) {
  const Intrinsics K = test::smallCamera();
  FrameParams params;
  params.pixel_stride = 2;
  params.max_range_m = 10.f;
  // Millimetre depths, and the same values as float metres.
  std::vector<uint16_t> mm(K.width_px * K.height_px);
  std::vector<float> m(mm.size());
  for (size_t i = 0; i < mm.size(); ++i) {
    mm[i] = static_cast<uint16_t>(500 + (i * 37) % 5000);
    m[i] = 0.001f * mm[i];
  }
  mm[0] = 0;
  m[0] = std::numeric_limits<float>::quiet_NaN();
  mm[2] = 65535;
  m[2] = std::numeric_limits<float>::infinity();
  mm[4] = 0;
  m[4] = 0.f;
  const DepthFrame a =
      prepareFrame(DepthImage::fromMillimetres(K.width_px, K.height_px, mm), K, params);
  const DepthFrame b = prepareFrame(DepthImage::fromMetres(K.width_px, K.height_px, m), K, params);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.invalid_pixels, 3);
  EXPECT_EQ(b.invalid_pixels, 3);
  EXPECT_EQ(a.patch_begin, b.patch_begin);
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_FLOAT_EQ(a.x_m[i], b.x_m[i]);
    ASSERT_FLOAT_EQ(a.y_m[i], b.y_m[i]);
    ASSERT_FLOAT_EQ(a.z_m[i], b.z_m[i]);
  }
}

TEST(DepthFrameTest, StrideRangeWindowAndPatchGrouping) {
  const Intrinsics K = test::smallCamera();
  FrameParams params;
  params.pixel_stride = 4;
  params.patch_size_px = 32;
  params.min_range_m = 1.0f;
  params.max_range_m = 3.0f;
  std::vector<float> d(K.width_px * K.height_px, 2.0f);
  d[0] = 0.5f;               // below range
  d[4] = 3.5f;               // above range
  d[K.width_px * 1] = 1.0f;  // off the stride grid: never sampled
  const DepthFrame f = prepareFrame(DepthImage::fromMetres(K.width_px, K.height_px, d), K, params);
  EXPECT_EQ(f.total_pixels_sampled, 80 * 60);
  EXPECT_EQ(f.out_of_range_pixels, 2);
  EXPECT_EQ(static_cast<int>(f.size()), 80 * 60 - 2);
  EXPECT_EQ(f.grid.cols, 10);
  EXPECT_EQ(f.grid.rows, 8);  // 240 / 32 = 7.5: a partial last row
  // Every point of patch p lies within that patch's pixel square.
  for (int p = 0; p < f.grid.count(); ++p) {
    const int col = p % f.grid.cols, row = p / f.grid.cols;
    for (int i = f.patch_begin[p]; i < f.patch_begin[p + 1]; ++i) {
      const float u = f.x_m[i] * K.fx_px / f.z_m[i] + K.cx_px;
      const float v = f.y_m[i] * K.fy_px / f.z_m[i] + K.cy_px;
      ASSERT_GE(u, col * 32 - 1e-3f);
      ASSERT_LT(u, (col + 1) * 32);
      ASSERT_GE(v, row * 32 - 1e-3f);
      ASSERT_LT(v, (row + 1) * 32);
    }
  }
  // Back-projection: pixel (cx + fx, cy) at z = 2 is at x = 2.
  float p[3];
  backProject(K, K.cx_px + K.fx_px, K.cy_px, 2.f, p);
  EXPECT_FLOAT_EQ(p[0], 2.f);
  EXPECT_FLOAT_EQ(p[1], 0.f);
}

TEST(DepthFrameTest, SizeMismatchAndBadLayoutAreClearErrors) {
  const Intrinsics K = test::smallCamera();
  const DepthImage small = DepthImage::fromMetres(10, 10, std::vector<float>(100, 1.f));
  try {
    prepareFrame(small, K, FrameParams());
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("10x10 but the camera info says 320x240"),
              std::string::npos);
  }
  DepthImage truncated = DepthImage::fromMetres(320, 240, std::vector<float>(320 * 240, 1.f));
  truncated.data.resize(100);
  EXPECT_THROW(prepareFrame(truncated, K, FrameParams()), std::invalid_argument);
  const double K_bad[9] = {0, 0, 160, 0, 0, 120, 0, 0, 1};
  EXPECT_THROW(makeIntrinsics(K_bad, 320, 240), std::invalid_argument);
  DepthEncoding enc;
  EXPECT_TRUE(parseDepthEncoding("16UC1", &enc));
  EXPECT_TRUE(parseDepthEncoding("32FC1", &enc));
  EXPECT_FALSE(parseDepthEncoding("rgb8", &enc));
}

TEST(DepthFrameTest, AllInvalidFrameIsEmptyNotAnError) {
  const Intrinsics K = test::smallCamera();
  std::vector<float> d(K.width_px * K.height_px, std::numeric_limits<float>::quiet_NaN());
  const DepthFrame f =
      prepareFrame(DepthImage::fromMetres(K.width_px, K.height_px, d), K, FrameParams());
  EXPECT_TRUE(f.empty());
  EXPECT_EQ(f.invalid_pixels, f.total_pixels_sampled);
}

#if defined(GMM_MCL_HAVE_PNG)
TEST(DepthFrameTest, PngRoundTripAndSevenScenesFrame) {
  std::vector<uint16_t> mm(64 * 48);
  for (size_t i = 0; i < mm.size(); ++i) mm[i] = static_cast<uint16_t>(i * 13 % 65536);
  const DepthImage img = DepthImage::fromMillimetres(64, 48, mm);
  const std::string path = ::testing::TempDir() + "depth.png";
  saveDepthPng16(img, path);
  const DepthImage back = loadDepthPng16(path);
  EXPECT_EQ(back.data, img.data);

  const std::string root = test::datasetsRoot();
  if (root.empty()) {
    std::printf("[  SKIPPED ] 7-Scenes part: ../shared/datasets not found\n");
    return;
  }
  const DepthImage frame = loadDepthPng16(root + "/7scenes_redkitchen/data/frame-000000.depth.png");
  EXPECT_EQ(frame.width_px, 640);
  EXPECT_EQ(frame.height_px, 480);
  int zeros = 0, plausible = 0;
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const float z = frame.depthMetres(u, v);
      if (!std::isfinite(z))
        ++zeros;
      else if (z > 0.3f && z < 5.0f)
        ++plausible;
    }
  }
  // SOURCES.md: about 11% of pixels are 0; the rest are room-scale depths in millimetres.
  EXPECT_GT(zeros, 0.02 * 640 * 480);
  EXPECT_LT(zeros, 0.30 * 640 * 480);
  EXPECT_GT(plausible, 0.65 * 640 * 480);
}
#endif

}  // namespace
}  // namespace gmm_mcl
