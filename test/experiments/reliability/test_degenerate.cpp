// Degenerate views and numerical safety: the filter keeps its state, its covariance
// grows or stays positive-definite, it never produces NaN, and the status says why.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <random>

#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/pose.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

LocalizerParams params() {
  LocalizerParams p;
  p.frame.pixel_stride = 8;
  p.frame.max_range_m = 8.f;
  p.T_base_cam = test::world().T_base_cam;
  const Particle s = poseToParticle(test::referenceBasePose());
  p.init.centre_m = Eigen::Vector3d(s.x_m, s.y_m, s.z_m);
  p.init.yaw_centre_rad = s.yaw_rad;
  return p;
}

bool finiteEstimate(const StepResult& r) {
  const Particle& m = r.estimate.mean;
  return std::isfinite(m.x_m) && std::isfinite(m.y_m) && std::isfinite(m.z_m) &&
         std::isfinite(m.yaw_rad) && r.estimate.covariance.allFinite() && std::isfinite(r.neff);
}

bool positiveDefinite(const Eigen::Matrix<double, 6, 6>& c) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(c);
  return es.info() == Eigen::Success && es.eigenvalues().minCoeff() > 0.0;
}

StepInput input(double stamp, const DepthImage* depth) {
  StepInput in;
  in.stamp_s = stamp;
  in.has_odometry = true;
  in.T_odom_base = Eigen::Isometry3d::Identity();  // standing still
  in.has_attitude = true;
  in.depth = depth;
  in.intrinsics = test::smallCamera();
  return in;
}

// Every pixel invalid (a covered lens, a sensor fault): predicted only, weights untouched, the
// covariance grows with the process noise, the status names the reason.
TEST(DegenerateViewTest, AllPixelsInvalidKeepsStateAndGrowsCovariance) {
  Localizer loc(params(), test::world().map);
  loc.resetToPose(poseToParticle(test::referenceBasePose()),
                  Eigen::Vector4d(0.05, 0.05, 0.05, 0.05));
  const Intrinsics K = test::smallCamera();
  const DepthImage blank = DepthImage::fromMillimetres(
      K.width_px, K.height_px, std::vector<uint16_t>(K.width_px * K.height_px, 0));
  const double trace0 = loc.filter().estimate().covariance.trace();
  const std::vector<double> w0 = loc.filter().weights();
  StepResult r;
  for (int f = 0; f < 30; ++f) {
    r = loc.step(input(f / 30.0, &blank));
    ASSERT_EQ(r.status, StepStatus::kNoValidPixels) << r.message;
    ASSERT_TRUE(finiteEstimate(r));
  }
  EXPECT_NE(r.message.find("no valid depth pixel"), std::string::npos) << r.message;
  EXPECT_EQ(loc.filter().weights(), w0);  // no update, no resampling
  // 30 steps of 2 cm process noise: variance +0.012 m^2 per axis.
  EXPECT_GT(r.estimate.covariance.trace(), trace0 + 0.02);
  EXPECT_LT(poseToParticle(loc.meanPose()).x_m - poseToParticle(test::referenceBasePose()).x_m,
            0.1);
}

// NaN depth in a 32FC1 frame is "no return", never a NaN in the filter.
TEST(DegenerateViewTest, NanDepthFrameIsNoValidPixels) {
  Localizer loc(params(), test::world().map);
  const Intrinsics K = test::smallCamera();
  const DepthImage nan_img = DepthImage::fromMetres(
      K.width_px, K.height_px, std::vector<float>(K.width_px * K.height_px, std::nanf("")));
  const StepResult r = loc.step(input(0.0, &nan_img));
  EXPECT_EQ(r.status, StepStatus::kNoValidPixels);
  EXPECT_TRUE(finiteEstimate(r));
}

// Empty space: every return beyond max_range.
TEST(DegenerateViewTest, EmptySpaceIsOutOfRange) {
  LocalizerParams p = params();
  p.frame.max_range_m = 0.3f;  // the room's surfaces are all farther away
  Localizer loc(p, test::world().map);
  const Intrinsics K = test::smallCamera();
  const DepthImage img =
      sim::renderDepth(test::world().scene, K, test::referenceBasePose() * test::world().T_base_cam,
                       DepthEncoding::kMono16Millimetres, 9.0);
  const StepResult r = loc.step(input(0.0, &img));
  EXPECT_EQ(r.status, StepStatus::kNoValidPixels);
  EXPECT_NE(r.message.find("out of range"), std::string::npos) << r.message;
  EXPECT_TRUE(finiteEstimate(r));
}

