// Pose refinement (gmm_mcl/filter/pose_refinement.h): from starts a few centimetres and
// degrees off, the EM / Gauss-Newton maximisation of the frame likelihood lands closer to the
// true pose than the start (well below the particle spacing), raises the likelihood, and
// rejects a correction larger than its bound.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/measurement/depth_noise.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

using test::distance;

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

// The frame's depths times `scale`, each with the measurement model's depth noise N(0,
// sigma(z)^2) (a depth camera's, which the depth-scale estimate is corrected for).
DepthFrame noisyFrame(const DepthFrame& f, double scale, const MeasurementParams& mp,
                      uint64_t seed) {
  DepthFrame out = f;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (size_t i = 0; i < out.size(); ++i) {
    const double z = f.z_m[i];
    const double k = scale * (1.0 + depthNoiseSigma(mp.depth_noise, z) * n01(rng) / z);
    out.x_m[i] = static_cast<float>(k * f.x_m[i]);
    out.y_m[i] = static_cast<float>(k * f.y_m[i]);
    out.z_m[i] = static_cast<float>(k * z);
  }
  return out;
}

// Refines `frame` from `start` with the depth scale held at `scale` (the localizer's estimate).
RefinementResult refineAtScale(const DepthFrame& frame, double scale, const Particle& start,
                               double roll, double pitch, const RefinementParams& rp) {
  RefinementFrame rf = RefinementFrame::of(frame);
  rf.depth_scale = scale;
  return refinePose(test::world().map.packed(), rf, start, roll, pitch, test::world().T_base_cam,
                    MeasurementParams(), rp);
}

// A camera whose depths read 0.4% long (a RealSense-class scale error), with a depth camera's
// noise: the pose is refined with the scale given (the localizer's estimate), and the frame's
// estimate moves from it toward the truth (1 / 1.004); fed back frame after frame it settles
// within 0.1% of the truth, where the refined pose is as good as an exact camera's. With an
// exact camera the estimate stays within 0.1% of 1.
TEST_F(PoseRefinementTest, EstimatesTheDepthScale) {
  const MeasurementParams mp;
  RefinementParams off, on;
  on.estimate_depth_scale = true;
  const double truth_scale = 1.0 / 1.004;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst_first = 0.0, worst_settled = 0.0, worst_exact = 0.0;
  double sum_off = 0.0, sum_settled = 0.0, sum_exact = 0.0;
  const int starts = 4, frames = 8;
  for (int k = 0; k < starts; ++k) {
    const Particle start = test::perturbed(truth, n01, rng);
    // One frame with the scale at 1: the pose as without the estimate, the scale moved.
    const DepthFrame first = noisyFrame(frame, 1.004, mp, 100 + k);
    const RefinementResult a = refineAtScale(first, 1.0, start, roll, pitch, off);
    const RefinementResult b = refineAtScale(first, 1.0, start, roll, pitch, on);
    ASSERT_TRUE(a.refined && b.refined) << k << ": " << a.why << b.why;
    EXPECT_EQ(a.depth_scale, 1.0);
    EXPECT_EQ(b.pose.x_m, a.pose.x_m);
    EXPECT_GT(b.depth_scale_information, 0.0);
    worst_first = std::max(worst_first, std::abs(b.depth_scale / truth_scale - 1.0));
    sum_off += distance(a.pose, truth);
    // Frame after frame (each with its own noise), the estimate fed back.
    double scale = 1.0, exact_scale = 1.0;
    RefinementResult last, last_exact;
    for (int f = 0; f < frames; ++f) {
      last =
          refineAtScale(noisyFrame(frame, 1.004, mp, 1000 * k + f), scale, start, roll, pitch, on);
      last_exact = refineAtScale(noisyFrame(frame, 1.0, mp, 1000 * k + f), exact_scale, start, roll,
                                 pitch, on);
      ASSERT_TRUE(last.refined && last_exact.refined) << last.why << last_exact.why;
      scale = last.depth_scale;
      exact_scale = last_exact.depth_scale;
    }
    worst_settled = std::max(worst_settled, std::abs(scale / truth_scale - 1.0));
    worst_exact = std::max(worst_exact, std::abs(exact_scale - 1.0));
    sum_settled += distance(last.pose, truth);
    sum_exact += distance(last_exact.pose, truth);
  }
  std::printf(
      "[ measured ] depths 0.4%% long: one frame moves the scale from 1 to within %.3f%% of the "
      "truth, %d frames to within %.3f%%; pose error %.2f mm then, %.2f mm without the "
      "estimate; exact camera: scale within %.3f%% of 1, pose error %.2f mm\n",
      100.0 * worst_first, frames, 100.0 * worst_settled, 1000.0 * sum_settled / starts,
      1000.0 * sum_off / starts, 100.0 * worst_exact, 1000.0 * sum_exact / starts);
  EXPECT_LT(worst_first, 0.002);
  EXPECT_LT(worst_settled, 0.001);
  EXPECT_LT(worst_exact, 0.001);
  EXPECT_LT(sum_settled, 0.5 * sum_off);
  EXPECT_LT(sum_settled, 1.3 * sum_exact + 0.001 * starts);
  RefinementParams bad;
  bad.depth_scale_rate = 0.0;
  EXPECT_NE(bad.validate().find("depth_scale_rate"), std::string::npos);
}

