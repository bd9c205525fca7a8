#include <gtest/gtest.h>

#include "gmm_mcl/common/fast_math.h"
#include "gmm_mcl/filter/pose.h"
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
  const FrameLikelihood f = frameLogLikelihood(w.map.packed(), frame, toRigidF(T), all, -10.f, &values);
  const FrameLikelihood d = exactFrameLogLikelihood(w.map, frame, T, -10.f);
  EXPECT_NEAR(f.log_likelihood, d.log_likelihood, 2e-4 * f.pixels);
  EXPECT_EQ(f.floor_hits, d.floor_hits);
}

TEST(LikelihoodTest, FastExpIsAccurate) {
  double worst = 0.0;
  for (float x = -87.f; x <= 0.f; x += 0.0137f) {
    const double rel = std::abs(expNonPositive(x) - std::exp(static_cast<double>(x))) / std::exp(static_cast<double>(x));
    worst = std::max(worst, rel);
  }
  EXPECT_LT(worst, 3e-7);
  EXPECT_GT(expNonPositive(-1000.f), 0.f);
  EXPECT_EQ(expNonPositive(0.f), 1.f);
}

}  // namespace
}  // namespace gmm_mcl
