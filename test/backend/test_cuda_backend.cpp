// CPU (reference) vs CUDA backend: the same particles and frame give the same per-particle
// log-likelihood within a stated tolerance and the same membership sets (DESIGN.md "Backends").
// Skips with a printed reason when no CUDA device is present.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <set>
#include <string>

#include "bench/frame_set.h"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/backend/cuda_backend.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/normal_equations.h"
#include "gmm_mcl/sim/pose_scatter.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// Per-particle log-likelihood: |L_cuda - L_cpu| <= kRelTol * max(|L_cpu|, 1 nat x pixels).
// Both evaluate in float32 per pixel and accumulate in double; the CUDA kernel shifts by the
// patch's largest log-normaliser instead of the per-pixel maximum and uses the hardware exp2
// (relative error ~2^-22), so per-pixel values agree to ~1e-6 nats.
constexpr double kRelTol = 1e-5;
// Floor hits may differ on pixels whose mixture density is within rounding of exp(floor).
constexpr double kFloorHitTol = 1e-3;  // of the used pixels
// Membership: a (patch, component) pair may differ only where the patch centre lies on the
// inflated ellipse to within float rounding: |(c - mu)^T Q (c - mu) - 1| below this.
constexpr double kBorderlineTol = 1e-3;
// ... and such pairs are rare.
constexpr double kMaxMembershipMismatchFraction = 1e-3;

bool haveDevice(std::string* why) { return cudaDeviceCount(why) > 0; }

#define GMM_MCL_REQUIRE_DEVICE()                \
  do {                                          \
    std::string why;                            \
    if (!haveDevice(&why)) GTEST_SKIP() << why; \
  } while (0)

// The synthetic world from T_map_cam with the sensor model's noise and 5 % dropout, to 6 m.
DepthImage noisyImage(const Intrinsics& K, const Eigen::Isometry3d& T_map_cam, DepthEncoding enc,
                      std::mt19937_64* rng) {
  sim::DepthNoise noise;
  noise.dropout = 0.05;
  return sim::renderDepth(test::world().scene, K, T_map_cam, enc, 6.0, noise, rng);
}

// The true pose and n - 1 poses within +-0.5 m and +-0.3 rad of yaw about it.
std::vector<RigidTransformF> perturbedPoses(const Eigen::Isometry3d& T_true, int n, unsigned seed) {
  return sim::scatterPoses(T_true, n, 0.5, 0.3, seed);
}

// Compares membership of every pose; returns mismatching pairs (all must be borderline).
void expectSameMembership(const GmmMap& map, const DepthFrame& frame,
                          const std::vector<RigidTransformF>& poses, CpuBackend* cpu,
                          CudaBackend* gpu, const char* label) {
  const MeasurementParams mp;
  long long pairs = 0, mismatches = 0;
  double worst_margin = 0.0;
  for (const RigidTransformF& T : poses) {
    PatchMembership a, b;
    cpu->membership(frame, T, mp, &a);
    gpu->membership(frame, T, mp, &b);
    ASSERT_EQ(a.begin.size(), b.begin.size());
    const RigidTransformF T_cam_map = invertRigid(T);
    for (int p = 0; p + 1 < static_cast<int>(a.begin.size()); ++p) {
      const std::set<int> sa(a.comps.begin() + a.begin[p], a.comps.begin() + a.begin[p + 1]);
      const std::set<int> sb(b.comps.begin() + b.begin[p], b.comps.begin() + b.begin[p + 1]);
      pairs += static_cast<long long>(sa.size());
      for (int pass = 0; pass < 2; ++pass) {
        const std::set<int>& x = pass ? sb : sa;
        const std::set<int>& y = pass ? sa : sb;
        for (int i : x) {
          if (y.count(i)) continue;
          ++mismatches;
          ProjectedComponent pc;
          ASSERT_TRUE(projectComponent(map.packed()[i], T_cam_map, frame.intrinsics,
                                       mp.min_component_depth_m, mp.sigma_bound,
                                       patchInflation(frame.grid.patch_size_px), &pc));
          const double du = frame.grid.centreU(p % frame.grid.cols) - pc.u_px;
          const double dv = frame.grid.centreV(p / frame.grid.cols) - pc.v_px;
          const double q = pc.q_uu * du * du + 2 * pc.q_uv * du * dv + pc.q_vv * dv * dv;
          worst_margin = std::max(worst_margin, std::abs(q - 1.0));
          EXPECT_LT(std::abs(q - 1.0), kBorderlineTol)
              << label << ": patch " << p << " component " << i << " differs, q = " << q;
        }
      }
    }
  }
  std::printf(
      "[ measured ] %s membership: %lld pairs over %zu poses, %lld differ (all borderline, "
      "worst |q-1| = %.2e)\n",
      label, pairs, poses.size(), mismatches, worst_margin);
  EXPECT_GT(pairs, 0);
  EXPECT_LE(static_cast<double>(mismatches), kMaxMembershipMismatchFraction * pairs + 1);
}