// A rig of two cameras, the first reading 0.4% long and the second (turned 2.5 rad about the
// vertical) 1% short, each with a depth camera's noise: each camera's scale is estimated on its
// own, and fed back frame after frame both settle within 0.1% of their truths, the refined pose
// about as good as an exact rig's.
TEST_F(PoseRefinementTest, EstimatesEachCamerasDepthScale) {
  const MeasurementParams mp;
  RefinementParams on;
  on.estimate_depth_scale = true;
  const Eigen::Isometry3d T_base_cam2 = test::turnedCamera(2.5);
  const DepthFrame frame2 = test::renderFrame(T_map_base * T_base_cam2 * w.T_base_cam.inverse(),
                                              test::vgaCamera(), test::frameParams(8));
  ASSERT_GT(frame2.size(), 1000u);
  const double truth1 = 1.0 / 1.004, truth2 = 1.0 / 0.99;
  // Frames of both cameras with the given factors, refined with the scales s1, s2.
  auto refineRig = [&](double f1, double f2, double s1, double s2, const Particle& start,
                       uint64_t seed) {
    const DepthFrame a = noisyFrame(frame, f1, mp, seed);
    const DepthFrame b = noisyFrame(frame2, f2, mp, seed + 500000);
    RefinementFrame rf = RefinementFrame::of(a);
    rf.depth_scale = s1;
    RefinementView v;
    v.components = &w.map.packed();
    v.frame = RefinementFrame::of(b);
    v.frame.depth_scale = s2;
    v.T_base_cam = T_base_cam2;
    v.params = &mp;
    v.weight = static_cast<double>(a.size()) / b.size();
    return refinePose(w.map.packed(), rf, start, roll, pitch, w.T_base_cam, mp, on, nullptr, {v});
  };
  std::mt19937_64 rng(6);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst1 = 0.0, worst2 = 0.0, worst_exact = 0.0, sum_err = 0.0, sum_exact = 0.0;
  const int starts = 3, frames = 8;
  for (int k = 0; k < starts; ++k) {
    const Particle start = test::perturbed(truth, n01, rng);
    double s1 = 1.0, s2 = 1.0, e1 = 1.0, e2 = 1.0;
    RefinementResult last, last_exact;
    for (int f = 0; f < frames; ++f) {
      last = refineRig(1.004, 0.99, s1, s2, start, 1000 * k + f);
      last_exact = refineRig(1.0, 1.0, e1, e2, start, 1000 * k + f);
      ASSERT_TRUE(last.refined && last_exact.refined) << last.why << last_exact.why;
      ASSERT_EQ(last.more_depth_scale.size(), 1u);
      EXPECT_GT(last.more_depth_scale_information[0], 0.0);
      s1 = last.depth_scale;
      s2 = last.more_depth_scale[0];
      e1 = last_exact.depth_scale;
      e2 = last_exact.more_depth_scale[0];
    }
    worst1 = std::max(worst1, std::abs(s1 / truth1 - 1.0));
    worst2 = std::max(worst2, std::abs(s2 / truth2 - 1.0));
    worst_exact = std::max({worst_exact, std::abs(e1 - 1.0), std::abs(e2 - 1.0)});
    sum_err += distance(last.pose, truth);
    sum_exact += distance(last_exact.pose, truth);
  }
  std::printf(
      "[ measured ] rig, first camera 0.4%% long, second 1%% short: after %d frames the scales "
      "within %.3f%% and %.3f%% of their truths, pose error %.2f mm; exact rig: scales within "
      "%.3f%% of 1, pose error %.2f mm\n",
      frames, 100.0 * worst1, 100.0 * worst2, 1000.0 * sum_err / starts, 100.0 * worst_exact,
      1000.0 * sum_exact / starts);
  EXPECT_LT(worst1, 0.001);
  EXPECT_LT(worst2, 0.001);
  EXPECT_LT(worst_exact, 0.001);
  EXPECT_LT(sum_err, 1.3 * sum_exact + 0.001 * starts);
}

// The localizers of the depth-scale tests: 200 particles, stride 8, the estimate on and quick
// (rate 0.2).
LocalizerParams depthScaleParams() {
  LocalizerParams p;
  p.filter.num_particles = 200;
  p.frame.pixel_stride = 8;
  p.frame.max_range_m = 8.f;
  p.T_base_cam = test::world().T_base_cam;
  p.refinement.estimate_depth_scale = true;
  p.refinement.depth_scale_rate = 0.2;
  return p;
}

