// Several depth cameras in one update (docs/multi_camera.md): the log-likelihoods add up per
// particle, a camera without a usable frame is left out of the set (the first one too), and in a
// corridor where a forward camera alone cannot tell where it is along the corridor, a downward
// camera beside it resolves the pose.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "corridor_rig.h"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

using test::Corridor;
using test::corridor;
using test::corridorParams;
using test::corridorPose;
using test::CorridorRun;
using test::downCamera;
using test::forwardCamera;
using test::runCorridor;

TEST(LocalizerCamerasTest, AccumulatedFrameIsTheSumOfEachCamerasLikelihood) {
  const Corridor& c = corridor();
  const Intrinsics K = test::smallCamera();
  const FrameParams fp = test::frameParams(8);
  const Eigen::Isometry3d T = corridorPose(30);
  const DepthFrame f1 = prepareFrame(
      sim::renderDepth(c.scene, K, T * forwardCamera(), DepthEncoding::kMono16Millimetres, 9.0), K,
      fp);
  const DepthFrame f2 = prepareFrame(
      sim::renderDepth(c.scene, K, T * downCamera(), DepthEncoding::kMono16Millimetres, 9.0), K,
      fp);
  ASSERT_GT(f1.size(), 0u);
  ASSERT_GT(f2.size(), 0u);
  CpuBackend backend;
  backend.setMap(c.map);
  MeasurementParams mp;
  ParticleFilterParams pfp;
  pfp.num_particles = 64;
  ParticleFilter pf(pfp);
  InitRegion region;
  region.centre_m = Eigen::Vector3d(12.0, 1.0, 1.5);
  region.half_extent_m = Eigen::Vector3d(1.0, 0.3, 0.05);
  region.yaw_half_range_rad = 0.2;
  pf.initialiseUniform(region);
  MeasurementContext a;
  a.backend = &backend;
  a.frame = &f1;
  a.T_base_cam = forwardCamera();
  a.params = &mp;
  MeasurementContext b = a;
  b.frame = &f2;
  b.T_base_cam = downCamera();
  pf.evaluateFrame(b, nullptr);
  const std::vector<double> ll_b = pf.frameLogLikelihoods();
  pf.evaluateFrame(a, nullptr);
  const std::vector<double> ll_a = pf.frameLogLikelihoods();
  EvaluationStats stats;
  pf.accumulateFrame(b, 0.25, &stats);
  EXPECT_GT(stats.evaluations, 0);
  const std::vector<double>& sum = pf.frameLogLikelihoods();
  ASSERT_EQ(sum.size(), ll_a.size());
  for (size_t i = 0; i < sum.size(); ++i) EXPECT_DOUBLE_EQ(sum[i], ll_a[i] + 0.25 * ll_b[i]) << i;
  // Only onto a frame's likelihoods, not after a resampling.
  pf.resample();
  EXPECT_THROW(pf.accumulateFrame(b, 1.0, nullptr), std::logic_error);
}

