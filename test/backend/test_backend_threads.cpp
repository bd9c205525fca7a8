// The CPU backend's OpenMP path under the sanitizers (scripts/test.sh's sanitizer stage, where
// the localizer's convergence case is too slow): particles spread around the reference pose
// give the same per-particle log-likelihoods with 1, 2 and 3 threads, since each particle is one
// thread's work with its own scratch.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/filter/pose.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

TEST(BackendThreadsTest, SameLikelihoodsForEveryThreadCount) {
  const auto& w = test::world();
  const Intrinsics K = test::smallCamera();
  FrameParams fp = test::frameParams(8);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const DepthFrame frame = test::renderFrame(T_map_base, K, fp);
  ASSERT_FALSE(frame.empty());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 0.3);
  std::vector<RigidTransformF> poses;
  for (int i = 0; i < 48; ++i) {
    Eigen::Isometry3d T = T_map_base;
    T.translation() += Eigen::Vector3d(g(rng), g(rng), 0.3 * g(rng));
    poses.push_back(toRigidF(T * w.T_base_cam));
  }
  const MeasurementParams params;
  BackendOutput reference;
  CpuBackend one(1);
  one.setMap(w.map);
  one.evaluate(frame, poses, params, &reference);
  ASSERT_EQ(reference.log_likelihood.size(), poses.size());
  for (int threads : {2, 3}) {
    CpuBackend many(threads);
    many.setMap(w.map);
    BackendOutput out;
    many.evaluate(frame, poses, params, &out);
    EXPECT_EQ(out.log_likelihood, reference.log_likelihood) << threads << " threads";
    EXPECT_EQ(out.floor_hits, reference.floor_hits) << threads << " threads";
    EXPECT_EQ(out.evaluations, reference.evaluations) << threads << " threads";
  }
}

}  // namespace
}  // namespace gmm_mcl