void expectSameLikelihood(const GmmMap& map, const DepthFrame& frame,
                          const std::vector<RigidTransformF>& poses, CpuBackend* cpu,
                          CudaBackend* gpu, const char* label,
                          const MeasurementParams& mp = MeasurementParams()) {
  BackendOutput a, b;
  cpu->evaluate(frame, poses, mp, &a);
  gpu->evaluate(frame, poses, mp, &b);
  ASSERT_EQ(a.log_likelihood.size(), poses.size());
  ASSERT_EQ(b.log_likelihood.size(), poses.size());
  const double px = static_cast<double>(frame.size());
  double worst = 0.0;
  int worst_hits = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    ASSERT_TRUE(std::isfinite(b.log_likelihood[i])) << label << " particle " << i;
    const double scale = std::max(std::abs(a.log_likelihood[i]), px);
    const double rel = std::abs(a.log_likelihood[i] - b.log_likelihood[i]) / scale;
    worst = std::max(worst, rel);
    EXPECT_LT(rel, kRelTol) << label << " particle " << i << ": cpu " << a.log_likelihood[i]
                            << " cuda " << b.log_likelihood[i];
    const int dh = std::abs(a.floor_hits[i] - b.floor_hits[i]);
    worst_hits = std::max(worst_hits, dh);
    EXPECT_LE(dh, kFloorHitTol * px + 1) << label << " particle " << i;
  }
  const double eval_rel = std::abs(double(a.evaluations - b.evaluations)) / double(a.evaluations);
  std::printf(
      "[ measured ] %s likelihood: %zu particles, %.0f px, worst relative difference "
      "%.2e (tolerance %.0e), worst floor-hit difference %d px, evaluations cpu %lld "
      "cuda %lld, L(true pose) cpu %.3f cuda %.3f\n",
      label, poses.size(), px, worst, kRelTol, worst_hits, a.evaluations, b.evaluations,
      a.log_likelihood[0], b.log_likelihood[0]);
  EXPECT_LT(eval_rel, 1e-3);
  EXPECT_EQ(a.patches_with_pixels, b.patches_with_pixels);
  (void)map;
}

TEST(CudaBackendTest, SyntheticSceneMatchesCpu) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CpuBackend cpu;
  CudaBackend gpu;
  cpu.setMap(w.map);
  gpu.setMap(w.map);
  for (int stride : {4, 1, 8}) {
    FrameParams fp = test::frameParams(stride);
    const Eigen::Isometry3d T_map_base = test::referenceBasePose();
    const DepthFrame frame = test::renderFrame(T_map_base, test::vgaCamera(), fp);
    const auto poses = perturbedPoses(T_map_base * w.T_base_cam, 256, 10u + stride);
    const std::string label = "synthetic stride " + std::to_string(stride);
    expectSameLikelihood(w.map, frame, poses, &cpu, &gpu, label.c_str());
    if (stride == 4) {
      // The paper's model (no depth noise): one evaluation form for every particle.
      MeasurementParams noise_off;
      noise_off.depth_noise.a_m = noise_off.depth_noise.b_per_m = 0.f;
      expectSameLikelihood(w.map, frame, poses, &cpu, &gpu, (label + ", no depth noise").c_str(),
                           noise_off);
      const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 32);
      expectSameMembership(w.map, frame, some, &cpu, &gpu, label.c_str());
    }
  }
}