TEST(LocalizerCamerasTest, ACameraWithoutAUsableFrameIsLeftOutAndTheFirstIsReplaced) {
  const Corridor& c = corridor();
  const Intrinsics K = test::smallCamera();
  const LocalizerParams params = corridorParams();
  Localizer loc(params, c.map);
  const Eigen::Isometry3d T = corridorPose(0);
  const DepthImage forward =
      sim::renderDepth(c.scene, K, T * forwardCamera(), DepthEncoding::kMono16Millimetres, 4.0);
  const DepthImage down =
      sim::renderDepth(c.scene, K, T * downCamera(), DepthEncoding::kMono16Millimetres, 4.0);
  DepthImage blank = down;  // every pixel missing
  std::fill(blank.data.begin(), blank.data.end(), 0);
  CameraInput cam;
  cam.name = "down";
  cam.intrinsics = K;
  cam.T_base_cam = downCamera();
  cam.frame = params.frame;
  cam.measurement = params.measurement;

  StepInput in;
  in.intrinsics = K;
  in.has_attitude = true;
  // One step with these frames of the forward and the down camera (nullptr: none), 0.1 s on.
  auto stepWith = [&](const DepthImage* first, const DepthImage* second,
                      const Intrinsics& second_K) {
    in.stamp_s += 0.1;
    in.depth = first;
    cam.depth = second;
    cam.intrinsics = second_K;
    in.more_cameras = {cam};
    return loc.step(in);
  };

  // Both cameras.
  StepResult res = stepWith(&forward, &down, K);
  ASSERT_EQ(res.status, StepStatus::kOk) << res.message;
  ASSERT_EQ(res.cameras.size(), 2u);
  EXPECT_TRUE(res.cameras[0].used && res.cameras[1].used);
  EXPECT_EQ(res.pixels, res.cameras[0].pixels + res.cameras[1].pixels);
  EXPECT_GT(res.cameras[1].pixels, 0);

  // The down camera's frame has no valid pixel: the update goes on with the forward camera.
  res = stepWith(&forward, &blank, K);
  EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
  EXPECT_TRUE(res.cameras[0].used);
  EXPECT_FALSE(res.cameras[1].used);
  EXPECT_NE(res.cameras[1].problem.find("no valid depth pixel"), std::string::npos);
  EXPECT_NE(res.message.find("camera 'down' not used"), std::string::npos) << res.message;
  EXPECT_EQ(res.pixels, res.cameras[0].pixels);

  // No forward frame: the down camera measures first.
  res = stepWith(nullptr, &down, K);
  EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
  EXPECT_FALSE(res.cameras[0].used);
  EXPECT_EQ(res.cameras[0].problem, "no frame");
  EXPECT_TRUE(res.cameras[1].used);
  EXPECT_EQ(res.pixels, res.cameras[1].pixels);
  EXPECT_NE(res.message.find("camera 'down' measured first"), std::string::npos) << res.message;

  // Neither usable: predict only, naming both.
  res = stepWith(nullptr, &blank, K);
  EXPECT_EQ(res.status, StepStatus::kNoValidPixels) << res.message;
  EXPECT_NE(res.message.find("camera 'down': no valid depth pixel"), std::string::npos)
      << res.message;

  // A bad frame (its size disagrees with its intrinsics) is left out the same way.
  Intrinsics wrong = K;
  wrong.width_px = 640;
  res = stepWith(&forward, &down, wrong);
  EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
  EXPECT_FALSE(res.cameras[1].used);
  EXPECT_FALSE(res.cameras[1].problem.empty());
}

TEST(LocalizerCamerasTest, ADownwardCameraResolvesTheCorridorTheForwardCameraCannot) {
  constexpr int kFrames = 240;  // 8 s along the corridor
  const CorridorRun forward_only = runCorridor(false, kFrames);
  const CorridorRun rig = runCorridor(true, kFrames);
  std::printf(
      "[ measured ] corridor, forward camera alone: error %.3f m, sigma_x %.3f m, step %.1f ms\n",
      forward_only.final_error_m, forward_only.final_sigma_x_m, forward_only.last_step_ms);
  std::printf(
      "[ measured ] corridor, forward + down cameras: error %.3f m (worst of the last 10 steps "
      "%.3f m), sigma_x %.3f m, step %.1f ms\n",
      rig.final_error_m, rig.worst_last_error_m, rig.final_sigma_x_m, rig.last_step_ms);
  // Alone, the forward camera does not know where it is along the corridor: either the belief
  // stays spread or it settled somewhere wrong.
  EXPECT_TRUE(forward_only.final_error_m > 0.5 || forward_only.final_sigma_x_m > 0.5);
  EXPECT_EQ(forward_only.two_camera_updates, 0);
  // With the downward camera: every update used both, and the pose is found.
  EXPECT_EQ(rig.two_camera_updates, (kFrames + 2) / 3);
  // The boxes' edges are soft in a GMM (flat Gaussians, in-plane sigma 0.3 x the 25 cm cells),
  // so the rig's belief along the corridor stays a few centimetres wide.
  EXPECT_LT(rig.worst_last_error_m, 0.1);
  EXPECT_LT(rig.final_sigma_x_m, 0.15);
}

struct BoxRun {
  double worst_m = 0.0, mean_m = 0.0;  // refined-or-mean error over frames 50..149
  int lost = 0;                        // lost-detector firings
  int two_camera_updates = 0;
};

