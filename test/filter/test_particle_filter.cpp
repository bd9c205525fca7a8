#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gmm_mcl/filter/particle_filter.h"

namespace gmm_mcl {
namespace {

// Toy state against an analytic posterior: prior x ~ N(0, 1), likelihood N(z = 1; x, 0.5^2)
// supplied as a log-likelihood over `pixels` pixels with temperature 1, so the tempered weight
// is exactly the likelihood. Posterior: mean 0.8, variance 0.2.
// n particles resampled as one group.
ParticleFilterParams oneGroup(int n) {
  ParticleFilterParams p;
  p.num_particles = n;
  p.resample_groups = 1;
  return p;
}

// Log-likelihoods 0, -step, -2 step, ...: particle 0 the best.
std::vector<double> descendingScores(int n, double step) {
  std::vector<double> ll(n);
  for (int i = 0; i < n; ++i) ll[i] = -step * i;
  return ll;
}

TEST(ParticleFilterTest, TemperedWeightsGiveTheAnalyticPosterior) {
  ParticleFilterParams p;
  p.num_particles = 40000;
  p.resample_groups = 4;
  p.neff_floor_fraction = 0.0;  // the plain tempered likelihood (Neff/N here is about 0.42)
  ParticleFilter pf(p);
  pf.initialiseGaussian(Particle(), Eigen::Vector4d(1.0, 1e-9, 1e-9, 1e-9));
  const int pixels = 100;
  std::vector<double> ll(pf.size());
  for (int i = 0; i < pf.size(); ++i) {
    const double x = pf.particles()[i].x_m;
    ll[i] = pixels * (-0.5 * (x - 1.0) * (x - 1.0) / 0.25);
  }
  ASSERT_TRUE(pf.updateWeights(ll, pixels));
  PoseEstimate e = pf.estimate();
  EXPECT_NEAR(e.mean.x_m, 0.8, 0.01);
  EXPECT_NEAR(e.covariance(0, 0), 0.2, 0.01);
  pf.resample();
  e = pf.estimate();
  EXPECT_NEAR(e.mean.x_m, 0.8, 0.015);
  EXPECT_NEAR(e.covariance(0, 0), 0.2, 0.015);
}

// Adaptive tempering: a sharp likelihood is softened just enough to keep Neff at the floor;
// a flat one is used as is.
TEST(ParticleFilterTest, NeffFloorLimitsOneFramesCollapse) {
  ParticleFilterParams p;
  p.num_particles = 2000;
  p.neff_floor_fraction = 0.5;
  ParticleFilter pf(p);
  pf.initialiseGaussian(Particle(), Eigen::Vector4d(1.0, 1e-9, 1e-9, 1e-9));
  const int pixels = 100;
  std::vector<double> sharp(pf.size()), flat(pf.size());
  for (int i = 0; i < pf.size(); ++i) {
    const double x = pf.particles()[i].x_m;
    sharp[i] = pixels * (-0.5 * (x - 1.0) * (x - 1.0) / 0.0025);  // sigma 5 cm: Neff ~ 1%
    flat[i] = pixels * (-0.5 * (x - 1.0) * (x - 1.0) / 100.0);
  }
  ASSERT_TRUE(pf.updateWeights(sharp, pixels));
  EXPECT_NEAR(pf.effectiveSampleSize(), 1000.0, 1.0);
  EXPECT_LT(pf.lastBetaFraction(), 0.1);
  EXPECT_GT(pf.estimate().mean.x_m, 0.1);  // still pulled towards the measurement
  pf.resample();
  ASSERT_TRUE(pf.updateWeights(flat, pixels));
  EXPECT_DOUBLE_EQ(pf.lastBetaFraction(), 1.0);
}

TEST(ParticleFilterTest, PaperWeightsFollowInverseNllAndGuardNegativeNll) {
  ParticleFilterParams p = oneGroup(3);
  p.weighting = WeightingMode::kPaper;
  ParticleFilter pf(p);
  // NLL 100, 200, 400 over 10 pixels: all above the 1 nat/pixel margin, plain 1/NLL.
  ASSERT_TRUE(pf.updateWeights({-100.0, -200.0, -400.0}, 10));
  EXPECT_NEAR(pf.weights()[0], 4.0 / 7.0, 1e-12);
  EXPECT_NEAR(pf.weights()[2], 1.0 / 7.0, 1e-12);
  // Negative NLL (log-likelihood +50): shifted so the best NLL equals the margin (10 nats);
  // ordering kept, weights finite and positive.
  ParticleFilter pf2(p);
  ASSERT_TRUE(pf2.updateWeights({50.0, -20.0, -100.0}, 10));
  EXPECT_GT(pf2.weights()[0], pf2.weights()[1]);
  EXPECT_GT(pf2.weights()[1], pf2.weights()[2]);
  EXPECT_NEAR(pf2.weights()[0] / pf2.weights()[1], 80.0 / 10.0, 1e-9);
}

TEST(ParticleFilterTest, NonFiniteLikelihoodsKeepTheWeights) {
  ParticleFilterParams p = oneGroup(4);
  ParticleFilter pf(p);
  const std::vector<double> before = pf.weights();
  EXPECT_FALSE(pf.updateWeights(std::vector<double>(4, std::nan("")), 10));
  EXPECT_EQ(pf.weights(), before);
  EXPECT_TRUE(pf.updateWeights({std::nan(""), -5.0, -INFINITY, -6.0}, 10));
  EXPECT_EQ(pf.weights()[0], 0.0);
  EXPECT_EQ(pf.weights()[2], 0.0);
}

TEST(ParticleFilterTest, PredictAppliesOdometryInEachParticlesYawFrame) {
  ParticleFilterParams p = oneGroup(2);
  p.sigma_translation_m = 0.0;
  p.sigma_yaw_rad = 0.0;
  ParticleFilter pf(p);
  Particle a, b;
  b.yaw_rad = M_PI / 2;
  pf.setParticles({a, b}, {1.0, 1.0});
  PlanarDelta d;
  d.translation_m = Eigen::Vector3d(1.0, 0.0, 0.2);
  d.yaw_rad = 0.1;
  pf.predict(d);
  EXPECT_NEAR(pf.particles()[0].x_m, 1.0, 1e-12);
  EXPECT_NEAR(pf.particles()[1].y_m, 1.0, 1e-12);  // forward is +y for the second
  EXPECT_NEAR(pf.particles()[1].z_m, 0.2, 1e-12);
  EXPECT_NEAR(pf.particles()[1].yaw_rad, M_PI / 2 + 0.1, 1e-12);
}

TEST(ParticleFilterTest, OdometryDeltaIsIndependentOfTheOdometryFrame) {
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = a;
  a.linear() = rotationFromRpy(0.1, -0.05, 0.7);
  a.translation() = Eigen::Vector3d(1, 2, 3);
  b.linear() = rotationFromRpy(0.12, -0.02, 0.9);
  b.translation() = a.translation() + Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                                          Eigen::Vector3d(0.3, 0.1, -0.05);
  const PlanarDelta d = odometryDelta(a, b);
  EXPECT_NEAR(d.translation_m.x(), 0.3, 1e-12);
  EXPECT_NEAR(d.translation_m.y(), 0.1, 1e-12);
  EXPECT_NEAR(d.translation_m.z(), -0.05, 1e-12);
  EXPECT_NEAR(d.yaw_rad, 0.2, 1e-12);
}

// Augmented MCL: zero reinitialisation in steady tracking, a rising count after a sharp drop.
TEST(ParticleFilterTest, RecoveryReactsToALikelihoodDropOnly) {
  ParticleFilterParams p;
  p.num_particles = 1000;
  ParticleFilter pf(p);
  InitRegion region;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  const int pixels = 5000;
  auto frame_ll = [&](double per_pixel) {
    std::vector<double> ll(pf.size());
    for (double& l : ll) l = pixels * (per_pixel + 0.05 * g(rng));
    return ll;
  };
  int steady_total = 0;
  for (int f = 0; f < 500; ++f) {
    // Steady tracking: mean per-pixel log-likelihood 1.5 +- 0.1 frame to frame.
    steady_total += pf.recover(frame_ll(1.5 + 0.1 * g(rng)), pixels, region);
  }
  EXPECT_EQ(steady_total, 0);
  std::vector<int> after_drop;
  for (int f = 0; f < 30; ++f) after_drop.push_back(pf.recover(frame_ll(-6.0), pixels, region));
  std::printf("[ measured ] reinitialised after the drop:");
  for (int c : after_drop) std::printf(" %d", c);
  std::printf("\n");
  // Reinitialisation starts within 1 s of data at 30 Hz and keeps rising.
  EXPECT_GT(after_drop[29], 0);
  EXPECT_GT(after_drop[29], after_drop[24]);
  for (size_t k = 1; k < after_drop.size(); ++k) EXPECT_GE(after_drop[k], after_drop[k - 1]);
}

TEST(ParticleFilterTest, SeededRunsAreIdentical) {
  ParticleFilterParams p;
  p.num_particles = 500;
  ParticleFilter a(p), b(p);
  a.initialiseUniform(InitRegion());
  b.initialiseUniform(InitRegion());
  PlanarDelta d;
  d.translation_m.x() = 0.1;
  a.predict(d);
  b.predict(d);
  a.resample();
  b.resample();
  for (int i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.particles()[i].x_m, b.particles()[i].x_m);
    ASSERT_EQ(a.particles()[i].yaw_rad, b.particles()[i].yaw_rad);
  }
}

// KLD-sampling (Fox 2003): the bound grows with the occupied bins; a spread set keeps the
// largest count, a concentrated one shrinks to the smallest, and a uniform reinitialisation
// restores the largest.
TEST(ParticleFilterTest, AdaptiveCountFollowsTheBeliefsSpread) {
  EXPECT_EQ(kldParticleBound(1, 0.05, 2.326), 1);
  int last = 1;
  for (int k : {2, 10, 100, 1000, 10000}) {
    const int n = kldParticleBound(k, 0.05, 2.326);
    EXPECT_GT(n, last) << k;
    last = n;
  }
  // Fox's Eq. 8 for k = 100: 99 / 0.1 * (1 - 2/891 + sqrt(2/891) * 2.326)^3.
  const double a = 2.0 / (9.0 * 99.0);
  EXPECT_EQ(kldParticleBound(100, 0.05, 2.326),
            static_cast<int>(std::ceil(990.0 * std::pow(1.0 - a + std::sqrt(a) * 2.326, 3))));

  ParticleFilterParams p;
  p.num_particles = 5000;
  p.min_particles = 300;
  p.neff_floor_fraction = 0.0;  // the plain likelihood, no tempering floor
  ASSERT_TRUE(p.adaptive());
  ASSERT_EQ(p.validate(), "");
  ParticleFilter pf(p);
  pf.initialiseUniform(InitRegion());  // 4 m cube, yaw range pi: thousands of bins
  pf.resample();
  EXPECT_EQ(pf.size(), 5000);
  // Weight concentrated near one pose (a few centimetres): a handful of bins.
  std::vector<double> ll(pf.size());
  for (int i = 0; i < pf.size(); ++i) {
    const Particle& q = pf.particles()[i];
    const double d2 = std::pow(q.x_m - 0.5, 2) + std::pow(q.y_m - 0.5, 2) +
                      std::pow(q.z_m - 0.5, 2) + std::pow(q.yaw_rad - 0.3, 2);
    ll[i] = -d2 / (2 * 0.05 * 0.05);
  }
  ASSERT_TRUE(pf.updateWeights(ll, 1));
  pf.resample();
  EXPECT_EQ(pf.size(), 300);
  pf.initialiseUniform(InitRegion());
  EXPECT_EQ(pf.size(), 5000);
  // Fixed count (min_particles 0): resampling keeps the count.
  ParticleFilterParams fixed;
  fixed.num_particles = 500;
  ParticleFilter f(fixed);
  f.initialiseUniform(InitRegion());
  ASSERT_TRUE(f.updateWeights(std::vector<double>(500, -1.0), 10));
  f.resample();
  EXPECT_EQ(f.size(), 500);
  ParticleFilterParams bad = p;
  bad.min_particles = 6000;
  EXPECT_NE(bad.validate().find("min_particles"), std::string::npos);
}

// The lost detector's redraw keeps the best particles and can grow the set.
TEST(ParticleFilterTest, ReplaceWorstKeepsTheBestAndCanGrow) {
  ParticleFilterParams p;
  p.num_particles = 10;
  ParticleFilter pf(p);
  pf.initialiseUniform(InitRegion());
  std::vector<double> ll = descendingScores(10, 1.0);  // particle 0 best
  const Particle best0 = pf.particles()[0], best1 = pf.particles()[1];
  Particle fresh;
  fresh.x_m = 42.0;
  pf.replaceWorst(ll, std::vector<Particle>(18, fresh), 2);
  ASSERT_EQ(pf.size(), 20);
  int kept = 0, added = 0;
  for (const Particle& q : pf.particles()) {
    kept += (q.x_m == best0.x_m || q.x_m == best1.x_m) ? 1 : 0;
    added += q.x_m == 42.0 ? 1 : 0;
  }
  EXPECT_EQ(kept, 2);
  EXPECT_EQ(added, 18);
  double total = 0.0;
  for (double w : pf.weights()) total += w;
  EXPECT_NEAR(total, 1.0, 1e-12);
}

// The local stage's draws (a wide start's, a redraw's): the centres are the pool's best in score
// order, and the draws go round them in turn with the given spread.
TEST(ParticleFilterTest, LocalDrawsGoRoundTheBestCandidatesInTurn) {
  ParticleFilter pf(oneGroup(10));
  std::vector<std::pair<double, Particle>> pool;
  for (int i = 0; i < 4; ++i) pool.emplace_back(-double(i), Particle{10.0 * (3 - i), 0, 0, 0});
  pf.setCandidatePool(pool);  // the best at x = 30, then 20; 10 and 0 left out
  pf.selectCandidateCentres(2, true);
  EXPECT_EQ(pf.scoredCandidates(), 0);  // the pool was cleared
  const int n = 4000;
  pf.drawCandidatesAroundCentres(0.25, 0.2, n);
  const std::vector<Particle>& drawn = pf.pendingCandidates();
  ASSERT_EQ(static_cast<int>(drawn.size()), n);
  double sum[2] = {0.0, 0.0}, sq[2] = {0.0, 0.0}, yaw_sq = 0.0;
  for (int k = 0; k < n; ++k) {
    const double dx = drawn[k].x_m - (k % 2 == 0 ? 30.0 : 20.0);
    ASSERT_LT(std::abs(dx), 8 * 0.25) << "draw " << k << " is not around its centre";
    sum[k % 2] += dx;
    sq[k % 2] += dx * dx;
    yaw_sq += drawn[k].yaw_rad * drawn[k].yaw_rad;
  }
  for (int c = 0; c < 2; ++c) {
    const double m = sum[c] / (n / 2), sd = std::sqrt(sq[c] / (n / 2) - m * m);
    EXPECT_LT(std::abs(m), 5 * 0.25 / std::sqrt(n / 2.0)) << "centre " << c;
    EXPECT_NEAR(sd, 0.25, 0.025) << "centre " << c;
  }
  EXPECT_NEAR(std::sqrt(yaw_sq / n), 0.2, 0.02);
}

// Parameters change in place: the particles and weights stay, the next prediction uses the new
// noise, a count outside the new range is resampled from the same set.
TEST(ParticleFilterTest, SetParamsKeepsTheParticlesAndTheirWeights) {
  ParticleFilterParams p;
  p.num_particles = 500;
  ParticleFilter pf(p);
  pf.initialiseUniform(InitRegion());
  std::vector<double> ll = descendingScores(500, 0.01);
  ASSERT_TRUE(pf.updateWeights(ll, 1));
  const std::vector<Particle> before = pf.particles();
  const std::vector<double> weights = pf.weights();

  ParticleFilterParams q = p;
  q.sigma_translation_m = 0.5;
  q.sigma_yaw_rad = 0.0;
  q.alpha_fast = 0.2;
  q.temperature = 3.0;
  pf.setParams(q);
  ASSERT_EQ(pf.size(), 500);
  for (int i = 0; i < 500; ++i) {
    ASSERT_EQ(pf.particles()[i].x_m, before[i].x_m);
    ASSERT_EQ(pf.weights()[i], weights[i]);
  }
  EXPECT_EQ(pf.params().temperature, 3.0);
  pf.predict(PlanarDelta());
  double sum_sq = 0.0, yaw_moved = 0.0;
  for (int i = 0; i < 500; ++i) {
    sum_sq += std::pow(pf.particles()[i].x_m - before[i].x_m, 2);
    yaw_moved += std::abs(pf.particles()[i].yaw_rad - before[i].yaw_rad);
  }
  EXPECT_NEAR(std::sqrt(sum_sq / 500), 0.5, 0.05) << "the new process noise is not used";
  EXPECT_EQ(yaw_moved, 0.0);

  // A smaller fixed count: resampled from the same set.
  const std::vector<Particle> moved = pf.particles();
  q.num_particles = 200;
  q.resample_groups = 4;
  pf.setParams(q);
  ASSERT_EQ(pf.size(), 200);
  for (const Particle& a : pf.particles()) {
    bool found = false;
    for (const Particle& b : moved) found = found || (a.x_m == b.x_m && a.yaw_rad == b.yaw_rad);
    ASSERT_TRUE(found) << "a particle not from the previous set";
  }
  EXPECT_NEAR(pf.weights()[0], 1.0 / 200, 1e-15);

  // Invalid parameters: refused, nothing changes.
  ParticleFilterParams bad = q;
  bad.alpha_slow = 0.5;
  bad.alpha_fast = 0.1;
  EXPECT_THROW(pf.setParams(bad), std::invalid_argument);
  EXPECT_EQ(pf.params().alpha_fast, q.alpha_fast);
  EXPECT_EQ(pf.size(), 200);
}

}  // namespace
}  // namespace gmm_mcl
