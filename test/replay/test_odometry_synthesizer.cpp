// The protocol's odometry and attitude noise: seeded, per-frame sigmas as DESIGN.md says,
// variance scaled by the step length in frames, odometry frame gravity-aligned at the start.
#include <gtest/gtest.h>

#include <cmath>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"

namespace gmm_mcl {
namespace {

constexpr int kSteps = 20000;
constexpr double kSigmaRelTol = 0.05;  // sample sigma of 20000 draws: about 0.5% standard error

Eigen::Isometry3d tilted(double x, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(0.05, -0.08, yaw);
  T.translation() = Eigen::Vector3d(x, 2.0, 1.0);
  return T;
}

// Sample sigmas of the odometry increments (x in the previous odometry pose's frame, yaw) for
// a base standing still.
void incrementSigmas(double frames, double* sigma_x, double* sigma_yaw) {
  OdometrySynthesizer odo(ProtocolNoise(), 3);
  const Eigen::Isometry3d truth = tilted(1.0, 0.4);
  Eigen::Isometry3d prev = odo.next(truth);
  double sx = 0, sy = 0;
  for (int i = 0; i < kSteps; ++i) {
    const Eigen::Isometry3d cur = odo.next(truth, frames);
    const Eigen::Isometry3d d = prev.inverse() * cur;
    sx += d.translation().x() * d.translation().x();
    const double dyaw = std::atan2(d.linear()(1, 0), d.linear()(0, 0));
    sy += dyaw * dyaw;
    prev = cur;
  }
  *sigma_x = std::sqrt(sx / kSteps);
  *sigma_yaw = std::sqrt(sy / kSteps);
}

TEST(OdometrySynthesizerTest, PerFrameSigmasAndScaling) {
  double sx, sy;
  incrementSigmas(1.0, &sx, &sy);
  EXPECT_NEAR(sx, 0.005, 0.005 * kSigmaRelTol);
  EXPECT_NEAR(sy, 0.002, 0.002 * kSigmaRelTol);
  // A step of 4 frames (e.g. a 7.5 Hz pose stream): variance 4x, sigma 2x.
  incrementSigmas(4.0, &sx, &sy);
  EXPECT_NEAR(sx, 0.010, 0.010 * kSigmaRelTol);
  EXPECT_NEAR(sy, 0.004, 0.004 * kSigmaRelTol);
}

TEST(OdometrySynthesizerTest, StartsGravityAlignedAndFollowsTheMotion) {
  ProtocolNoise none;
  none.odom_sigma_m = none.odom_sigma_yaw_rad = none.attitude_sigma_rad = 0.0;
  OdometrySynthesizer odo(none, 1);
  const Eigen::Isometry3d a = tilted(1.0, 0.4), b = tilted(1.3, 0.7);
  const Eigen::Isometry3d oa = odo.next(a), ob = odo.next(b);
  double r, p, y;
  rpyFromRotation(oa.linear(), &r, &p, &y);
  EXPECT_NEAR(r, 0.05, 1e-12);
  EXPECT_NEAR(p, -0.08, 1e-12);
  EXPECT_NEAR(y, 0.0, 1e-12);
  EXPECT_LT(oa.translation().norm(), 1e-12);
  // Noise-free: the odometry motion equals the true motion.
  const Eigen::Isometry3d d_true = a.inverse() * b, d_odo = oa.inverse() * ob;
  EXPECT_LT((d_true.matrix() - d_odo.matrix()).norm(), 1e-12);
  odo.attitude(b, &r, &p);
  EXPECT_NEAR(r, 0.05, 1e-12);
  EXPECT_NEAR(p, -0.08, 1e-12);
}

TEST(OdometrySynthesizerTest, AttitudeNoiseAndSeeding) {
  OdometrySynthesizer a(ProtocolNoise(), 7), b(ProtocolNoise(), 7), c(ProtocolNoise(), 8);
  const Eigen::Isometry3d T = tilted(0.0, 1.0);
  double s = 0;
  bool differs = false;
  for (int i = 0; i < kSteps; ++i) {
    double ra, pa, rb, pb, rc, pc;
    a.attitude(T, &ra, &pa);
    b.attitude(T, &rb, &pb);
    c.attitude(T, &rc, &pc);
    ASSERT_EQ(ra, rb);
    ASSERT_EQ(pa, pb);
    differs = differs || ra != rc;
    s += (ra - 0.05) * (ra - 0.05);
  }
  EXPECT_TRUE(differs);
  const double sigma = 0.5 * M_PI / 180.0;
  EXPECT_NEAR(std::sqrt(s / kSteps), sigma, sigma * kSigmaRelTol);
}

// The gyro's rate samples: the true rate plus a constant bias per axis and trial (of the
// configured spread) and white noise of density / sqrt(dt); seeded.
TEST(OdometrySynthesizerTest, GyroRatesCarryABiasAndWhiteNoise) {
  ProtocolNoise noise;
  const double dt = 1.0 / 30.0, sigma = noise.gyro_noise_density_rad_s_sqrt_hz / std::sqrt(dt);
  const Eigen::Vector3d truth(0.3, -0.1, 1.2);
  Eigen::Vector3d bias_sum = Eigen::Vector3d::Zero();
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    OdometrySynthesizer a(noise, seed), b(noise, seed);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
    for (int i = 0; i < kSteps; ++i) {
      const Eigen::Vector3d r = a.gyroRate(truth, dt);
      ASSERT_EQ(r, b.gyroRate(truth, dt));
      sum += r - truth;
      sq += (r - truth).cwiseProduct(r - truth);
    }
    const Eigen::Vector3d mean = sum / kSteps;
    for (int k = 0; k < 3; ++k) {
      const double sd = std::sqrt(sq[k] / kSteps - mean[k] * mean[k]);
      EXPECT_NEAR(sd, sigma, sigma * kSigmaRelTol) << "seed " << seed << " axis " << k;
      EXPECT_LT(std::abs(mean[k]), 5.0 * noise.gyro_bias_sigma_rad_s);
    }
    bias_sum += mean.cwiseAbs();
    // dt 0 (no interval): the bias alone.
    EXPECT_LT((a.gyroRate(truth, 0.0) - truth - mean).norm(), 5.0 * sigma / std::sqrt(kSteps));
  }
  EXPECT_GT(bias_sum.sum(), 0.1 * noise.gyro_bias_sigma_rad_s) << "no bias at all";
}

}  // namespace
}  // namespace gmm_mcl
