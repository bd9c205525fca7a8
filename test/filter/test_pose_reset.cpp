// The pose-reset policy (a requested pose -> the Gaussian the filter restarts from) and the
// motion gate.
#include <gtest/gtest.h>

#include <cmath>

#include "gmm_mcl/filter/pose_reset.h"

namespace gmm_mcl {
namespace {

const Eigen::Vector4d kDefaultSigma(0.25, 0.25, 0.1, 0.2);

Eigen::Isometry3d planarPose(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0.0);
  T.linear() = rotationFromRpy(0, 0, yaw);
  return T;
}

PoseEstimate estimateAt(double z, double sigma_z) {
  PoseEstimate e;
  e.mean.z_m = z;
  e.covariance.diagonal().setConstant(1e-4);
  e.covariance(2, 2) = sigma_z * sigma_z;
  return e;
}

// rviz's 2D Pose Estimate: z = 0, no z variance, x/y 0.25 m^2 and yaw 0.0685 rad^2. The drone
// stays at its height.
TEST(PoseResetTest, PlanarToolKeepsTheCurrentHeight) {
  PoseResetRequest r;
  r.T_map_base = planarPose(1.0, 2.0, 0.5);
  r.covariance(0, 0) = r.covariance(1, 1) = 0.25;
  r.covariance(5, 5) = 0.0685;
  ASSERT_TRUE(isPlanarPose(r.T_map_base, r.covariance));
  r.planar = true;
  const PoseEstimate current = estimateAt(1.33, 0.02);
  const PoseReset out = resolvePoseReset(r, &current, 0.7, kDefaultSigma);
  ASSERT_TRUE(out.ok) << out.message;
  EXPECT_NEAR(out.pose.z_m, 1.33, 1e-12);
  EXPECT_NEAR(out.pose.x_m, 1.0, 1e-12);
  EXPECT_NEAR(out.pose.yaw_rad, 0.5, 1e-12);
  EXPECT_NEAR(out.sigma[0], 0.5, 1e-12);
  EXPECT_NEAR(out.sigma[2], 0.02, 1e-12);  // the estimate's
  EXPECT_NEAR(out.sigma[3], std::sqrt(0.0685), 1e-12);
  EXPECT_NE(out.message.find("height 1.33 m kept from the current estimate"), std::string::npos)
      << out.message;
  // Before any estimate: the fallback height.
  const PoseReset early = resolvePoseReset(r, nullptr, 0.7, kDefaultSigma);
  EXPECT_NEAR(early.pose.z_m, 0.7, 1e-12);
}

TEST(PoseResetTest, FullPosesAreNotPlanar) {
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Isometry3d T = planarPose(1, 2, 0.3);
  EXPECT_TRUE(isPlanarPose(T, cov));
  T.translation().z() = 1.2;
  EXPECT_FALSE(isPlanarPose(T, cov));  // a height
  T.translation().z() = 0.0;
  cov(2, 2) = 0.01;
  EXPECT_FALSE(isPlanarPose(T, cov));  // a z variance
  cov(2, 2) = 0.0;
  T.linear() = rotationFromRpy(0.1, 0, 0.3);
  EXPECT_FALSE(isPlanarPose(T, cov));  // a roll
  // Not planar: used as given.
  PoseResetRequest r;
  r.T_map_base = planarPose(1, 2, 0.3);
  r.T_map_base.translation().z() = 1.2;
  const PoseEstimate current = estimateAt(0.4, 0.02);
  const PoseReset out = resolvePoseReset(r, &current, 0.0, kDefaultSigma);
  EXPECT_NEAR(out.pose.z_m, 1.2, 1e-12);
  EXPECT_EQ(out.sigma, kDefaultSigma);  // no spread in the covariance: the defaults
}

TEST(PoseResetTest, StaleStampIsCarriedForwardByOdometry) {
  PoseResetRequest r;
  r.T_map_base = planarPose(1.0, 0.0, M_PI / 2);  // facing +y in the map
  r.T_map_base.translation().z() = 1.0;
  r.carry_forward = true;
  r.age_s = 1.5;
  r.T_odom_base_then = planarPose(5.0, 5.0, 0.0);
  r.T_odom_base_now = planarPose(5.5, 5.0, 0.0);  // 0.5 m forward since
  const PoseReset out = resolvePoseReset(r, nullptr, 0.0, kDefaultSigma);
  ASSERT_TRUE(out.ok);
  EXPECT_NEAR(out.pose.x_m, 1.0, 1e-12);
  EXPECT_NEAR(out.pose.y_m, 0.5, 1e-12);
  EXPECT_NE(out.message.find("carried forward 1.5 s"), std::string::npos) << out.message;
}

TEST(PoseResetTest, NonFinitePoseIsRefused) {
  PoseResetRequest r;
  r.T_map_base.translation().x() = NAN;
  const PoseReset out = resolvePoseReset(r, nullptr, 0.0, kDefaultSigma);
  EXPECT_FALSE(out.ok);
  EXPECT_NE(out.message.find("not finite"), std::string::npos);
}

TEST(MotionGateTest, UpdatesOnlyAfterMovingOrTurning) {
  MotionGate gate(0.2, 0.5);
  const Eigen::Isometry3d start = planarPose(0, 0, 0);
  EXPECT_TRUE(gate.shouldUpdate(true, start));  // the first frame
  gate.updated(true, start);
  EXPECT_FALSE(gate.shouldUpdate(true, planarPose(0.1, 0.1, 0.3)));   // hovering
  EXPECT_TRUE(gate.shouldUpdate(true, planarPose(0.15, 0.15, 0.0)));  // 0.21 m
  EXPECT_TRUE(gate.shouldUpdate(true, planarPose(0.0, 0.0, -0.6)));   // turned
  EXPECT_TRUE(gate.shouldUpdate(false, start));                       // no odometry
  gate.force();
  EXPECT_TRUE(gate.shouldUpdate(true, start));
  gate.updated(true, start);
  gate.setThresholds(0.0, 0.0);
  EXPECT_TRUE(gate.shouldUpdate(true, start));  // both 0: every frame
  gate.setThresholds(0.2, 0.0);
  EXPECT_TRUE(gate.shouldUpdate(true, planarPose(0.0, 0.0, 0.01)));  // any turn
  EXPECT_FALSE(gate.shouldUpdate(true, planarPose(0.1, 0.0, 0.0)));
}

}  // namespace
}  // namespace gmm_mcl
