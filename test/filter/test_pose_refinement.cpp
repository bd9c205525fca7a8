// Pose refinement (gmm_mcl/filter/pose_refinement.h): from starts a few centimetres and
// degrees off, the EM / Gauss-Newton maximisation of the frame likelihood lands closer to the
// true pose than the start (well below the particle spacing), raises the likelihood, and
// rejects a correction larger than its bound.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "gmm_mcl/filter/pose_refinement.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

double distance(const Particle& a, const Particle& b) {
  return std::sqrt(std::pow(a.x_m - b.x_m, 2) + std::pow(a.y_m - b.y_m, 2) +
                   std::pow(a.z_m - b.z_m, 2));
}

// The reference pose seen by the 7-Scenes camera at stride 8, and that pose's attitude.
class PoseRefinementTest : public ::testing::Test {
 protected:
  void SetUp() override { rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw); }

  const test::SyntheticWorld& w = test::world();
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), test::frameParams(8));
  const Particle truth = poseToParticle(T_map_base);
  double roll = 0.0, pitch = 0.0, yaw = 0.0;
};

TEST_F(PoseRefinementTest, ConvergesToTheTruePoseFromNearbyStarts) {
  const MeasurementParams mp;
  const RefinementParams rp;
  std::mt19937_64 rng(21);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst_start = 0.0, worst_end = 0.0, worst_yaw_end = 0.0;
  for (int k = 0; k < 12; ++k) {
    const Particle start = test::perturbed(truth, n01, rng);
    const RefinementResult r =
        refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, mp, rp);
    ASSERT_TRUE(r.refined) << r.why;
    EXPECT_GT(r.loglik_refined, r.loglik_start);
    worst_start = std::max(worst_start, distance(start, truth));
    worst_end = std::max(worst_end, distance(r.pose, truth));
    worst_yaw_end = std::max(worst_yaw_end, std::abs(wrapAngle(r.pose.yaw_rad - truth.yaw_rad)));
    EXPECT_LT(distance(r.pose, truth), 0.5 * distance(start, truth) + 0.002) << "start " << k;
  }
  std::printf(
      "[ measured ] 12 starts up to %.1f cm off: refined to within %.2f cm and %.3f deg "
      "of the true pose\n",
      100.0 * worst_start, 100.0 * worst_end, worst_yaw_end * 180.0 / M_PI);
  EXPECT_LT(worst_end, 0.01);
  EXPECT_LT(worst_yaw_end, 0.005);
}

TEST_F(PoseRefinementTest, CorrectsTheAttitudeInputsTilt) {
  // Roll and pitch given 0.5 deg off (an IMU's noise): the 6-DoF refinement finds the true
  // tilt and position; with roll and pitch held (prior sigma 0) the position absorbs the tilt.
  const double off = 0.5 * M_PI / 180.0;
  Particle start = truth;
  start.x_m += 0.02;
  start.y_m -= 0.015;
  RefinementParams six;
  RefinementParams four;
  four.attitude_prior_sigma_rad = 0.0;
  const RefinementResult a = refinePose(w.map.packed(), frame, start, roll + off, pitch - off,
                                        w.T_base_cam, MeasurementParams(), six);
  const RefinementResult b = refinePose(w.map.packed(), frame, start, roll + off, pitch - off,
                                        w.T_base_cam, MeasurementParams(), four);
  ASSERT_TRUE(a.refined) << a.why;
  ASSERT_TRUE(b.refined) << b.why;
  std::printf(
      "[ measured ] roll and pitch given 0.5 deg off: 6-DoF refinement %.2f mm, roll "
      "%.3f deg, pitch %.3f deg from the truth; 4-DoF %.2f mm\n",
      1e3 * distance(a.pose, truth), (a.roll_rad - roll) * 180.0 / M_PI,
      (a.pitch_rad - pitch) * 180.0 / M_PI, 1e3 * distance(b.pose, truth));
  EXPECT_LT(std::abs(a.roll_rad - roll), 0.1 * M_PI / 180.0);
  EXPECT_LT(std::abs(a.pitch_rad - pitch), 0.1 * M_PI / 180.0);
  EXPECT_LT(distance(a.pose, truth), 0.005);
  EXPECT_LT(distance(a.pose, truth), distance(b.pose, truth));
  EXPECT_EQ(b.roll_rad, roll + off);  // held
}

TEST_F(PoseRefinementTest, RejectsACorrectionBeyondItsBound) {
  Particle start = truth;
  start.x_m += 0.08;
  RefinementParams rp;
  rp.max_correction_m = 0.03;
  const RefinementResult r =
      refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, MeasurementParams(), rp);
  EXPECT_FALSE(r.refined);
  EXPECT_NE(r.why.find("rejected"), std::string::npos) << r.why;
  EXPECT_EQ(r.pose.x_m, start.x_m);
  // An empty frame is not refined, and says so.
  const DepthFrame empty;
  const RefinementResult e = refinePose(w.map.packed(), empty, start, roll, pitch, w.T_base_cam,
                                        MeasurementParams(), RefinementParams());
  EXPECT_FALSE(e.refined);
  EXPECT_FALSE(e.why.empty());
  RefinementParams bad;
  bad.max_iterations = 0;
  EXPECT_NE(bad.validate().find("max_iterations"), std::string::npos);
}

}  // namespace
}  // namespace gmm_mcl
