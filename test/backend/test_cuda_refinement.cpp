// The refinement's normal equations and refined poses on the GPU against the host's, on host
// points and on the frame the CUDA backend prepared.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <set>
#include <string>

#include "backend/cuda_backend_test_utils.h"
#include "cuda/cuda_backend.h"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/bench/frame_set.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/normal_equations.h"
#include "gmm_mcl/sim/pose_scatter.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

using test::distance;
using test::noisyImage;

constexpr double kNormalEquationsRelTol = 1e-4;  // of the largest entry of H (or of g, |loglik|)
constexpr double kRefinedPoseTolM = 2e-4;        // refined positions, host vs GPU
constexpr double kScaleTol = 2e-5;               // depth-scale estimates, host vs GPU

// The reference base pose, its attitude and particle, and starts near it.
struct Reference {
  Eigen::Isometry3d T_map_base = test::referenceBasePose();
  double roll = 0.0, pitch = 0.0;
  Particle truth;
  Reference() {
    double yaw;
    rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
    truth = poseToParticle(T_map_base);
  }
  // Gaussian offsets of 3 cm in x and y and 0.015 rad in yaw, drawn in that order.
  Particle near(std::normal_distribution<double>& n01, std::mt19937_64& rng) const {
    Particle start = truth;
    start.x_m += 0.03 * n01(rng);
    start.y_m += 0.03 * n01(rng);
    start.yaw_rad += 0.015 * n01(rng);
    return start;
  }
};

TEST_F(CudaBackendTest, RefinementSumsMatchHost) {
  const auto& w = test::world();
  gpu->setMap(w.map);
  ASSERT_NE(gpu->normalEquations(), nullptr);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  double roll, pitch, yaw;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  const Particle truth = poseToParticle(T_map_base);
  const MeasurementParams mp;
  for (int stride : {8, 4}) {
    FrameParams fp = test::frameParams(stride);
    const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), fp);
    std::mt19937_64 rng(40 + stride);
    std::normal_distribution<double> n01(0.0, 1.0);
    double worst = 0.0, worst_yaw = 0.0, host_ms = 0.0, gpu_ms = 0.0;
    int host_iterations = 0, gpu_iterations = 0;
    for (int k = 0; k < 6; ++k) {
      const Particle start = test::perturbed(truth, n01, rng);
      RefinementParams rp;
      rp.max_iterations = 1;  // one linearisation and one step: the sums themselves compared
      const RefinementResult h1 =
          refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, mp, rp);
      const RefinementResult g1 = refinePose(w.map.packed(), frame, start, roll, pitch,
                                             w.T_base_cam, mp, rp, gpu->normalEquations());
      EXPECT_NEAR(g1.loglik_start, h1.loglik_start,
                  kNormalEquationsRelTol * std::max(1.0, std::abs(h1.loglik_start)))
          << "stride " << stride << " start " << k;
      const RefinementParams full;
      const RefinementResult h =
          refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, mp, full);
      const RefinementResult g = refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam,
                                            mp, full, gpu->normalEquations());
      ASSERT_TRUE(h.refined) << h.why;
      ASSERT_TRUE(g.refined) << g.why;
      host_ms += h.ms;
      gpu_ms += g.ms;
      host_iterations += h.iterations;
      gpu_iterations += g.iterations;
      const double d =
          std::sqrt(std::pow(h.pose.x_m - g.pose.x_m, 2) + std::pow(h.pose.y_m - g.pose.y_m, 2) +
                    std::pow(h.pose.z_m - g.pose.z_m, 2));
      worst = std::max(worst, d);
      worst_yaw = std::max(worst_yaw, std::abs(wrapAngle(h.pose.yaw_rad - g.pose.yaw_rad)));
      EXPECT_LT(d, kRefinedPoseTolM) << "stride " << stride << " start " << k;
      EXPECT_NEAR(g.loglik_refined, h.loglik_refined,
                  kNormalEquationsRelTol * std::max(1.0, std::abs(h.loglik_refined)));
    }
    std::printf(
        "[ measured ] stride %d, %zu pixels: refined poses host vs GPU within %.3f mm, %.5f deg; "
        "per refinement host %.2f ms (%.1f iterations), GPU %.2f ms (%.1f iterations)\n",
        stride, frame.size(), 1000.0 * worst, worst_yaw * 180.0 / M_PI, host_ms / 6,
        host_iterations / 6.0, gpu_ms / 6, gpu_iterations / 6.0);
  }
}

