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
  pf.accumulateFrame(b, &stats);
  EXPECT_GT(stats.evaluations, 0);
  const std::vector<double>& sum = pf.frameLogLikelihoods();
  ASSERT_EQ(sum.size(), ll_a.size());
  for (size_t i = 0; i < sum.size(); ++i) EXPECT_DOUBLE_EQ(sum[i], ll_a[i] + ll_b[i]) << i;
  // Only onto a frame's likelihoods, not after a resampling.
  pf.resample();
  EXPECT_THROW(pf.accumulateFrame(b, nullptr), std::logic_error);
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

  // Both cameras.
  StepInput in;
  in.stamp_s = 1.0;
  in.depth = &forward;
  in.intrinsics = K;
  in.has_attitude = true;
  cam.depth = &down;
  in.more_cameras = {cam};
  StepResult res = loc.step(in);
  ASSERT_EQ(res.status, StepStatus::kOk) << res.message;
  ASSERT_EQ(res.cameras.size(), 2u);
  EXPECT_TRUE(res.cameras[0].used && res.cameras[1].used);
  EXPECT_EQ(res.pixels, res.cameras[0].pixels + res.cameras[1].pixels);
  EXPECT_GT(res.cameras[1].pixels, 0);

  // The down camera's frame has no valid pixel: the update goes on with the forward camera.
  cam.depth = &blank;
  in.more_cameras = {cam};
  in.stamp_s = 1.1;
  res = loc.step(in);
  EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
  EXPECT_TRUE(res.cameras[0].used);
  EXPECT_FALSE(res.cameras[1].used);
  EXPECT_NE(res.cameras[1].problem.find("no valid depth pixel"), std::string::npos);
  EXPECT_NE(res.message.find("camera 'down' not used"), std::string::npos) << res.message;
  EXPECT_EQ(res.pixels, res.cameras[0].pixels);

  // No forward frame: the down camera measures first.
  in.depth = nullptr;
  cam.depth = &down;
  in.more_cameras = {cam};
  in.stamp_s = 1.2;
  res = loc.step(in);
  EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
  EXPECT_FALSE(res.cameras[0].used);
  EXPECT_EQ(res.cameras[0].problem, "no frame");
  EXPECT_TRUE(res.cameras[1].used);
  EXPECT_EQ(res.pixels, res.cameras[1].pixels);
  EXPECT_NE(res.message.find("camera 'down' measured first"), std::string::npos) << res.message;

  // Neither usable: predict only, naming both.
  cam.depth = &blank;
  in.more_cameras = {cam};
  in.stamp_s = 1.3;
  res = loc.step(in);
  EXPECT_EQ(res.status, StepStatus::kNoValidPixels) << res.message;
  EXPECT_NE(res.message.find("camera 'down': no valid depth pixel"), std::string::npos)
      << res.message;

  // A bad frame (its size disagrees with its intrinsics) is left out the same way.
  Intrinsics wrong = K;
  wrong.width_px = 640;
  cam.depth = &down;
  cam.intrinsics = wrong;
  in.depth = &forward;
  in.more_cameras = {cam};
  in.stamp_s = 1.4;
  res = loc.step(in);
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

}  // namespace
}  // namespace gmm_mcl
