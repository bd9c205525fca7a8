// The structured-light sensor model: axial noise statistics, disparity quantisation, grazing
// incidence, projector shadow, depth edges, range window, determinism and validation.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <vector>

#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/sensor_noise.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kSigmaRelTol = 0.05;  // sample std vs model sigma (about 75k samples)

Mesh quad(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
          const Eigen::Vector3f& d) {
  Mesh m;
  m.vertices_m = {a, b, c, d};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

Mesh wallAt(float z) { return quad({-20, -20, z}, {20, -20, z}, {20, 20, z}, {-20, 20, z}); }

TEST(SensorNoiseTest, DefaultsAreValidAndNumbersMatchTheSource) {
  const SensorNoiseParams p;
  EXPECT_EQ(p.validate(), "");
  EXPECT_EQ(SensorNoiseParams::noiseFree().validate(), "");
  // Nguyen et al. 2012: 0.0012 + 0.0019 (z - 0.4)^2 at small angles.
  EXPECT_NEAR(axialSigma(p, 1.0, 0.0), 0.0012 + 0.0019 * 0.36, 1e-12);
  EXPECT_NEAR(axialSigma(p, 3.0, 0.0), 0.0012 + 0.0019 * 2.6 * 2.6, 1e-12);
  EXPECT_GT(axialSigma(p, 1.0, 1.2), axialSigma(p, 1.0, 0.2));
  // Kinect disparity step: z^2 / (f b subpixel): 2.9 mm at 1 m, 72 mm at 5 m.
  const double z1 = 1.0, step1 = z1 * z1 / (580.0 * 0.075 * 8.0);
  EXPECT_NEAR(step1, 0.00287, 1e-4);
  EXPECT_LE(std::abs(quantiseDepth(p, 1.0) - 1.0), 0.5 * step1 + 1e-9);
  SensorNoiseParams bad;
  bad.max_range_m = 0.1;
  EXPECT_NE(bad.validate().find("range window"), std::string::npos);
  bad = SensorNoiseParams();
  bad.grazing_end_rad = 0.1;
  EXPECT_NE(bad.validate().find("grazing"), std::string::npos);
  bad = SensorNoiseParams();
  bad.random_dropout = 1.5;
  EXPECT_NE(bad.validate().find("dropout"), std::string::npos);
  bad = SensorNoiseParams();
  bad.baseline_m = 0.0;
  EXPECT_NE(bad.validate().find("baseline"), std::string::npos);
  const MeshBvh bvh(wallAt(2.f));
  EXPECT_THROW(renderDepth(bvh, test::smallCamera(), Eigen::Isometry3d::Identity(),
                           DepthEncoding::kFloat32Metres, 10.0, &bad, 1),
               std::invalid_argument);
}

TEST(SensorNoiseTest, AxialNoiseHasTheModelSigmaAndQuantisationSnapsToDisparitySteps) {
  const MeshBvh bvh(wallAt(2.f));
  const Intrinsics K = test::smallCamera();
  const IdealDepth ideal = renderIdealDepth(bvh, K, Eigen::Isometry3d::Identity(), 10.0);
  SensorNoiseParams p = SensorNoiseParams::noiseFree();
  p.axial_a_m = 0.0012;
  p.axial_b_per_m = 0.0019;
  p.axial_angle_m = 0.0001;
  p.max_range_m = 10.0;
  const std::vector<float> z = applySensorNoise(ideal, p, 5);
  double s = 0.0, s2 = 0.0, model = 0.0;
  int n = 0;
  for (size_t i = 0; i < z.size(); ++i) {
    ASSERT_TRUE(std::isfinite(z[i]));
    const double e = z[i] - ideal.z_m[i];
    s += e;
    s2 += e * e;
    const double sg = axialSigma(p, ideal.z_m[i], std::acos(ideal.cos_incidence[i]));
    model += sg * sg;
    ++n;
  }
  const double mean = s / n, sd = std::sqrt(s2 / n - mean * mean), sd_model = std::sqrt(model / n);
  EXPECT_NEAR(sd, sd_model, kSigmaRelTol * sd_model);
  EXPECT_LT(std::abs(mean), 5.0 * sd_model / std::sqrt(n));

  // Quantisation on, noise off: every depth is f b subpixel / integer.
  SensorNoiseParams q = SensorNoiseParams::noiseFree();
  q.disparity_subpixel = 8.0;
  const std::vector<float> zq = applySensorNoise(ideal, q, 5);
  const double fbs = 580.0 * 0.075 * 8.0;
  for (size_t i = 0; i < zq.size(); i += 97) {
    const double d = fbs / zq[i];
    EXPECT_NEAR(d, std::round(d), 1e-3 * d);
    EXPECT_LE(std::abs(zq[i] - ideal.z_m[i]), 0.5 * 4.0 / fbs + 1e-5);  // half a step at 2 m
  }
}

TEST(SensorNoiseTest, GrazingIncidenceIsMissing) {
  // A floor 1 m below a camera looking forward: incidence grows towards the horizon.
  const MeshBvh bvh(quad({-50, 1, 0}, {50, 1, 0}, {50, 1, 100}, {-50, 1, 100}));
  const Intrinsics K = test::smallCamera();
  const IdealDepth ideal = renderIdealDepth(bvh, K, Eigen::Isometry3d::Identity(), 200.0);
  SensorNoiseParams p = SensorNoiseParams::noiseFree();
  p.grazing_start_rad = 70.0 * M_PI / 180.0;
  p.grazing_end_rad = 85.0 * M_PI / 180.0;
  const std::vector<float> z = applySensorNoise(ideal, p, 3);
  int below = 0, below_kept = 0, beyond = 0, beyond_kept = 0;
  for (size_t i = 0; i < z.size(); ++i) {
    if (!std::isfinite(ideal.z_m[i])) continue;
    const double theta = std::acos(ideal.cos_incidence[i]);
    if (theta < p.grazing_start_rad) {
      ++below;
      below_kept += std::isfinite(z[i]);
    } else if (theta > p.grazing_end_rad) {
      ++beyond;
      beyond_kept += std::isfinite(z[i]);
    }
  }
  ASSERT_GT(below, 1000);
  ASSERT_GT(beyond, 100);
  EXPECT_EQ(below_kept, below);
  EXPECT_EQ(beyond_kept, 0);
}

TEST(SensorNoiseTest, ProjectorShadowLiesLeftOfAForegroundPlateWithTheExpectedWidth) {
  Mesh m = wallAt(3.f);
  m.append(
      quad({-0.2f, -0.2f, 1.5f}, {0.2f, -0.2f, 1.5f}, {0.2f, 0.2f, 1.5f}, {-0.2f, 0.2f, 1.5f}));
  const MeshBvh bvh(m);
  const Intrinsics K = test::smallCamera();
  const double b = 0.075;
  const IdealDepth ideal = renderIdealDepth(bvh, K, Eigen::Isometry3d::Identity(), 10.0, b);
  const int v = static_cast<int>(K.cy_px + 0.5);
  int left = 0, right = 0;
  for (int u = 0; u < K.width_px; ++u) {
    const size_t i = static_cast<size_t>(v) * K.width_px + u;
    if (!ideal.shadowed[i]) continue;
    EXPECT_NEAR(ideal.z_m[i], 3.0, 1e-4);  // only the wall is shadowed
    (u < K.cx_px ? left : right)++;
  }
  // Projector at +x: the shadow band is f b (1/z_near - 1/z_far) px wide, left of the plate.
  const double expected_px = K.fx_px * b * (1.0 / 1.5 - 1.0 / 3.0);
  EXPECT_NEAR(left, expected_px, 1.5);
  EXPECT_EQ(right, 0);
  // The model drops shadowed pixels and the 1-pixel band around both depth edges.
  SensorNoiseParams p = SensorNoiseParams::noiseFree();
  p.projector_shadow = true;
  p.edge_radius_px = 1;
  const std::vector<float> z = applySensorNoise(ideal, p, 1);
  const int plate_right = static_cast<int>(std::floor(K.cx_px + K.fx_px * 0.2 / 1.5));
  const size_t row = static_cast<size_t>(v) * K.width_px;
  EXPECT_TRUE(std::isfinite(ideal.z_m[row + plate_right]));
  EXPECT_TRUE(std::isnan(z[row + plate_right]));      // on the plate, next to the edge
  EXPECT_TRUE(std::isnan(z[row + plate_right + 1]));  // on the wall, next to the edge
  EXPECT_TRUE(std::isfinite(z[row + plate_right + 3]));
  EXPECT_TRUE(std::isfinite(z[row + plate_right - 3]));
}

TEST(SensorNoiseTest, RangeWindowDropoutAndDeterminism) {
  const MeshBvh bvh(wallAt(2.f));
  const Intrinsics K = test::smallCamera();
  SensorNoiseParams p;  // defaults
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const DepthImage a = renderDepth(bvh, K, I, DepthEncoding::kMono16Millimetres, 10.0, &p, 11);
  omp_set_num_threads(1);
  const DepthImage b = renderDepth(bvh, K, I, DepthEncoding::kMono16Millimetres, 10.0, &p, 11);
  omp_set_num_threads(omp_get_num_procs());
  const DepthImage c = renderDepth(bvh, K, I, DepthEncoding::kMono16Millimetres, 10.0, &p, 12);
  EXPECT_EQ(a.data, b.data);  // same seed, any thread count
  EXPECT_NE(a.data, c.data);
  int missing = 0;
  for (int v = 0; v < K.height_px; ++v) {
    for (int u = 0; u < K.width_px; ++u) missing += std::isnan(a.depthMetres(u, v));
  }
  const double frac = missing / static_cast<double>(K.width_px * K.height_px);
  EXPECT_NEAR(frac, p.random_dropout, 0.003);  // a flat wall: only the random dropout
  // Max range below the wall: nothing; the renderer's max_range_m also limits the window.
  SensorNoiseParams near = p;
  near.max_range_m = 1.5;
  const DepthImage d = renderDepth(bvh, K, I, DepthEncoding::kFloat32Metres, 10.0, &near, 1);
  const DepthImage e = renderDepth(bvh, K, I, DepthEncoding::kFloat32Metres, 1.5, &p, 1);
  for (int v = 0; v < K.height_px; v += 5) {
    for (int u = 0; u < K.width_px; u += 5) {
      EXPECT_TRUE(std::isnan(d.depthMetres(u, v)));
      EXPECT_TRUE(std::isnan(e.depthMetres(u, v)));
    }
  }
}

}  // namespace
}  // namespace sim
}  // namespace gmm_mcl