// The refinement reading the frame the backend prepared on the GPU (no host points; the camera's
// extrinsics folded into each pose) lands where the host refinement of the same frame does.
TEST_F(CudaBackendTest, ARigsSecondCameraRefinesOnItsOwnDeviceEvaluator) {
  // docs/multi_camera.md: the rig's second camera's pixel sums on an evaluator of its own
  // (makeNormalEquations, points from the host) beside the first camera's on the backend's:
  // the refined pose as with every sum on the host.
  const auto& w = test::world();
  gpu->setMap(w.map);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  double roll, pitch, yaw;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  const Particle truth = poseToParticle(T_map_base);
  const Eigen::Isometry3d T_base_cam2 = test::turnedCamera(2.5);
  const FrameParams fp = test::frameParams(8);
  const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), fp);
  const DepthFrame frame2 =
      test::renderFrame(T_map_base * T_base_cam2 * w.T_base_cam.inverse(), test::vgaCamera(), fp);
  ASSERT_GT(frame2.size(), 0u);
  const MeasurementParams mp;
  std::unique_ptr<NormalEquationsEvaluator> second = gpu->makeNormalEquations();
  ASSERT_NE(second, nullptr);
  RefinementView host_view;
  host_view.components = &w.map.packed();
  host_view.frame = RefinementFrame::of(frame2);
  host_view.T_base_cam = T_base_cam2;
  host_view.params = &mp;
  host_view.weight = 0.5;
  RefinementView device_view = host_view;
  device_view.sums = second.get();
  std::mt19937_64 rng(47);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst = 0.0, worst_scale = 0.0;
  for (int k = 0; k < 8; ++k) {
    const Particle start = test::perturbed(truth, n01, rng);
    // Half the starts with each camera's depth scale estimated as well.
    RefinementParams rp;
    rp.estimate_depth_scale = k % 2 == 1;
    const RefinementResult h = refinePose(w.map.packed(), RefinementFrame::of(frame), start, roll,
                                          pitch, w.T_base_cam, mp, rp, nullptr, {host_view});
    const RefinementResult g =
        refinePose(w.map.packed(), RefinementFrame::of(frame), start, roll, pitch, w.T_base_cam, mp,
                   rp, gpu->normalEquations(), {device_view});
    ASSERT_EQ(g.refined, h.refined) << k;
    worst = std::max(worst, distance(g.pose, h.pose));
    ASSERT_EQ(g.more_depth_scale.size(), 1u);
    ASSERT_EQ(h.more_depth_scale.size(), 1u);
    worst_scale = std::max({worst_scale, std::abs(g.depth_scale - h.depth_scale),
                            std::abs(g.more_depth_scale[0] - h.more_depth_scale[0])});
    if (rp.estimate_depth_scale && h.refined) {
      EXPECT_GT(h.more_depth_scale_information[0], 0.0);
      EXPECT_NE(h.more_depth_scale[0], 1.0);  // estimated, not left as it was
    }
  }
  std::printf(
      "[ measured ] rig refinement, second camera on the GPU: worst %.2e m from the host's, "
      "depth scales (both cameras' estimated) within %.2e\n",
      worst, worst_scale);
  EXPECT_LT(worst, kRefinedPoseTolM);
  EXPECT_LT(worst_scale, kScaleTol);
}

