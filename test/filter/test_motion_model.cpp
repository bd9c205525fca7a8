// The constant-velocity motion model of steps without odometry (motion_model.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "gmm_mcl/filter/motion_model.h"

namespace gmm_mcl {
namespace {

constexpr double kDt = 1.0 / 30.0;

// A base moving forward at speed_m_s and turning at yaw_rate_rad_s (in its own frame), sampled
// every kDt from (1, 2, 0.5), heading 0.3 rad.
Particle turningPose(int k, double speed_m_s, double yaw_rate_rad_s, double climb_m_s) {
  Particle p{1.0, 2.0, 0.5, 0.3};
  for (int i = 0; i < k; ++i) {
    p.x_m += speed_m_s * kDt * std::cos(p.yaw_rad);
    p.y_m += speed_m_s * kDt * std::sin(p.yaw_rad);
    p.z_m += climb_m_s * kDt;
    p.yaw_rad = wrapAngle(p.yaw_rad + yaw_rate_rad_s * kDt);
  }
  return p;
}

TEST(MotionModelTest, ExtrapolatesTheSmoothedBodyVelocity) {
  ConstantVelocityModel model;
  EXPECT_FALSE(model.hasVelocity());
  for (int k = 0; k < 30; ++k) model.observe(10.0 + k * kDt, turningPose(k, 0.6, 0.4, 0.1));
  ASSERT_TRUE(model.hasVelocity());
  // Body frame: forward, no sideways motion (to first order in the turn), the climb (learned
  // over its time constant: 29 samples, 29 kDt), the turn.
  const Eigen::Vector4d& v = model.velocity();
  const double climb = 0.1 * (1.0 - std::exp(-29 * kDt / 0.5));
  EXPECT_NEAR(v[0], 0.6, 1e-3);
  EXPECT_NEAR(v[1], 0.0, 0.01);
  EXPECT_NEAR(v[2], climb, 1e-9);
  EXPECT_NEAR(v[3], 0.4, 1e-6);
  const PlanarDelta d = model.predict(0.1, 0.02, 0.01);
  EXPECT_NEAR(d.translation_m.x(), 0.06, 1e-4);
  EXPECT_NEAR(d.translation_m.z(), 0.1 * climb, 1e-9);
  EXPECT_NEAR(d.yaw_rad, 0.04, 1e-6);
}

TEST(MotionModelTest, SmoothsFromZeroAtTheFirstSample) {
  ConstantVelocityParams p;
  p.velocity_smoothing = 0.5;
  ConstantVelocityModel model(p);
  model.observe(0.0, Particle{0, 0, 0, 0});
  EXPECT_FALSE(model.hasVelocity());  // one estimate: no velocity yet
  model.observe(0.1, Particle{0.1, 0, 0, 0});
  ASSERT_TRUE(model.hasVelocity());
  EXPECT_NEAR(model.velocity()[0], 0.5, 1e-9);  // half of the 1 m/s sample
  model.observe(0.2, Particle{0.2, 0, 0, 0});
  EXPECT_NEAR(model.velocity()[0], 0.75, 1e-9);
}

// The vertical speed learns over a time constant: after the same time the same fraction of a
// climb, whatever the frame rate; the other axes by velocity_smoothing per sample.
TEST(MotionModelTest, TheVerticalSpeedLearnsOverItsTimeConstantAtAnyRate) {
  for (const double tau : {0.5, 0.0}) {
    ConstantVelocityParams p;
    p.vertical_time_constant_s = tau;
    double climb[2];
    for (const int hz : {30, 10}) {
      ConstantVelocityModel model(p);
      const int samples = hz / 2;  // 0.5 s
      for (int k = 0; k <= samples; ++k) {
        const double t = static_cast<double>(k) / hz;
        model.observe(t, Particle{0.5 * t, 0.0, 1.0 + 0.3 * t, 0.0});
      }
      climb[hz == 30 ? 0 : 1] = model.velocity()[2];
      EXPECT_NEAR(model.velocity()[0], 0.5 * (1.0 - std::pow(0.5, samples)), 1e-9) << hz << " Hz";
    }
    if (tau > 0.0) {
      EXPECT_NEAR(climb[0], 0.3 * (1.0 - std::exp(-1.0)), 1e-9);
      EXPECT_NEAR(climb[1], climb[0], 1e-9);
    } else {  // per sample, as the other axes
      EXPECT_NEAR(climb[0], 0.3 * (1.0 - std::pow(0.5, 15)), 1e-9);
      EXPECT_NEAR(climb[1], 0.3 * (1.0 - std::pow(0.5, 5)), 1e-9);
    }
  }
}

// The loop that the time constant damps: each step the set moves by the predicted climb, the
// frame pulls it back by a small fraction of its height error (a view that pins the height
// weakly), resampling jitters it by millimetres, and the model learns from the set's mean. The
// camera keeps its height. A per-frame weight on the vertical speed reads the set's own slide as
// a climb and swings the set far off (the Replica runs at 30 Hz: 1.1-1.3 m); the time constant
// keeps it near.
double worstHeightInLoop(double vertical_time_constant_s, unsigned seed) {
  ConstantVelocityParams p;
  p.vertical_time_constant_s = vertical_time_constant_s;
  ConstantVelocityModel model(p);
  std::mt19937 rng(seed);
  std::normal_distribution<double> jitter(0.0, 0.005);
  double z = 0.0, worst = 0.0;
  for (int k = 0; k < 600; ++k) {  // 20 s at 30 Hz
    z += model.predict(kDt, 0.02, 0.01).translation_m.z();
    z += -0.02 * z + jitter(rng);
    model.observe(k * kDt, Particle{0.3 * k * kDt, 0.0, z, 0.0});
    worst = std::max(worst, std::abs(z));
  }
  return worst;
}

TEST(MotionModelTest, TheTimeConstantDampsAWeaklyPinnedHeight) {
  double per_frame = 0.0, time_constant = 0.0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    per_frame += worstHeightInLoop(0.0, seed) / 10;
    time_constant += worstHeightInLoop(0.5, seed) / 10;
  }
  std::printf("mean worst height error over 10 seeds: %.3f m per frame, %.3f m with 0.5 s\n",
              per_frame, time_constant);
  EXPECT_LT(time_constant, 0.6 * per_frame)
      << "mean worst height error: " << time_constant << " m with the time constant, " << per_frame
      << " m per frame";
}

TEST(MotionModelTest, NoiseGrowsWithTheTimeSinceTheLastStep) {
  ConstantVelocityParams p;
  p.sigma_speed_m_s = 0.3;
  p.sigma_yaw_rate_rad_s = 0.5;
  ConstantVelocityModel model(p);
  // No velocity yet: zero motion, twice the growth.
  PlanarDelta d = model.predict(0.1, 0.02, 0.01);
  EXPECT_EQ(d.translation_m.norm(), 0.0);
  EXPECT_NEAR(d.sigma_translation_m, 0.02 + 2 * 0.3 * 0.1, 1e-12);
  EXPECT_NEAR(d.sigma_yaw_rad, 0.01 + 2 * 0.5 * 0.1, 1e-12);
  for (int k = 0; k < 5; ++k) model.observe(k * kDt, turningPose(k, 0.3, 0.0, 0.0));
  ASSERT_TRUE(model.hasVelocity());
  const PlanarDelta d30 = model.predict(1.0 / 30, 0.02, 0.01);
  const PlanarDelta d10 = model.predict(1.0 / 10, 0.02, 0.01);
  EXPECT_NEAR(d30.sigma_translation_m, 0.02 + 0.3 / 30, 1e-12);
  EXPECT_NEAR(d10.sigma_translation_m, 0.02 + 0.3 / 10, 1e-12);
  EXPECT_NEAR(d10.sigma_yaw_rad, 0.01 + 0.5 / 10, 1e-12);
  EXPECT_NEAR(d10.translation_m.x(), 3.0 * d30.translation_m.x(), 1e-12);
  // dt 0 (the first step) or negative: the base noise only.
  const PlanarDelta d0 = model.predict(-1.0, 0.02, 0.01);
  EXPECT_EQ(d0.sigma_translation_m, 0.02);
  EXPECT_EQ(d0.translation_m.norm(), 0.0);
}

TEST(MotionModelTest, TheGyroGivesTheYawChangeWithItsOwnNoise) {
  ConstantVelocityParams p;
  p.sigma_yaw_rate_rad_s = 0.5;
  p.gyro_sigma_yaw_rate_rad_s = 0.02;
  p.world_velocity = false;  // below: the body-frame translation of the model, unchanged
  ConstantVelocityModel model(p);
  for (int k = 0; k < 5; ++k) model.observe(k * kDt, turningPose(k, 0.3, 0.4, 0.0));
  ASSERT_TRUE(model.hasVelocity());
  const double gyro = -0.25;  // turning the other way since the last step
  const PlanarDelta d = model.predict(0.1, 0.02, 0.01, &gyro);
  EXPECT_EQ(d.yaw_rad, -0.25);
  EXPECT_NEAR(d.sigma_yaw_rad, 0.01 + 0.02 * 0.1, 1e-12);
  const PlanarDelta cv = model.predict(0.1, 0.02, 0.01);  // the translation is the model's
  EXPECT_EQ(d.translation_m, cv.translation_m);
  EXPECT_NEAR(cv.yaw_rad, 0.1 * model.velocity()[3], 1e-12);
  // Off, or not a number: the model's own yaw rate.
  const double nan = std::nan("");
  EXPECT_EQ(model.predict(0.1, 0.02, 0.01, &nan).yaw_rad, cv.yaw_rad);
  p.use_gyro = false;
  model.setParams(p);
  EXPECT_EQ(model.predict(0.1, 0.02, 0.01, &gyro).yaw_rad, cv.yaw_rad);
}

// A drone flying straight along the map's x axis at 0.5 m/s while it yaws at 1 rad/s: with the
// gyro's turn, the map-frame velocity predicts the flight (in the last estimate's body frame);
// the body-frame velocity would swing with the yaw.
TEST(MotionModelTest, AGyroTurnedStepMovesWithTheMapFrameVelocity) {
  ConstantVelocityParams p;
  p.velocity_smoothing = 1.0;
  ConstantVelocityModel model(p);
  double yaw = 0.0;
  for (int k = 0; k < 10; ++k) {
    yaw = 1.0 * k * kDt;
    model.observe(k * kDt, Particle{0.5 * k * kDt, 1.0, 0.5, yaw});
  }
  const double gyro = 1.0 * 0.1;
  const PlanarDelta d = model.predict(0.1, 0.02, 0.01, &gyro);
  // The body-frame delta back into the map frame at the last estimate's yaw.
  const double c = std::cos(yaw), s = std::sin(yaw);
  EXPECT_NEAR(c * d.translation_m.x() - s * d.translation_m.y(), 0.05, 1e-9);
  EXPECT_NEAR(s * d.translation_m.x() + c * d.translation_m.y(), 0.0, 1e-9);
  EXPECT_EQ(d.yaw_rad, gyro);
}

TEST(MotionModelTest, ForgetsTheVelocityOnTimeJumpsGapsAndJumps) {
  ConstantVelocityParams p;
  p.max_gap_s = 0.5;
  p.max_speed_m_s = 3.0;
  const auto moving = [&] {
    auto model = ConstantVelocityModel(p);
    for (int k = 0; k < 5; ++k) model.observe(5.0 + k * kDt, turningPose(k, 0.5, 0.0, 0.0));
    EXPECT_TRUE(model.hasVelocity());
    return model;
  };
  // Time going back between two estimates.
  ConstantVelocityModel back = moving();
  back.observe(1.0, turningPose(6, 0.5, 0.0, 0.0));
  EXPECT_FALSE(back.hasVelocity());
  EXPECT_EQ(back.velocity().norm(), 0.0);
  // A gap between two estimates longer than max_gap_s.
  ConstantVelocityModel gap = moving();
  gap.observe(6.0, turningPose(6, 0.5, 0.0, 0.0));
  EXPECT_FALSE(gap.hasVelocity());
  // A prediction over a gap longer than max_gap_s: no motion, the unknown-velocity noise.
  ConstantVelocityModel long_step = moving();
  const PlanarDelta d = long_step.predict(0.8, 0.02, 0.01);
  EXPECT_EQ(d.translation_m.norm(), 0.0);
  EXPECT_NEAR(d.sigma_translation_m, 0.02 + 2 * p.sigma_speed_m_s * 0.8, 1e-12);
  EXPECT_FALSE(long_step.hasVelocity());
  // The estimate jumping (a recovery): faster than max_speed_m_s.
  ConstantVelocityModel jump = moving();
  jump.observe(5.0 + 5 * kDt, Particle{4.0, 2.0, 0.5, 0.3});
  EXPECT_FALSE(jump.hasVelocity());
  // reset(): the next estimate gives no sample.
  ConstantVelocityModel reset = moving();
  reset.reset();
  reset.observe(5.0 + 5 * kDt, turningPose(5, 0.5, 0.0, 0.0));
  EXPECT_FALSE(reset.hasVelocity());
}

TEST(MotionModelTest, ParametersAreValidated) {
  EXPECT_EQ(ConstantVelocityParams().validate(), "");
  ConstantVelocityParams p;
  p.velocity_smoothing = 0.0;
  p.sigma_speed_m_s = -1.0;
  p.max_gap_s = 0.0;
  p.vertical_time_constant_s = -0.1;
  const std::string err = p.validate();
  EXPECT_NE(err.find("cv_velocity_smoothing"), std::string::npos) << err;
  EXPECT_NE(err.find("cv_sigma_speed_m_s"), std::string::npos) << err;
  EXPECT_NE(err.find("cv_max_gap_s"), std::string::npos) << err;
  EXPECT_NE(err.find("cv_vertical_time_constant_s"), std::string::npos) << err;
}

}  // namespace
}  // namespace gmm_mcl
