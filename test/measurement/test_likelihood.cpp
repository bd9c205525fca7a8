#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/internal/cpu_simd.h"
#include "gmm_mcl/internal/fast_math.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

constexpr double kSweepStepM = 0.05;
constexpr double kSweepStepRad = 0.05;
constexpr int kSweepHalfSteps = 10;  // +-0.5 m, +-0.5 rad

double logLikelihoodAt(const DepthFrame& frame, const Particle& p, double roll, double pitch) {
  const auto& w = test::world();
  LikelihoodScratch scratch;
  return poseLogLikelihood(w.map.packed(), frame,
                           toRigidF(particleToPose(p, roll, pitch) * w.T_base_cam),
                           MeasurementParams(), &scratch)
      .log_likelihood;
}

// Paper Fig. 2: the log-likelihood peaks at the true pose along x, y, z and yaw.
TEST(LikelihoodTest, PeaksAtTheTruePose) {
  const Eigen::Isometry3d T_true = test::referenceBasePose();
  FrameParams fp;
  fp.max_range_m = 8.f;
  const DepthFrame frame = test::renderFrame(T_true, test::smallCamera(), fp);
  double roll, pitch, yaw;
  rpyFromRotation(T_true.linear(), &roll, &pitch, &yaw);
  const Particle truth = poseToParticle(T_true);
  const char* names[4] = {"x", "y", "z", "yaw"};
  for (int axis = 0; axis < 4; ++axis) {
    int best_k = 0;
    double best = -1e300;
    std::printf("[ measured ] sweep %s:", names[axis]);
    for (int k = -kSweepHalfSteps; k <= kSweepHalfSteps; ++k) {
      Particle p = truth;
      if (axis == 0) p.x_m += k * kSweepStepM;
      if (axis == 1) p.y_m += k * kSweepStepM;
      if (axis == 2) p.z_m += k * kSweepStepM;
      if (axis == 3) p.yaw_rad += k * kSweepStepRad;
      const double l = logLikelihoodAt(frame, p, roll, pitch);
      if (k % 5 == 0) std::printf(" %+d:%.0f", k, l);
      if (l > best) {
        best = l;
        best_k = k;
      }
    }
    std::printf("  argmax step %d\n", best_k);
    EXPECT_LE(std::abs(best_k), 1) << names[axis];
  }
}

TEST(LikelihoodTest, FloatKernelAgreesWithDoubleReferencePerPixel) {
  // With all components relevant, the float32 kernel equals the exact double sum up to
  // float rounding: DESIGN.md quotes about 1e-4 nats per pixel.
  const auto& w = test::world();
  FrameParams fp;
  fp.pixel_stride = 8;
  const Eigen::Isometry3d T = test::referenceBasePose() * w.T_base_cam;
  const DepthFrame frame = test::renderFrame(test::referenceBasePose(), test::smallCamera(), fp);
  PatchMembership all;
  all.begin.push_back(0);
  for (int p = 0; p < frame.grid.count(); ++p) {
    for (size_t i = 0; i < w.map.size(); ++i) all.comps.push_back(static_cast<int>(i));
    all.begin.push_back(static_cast<int>(all.comps.size()));
  }
  std::vector<float> values;
  const FrameLikelihood f =
      frameLogLikelihood(w.map.packed(), frame, toRigidF(T), all, -10.f, &values);
  const FrameLikelihood d = exactFrameLogLikelihood(w.map, frame, T, -10.f);
  EXPECT_NEAR(f.log_likelihood, d.log_likelihood, 2e-4 * f.pixels);
  EXPECT_EQ(f.floor_hits, d.floor_hits);
}

TEST(LikelihoodTest, CholeskyEvaluationFormMatchesThePrecisionForm) {
  // makeEvalComponentF: base - |U p + c|^2 (both kernels) against the double-precision density
  // of the packed component, within 3 standard deviations of each mean.
  const auto& comps = test::world().map.packed();
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst = 0.0;
  for (const ComponentF& c : comps) {
    const EvalComponentF e = makeEvalComponentF(c, kEvalScaleNats);
    const EvalComponentF e2 = makeEvalComponentF(c, kEvalScaleLog2);
    const Eigen::Matrix3d cov =
        (Eigen::Matrix3d() << c.cov_m2[0], c.cov_m2[1], c.cov_m2[2], c.cov_m2[1], c.cov_m2[3],
         c.cov_m2[4], c.cov_m2[2], c.cov_m2[4], c.cov_m2[5])
            .finished();
    const Eigen::Matrix3d L = cov.llt().matrixL();
    for (int k = 0; k < 20; ++k) {
      Eigen::Vector3d z(n01(rng), n01(rng), n01(rng));
      if (z.norm() > 3.0) z *= 3.0 / z.norm();
      const Eigen::Vector3d p = Eigen::Vector3d(c.mean_m[0], c.mean_m[1], c.mean_m[2]) + L * z;
      const double ref = c.log_norm - 0.5 * z.squaredNorm();
      const float pf[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()),
                           static_cast<float>(p.z())};
      worst = std::max(worst, std::abs(evalLogDensity(e, pf[0], pf[1], pf[2]) - ref));
      worst =
          std::max(worst, std::abs(evalLogDensity(e2, pf[0], pf[1], pf[2]) / kEvalScaleLog2 - ref));
    }
  }
  std::printf(
      "[ measured ] Cholesky form: worst |ln density error| %.2e nats over %zu components\n", worst,
      comps.size());
  EXPECT_LT(worst, 1e-3);  // float rounding of map-frame points (DESIGN.md: ~1e-4 per pixel)
}

