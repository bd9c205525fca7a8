// The KL divergence of the Sensitivity Analysis: closed form against known values and a
// Monte-Carlo estimate, yaw wrapping, and the Gaussian of a filter estimate.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gmm_mcl/experiments/figures/gaussian_kl.h"

namespace gmm_mcl {
namespace figures {
namespace {

constexpr double kClosedFormTol = 1e-12;
// Monte-Carlo estimate of E_p[ln p - ln q] with 400k samples: standard error about 2e-3 here.
constexpr int kMonteCarloSamples = 400000;
constexpr double kMonteCarloTol = 0.01;

TEST(GaussianKlTest, IdenticalGaussiansHaveZeroDivergence) {
  StateGaussian g;
  g.mean << 1.0, 2.0, 0.5, 0.3;
  g.cov << 0.04, 0.01, 0.0, 0.002, 0.01, 0.09, 0.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.002, 0.0, 0.0, 0.01;
  EXPECT_NEAR(stateKl(g, g, 0.0), 0.0, kClosedFormTol);
}

TEST(GaussianKlTest, UnivariateClosedForm) {
  // KL(N(m1, s1^2) || N(m2, s2^2)) = ln(s2/s1) + (s1^2 + (m1 - m2)^2) / (2 s2^2) - 1/2.
  const double m1 = 0.3, s1 = 0.2, m2 = -0.1, s2 = 0.5;
  Eigen::VectorXd mp(1), mq(1);
  Eigen::MatrixXd sp(1, 1), sq(1, 1);
  mp << m1;
  mq << m2;
  sp << s1 * s1;
  sq << s2 * s2;
  const double expected =
      std::log(s2 / s1) + (s1 * s1 + (m1 - m2) * (m1 - m2)) / (2 * s2 * s2) - 0.5;
  EXPECT_NEAR(gaussianKl(mp, sp, mq, sq), expected, kClosedFormTol);
  // Not symmetric.
  EXPECT_GT(std::abs(gaussianKl(mq, sq, mp, sp) - expected), 0.1);
}

TEST(GaussianKlTest, MatchesMonteCarloIn4D) {
  Eigen::Vector4d mp(0.0, 0.1, -0.2, 0.05), mq(0.05, 0.0, -0.1, 0.0);
  Eigen::Matrix4d A, B;
  A << 0.2, 0.05, 0.0, 0.01, 0.0, 0.3, 0.02, 0.0, 0.0, 0.0, 0.1, 0.03, 0.0, 0.0, 0.0, 0.15;
  B << 0.25, 0.0, 0.03, 0.0, 0.04, 0.2, 0.0, 0.01, 0.0, 0.0, 0.12, 0.0, 0.02, 0.0, 0.0, 0.1;
  const Eigen::Matrix4d Sp = A * A.transpose(), Sq = B * B.transpose();
  const double kl = gaussianKl(mp, Sp, mq, Sq);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Matrix4d Lp = Sp.llt().matrixL();
  const Eigen::Matrix4d Pp = Sp.inverse(), Pq = Sq.inverse();
  const double c = 0.5 * (std::log(Sq.determinant()) - std::log(Sp.determinant()));
  double sum = 0.0;
  for (int i = 0; i < kMonteCarloSamples; ++i) {
    const Eigen::Vector4d x = mp + Lp * Eigen::Vector4d(g(rng), g(rng), g(rng), g(rng));
    const Eigen::Vector4d dp = x - mp, dq = x - mq;
    sum += c - 0.5 * dp.dot(Pp * dp) + 0.5 * dq.dot(Pq * dq);
  }
  std::printf("[ measured ] closed form %.5f, Monte Carlo %.5f\n", kl, sum / kMonteCarloSamples);
  EXPECT_NEAR(kl, sum / kMonteCarloSamples, kMonteCarloTol);
}

TEST(GaussianKlTest, YawDifferenceIsWrapped) {
  StateGaussian p, q;
  p.cov = q.cov = Eigen::Vector4d(0.01, 0.01, 0.01, 0.01).asDiagonal();
  p.mean << 0, 0, 0, M_PI - 0.05;
  q.mean << 0, 0, 0, -M_PI + 0.05;  // 0.1 rad apart across the wrap
  // 0.5 * 0.1^2 / 0.01 = 0.5.
  EXPECT_NEAR(stateKl(p, q, 0.0), 0.5, 1e-9);
}

TEST(GaussianKlTest, SingularCovarianceIsInfiniteUnlessRegularised) {
  StateGaussian p, q;
  p.cov = Eigen::Matrix4d::Identity() * 0.01;
  q.cov = Eigen::Matrix4d::Zero();  // every particle identical
  EXPECT_TRUE(std::isinf(stateKl(p, q, 0.0)));
  EXPECT_TRUE(std::isfinite(stateKl(p, q, 1e-8)));
}

TEST(GaussianKlTest, StateGaussianTakesTheXyzYawBlock) {
  PoseEstimate e;
  e.mean = Particle{1.0, 2.0, 3.0, 0.4};
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) e.covariance(r, c) = 10 * r + c;
  }
  const StateGaussian g = stateGaussian(e);
  EXPECT_EQ(g.mean, Eigen::Vector4d(1.0, 2.0, 3.0, 0.4));
  EXPECT_EQ(g.cov(0, 3), 5.0);   // x-yaw
  EXPECT_EQ(g.cov(3, 3), 55.0);  // yaw-yaw
  EXPECT_EQ(g.cov(2, 1), 21.0);  // z-y
}

}  // namespace
}  // namespace figures
}  // namespace gmm_mcl
