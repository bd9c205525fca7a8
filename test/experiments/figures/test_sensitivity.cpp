// The Sensitivity Analysis pipeline on the synthetic scene: the variance definition on
// hand-made samples, determinism (a run equal to the reference has zero divergence), and fewer
// particles giving a larger KL variance against the reference filter.
#include <gtest/gtest.h>

#include <cmath>

#include "gmm_mcl/experiments/figures/scenario.h"
#include "gmm_mcl/experiments/figures/sensitivity.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace figures {
namespace {

constexpr int kFrames = 12;
constexpr int kEvalFrom = 6;

TEST(SensitivitySummaryTest, VarianceAcrossRunsAveragedOverFrames) {
  // Frame 0: runs give 1, 2, 3 (variance 1); frame 1: 2, 4, 6 (variance 4) -> mean 2.5.
  std::vector<KlSample> s;
  const double v[2][3] = {{1, 2, 3}, {2, 4, 6}};
  for (int f = 0; f < 2; ++f) {
    for (int r = 0; r < 3; ++r) {
      KlSample k;
      k.sweep = "particles";
      k.value = 100;
      k.run = r;
      k.frame = f;
      k.kl = v[f][r];
      k.error_m = 0.01 * (r + 1);
      s.push_back(k);
    }
  }
  KlSample other = s[0];
  other.value = 200;
  other.kl = 1000.0;
  s.push_back(other);  // another value: ignored
  const KlSummary sum = summarise(s, "particles", 100);
  EXPECT_EQ(sum.runs, 3);
  EXPECT_EQ(sum.frames, 2);
  EXPECT_NEAR(sum.variance_kl, 2.5, 1e-12);
  EXPECT_NEAR(sum.mean_kl, 3.0, 1e-12);
  EXPECT_NEAR(sum.median_kl, 2.5, 1e-12);
  // Pooled over the six samples {1, 2, 3, 2, 4, 6}: mean 3, squared deviations 16, / 5.
  EXPECT_NEAR(sum.pooled_variance_kl, 3.2, 1e-12);
  EXPECT_NEAR(sum.mean_error_m, 0.02, 1e-12);
}

class SensitivityTest : public ::testing::Test {
 protected:
  static void SetUpTestCase() {
    scenario_ = new Scenario(syntheticScenario(0, kFrames, 320, 1));
    inputs_ = new SensorInputs(synthesiseInputs(*scenario_, SensorNoise(), 1));
  }
  static void TearDownTestCase() {
    delete scenario_;
    delete inputs_;
  }
  static FilterRunParams params(int particles) {
    FilterRunParams p;
    p.localizer.filter.num_particles = particles;
    p.localizer.frame.pixel_stride = 8;
    p.localizer.frame.max_range_m = scenario_->max_range_m;
    return p;
  }
  static Scenario* scenario_;
  static SensorInputs* inputs_;
};
Scenario* SensitivityTest::scenario_ = nullptr;
SensorInputs* SensitivityTest::inputs_ = nullptr;

TEST_F(SensitivityTest, InputsAreSeededAndDrift) {
  const SensorInputs again = synthesiseInputs(*scenario_, SensorNoise(), 1);
  const SensorInputs other = synthesiseInputs(*scenario_, SensorNoise(), 2);
  ASSERT_EQ(inputs_->T_odom_base.size(), static_cast<size_t>(kFrames));
  EXPECT_TRUE(inputs_->T_odom_base[0].isApprox(scenario_->T_map_base[0]));
  EXPECT_TRUE(again.T_odom_base.back().isApprox(inputs_->T_odom_base.back()));
  EXPECT_FALSE(other.T_odom_base.back().isApprox(inputs_->T_odom_base.back(), 1e-6));
  const double drift =
      (inputs_->T_odom_base.back().translation() - scenario_->T_map_base.back().translation())
          .norm();
  EXPECT_GT(drift, 0.0);
  EXPECT_LT(drift, 0.1);  // 11 steps of 5 mm per axis
}

TEST_F(SensitivityTest, ARunEqualToTheReferenceHasZeroDivergence) {
  const GmmMap& map = test::world().map;
  const RunTrace a = runFilter(*scenario_, *inputs_, map, params(100), 7);
  const RunTrace b = runFilter(*scenario_, *inputs_, map, params(100), 7);
  const RunTrace c = runFilter(*scenario_, *inputs_, map, params(100), 8);
  std::vector<KlSample> same, other;
  collectKl(a, b, "particles", 100, 0, 7, 0, 0.0, &same);
  collectKl(a, c, "particles", 100, 0, 8, 0, 1e-8, &other);
  ASSERT_EQ(same.size(), static_cast<size_t>(kFrames));
  double other_sum = 0.0;
  for (size_t i = 0; i < same.size(); ++i) {
    EXPECT_EQ(same[i].kl, 0.0) << "frame " << i;
    EXPECT_TRUE(std::isfinite(other[i].kl));
    other_sum += other[i].kl;
  }
  EXPECT_GT(other_sum, 0.0);  // another seed: another particle set
  // The filter tracks from the local start on the synthetic scene.
  EXPECT_LT(a.error_m.back(), 0.1);
}

TEST_F(SensitivityTest, FewerParticlesGiveLargerKlVariance) {
  const GmmMap& map = test::world().map;
  SweepParams sweep;
  sweep.runs = 3;
  sweep.eval_from_frame = kEvalFrom;
  std::vector<KlSample> samples;
  const std::vector<KlSummary> rows =
      particleSweep(*scenario_, *inputs_, map, params(0), {16, 128}, 512, sweep, &samples);
  ASSERT_EQ(rows.size(), 3u);  // two counts and the reference row
  EXPECT_EQ(rows[2].value, 512);
  EXPECT_EQ(rows[2].runs, 1);
  EXPECT_EQ(samples.size(), 2u * 3u * (kFrames - kEvalFrom));
  for (const KlSample& s : samples) {
    EXPECT_TRUE(std::isfinite(s.kl));
    EXPECT_GE(s.kl, 0.0);
  }
  std::printf("[ measured ] N=16: Var KL %.3g mean KL %.3g; N=128: Var KL %.3g mean KL %.3g\n",
              rows[0].variance_kl, rows[0].mean_kl, rows[1].variance_kl, rows[1].mean_kl);
  EXPECT_EQ(rows[0].runs, 3);
  EXPECT_EQ(rows[0].frames, kFrames - kEvalFrom);
  EXPECT_GT(rows[0].variance_kl, rows[1].variance_kl);
  EXPECT_GT(rows[0].mean_kl, rows[1].mean_kl);
}

}  // namespace
}  // namespace figures
}  // namespace gmm_mcl