TEST_F(CudaBackendTest, RefinementOnTheDeviceFrameMatchesHost) {
  const auto& w = test::world();
  gpu->setMap(w.map);
  const Intrinsics K = test::vgaCamera();
  const Reference ref;
  const Eigen::Isometry3d& T_map_base = ref.T_map_base;
  const double roll = ref.roll, pitch = ref.pitch;
  const Particle& truth = ref.truth;
  std::mt19937_64 rng(11);
  const DepthImage img =
      noisyImage(K, T_map_base * w.T_base_cam, DepthEncoding::kMono16Millimetres, &rng);
  FrameParams fp;
  fp.pixel_stride = 8;
  fp.max_range_m = 5.f;
  const DepthFrame frame = prepareFrame(img, K, fp);
  NormalEquationsEvaluator* sums = gpu->normalEquations();
  EXPECT_FALSE(sums->hasBackendFrame());  // nothing prepared yet
  const CudaBackend::DeviceFrameInfo info = gpu->prepareDeviceFrame(img, K, fp);
  ASSERT_EQ(info.pixels, static_cast<int>(frame.size()));
  ASSERT_TRUE(sums->hasBackendFrame());
  RefinementFrame on_device;
  on_device.intrinsics = K;
  on_device.grid = frame.grid;
  on_device.pixels = info.pixels;
  const MeasurementParams mp;
  const RefinementParams rp;
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Particle start = ref.near(n01, rng);
    const RefinementResult h =
        refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, mp, rp);
    const RefinementResult d =
        refinePose(w.map.packed(), on_device, start, roll, pitch, w.T_base_cam, mp, rp, sums);
    ASSERT_TRUE(h.refined) << h.why;
    ASSERT_TRUE(d.refined) << d.why;
    const double dist =
        std::sqrt(std::pow(h.pose.x_m - d.pose.x_m, 2) + std::pow(h.pose.y_m - d.pose.y_m, 2) +
                  std::pow(h.pose.z_m - d.pose.z_m, 2));
    worst = std::max(worst, dist);
    EXPECT_LT(dist, kRefinedPoseTolM) << "start " << k;
    EXPECT_NEAR(d.loglik_start, h.loglik_start,
                kNormalEquationsRelTol * std::max(1.0, std::abs(h.loglik_start)));
  }
  std::printf("[ measured ] refinement on the device frame vs host points: within %.3f mm\n",
              1000.0 * worst);
  // Points without a device frame are an error, not a silent host fallback.
  CpuBackend cpu;
  EXPECT_EQ(cpu.normalEquations(), nullptr);
  EXPECT_THROW(refinePose(w.map.packed(), on_device, truth, roll, pitch, w.T_base_cam, mp, rp),
               std::invalid_argument);
}