// The pose refinement's pixel sums on the GPU (float per pair, double per block) match the host's
// (double throughout): the log-likelihood and the normal equations at poses near and off the
// truth, and the refined pose.
constexpr double kNormalEquationsRelTol = 1e-4;  // of the largest entry of H (or of g, |loglik|)
constexpr double kRefinedPoseTolM = 2e-4;        // refined positions, host vs GPU

TEST(CudaBackendTest, RefinementSumsMatchHost) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CudaBackend gpu;
  gpu.setMap(w.map);
  ASSERT_NE(gpu.normalEquations(), nullptr);
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
                                             w.T_base_cam, mp, rp, gpu.normalEquations());
      EXPECT_NEAR(g1.loglik_start, h1.loglik_start,
                  kNormalEquationsRelTol * std::max(1.0, std::abs(h1.loglik_start)))
          << "stride " << stride << " start " << k;
      const RefinementParams full;
      const RefinementResult h =
          refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam, mp, full);
      const RefinementResult g = refinePose(w.map.packed(), frame, start, roll, pitch, w.T_base_cam,
                                            mp, full, gpu.normalEquations());
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
TEST(CudaBackendTest, RefinementOnTheDeviceFrameMatchesHost) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CudaBackend gpu;
  gpu.setMap(w.map);
  const Intrinsics K = test::vgaCamera();
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  double roll, pitch, yaw;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  const Particle truth = poseToParticle(T_map_base);
  std::mt19937_64 rng(11);
  const DepthImage img =
      noisyImage(K, T_map_base * w.T_base_cam, DepthEncoding::kMono16Millimetres, &rng);
  FrameParams fp;
  fp.pixel_stride = 8;
  fp.max_range_m = 5.f;
  const DepthFrame frame = prepareFrame(img, K, fp);
  NormalEquationsEvaluator* sums = gpu.normalEquations();
  EXPECT_FALSE(sums->hasBackendFrame());  // nothing prepared yet
  const CudaBackend::DeviceFrameInfo info = gpu.prepareDeviceFrame(img, K, fp);
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
    Particle start = truth;
    start.x_m += 0.03 * n01(rng);
    start.y_m += 0.03 * n01(rng);
    start.yaw_rad += 0.015 * n01(rng);
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
TEST(CudaBackendTest, NormalEquationsMatchHost) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CudaBackend gpu;
  gpu.setMap(w.map);
  NormalEquationsEvaluator* dev = gpu.normalEquations();
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
  double worst_h = 0.0, worst_g = 0.0;
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
  }
  std::printf("[ measured ] normal equations GPU vs host: H within %.2e, g within %.2e relative\n",
              worst_h, worst_g);
}

// Frame preparation on the GPU gives prepareFrame's points: the same likelihoods, to the bit
// when the order and arithmetic agree, for both encodings and several strides.
TEST(CudaBackendTest, GpuFramePreparationMatchesHost) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CudaBackend gpu;
  gpu.setMap(w.map);
  const Intrinsics K = test::vgaCamera();
  const Eigen::Isometry3d T_map_cam = test::referenceBasePose() * w.T_base_cam;
  const auto poses = perturbedPoses(T_map_cam, 64, 5);
  for (DepthEncoding enc : {DepthEncoding::kMono16Millimetres, DepthEncoding::kFloat32Metres}) {
    std::mt19937_64 rng(7);
    const DepthImage img = noisyImage(K, T_map_cam, enc, &rng);
    for (int stride : {1, 3, 4, 8}) {
      FrameParams fp;
      fp.pixel_stride = stride;
      fp.max_range_m = 5.f;
      const DepthFrame frame = prepareFrame(img, K, fp);
      BackendOutput host, dev;
      gpu.evaluate(frame, poses, MeasurementParams(), &host);
      gpu.evaluateImage(img, K, fp, poses, MeasurementParams(), &dev);
      EXPECT_EQ(gpu.lastFramePixels(), static_cast<int>(frame.size()));
      EXPECT_EQ(host.patches_with_pixels, dev.patches_with_pixels);
      EXPECT_EQ(host.evaluations, dev.evaluations);
      double worst = 0.0;
      for (size_t i = 0; i < poses.size(); ++i) {
        worst = std::max(worst, std::abs(host.log_likelihood[i] - dev.log_likelihood[i]) /
                                    std::max(1.0, std::abs(host.log_likelihood[i])));
        EXPECT_EQ(host.floor_hits[i], dev.floor_hits[i]);
      }
      EXPECT_LT(worst, 1e-12) << "stride " << stride;
      std::printf(
          "[ measured ] GPU frame prep, %s stride %d: %zu px, worst relative difference "
          "%.1e\n",
          depthEncodingName(enc), stride, frame.size(), worst);
    }
  }
  // What prepareFrame rejects, evaluateImage rejects.
  FrameParams bad;
  bad.pixel_stride = 0;
  BackendOutput out;
  const DepthImage img =
      sim::renderDepth(w.scene, K, T_map_cam, DepthEncoding::kMono16Millimetres, 6.0);
  EXPECT_THROW(gpu.evaluateImage(img, K, bad, poses, MeasurementParams(), &out),
               std::invalid_argument);
  EXPECT_THROW(
      gpu.evaluateImage(img, test::smallCamera(), FrameParams(), poses, MeasurementParams(), &out),
      std::invalid_argument);
}