// The localizer's estimate over frames of a camera whose depths read 0.4% long (with a depth
// camera's noise, drawn anew per frame): starting at 1, it follows the refined frames' to
// within 0.1% of 1 / 1.004 and reports it in every step.
TEST(DepthScaleTest, LocalizerEstimateFollowsTheFrames) {
  const auto& w = test::world();
  LocalizerParams p = depthScaleParams();
  Localizer loc(p, w.map);
  const Particle truth = poseToParticle(test::referenceBasePose());
  loc.resetToPose(truth, Eigen::Vector4d(0.02, 0.02, 0.02, 0.02));
  std::mt19937_64 rng(9);
  const int frames = 30;
  test::LongDepthRun run = test::stepLongDepths(&loc, p, frames, 1.004, 1.0, &rng);
  const StepResult& r = run.last;
  std::printf("[ measured ] depth scale after %d frames (%d refined): %.5f (truth %.5f)\n", frames,
              run.refined, r.depth_scale, 1.0 / 1.004);
  EXPECT_GE(run.refined, 20);
  EXPECT_NEAR(r.depth_scale * 1.004, 1.0, 0.001);
  EXPECT_FALSE(r.depth_scale_at_bound);
  EXPECT_LT(distance(r.refinement.pose, truth), 0.005);
  // The same camera with the bound at 0.2%: the estimate is held there, and the step says so.
  p.refinement.depth_scale_max_error = 0.002;
  loc.setParams(p);
  run = test::stepLongDepths(&loc, p, 10, 1.004, 2.0, &rng);
  std::printf("[ measured ] with the bound at 0.2%%: %.5f, at the bound: %d\n",
              run.last.depth_scale, run.last.depth_scale_at_bound ? 1 : 0);
  EXPECT_TRUE(run.last.depth_scale_at_bound);
  EXPECT_NEAR(run.last.depth_scale, 0.998, 1e-9);
}

// A rig (the second camera turned 2.5 rad about the vertical, reading 1% short, its estimate
// starting at 0.995): each camera's estimate follows its own frames, reported per camera.
TEST(DepthScaleTest, EachCameraOfARigHasItsOwnEstimate) {
  const auto& w = test::world();
  LocalizerParams p = depthScaleParams();
  Localizer loc(p, w.map);
  const Particle truth = poseToParticle(test::referenceBasePose());
  loc.resetToPose(truth, Eigen::Vector4d(0.02, 0.02, 0.02, 0.02));
  const test::LongDepthCamera second = test::shortSecondCamera();
  std::mt19937_64 rng(10);
  const test::LongDepthRun run = test::stepLongDepths(&loc, p, 30, 1.004, 1.0, &rng, &second);
  const StepResult& r = run.last;
  ASSERT_EQ(r.cameras.size(), 2u);
  // The same rig with exact cameras.
  Localizer exact_loc(p, w.map);
  exact_loc.resetToPose(truth, Eigen::Vector4d(0.02, 0.02, 0.02, 0.02));
  test::LongDepthCamera exact_second = second;
  exact_second.factor = 1.0;
  exact_second.depth_scale_initial = 1.0;
  std::mt19937_64 rng_exact(10);
  const test::LongDepthRun exact =
      test::stepLongDepths(&exact_loc, p, 30, 1.0, 1.0, &rng_exact, &exact_second);
  const double err = distance(r.refinement.pose, truth);
  const double exact_err = distance(exact.last.refinement.pose, truth);
  std::printf(
      "[ measured ] rig after 30 frames (%d refined): first camera %.5f (truth %.5f), second "
      "%.5f (truth %.5f), refined pose %.2f mm off; exact rig %.5f and %.5f, %.2f mm off\n",
      run.refined, r.cameras[0].depth_scale, 1.0 / 1.004, r.cameras[1].depth_scale, 1.0 / 0.99,
      1000.0 * err, exact.last.cameras[0].depth_scale, exact.last.cameras[1].depth_scale,
      1000.0 * exact_err);
  EXPECT_LT(err, 1.3 * exact_err + 0.001);
  EXPECT_GE(run.refined, 20);
  EXPECT_TRUE(r.cameras[0].used && r.cameras[1].used);
  EXPECT_EQ(r.depth_scale, r.cameras[0].depth_scale);
  EXPECT_NEAR(r.cameras[0].depth_scale * 1.004, 1.0, 0.001);
  EXPECT_NEAR(r.cameras[1].depth_scale * 0.99, 1.0, 0.001);
  EXPECT_FALSE(r.cameras[1].depth_scale_at_bound);
  EXPECT_NEAR(exact.last.cameras[1].depth_scale, 1.0, 0.001);
}

}  // namespace
}  // namespace gmm_mcl
