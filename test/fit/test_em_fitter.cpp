#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "test_utils/assertions.h"

namespace gmm_mcl {
namespace {

constexpr double kMeanTolM = 0.01;

PointCloud twoBlobs(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.f, 1.f);
  PointCloud pts;
  for (size_t i = 0; i < n; ++i) {
    if (i % 4 == 0) {  // weight 0.25, sigma (0.1, 0.2, 0.05) at (1, 2, 3)
      pts.emplace_back(1.f + 0.1f * g(rng), 2.f + 0.2f * g(rng), 3.f + 0.05f * g(rng));
    } else {  // weight 0.75, isotropic 0.3 at (-2, 0, 0)
      pts.emplace_back(-2.f + 0.3f * g(rng), 0.3f * g(rng), 0.3f * g(rng));
    }
  }
  return pts;
}

EmParams smallParams(int m) {
  EmParams p;
  p.components = m;
  p.max_iterations = 200;
  p.tolerance = 1e-6;
  return p;
}

// A map must survive the float32 file and validate when loaded back.
void expectStorable(const EmResult& r, double reg) {
  for (const auto& c : r.components) {
    ASSERT_TRUE(std::isfinite(c.weight));
    ASSERT_TRUE(c.mean_m.allFinite());
    ASSERT_TRUE(c.cov_m2.allFinite());
  }
  const GmmMap map = makeStorableMap(r.components, reg, "<test>");
  EXPECT_NO_THROW(decodeMap(encodeMap(map), "<test>"));
}

TEST(EmParamsTest, DefaultsAreValidAndFaultsNamed) {
  EXPECT_EQ(EmParams().validate(), "");
  EXPECT_EQ(EmParams().components, 1000);
  EXPECT_EQ(EmParams().reg_covar_m2, 1e-6);
  EmParams p;
  p.components = 0;
  p.tolerance = -1;
  p.prune_sigma = 1.0;
  const std::string f = p.validate();
  EXPECT_NE(f.find("components"), std::string::npos);
  EXPECT_NE(f.find("tolerance"), std::string::npos);
  EXPECT_NE(f.find("prune_sigma"), std::string::npos);
  EXPECT_THROW(fitGmm(twoBlobs(100, 1), p), FitError);
}

TEST(EmFitterTest, RecoversTwoGaussians) {
  const EmResult r = fitGmm(twoBlobs(20000, 1), smallParams(2));
  ASSERT_EQ(r.components.size(), 2u);
  EXPECT_TRUE(r.converged);
  const GaussianComponent& a =
      r.components[0].weight < r.components[1].weight ? r.components[0] : r.components[1];
  const GaussianComponent& b = &a == &r.components[0] ? r.components[1] : r.components[0];
  EXPECT_NEAR(a.weight, 0.25, 0.01);
  EXPECT_NEAR(b.weight, 0.75, 0.01);
  EXPECT_LT((a.mean_m - Eigen::Vector3d(1, 2, 3)).norm(), kMeanTolM);
  EXPECT_LT((b.mean_m - Eigen::Vector3d(-2, 0, 0)).norm(), kMeanTolM);
  EXPECT_NEAR(std::sqrt(a.cov_m2(0, 0)), 0.1, 0.005);
  EXPECT_NEAR(std::sqrt(a.cov_m2(1, 1)), 0.2, 0.01);
  EXPECT_NEAR(std::sqrt(a.cov_m2(2, 2)), 0.05, 0.003);
  EXPECT_NEAR(std::sqrt(b.cov_m2(0, 0)), 0.3, 0.01);
  // The log-likelihood never decreases (EM), and the final value is the returned map's.
  for (size_t i = 1; i < r.history.size(); ++i) {
    EXPECT_GE(r.history[i].mean_log_likelihood, r.history[i - 1].mean_log_likelihood - 1e-9);
  }
  EXPECT_NEAR(r.final_mean_log_likelihood, meanLogLikelihood(r.components, twoBlobs(20000, 1)),
              1e-9);
}

TEST(EmFitterTest, DeterministicForSeedAndThreadCount) {
  const PointCloud pts = twoBlobs(5000, 2);
  EmParams p = smallParams(20);
  p.max_iterations = 15;
  omp_set_num_threads(1);
  const EmResult one = fitGmm(pts, p);
  omp_set_num_threads(2);
  const EmResult two = fitGmm(pts, p);
  const EmResult again = fitGmm(pts, p);
  ASSERT_TRUE(test::sameComponents(one.components, two.components));
  EXPECT_TRUE(test::sameComponents(two.components, again.components));
  p.seed = 2;
  const EmResult other = fitGmm(pts, p);
  EXPECT_NE(other.components[0].mean_m, one.components[0].mean_m);
}

TEST(EmFitterTest, PrunedMatchesExact) {
  const PointCloud pts = twoBlobs(8000, 3);
  EmParams p = smallParams(30);
  p.max_iterations = 20;
  const EmResult pruned = fitGmm(pts, p);
  p.prune_sigma = 0.0;
  const EmResult exact = fitGmm(pts, p);
  EXPECT_NEAR(pruned.final_mean_log_likelihood, exact.final_mean_log_likelihood,
              1e-6 * std::abs(exact.final_mean_log_likelihood));
  EXPECT_LT(pruned.history.back().mean_candidates, 30.0);
}

TEST(EmFitterTest, GivenMeans) {
  EmParams p = smallParams(2);
  p.init = EmInit::kGivenMeans;
  p.initial_means_m = {Eigen::Vector3d(0.5, 1.5, 3), Eigen::Vector3d(-1.5, 0, 0)};
  const EmResult r = fitGmm(twoBlobs(4000, 4), p);
  EXPECT_LT((r.components[0].mean_m - Eigen::Vector3d(1, 2, 3)).norm(), 0.02);
  p.initial_means_m.pop_back();
  EXPECT_THROW(fitGmm(twoBlobs(4000, 4), p), FitError);
}

TEST(EmFitterTest, BadInputIsAClearError) {
  EXPECT_THROW(fitGmm(PointCloud(), smallParams(1)), FitError);
  EXPECT_TRUE(
      test::throwsWith<FitError>([] { fitGmm(twoBlobs(10, 1), smallParams(50)); }, {"fewer"}));
  PointCloud nan = twoBlobs(100, 1);
  nan[7].x() = NAN;
  EXPECT_TRUE(test::throwsWith<FitError>([&] { fitGmm(nan, smallParams(2)); }, {"NaN"}));
}

TEST(EmFitterTest, DegenerateClustersGiveValidMaps) {
  PointCloud line, plane, same, dup;
  for (int i = 0; i < 2000; ++i) {
    line.emplace_back(0.001f * i, 0.f, 1.f);                      // collinear
    plane.emplace_back(0.01f * (i % 50), 0.01f * (i / 50), 2.f);  // planar
    same.emplace_back(1.f, 1.f, 1.f);                             // one point repeated
    dup.emplace_back(static_cast<float>(i % 3), 0.f, 0.f);        // 3 distinct points
  }
  for (const PointCloud* pts : {&line, &plane, &same, &dup}) {
    EmParams p = smallParams(10);
    p.max_iterations = 50;
    EmResult r;
    ASSERT_NO_THROW(r = fitGmm(*pts, p));
    expectStorable(r, p.reg_covar_m2);
    p.reg_covar_m2 = 0.0;  // no regularisation at all: still valid (diagonal loading)
    ASSERT_NO_THROW(r = fitGmm(*pts, p));
    expectStorable(r, 0.0);
  }
}

TEST(EmFitterTest, StorableMapRepairsIllConditionedCovariance) {
  GaussianComponent c;
  c.weight = 1.0;
  const Eigen::Vector3d u = Eigen::Vector3d(1, 2, 3).normalized();
  c.cov_m2 = u * u.transpose() * 4.0 + 1e-13 * Eigen::Matrix3d::Identity();
  int repaired = -1;
  const GmmMap map = makeStorableMap({c}, 0.0, "<test>", &repaired);
  EXPECT_EQ(repaired, 1);
  EXPECT_NO_THROW(decodeMap(encodeMap(map), "<test>"));
}

TEST(EmFitterTest, RefineContinuesEm) {
  const PointCloud pts = twoBlobs(6000, 5);
  EmParams p = smallParams(8);
  p.max_iterations = 5;
  const EmResult start = fitGmm(pts, p);
  const EmResult more = refineGmm(pts, start.components, p);
  EXPECT_EQ(more.components.size(), 8u);
  // EM never lowers the log-likelihood; its first iteration scores the given components.
  EXPECT_NEAR(more.history.front().mean_log_likelihood, start.final_mean_log_likelihood, 1e-9);
  EXPECT_GE(more.final_mean_log_likelihood, start.final_mean_log_likelihood - 1e-9);
  expectStorable(more, p.reg_covar_m2);
  std::vector<GaussianComponent> bad = start.components;
  bad[2].weight = 0.0;
  EXPECT_THROW(refineGmm(pts, bad, p), FitError);
  EXPECT_THROW(refineGmm(pts, {}, p), FitError);
  EXPECT_THROW(refineGmm(PointCloud(), start.components, p), FitError);
}

// Many small components over a wide cloud: the pruned scoring (each point against the
// components whose 6-sigma box overlaps its grid cell) agrees with the exact one.
TEST(EmFitterTest, PrunedScoringMatchesExactForManyComponents) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> g(0.f, 0.01f);
  PointCloud pts;
  for (int i = 0; i < 40000; ++i) pts.emplace_back(40.f * u(rng), 30.f * u(rng), g(rng));
  EmParams p = smallParams(2000);
  p.max_iterations = 3;
  p.kmeans_iterations = 2;
  const EmResult r = fitGmm(pts, p);
  const double exact = meanLogLikelihood(r.components, pts);
  EXPECT_NEAR(meanLogLikelihood(r.components, pts, 6.0), exact, 1e-9 * std::abs(exact));
  EXPECT_NEAR(r.final_mean_log_likelihood, exact, 1e-9 * std::abs(exact));
  EXPECT_THROW(meanLogLikelihood(r.components, pts, 1.0), FitError);
}

}  // namespace
}  // namespace gmm_mcl