// A blank wall filling the view: translation along the wall is unobservable. The filter keeps
// tracking the observable direction, its covariance along the wall grows, and nothing is NaN.
TEST(DegenerateViewTest, BlankWallGrowsCovarianceAlongTheWall) {
  // Base 0.8 m in front of the room's x = 0 wall, looking at it (yaw pi), camera pitched 10 deg
  // down: only the wall is seen (f = 290 px: +-29 deg horizontally, +-22 deg vertically).
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(0.0, 0.0, M_PI);
  T.translation() = Eigen::Vector3d(0.8, 3.0, 1.6);
  LocalizerParams p = params();
  const Particle truth = poseToParticle(T);
  p.init.centre_m = Eigen::Vector3d(truth.x_m, truth.y_m, truth.z_m);
  p.init.yaw_centre_rad = truth.yaw_rad;
  Localizer loc(p, test::world().map);
  loc.resetToPose(truth, Eigen::Vector4d(0.02, 0.02, 0.02, 0.01));
  const Intrinsics K = test::smallCamera();
  const DepthImage img = sim::renderDepth(test::world().scene, K, T * test::world().T_base_cam,
                                          DepthEncoding::kMono16Millimetres, 9.0);
  const Eigen::Matrix<double, 6, 6> c0 = loc.filter().estimate().covariance;
  StepResult r;
  for (int f = 0; f < 60; ++f) {
    r = loc.step(input(f / 30.0, &img));
    ASSERT_TRUE(finiteEstimate(r)) << "frame " << f;
    ASSERT_EQ(r.status, StepStatus::kOk) << r.message;
  }
  // Along the wall (map y) the spread grows; towards it (map x) it stays tight.
  EXPECT_GT(r.estimate.covariance(1, 1), 4.0 * c0(1, 1));
  EXPECT_LT(std::sqrt(r.estimate.covariance(0, 0)), 0.05);
  EXPECT_LT(std::abs(r.estimate.mean.x_m - truth.x_m), 0.05);
}

// Every particle outside the map (nothing projects into the image): all pixels sit at the
// floor, the weights stay finite, the status says why, and the lost detector redraws particles
// from the recovery region.
TEST(DegenerateViewTest, AllParticlesOutsideTheMap) {
  Localizer loc(params(), test::world().map);
  Particle far = poseToParticle(test::referenceBasePose());
  far.x_m += 100.0;
  loc.resetToPose(far, Eigen::Vector4d(0.1, 0.1, 0.1, 0.1));
  const Intrinsics K = test::smallCamera();
  const DepthImage img =
      sim::renderDepth(test::world().scene, K, test::referenceBasePose() * test::world().T_base_cam,
                       DepthEncoding::kMono16Millimetres, 9.0);
  bool said_floor = false, lost = false;
  for (int f = 0; f < 60; ++f) {
    const StepResult r = loc.step(input(f / 30.0, &img));
    ASSERT_TRUE(finiteEstimate(r)) << "frame " << f;
    if (f == 0) {
      EXPECT_DOUBLE_EQ(r.floor_hit_fraction, 1.0);
      said_floor = r.message.find("likelihood floor") != std::string::npos;
    }
    lost = lost || r.lost;
  }
  EXPECT_TRUE(said_floor);
  EXPECT_TRUE(lost);
}

// ---- numerical safety of the weighting -------------------------------------------------------

class WeightSafetyTest : public ::testing::TestWithParam<WeightingMode> {
 protected:
  ParticleFilter makeFilter() {
    ParticleFilterParams p;
    p.num_particles = 200;
    p.weighting = GetParam();
    ParticleFilter pf(p);
    pf.initialiseGaussian(Particle(), Eigen::Vector4d(1.0, 1.0, 1.0, 0.5));
    return pf;
  }
};

TEST_P(WeightSafetyTest, NonFiniteLikelihoodsKeepTheWeights) {
  ParticleFilter pf = makeFilter();
  const std::vector<double> w0 = pf.weights();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(pf.updateWeights(std::vector<double>(pf.size(), -inf), 100));
  EXPECT_FALSE(pf.updateWeights(std::vector<double>(pf.size(), std::nan("")), 100));
  EXPECT_FALSE(pf.updateWeights(std::vector<double>(pf.size(), inf), 100));
  EXPECT_EQ(pf.weights(), w0);
}

TEST_P(WeightSafetyTest, UnderflowAndHugeSpreadStayFinite) {
  ParticleFilter pf = makeFilter();
  std::vector<double> ll(pf.size());
  for (int i = 0; i < pf.size(); ++i) ll[i] = -1e300 * (i + 1) / pf.size();  // exp() underflows
  ll[7] = std::nan("");
  ll[8] = -std::numeric_limits<double>::infinity();
  ASSERT_TRUE(pf.updateWeights(ll, 1000));
  double total = 0.0;
  for (double w : pf.weights()) {
    ASSERT_TRUE(std::isfinite(w));
    ASSERT_GE(w, 0.0);
    total += w;
  }
  EXPECT_NEAR(total, 1.0, 1e-9);
  EXPECT_EQ(pf.weights()[7], 0.0);
  EXPECT_EQ(pf.weights()[8], 0.0);
  EXPECT_GT(pf.effectiveSampleSize(), 0.0);
  const PoseEstimate e = pf.estimate();
  EXPECT_TRUE(e.covariance.allFinite());
}

TEST_P(WeightSafetyTest, CollapsedSetHasPositiveDefiniteCovariance) {
  ParticleFilter pf = makeFilter();
  std::vector<double> ll(pf.size(), -1e6);
  ll[3] = 0.0;  // one particle explains everything: after resampling all are its copies
  ASSERT_TRUE(pf.updateWeights(ll, 1));
  pf.resample();
  const PoseEstimate e = pf.estimate();
  EXPECT_TRUE(positiveDefinite(e.covariance)) << e.covariance;
  // Reweighting a collapsed set is still well defined.
  ASSERT_TRUE(pf.updateWeights(std::vector<double>(pf.size(), -5.0), 100));
  EXPECT_NEAR(pf.effectiveSampleSize(), pf.size(), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(BothModes, WeightSafetyTest,
                         ::testing::Values(WeightingMode::kPaper, WeightingMode::kTempered),
                         [](const ::testing::TestParamInfo<WeightingMode>& info) {
                           return std::string(weightingModeName(info.param));
                         });

}  // namespace
}  // namespace gmm_mcl