TEST(CudaBackendTest, EmptyAndDegenerateInputs) {
  GMM_MCL_REQUIRE_DEVICE();
  const auto& w = test::world();
  CudaBackend gpu;
  BackendOutput out;
  FrameParams fp;
  const DepthFrame frame = test::renderFrame(test::referenceBasePose(), test::vgaCamera(), fp);
  EXPECT_THROW(gpu.evaluate(frame, {}, MeasurementParams(), &out), BackendError);  // no map
  gpu.setMap(w.map);
  gpu.evaluate(frame, {}, MeasurementParams(), &out);
  EXPECT_TRUE(out.log_likelihood.empty());
  // A frame with no used pixels: every particle scores 0 nats.
  DepthFrame empty = frame;
  empty.x_m.clear();
  empty.y_m.clear();
  empty.z_m.clear();
  std::fill(empty.patch_begin.begin(), empty.patch_begin.end(), 0);
  const auto poses = perturbedPoses(test::referenceBasePose() * w.T_base_cam, 5, 3);
  gpu.evaluate(empty, poses, MeasurementParams(), &out);
  ASSERT_EQ(out.log_likelihood.size(), 5u);
  for (double l : out.log_likelihood) EXPECT_EQ(l, 0.0);
  // More particles than one mask batch holds still gives every particle its value.
  CpuBackend cpu;
  cpu.setMap(w.map);
  FrameParams coarse;
  coarse.pixel_stride = 16;
  const DepthFrame small = test::renderFrame(test::referenceBasePose(), test::vgaCamera(), coarse);
  const auto many = perturbedPoses(test::referenceBasePose() * w.T_base_cam, 7000, 4);
  BackendOutput a, b;
  cpu.evaluate(small, many, MeasurementParams(), &a);
  gpu.evaluate(small, many, MeasurementParams(), &b);
  for (size_t i = 0; i < many.size(); i += 97) {
    EXPECT_NEAR(a.log_likelihood[i], b.log_likelihood[i],
                kRelTol * std::max(std::abs(a.log_likelihood[i]), double(small.size())));
  }
}

