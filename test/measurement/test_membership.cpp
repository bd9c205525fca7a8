#include <gtest/gtest.h>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// The paper's approximation vs the exact sum over all components (DESIGN.md, Fig. 2).
constexpr double kApproxRelTol = 0.01;

TEST(MembershipTest, FastTableEqualsBruteForce) {
  const auto& w = test::world();
  FrameParams fp;
  for (const Intrinsics& K : {test::smallCamera(), test::vgaCamera()}) {
    const PatchGrid grid = PatchGrid::forImage(K.width_px, K.height_px, fp.patch_size_px);
    for (double yaw : {-0.6, 0.4, 2.0, 3.0}) {
      Eigen::Isometry3d T = test::referenceBasePose();
      T.linear() = rotationFromRpy(0.02, -0.03, yaw);
      const RigidTransformF T_cam_map = toRigidF((T * w.T_base_cam).inverse());
      PatchMembership fast, brute;
      std::vector<ProjectedComponent> proj;
      std::vector<char> valid;
      computeMembership(w.map.packed(), T_cam_map, K, grid, MeasurementParams(), &proj, &valid, &fast);
      computeMembershipBruteForce(w.map.packed(), T_cam_map, K, grid, MeasurementParams(), &brute);
      EXPECT_EQ(fast.begin, brute.begin);
      EXPECT_EQ(fast.comps, brute.comps);
      EXPECT_GT(fast.comps.size(), 0u);
    }
  }
}

TEST(MembershipTest, ApproximateLikelihoodWithinOnePercentOfExact) {
  const auto& w = test::world();
  FrameParams fp;
  fp.pixel_stride = 4;
  fp.max_range_m = 8.f;
  for (const Intrinsics& K : {test::smallCamera(), test::vgaCamera()}) {
    const Eigen::Isometry3d T_map_base = test::referenceBasePose();
    const DepthFrame frame = test::renderFrame(T_map_base, K, fp);
    const Eigen::Isometry3d T_map_cam = T_map_base * w.T_base_cam;
    LikelihoodScratch scratch;
    const FrameLikelihood approx = poseLogLikelihood(w.map.packed(), frame, toRigidF(T_map_cam),
                                                     MeasurementParams(), &scratch);
    const FrameLikelihood exact =
        exactFrameLogLikelihood(w.map, frame, T_map_cam, kDefaultFloorLogDensity);
    const double rel = std::abs(approx.log_likelihood - exact.log_likelihood) /
                       std::abs(exact.log_likelihood);
    std::printf("[ measured ] %dx%d: approx %.2f exact %.2f nats over %d px, relative error %.2e, "
                "evaluations %lld vs %lld, floor hits %d vs %d\n",
                K.width_px, K.height_px, approx.log_likelihood, exact.log_likelihood,
                approx.pixels, rel, approx.evaluations, exact.evaluations, approx.floor_hits,
                exact.floor_hits);
    EXPECT_LT(rel, kApproxRelTol);
    EXPECT_LT(approx.evaluations, exact.evaluations / 10);  // the point of the approximation
  }
}

TEST(MembershipTest, PatchesWithoutComponentsGetTheFloor) {
  const auto& w = test::world();
  const Intrinsics K = test::smallCamera();
  FrameParams fp;
  const DepthFrame frame = test::renderFrame(test::referenceBasePose(), K, fp);
  PatchMembership none;
  none.begin.assign(frame.grid.count() + 1, 0);
  std::vector<float> values;
  const FrameLikelihood fl = frameLogLikelihood(w.map.packed(), frame,
                                                toRigidF(test::referenceBasePose() * w.T_base_cam),
                                                none, -10.f, &values);
  EXPECT_EQ(fl.floor_hits, fl.pixels);
  EXPECT_NEAR(fl.log_likelihood, -10.0 * fl.pixels, 1e-6 * fl.pixels);
}

}  // namespace
}  // namespace gmm_mcl