// The sums themselves: H, g and the log-likelihood at several poses, GPU against host.
TEST_F(CudaBackendTest, NormalEquationsMatchHost) {
  const auto& w = test::world();
  gpu->setMap(w.map);
  NormalEquationsEvaluator* dev = gpu->normalEquations();
  HostNormalEquations host;
  FrameParams fp = test::frameParams(4);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), fp);
  std::vector<double> x(frame.size()), y(frame.size()), z(frame.size());
  for (size_t i = 0; i < frame.size(); ++i) {
    const Eigen::Vector3d p =
        w.T_base_cam * Eigen::Vector3d(frame.x_m[i], frame.y_m[i], frame.z_m[i]);
    x[i] = p.x();
    y[i] = p.y();
    z[i] = p.z();
  }
  host.setPoints(x, y, z, frame.patch_begin);
  dev->setPoints(x, y, z, frame.patch_begin);
  const MeasurementParams mp;
  std::vector<EvalComponentF> eval;
  makeEvalComponents(w.map.packed(), &eval);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst_h = 0.0, worst_g = 0.0, worst_s = 0.0;
  for (int k = 0; k < 5; ++k) {
    Eigen::Isometry3d T = T_map_base;
    T.translation() += Eigen::Vector3d(0.02 * n01(rng), 0.02 * n01(rng), 0.02 * n01(rng));
    PatchMembership m;
    std::vector<ProjectedComponent> projected;
    std::vector<char> valid;
    computeMembership(w.map.packed(), toRigidF((T * w.T_base_cam).inverse()), frame.intrinsics,
                      frame.grid, mp, &projected, &valid, &m);
    host.setLinearisation(eval, m);
    dev->setLinearisation(eval, m);
    PoseDerivatives d;
    const Eigen::Matrix3d R = T.linear();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        d.R[3 * r + c] = R(r, c);
        // Any fixed matrices exercise the derivative columns alike on both sides.
        for (int a = 0; a < 3; ++a) d.dR[a][3 * r + c] = 0.1 * (a + 1) * ((r + 2 * c) % 3 - 1);
      }
      d.t[r] = T.translation()[r];
    }
    NormalEquationSums a, b;
    host.evaluate(d, mp.floor_log_density, true, &a);
    dev->evaluate(d, mp.floor_log_density, true, &b);
    EXPECT_NEAR(b.loglik, a.loglik, kNormalEquationsRelTol * std::abs(a.loglik));
    double h_scale = 0.0, g_scale = 0.0;
    for (double v : a.h) h_scale = std::max(h_scale, std::abs(v));
    for (double v : a.g) g_scale = std::max(g_scale, std::abs(v));
    ASSERT_GT(h_scale, 0.0);
    for (int i = 0; i < 21; ++i) {
      worst_h = std::max(worst_h, std::abs(a.h[i] - b.h[i]) / h_scale);
      EXPECT_NEAR(b.h[i], a.h[i], kNormalEquationsRelTol * h_scale) << "H entry " << i;
    }
    for (int i = 0; i < 6; ++i) {
      worst_g = std::max(worst_g, std::abs(a.g[i] - b.g[i]) / g_scale);
      EXPECT_NEAR(b.g[i], a.g[i], kNormalEquationsRelTol * g_scale) << "g entry " << i;
    }
    NormalEquationSums c;
    dev->evaluate(d, mp.floor_log_density, false, &c);
    EXPECT_EQ(c.loglik, b.loglik);  // the same kernel sums, with or without linearising
    // With a depth scale (points moved along their rays from the camera centre): the same sums
    // at the scaled points, and H's and g's depth-scale entries.
    d.scale = 0.996;
    for (int a = 0; a < 3; ++a) d.scale_origin[a] = w.T_base_cam.translation()[a];
    d.estimate_scale = true;
    NormalEquationSums as, bs;
    host.evaluate(d, mp.floor_log_density, true, &as);
    dev->evaluate(d, mp.floor_log_density, true, &bs);
    EXPECT_NE(as.loglik, a.loglik);
    EXPECT_NEAR(bs.loglik, as.loglik, kNormalEquationsRelTol * std::abs(as.loglik));
    double s_scale = std::abs(as.gs);
    for (double v : as.hs) s_scale = std::max(s_scale, std::abs(v));
    ASSERT_GT(s_scale, 0.0);
    for (int i = 0; i < 7; ++i) {
      worst_s = std::max(worst_s, std::abs(as.hs[i] - bs.hs[i]) / s_scale);
      EXPECT_NEAR(bs.hs[i], as.hs[i], kNormalEquationsRelTol * s_scale) << "H scale entry " << i;
    }
    worst_s = std::max(worst_s, std::abs(as.gs - bs.gs) / s_scale);
    EXPECT_NEAR(bs.gs, as.gs, kNormalEquationsRelTol * s_scale);
    for (int i = 0; i < 6; ++i) {
      EXPECT_NEAR(bs.g[i], as.g[i], kNormalEquationsRelTol * g_scale) << "scaled g entry " << i;
    }
  }
  std::printf(
      "[ measured ] normal equations GPU vs host: H within %.2e, g within %.2e, the depth "
      "scale's entries within %.2e relative\n",
      worst_h, worst_g, worst_s);
}