// 7-Scenes redkitchen, M = 1000 map: frames from $GMM_MCL_7SCENES_FRAMES (a raw frame file
// written by `gmm_mcl_bench --export-frames`) or the data set's PNGs; map from $GMM_MCL_MAP or
// build/maps/7scenes_redkitchen_m1000.gmm.
TEST(CudaBackendTest, SevenScenesFramesMatchCpu) {
  GMM_MCL_REQUIRE_DEVICE();
  struct stat st;
  const char* env_map = std::getenv("GMM_MCL_MAP");
  std::string map_path = env_map && *env_map ? env_map : "";
  for (const char* cand :
       {"build/maps/7scenes_redkitchen_m1000.gmm", "../build/maps/7scenes_redkitchen_m1000.gmm",
        "../../build/maps/7scenes_redkitchen_m1000.gmm"}) {
    if (map_path.empty() && stat(cand, &st) == 0) map_path = cand;
  }
  if (map_path.empty() || stat(map_path.c_str(), &st) != 0) {
    GTEST_SKIP() << "7-Scenes M=1000 map not found (set GMM_MCL_MAP)";
  }
  bench::FrameSet frames;
  const char* env_frames = std::getenv("GMM_MCL_7SCENES_FRAMES");
  if (env_frames && *env_frames) {
    frames = bench::loadFrameSet(env_frames);
  } else {
#if defined(GMM_MCL_HAVE_PNG)
    const std::string dir = test::datasetsRoot() + "/7scenes_redkitchen/data";
    if (test::datasetsRoot().empty() || stat((dir + "/frame-000000.depth.png").c_str(), &st) != 0) {
      GTEST_SKIP() << "7-Scenes frames not found (set GMM_MCL_7SCENES_FRAMES or GMM_MCL_DATASETS)";
    }
    frames = bench::loadSevenScenes(dir, 0, 1);
    frames.images.push_back(bench::loadSevenScenes(dir, 50, 1).images[0]);
    frames.T_map_cam.push_back(bench::loadSevenScenes(dir, 50, 1).T_map_cam[0]);
#else
    GTEST_SKIP() << "7-Scenes frames need libpng or GMM_MCL_7SCENES_FRAMES";
#endif
  }
  const GmmMap map = loadMap(map_path);
  CpuBackend cpu;
  CudaBackend gpu;
  cpu.setMap(map);
  gpu.setMap(map);
  const size_t used = std::min<size_t>(frames.images.size(), 3);
  for (size_t f = 0; f < used; ++f) {
    const size_t idx = f * (frames.images.size() / used);
    FrameParams fp;
    fp.pixel_stride = 4;
    const DepthFrame frame = prepareFrame(frames.images[idx], frames.K, fp);
    const auto poses = perturbedPoses(frames.T_map_cam[idx], 256, 100u + unsigned(idx));
    const std::string label = "7-Scenes frame " + std::to_string(idx);
    expectSameLikelihood(map, frame, poses, &cpu, &gpu, label.c_str());
    const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 32);
    expectSameMembership(map, frame, some, &cpu, &gpu, label.c_str());
  }
  // Another patch size (a parameter of the model) on the first frame (8x8 patches: 4,800 of them
  // exceed the membership bitmask's shared memory at M = 1000).
  for (int patch : {16}) {
    FrameParams fp;
    fp.pixel_stride = 4;
    fp.patch_size_px = patch;
    const DepthFrame frame = prepareFrame(frames.images[0], frames.K, fp);
    const auto poses = perturbedPoses(frames.T_map_cam[0], 64, 300u + unsigned(patch));
    const std::string label =
        "7-Scenes frame 0, " + std::to_string(patch) + "x" + std::to_string(patch) + " patches";
    expectSameLikelihood(map, frame, poses, &cpu, &gpu, label.c_str());
    const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 8);
    expectSameMembership(map, frame, some, &cpu, &gpu, label.c_str());
  }
  // The benchmark's `large` map (M = 4000, $GMM_MCL_LARGE_MAP) when given.
  const char* env_large = std::getenv("GMM_MCL_LARGE_MAP");
  if (env_large && *env_large && stat(env_large, &st) == 0) {
    const GmmMap large = loadMap(env_large);
    cpu.setMap(large);
    gpu.setMap(large);
    for (int stride : {4, 8}) {
      FrameParams fp;
      fp.pixel_stride = stride;
      const DepthFrame frame = prepareFrame(frames.images[0], frames.K, fp);
      const auto poses = perturbedPoses(frames.T_map_cam[0], 128, 400u + unsigned(stride));
      const std::string label = "7-Scenes frame 0, M=" + std::to_string(large.size()) +
                                ", stride " + std::to_string(stride);
      expectSameLikelihood(large, frame, poses, &cpu, &gpu, label.c_str());
      const std::vector<RigidTransformF> some(poses.begin(), poses.begin() + 8);
      expectSameMembership(large, frame, some, &cpu, &gpu, label.c_str());
    }
  } else {
    std::printf("[ skipped  ] M=4000 map: GMM_MCL_LARGE_MAP not set\n");
  }
}

}  // namespace
}  // namespace gmm_mcl
