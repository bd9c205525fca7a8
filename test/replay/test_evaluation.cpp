#include <gtest/gtest.h>

#include <cmath>

#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/replay/evaluation.h"

namespace gmm_mcl {
namespace {

std::vector<FrameError> errors(const std::vector<double>& e_m) {
  std::vector<FrameError> out;
  for (size_t i = 0; i < e_m.size(); ++i) {
    FrameError f;
    f.stamp_s = i / 30.0;
    f.translation_m = e_m[i];
    f.yaw_rad = 0.01;
    out.push_back(f);
  }
  return out;
}

TEST(EvaluationTest, ConvergenceAteAndSuccess) {
  EvaluationParams p;
  p.hold_frames = 3;
  p.tail_frames = 2;
  // Dips below 10 cm at frame 2 but only for two frames; stays from frame 5 on.
  const TrialMetrics m =
      evaluateTrial(errors({0.5, 0.3, 0.05, 0.06, 0.2, 0.04, 0.03, 0.05, 0.02}), p);
  EXPECT_TRUE(m.converged);
  EXPECT_EQ(m.converge_frame, 5);
  EXPECT_NEAR(m.converge_time_s, 5 / 30.0, 1e-12);
  EXPECT_NEAR(m.ate_translation_m,
              std::sqrt((0.04 * 0.04 + 0.03 * 0.03 + 0.05 * 0.05 + 0.02 * 0.02) / 4), 1e-12);
  EXPECT_NEAR(m.ate_yaw_rad, 0.01, 1e-12);
  EXPECT_TRUE(m.success);
}

TEST(EvaluationTest, LateDivergenceIsAFailureAndNeverConvergingToo) {
  EvaluationParams p;
  p.hold_frames = 2;
  p.tail_frames = 2;
  TrialMetrics m = evaluateTrial(errors({0.05, 0.05, 0.05, 0.5}), p);
  EXPECT_TRUE(m.converged);
  EXPECT_FALSE(m.success);
  m = evaluateTrial(errors({0.5, 0.05, 0.5, 0.05}), p);
  EXPECT_FALSE(m.converged);
  EXPECT_FALSE(m.success);
}

TEST(EvaluationTest, GravityAlignmentPointsDownAlongMinusZ) {
  const Eigen::Vector3d down(-0.0089, 0.9044, 0.4265);  // 7-Scenes redkitchen
  const Eigen::Matrix3d R = gravityAlignment(down);
  EXPECT_TRUE((R * R.transpose()).isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  const Eigen::Vector3d d = R * down.normalized();
  EXPECT_NEAR(d.z(), -1.0, 1e-12);
  EXPECT_GT((R * Eigen::Vector3d::UnitX()).x(), 0.9);  // x kept close to world x
}

}  // namespace
}  // namespace gmm_mcl