// The depth scale estimated with the pixel sums on the GPU (depths 0.4% long): the same estimate
// and pose as with the sums on the host, on host points (with the noise correction, whose noisy
// points are drawn on the host) and on the frame the backend prepared (without it; with it the
// refinement refuses the device frame).
TEST_F(CudaBackendTest, DepthScaleEstimatedOnTheDeviceMatchesHost) {
  const auto& w = test::world();
  gpu->setMap(w.map);
  const Intrinsics K = test::vgaCamera();
  const Reference ref;
  std::mt19937_64 rng(12);
  const DepthImage exact =
      noisyImage(K, ref.T_map_base * w.T_base_cam, DepthEncoding::kFloat32Metres, &rng);
  std::vector<float> z(static_cast<size_t>(exact.width_px) * exact.height_px);
  for (int v = 0; v < exact.height_px; ++v) {
    for (int u = 0; u < exact.width_px; ++u)
      z[v * exact.width_px + u] = 1.004f * exact.depthMetres(u, v);
  }
  const DepthImage img = DepthImage::fromMetres(exact.width_px, exact.height_px, z);
  FrameParams fp;
  fp.pixel_stride = 8;
  fp.max_range_m = 8.f;
  const DepthFrame frame = prepareFrame(img, K, fp);
  NormalEquationsEvaluator* sums = gpu->normalEquations();
  ASSERT_TRUE(sums->supportsDepthScale());
  const MeasurementParams mp;
  RefinementParams rp;
  rp.estimate_depth_scale = true;
  RefinementParams plain = rp;
  plain.depth_scale_noise_correction = false;
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst_scale = 0.0, worst_pose = 0.0, worst_scale_frame = 0.0, host_ms = 0.0, gpu_ms = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Particle start = ref.near(n01, rng);
    const RefinementResult h =
        refinePose(w.map.packed(), frame, start, ref.roll, ref.pitch, w.T_base_cam, mp, rp);
    const RefinementResult g =
        refinePose(w.map.packed(), frame, start, ref.roll, ref.pitch, w.T_base_cam, mp, rp, sums);
    ASSERT_TRUE(h.refined && g.refined) << h.why << g.why;
    EXPECT_FALSE(h.sums_on_backend);
    EXPECT_TRUE(g.sums_on_backend);
    EXPECT_LT(h.depth_scale, 0.999);  // moved from 1 toward 1 / 1.004
    host_ms += h.ms / 4;
    gpu_ms += g.ms / 4;
    worst_scale = std::max(worst_scale, std::abs(g.depth_scale - h.depth_scale));
    worst_pose = std::max(worst_pose, distance(g.pose, h.pose));
    EXPECT_NEAR(g.depth_scale_information, h.depth_scale_information,
                1e-3 * h.depth_scale_information);
    // The backend's own frame (camera points, the extrinsics folded into the pose).
    const RefinementResult hp =
        refinePose(w.map.packed(), frame, start, ref.roll, ref.pitch, w.T_base_cam, mp, plain);
    ASSERT_EQ(gpu->prepareDeviceFrame(img, K, fp).pixels, static_cast<int>(frame.size()));
    RefinementFrame on_device;
    on_device.intrinsics = K;
    on_device.grid = frame.grid;
    on_device.pixels = static_cast<int>(frame.size());
    const RefinementResult d = refinePose(w.map.packed(), on_device, start, ref.roll, ref.pitch,
                                          w.T_base_cam, mp, plain, sums);
    ASSERT_TRUE(hp.refined && d.refined) << hp.why << d.why;
    worst_scale_frame = std::max(worst_scale_frame, std::abs(d.depth_scale - hp.depth_scale));
    worst_pose = std::max(worst_pose, distance(d.pose, hp.pose));
    EXPECT_THROW(refinePose(w.map.packed(), on_device, start, ref.roll, ref.pitch, w.T_base_cam, mp,
                            rp, sums),
                 std::invalid_argument);
  }
  std::printf(
      "[ measured ] depth scale on the GPU vs host: within %.2e (host points, noise "
      "correction), %.2e (device frame); poses within %.3f mm; per refinement with the noise "
      "correction host %.2f ms, GPU %.2f ms\n",
      worst_scale, worst_scale_frame, 1000.0 * worst_pose, host_ms, gpu_ms);
  EXPECT_LT(worst_scale, kScaleTol);
  EXPECT_LT(worst_scale_frame, kScaleTol);
  EXPECT_LT(worst_pose, kRefinedPoseTolM);
}

}  // namespace
}  // namespace gmm_mcl