TEST(LikelihoodTest, FastLogIsAccurate) {
  double worst = 0.0;
  for (double lx = -85.0; lx <= 85.0; lx += 0.00037) {
    const float x = static_cast<float>(std::exp(lx));
    const double ref = std::log(static_cast<double>(x));
    worst = std::max(worst, std::abs(logPositive(x) - ref) / std::max(1.0, std::abs(ref)));
  }
  std::printf("[ measured ] logPositive: worst error / max(1, |ln x|) = %.2e\n", worst);
  EXPECT_LT(worst, 1e-7);
  EXPECT_EQ(logPositive(1.f), 0.f);
}

TEST(LikelihoodTest, FastExpIsAccurate) {
  double worst = 0.0;
  for (float x = -87.f; x <= 0.f; x += 0.0137f) {
    const double rel = std::abs(expNonPositive(x) - std::exp(static_cast<double>(x))) /
                       std::exp(static_cast<double>(x));
    worst = std::max(worst, rel);
  }
  EXPECT_LT(worst, 3e-7);
  EXPECT_GT(expNonPositive(-1000.f), 0.f);
  EXPECT_EQ(expNonPositive(0.f), 1.f);
}

// The CPU kernel's 8-lane exp and ln (cpu_simd.h).
TEST(LikelihoodTest, VectorExpAndLogAreAccurate) {
  double worst_exp = 0.0;
  for (float x0 = -87.f; x0 <= 0.f; x0 += 8 * 0.00137f) {
    alignas(32) float in[8], out[8];
    for (int i = 0; i < 8; ++i) in[i] = std::min(0.f, x0 + i * 0.00137f);
    simd::store(out, simd::expNonPositive8(simd::load(in)));
    for (int i = 0; i < 8; ++i) {
      const double ref = std::exp(static_cast<double>(in[i]));
      worst_exp = std::max(worst_exp, std::abs(out[i] - ref) / ref);
    }
  }
  double worst_log = 0.0;
  int differ = 0;
  for (double lx = -85.0; lx <= 85.0; lx += 8 * 0.00037) {
    alignas(32) float in[8], out[8];
    for (int i = 0; i < 8; ++i) in[i] = static_cast<float>(std::exp(lx + i * 0.00037));
    simd::store(out, simd::logPositive8(simd::load(in)));
    for (int i = 0; i < 8; ++i) {
      const double ref = std::log(static_cast<double>(in[i]));
      worst_log = std::max(worst_log, std::abs(out[i] - ref) / std::max(1.0, std::abs(ref)));
      differ += out[i] != logPositive(in[i]) ? 1 : 0;
    }
  }
  std::printf(
      "[ measured ] expNonPositive8: worst relative error %.2e on [-87, 0]; logPositive8: "
      "worst error / max(1, |ln x|) %.2e, %d values differ from logPositive\n",
      worst_exp, worst_log, differ);
  EXPECT_LT(worst_exp, 3e-7);
  EXPECT_LT(worst_log, 1e-7);
  alignas(32) float big[8] = {-1000.f, -88.f, -87.f, 0.f, -1e30f, -0.f, -1e-30f, -50.f}, e[8];
  simd::store(e, simd::expNonPositive8(simd::load(big)));
  for (int i = 0; i < 8; ++i) EXPECT_GT(e[i], 0.f) << big[i];
  EXPECT_EQ(e[3], 1.f);
}

#if defined(GMM_MCL_SIMD_16)
// The AVX-512 kernel's 16-lane exp and ln give the 8-lane ones' bits lane by lane (the CPU
// likelihood's sums do not depend on which of the two the build uses).
TEST(LikelihoodTest, SixteenLaneExpAndLogMatchEightLane) {
  int differ_exp = 0, differ_log = 0, compared = 0;
  for (float x0 = -90.f; x0 <= 0.f; x0 += 16 * 0.00071f) {
    alignas(64) float in[16], e16[16], e8[16], l16[16], l8[16], pos[16];
    for (int i = 0; i < 16; ++i) {
      in[i] = std::min(0.f, x0 + i * 0.00071f);
      pos[i] = std::exp(-x0 - i * 0.00071f) * 1e-20f;
    }
    simd::store16(e16, simd::expNonPositive16(simd::load16(in)));
    simd::store16(l16, simd::logPositive16(simd::load16(pos)));
    for (int h = 0; h < 2; ++h) {
      simd::store(e8 + 8 * h, simd::expNonPositive8(simd::load(in + 8 * h)));
      simd::store(l8 + 8 * h, simd::logPositive8(simd::load(pos + 8 * h)));
    }
    for (int i = 0; i < 16; ++i) {
      differ_exp += std::memcmp(&e16[i], &e8[i], sizeof(float)) != 0 ? 1 : 0;
      differ_log += std::memcmp(&l16[i], &l8[i], sizeof(float)) != 0 ? 1 : 0;
      ++compared;
    }
  }
  EXPECT_GT(compared, 100000);
  EXPECT_EQ(differ_exp, 0);
  EXPECT_EQ(differ_log, 0);
}
#endif

}  // namespace
}  // namespace gmm_mcl