// The synthetic room's loop (test_localizer's) from a 60 cm cube around the start, the small
// camera at every 8th pixel; with `down`, a second camera looking down and a little forward at
// every 4th pixel (four times the first camera's pixels, most of them on the floor), out of the
// sets of frames 100..129.
BoxRun runBoxRoom(bool down) {
  const auto& w = test::world();
  const Intrinsics K = test::smallCamera();
  const Eigen::Isometry3d T_base_down =
      sim::baseToCamera(Eigen::Vector3d(0.1, 0.0, -0.05),
                        Eigen::Vector3d(0.3, 0.0, -1.0).normalized(), -Eigen::Vector3d::UnitY());
  const std::vector<Eigen::Isometry3d> truth = sim::makeTrajectory(150);
  LocalizerParams p;
  p.filter.num_particles = 400;
  p.frame.pixel_stride = 8;
  p.frame.max_range_m = 6.f;
  p.T_base_cam = w.T_base_cam;
  const Particle s = poseToParticle(truth[0]);
  p.init.centre_m = Eigen::Vector3d(s.x_m, s.y_m, s.z_m);
  p.init.half_extent_m.setConstant(0.3);
  p.init.yaw_centre_rad = s.yaw_rad;
  p.init.yaw_half_range_rad = 0.3;
  Localizer loc(p, w.map);
  CameraInput cam;
  cam.name = "down";
  cam.intrinsics = K;
  cam.T_base_cam = T_base_down;
  cam.frame = p.frame;
  cam.frame.pixel_stride = 4;
  cam.frame.max_range_m = 4.f;
  cam.measurement = p.measurement;
  BoxRun run;
  for (int f = 0; f < 150; ++f) {
    const DepthImage forward = sim::renderDepth(w.scene, K, truth[f] * w.T_base_cam,
                                                DepthEncoding::kMono16Millimetres, 8.0);
    const DepthImage below = sim::renderDepth(w.scene, K, truth[f] * T_base_down,
                                              DepthEncoding::kMono16Millimetres, 8.0);
    StepInput in;
    in.stamp_s = 10.0 + f / 30.0;
    in.depth = &forward;
    in.intrinsics = K;
    in.has_odometry = true;
    in.T_odom_base = truth[f];
    double yaw;
    rpyFromRotation(truth[f].linear(), &in.roll_rad, &in.pitch_rad, &yaw);
    in.has_attitude = true;
    if (down) {
      cam.depth = f >= 100 && f < 130 ? nullptr : &below;
      in.more_cameras = {cam};
    }
    const StepResult res = loc.step(in);
    EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
    run.lost += res.lost ? 1 : 0;
    if (res.cameras.size() == 2 && res.cameras[1].used) ++run.two_camera_updates;
    if (f >= 50) {
      const Particle g = poseToParticle(truth[f]);
      const Particle& e = res.refinement.pose;
      const double err = std::hypot(std::hypot(e.x_m - g.x_m, e.y_m - g.y_m), e.z_m - g.z_m);
      run.worst_m = std::max(run.worst_m, err);
      run.mean_m += err / 100.0;
    }
  }
  return run;
}

TEST(LocalizerCamerasTest, ACameraWithMorePixelsAddsToTheFirstOneAndMayDropOut) {
  // Each camera's frame weighs as one frame (its log-likelihood scaled to the first camera's
  // pixel count): a downward camera with four times the pixels, most on the featureless floor,
  // does not drown the forward camera's evidence, and its dropping out for 30 frames is no
  // reason to call the filter lost.
  const BoxRun one = runBoxRoom(false);
  const BoxRun rig = runBoxRoom(true);
  std::printf(
      "[ measured ] room loop, forward camera: worst %.4f m, mean %.4f m; with the downward "
      "camera (out for 30 frames): worst %.4f m, mean %.4f m, lost %d\n",
      one.worst_m, one.mean_m, rig.worst_m, rig.mean_m, rig.lost);
  EXPECT_EQ(rig.two_camera_updates, 120);
  EXPECT_EQ(rig.lost, 0);
  EXPECT_LT(rig.worst_m, 0.02);
  EXPECT_LE(rig.mean_m, one.mean_m);
}

}  // namespace
}  // namespace gmm_mcl
