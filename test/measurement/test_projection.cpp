#include <gtest/gtest.h>

#include <random>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/projection.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// Linearised projection vs the empirical moments of 3D samples pushed through the pinhole.
// Tolerances: mean within kMeanTolPx, covariance entries within kCovRelTol of the largest
// covariance entry (first-order projection of a 5 cm component at 2-3 m; sampling error of
// 400k samples is about 0.2%).
constexpr int kSamples = 400000;
constexpr double kMeanTolPx = 0.25;
constexpr double kCovRelTol = 0.03;

void checkAgainstMonteCarlo(const Eigen::Vector3d& mean_cam, const Eigen::Matrix3d& cov_cam,
                            const Eigen::Isometry3d& T_map_cam) {
  const Intrinsics K = test::vgaCamera();
  // Component in the map frame.
  GaussianComponent gc;
  gc.weight = 1.0;
  gc.mean_m = T_map_cam * mean_cam;
  gc.cov_m2 = T_map_cam.linear() * cov_cam * T_map_cam.linear().transpose();
  gc.cov_m2 = 0.5 * (gc.cov_m2 + gc.cov_m2.transpose());
  const GmmMap map({gc}, "mc");
  ProjectedComponent p;
  ASSERT_TRUE(
      projectComponent(map.packed()[0], toRigidF(T_map_cam.inverse()), K, 0.1f, 3.f, 0.f, &p));

  std::mt19937_64 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Matrix3d L = gc.cov_m2.llt().matrixL();
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  Eigen::Matrix2d sum_sq = Eigen::Matrix2d::Zero();
  for (int i = 0; i < kSamples; ++i) {
    const Eigen::Vector3d x_map = gc.mean_m + L * Eigen::Vector3d(g(rng), g(rng), g(rng));
    const Eigen::Vector3d x = T_map_cam.inverse() * x_map;
    const Eigen::Vector2d uv(K.cx_px + K.fx_px * x.x() / x.z(), K.cy_px + K.fy_px * x.y() / x.z());
    sum += uv;
    sum_sq += uv * uv.transpose();
  }
  const Eigen::Vector2d mc_mean = sum / kSamples;
  const Eigen::Matrix2d mc_cov = sum_sq / kSamples - mc_mean * mc_mean.transpose();
  EXPECT_NEAR(p.u_px, mc_mean.x(), kMeanTolPx);
  EXPECT_NEAR(p.v_px, mc_mean.y(), kMeanTolPx);
  const double scale = mc_cov.cwiseAbs().maxCoeff();
  EXPECT_NEAR(p.cov_uu, mc_cov(0, 0), kCovRelTol * scale);
  EXPECT_NEAR(p.cov_uv, mc_cov(0, 1), kCovRelTol * scale);
  EXPECT_NEAR(p.cov_vv, mc_cov(1, 1), kCovRelTol * scale);
}

Eigen::Matrix3d anisotropicCov() {
  Eigen::Matrix3d A;
  A << 0.05, 0.01, 0.0, 0.0, 0.02, 0.015, 0.01, 0.0, 0.03;
  return A * A.transpose() + 1e-5 * Eigen::Matrix3d::Identity();
}

TEST(ProjectionTest, MatchesMonteCarloNearTheImageCentre) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(0.3, -0.2, 1.1);
  T.translation() = Eigen::Vector3d(1.0, -2.0, 0.5);
  checkAgainstMonteCarlo(Eigen::Vector3d(0.05, -0.03, 2.5), anisotropicCov(), T);
}

TEST(ProjectionTest, MatchesMonteCarloOffAxis) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(-0.1, 0.4, -2.0);
  // About 250 px right of and 150 px below the principal point.
  checkAgainstMonteCarlo(Eigen::Vector3d(0.9, 0.5, 2.1), anisotropicCov(), T);
}

TEST(ProjectionTest, DropsComponentsBehindOrTooNear) {
  GaussianComponent gc;
  gc.weight = 1.0;
  gc.cov_m2 = 0.01 * Eigen::Matrix3d::Identity();
  const Intrinsics K = test::vgaCamera();
  ProjectedComponent p;
  for (double z : {-1.0, 0.0, 0.05}) {
    gc.mean_m = Eigen::Vector3d(0, 0, z);
    const GmmMap map({gc}, "near");
    RigidTransformF I = toRigidF(Eigen::Isometry3d::Identity());
    EXPECT_FALSE(projectComponent(map.packed()[0], I, K, 0.1f, 3.f, 0.f, &p)) << z;
  }
}

TEST(ProjectionTest, InflatedEllipseContainsItsSemiAxisEnds) {
  // Axis-aligned projection: semi-axes 3 sigma + inflation along u and v.
  ProjectedComponent p;
  GaussianComponent gc;
  gc.weight = 1.0;
  gc.mean_m = Eigen::Vector3d(0, 0, 2.0);
  gc.cov_m2 = Eigen::Vector3d(0.04, 0.01, 0.0001).asDiagonal();
  const GmmMap map({gc}, "axes");
  const Intrinsics K = test::vgaCamera();
  ASSERT_TRUE(projectComponent(map.packed()[0], toRigidF(Eigen::Isometry3d::Identity()), K, 0.1f,
                               3.f, 10.f, &p));
  const float su = 3.f * K.fx_px * 0.2f / 2.f + 10.f;  // 3 sigma_u + inflation
  const float sv = 3.f * K.fy_px * 0.1f / 2.f + 10.f;
  EXPECT_TRUE(ellipseContains(p, p.u_px + 0.999f * su, p.v_px));
  EXPECT_FALSE(ellipseContains(p, p.u_px + 1.001f * su, p.v_px));
  EXPECT_TRUE(ellipseContains(p, p.u_px, p.v_px - 0.999f * sv));
  EXPECT_FALSE(ellipseContains(p, p.u_px, p.v_px - 1.001f * sv));
  EXPECT_NEAR(p.half_w_px, su, 1e-3);
  EXPECT_NEAR(p.half_h_px, sv, 1e-3);
}

}  // namespace
}  // namespace gmm_mcl
