// UpdateBudget: the frame period from stamps (seq gaps, clock rate), cuts over the budget
// (stride first, then particles, within bounds), steps back with hysteresis, and a simulated
// cost model that must settle without oscillating. Driven by synthetic numbers only.
#include <gtest/gtest.h>

#include <algorithm>

#include "gmm_mcl/filter/update_budget.h"

namespace gmm_mcl {
namespace {

constexpr double kPeriod30HzS = 1.0 / 30.0;
constexpr double kTolMs = 1e-6;

struct BudgetSetup {
  UpdateBudgetParams budget;
  LocalizerParams configured;
  BudgetSetup() {
    configured.filter.num_particles = 1000;
    configured.frame.pixel_stride = 4;
    configured.refinement.enabled = true;
    budget.max_pixel_stride = 12;
    budget.min_particles = 200;
  }
  UpdateBudget make() const { return UpdateBudget(budget, configured); }
};

// n frames at `period_s` on a clock running at `rate` times wall time, seq from seq0 by seq_step.
void feedFrames(UpdateBudget* b, int n, double period_s, double rate = 1.0, uint32_t seq_step = 1,
                double t0 = 100.0) {
  for (int i = 0; i < n; ++i) {
    const double stamp = t0 + i * period_s * seq_step;
    b->frameArrived(stamp, static_cast<uint32_t>(i * seq_step), stamp, 10.0 + (stamp - t0) / rate);
  }
}

// The budget's settings, and the parameters it gives the localizer configured with `configured`.
void expectState(const UpdateBudget& b, int pixel_stride, int particle_cap, bool refine) {
  EXPECT_EQ(b.state().pixel_stride, pixel_stride);
  EXPECT_EQ(b.state().particle_cap, particle_cap);
  EXPECT_EQ(b.state().refine, refine);
}
void expectApplied(const UpdateBudget& b, const LocalizerParams& configured, int pixel_stride,
                   int num_particles, bool refine) {
  const LocalizerParams p = b.apply(configured);
  EXPECT_EQ(p.frame.pixel_stride, pixel_stride);
  EXPECT_EQ(p.filter.num_particles, num_particles);
  EXPECT_EQ(p.refinement.enabled, refine);
}

TEST(UpdateBudgetParamsTest, DefaultsValidAndFaultsNamed) {
  EXPECT_EQ(UpdateBudgetParams().validate(), "");
  UpdateBudgetParams p;
  p.max_update_ms = -1;
  p.headroom_fraction = 1.5;
  p.min_particles = 0;
  const std::string err = p.validate();
  EXPECT_NE(err.find("max_update_ms"), std::string::npos) << err;
  EXPECT_NE(err.find("headroom_fraction"), std::string::npos) << err;
  EXPECT_NE(err.find("min_particles"), std::string::npos) << err;
}

TEST(UpdateBudgetTest, BudgetFromStampsSeqGapsAndClockRate) {
  BudgetSetup s;
  UpdateBudget b = s.make();
  EXPECT_EQ(b.budgetMs(), 0.0);  // no frame yet: no budget, and no cut
  EXPECT_FALSE(b.updateTook(500.0, 1000));
  feedFrames(&b, 10, kPeriod30HzS);
  EXPECT_NEAR(b.budgetMs(), 1000.0 * kPeriod30HzS, kTolMs);

  // Every third frame arrives (the others dropped before arriving): seq gaps are divided out.
  UpdateBudget gaps = s.make();
  feedFrames(&gaps, 10, kPeriod30HzS, 1.0, 3);
  EXPECT_NEAR(gaps.state().frame_period_s, kPeriod30HzS, 1e-9);

  // A bag played at half rate under --clock: twice the wall time per frame.
  UpdateBudget slow = s.make();
  feedFrames(&slow, 200, kPeriod30HzS, 0.5);
  EXPECT_NEAR(slow.state().clock_rate, 0.5, 1e-9);
  EXPECT_NEAR(slow.budgetMs(), 2000.0 * kPeriod30HzS, kTolMs);

  // max_update_ms wins.
  s.budget.max_update_ms = 20.0;
  UpdateBudget fixed = s.make();
  feedFrames(&fixed, 10, kPeriod30HzS);
  EXPECT_EQ(fixed.budgetMs(), 20.0);
}

TEST(UpdateBudgetTest, CutsStrideFirstThenParticlesWithinBounds) {
  BudgetSetup s;
  UpdateBudget b = s.make();
  feedFrames(&b, 10, kPeriod30HzS);
  // One or two slow updates are not a trend.
  EXPECT_FALSE(b.updateTook(100.0, 1000));
  EXPECT_FALSE(b.updateTook(100.0, 1000));
  EXPECT_EQ(b.state().pixel_stride, 4);
  EXPECT_TRUE(b.updateTook(100.0, 1000));  // the third
  const int stride1 = b.state().pixel_stride;
  EXPECT_GT(stride1, 4);
  EXPECT_LE(stride1, 12);
  EXPECT_EQ(b.state().particle_cap, 1000);  // stride first
  EXPECT_TRUE(b.state().refine);
  // Always far over: the stride reaches its ceiling, then the refinement goes, then the particles
  // reach their floor, no further.
  int prev_stride = stride1, prev_cap = 1000;
  for (int i = 0; i < 60; ++i) {
    b.updateTook(1000.0, b.state().particle_cap, 10.0);
    EXPECT_GE(b.state().pixel_stride, prev_stride);
    EXPECT_LE(b.state().particle_cap, prev_cap);
    if (!b.state().refine) {
      EXPECT_EQ(b.state().pixel_stride, 12);
    }
    if (b.state().particle_cap < 1000) {
      EXPECT_FALSE(b.state().refine);
    }
    prev_stride = b.state().pixel_stride;
    prev_cap = b.state().particle_cap;
  }
  expectState(b, 12, 200, false);
  EXPECT_FALSE(b.updateTook(1000.0, 200));
  EXPECT_TRUE(b.state().at_limit);
  expectApplied(b, s.configured, 12, 200, false);
}

TEST(UpdateBudgetTest, StepsBackParticlesFirstOnlyAfterSustainedHeadroom) {
  BudgetSetup s;
  s.budget.headroom_updates = 10;
  UpdateBudget b = s.make();
  feedFrames(&b, 10, kPeriod30HzS);
  for (int i = 0; i < 60; ++i) b.updateTook(1000.0, b.state().particle_cap);
  ASSERT_EQ(b.state().particle_cap, 200);
  // Fast updates, but one not fast enough in between restarts the count.
  for (int i = 0; i < 9; ++i) EXPECT_FALSE(b.updateTook(1.0, 200));
  EXPECT_FALSE(b.updateTook(30.0, 200));  // under the budget, without headroom for a step
  for (int i = 0; i < 9; ++i) EXPECT_FALSE(b.updateTook(1.0, 200));
  EXPECT_TRUE(b.updateTook(1.0, 200));
  EXPECT_GT(b.state().particle_cap, 200);
  EXPECT_EQ(b.state().pixel_stride, 12);  // particles first
  EXPECT_FALSE(b.state().refine);
  // Plenty of headroom for long: everything back to the configured values, in the reverse order
  // of the cuts: particles, refinement, stride.
  bool out_of_order = false;
  for (int i = 0; i < 2000; ++i) {
    b.updateTook(1.0, b.state().particle_cap, b.state().refine ? 0.5 : 0.0);
    if (b.state().refine && b.state().particle_cap < 1000) out_of_order = true;
    if (b.state().pixel_stride < 12 && !b.state().refine) out_of_order = true;
  }
  EXPECT_FALSE(out_of_order);
  expectState(b, 4, 1000, true);
  expectApplied(b, s.configured, 4, 1000, true);
}

// A machine where an update costs a fixed part plus a part proportional to particles times
// pixels: the budget settles under the period and stops changing (no oscillation).
TEST(UpdateBudgetTest, SettlesUnderTheBudgetWithoutOscillating) {
  BudgetSetup s;
  s.budget.max_pixel_stride = 16;
  s.budget.min_particles = 100;
  UpdateBudget b = s.make();
  const double budget_ms = 1000.0 * kPeriod30HzS;
  const double refine_ms = 12.0;
  auto cost = [refine_ms](int stride, int particles, bool refine) {
    const double pixels = (640.0 / stride) * (480.0 / stride);
    return 4.0 + 0.02 * particles + 1.2e-5 * particles * pixels + (refine ? refine_ms : 0.0);
  };
  feedFrames(&b, 10, kPeriod30HzS);
  ASSERT_GT(cost(4, 1000, true), 3 * budget_ms);  // far over at the configured values
  int changes_late = 0;
  for (int i = 0; i < 3000; ++i) {
    const int n = b.state().particle_cap;
    const bool r = b.state().refine;
    const bool changed = b.updateTook(cost(b.state().pixel_stride, n, r), n, r ? refine_ms : 0.0);
    if (i >= 1000 && changed) ++changes_late;
  }
  EXPECT_EQ(changes_late, 0);
  EXPECT_LE(cost(b.state().pixel_stride, b.state().particle_cap, b.state().refine), budget_ms);
  // ... and not needlessly far under it: the next step back would not fit in the headroom.
  EXPECT_GT(b.state().particle_cap, 100);
  EXPECT_GE(b.state().cuts, 1);
}

TEST(UpdateBudgetTest, DisabledChangesNothing) {
  BudgetSetup s;
  s.budget.enabled = false;
  UpdateBudget b = s.make();
  feedFrames(&b, 10, kPeriod30HzS);
  for (int i = 0; i < 20; ++i) EXPECT_FALSE(b.updateTook(1000.0, 1000));
  EXPECT_EQ(b.state().pixel_stride, 4);
  EXPECT_EQ(b.state().particle_cap, 1000);
}

TEST(UpdateBudgetTest, ApplyKeepsAdaptiveRangesValidAndReconfigureClamps) {
  BudgetSetup s;
  s.configured.filter.num_particles = 3000;
  s.configured.filter.min_particles = 1068;
  s.configured.filter.resample_groups = 4;
  s.budget.min_particles = 3;
  UpdateBudget b = s.make();
  feedFrames(&b, 10, kPeriod30HzS);
  for (int i = 0; i < 200; ++i) b.updateTook(1e5, b.state().particle_cap);
  ASSERT_EQ(b.state().particle_cap, 3);
  LocalizerParams c;
  c = s.configured;
  const LocalizerParams p = b.apply(c);
  EXPECT_EQ(p.validate(), "");
  EXPECT_EQ(p.filter.num_particles, 3);
  EXPECT_LE(p.filter.resample_groups, 3);
  // A larger floor and a smaller ceiling from dynamic_reconfigure clamp the choice.
  s.budget.min_particles = 500;
  s.budget.max_pixel_stride = 8;
  b.configure(s.budget, s.configured);
  EXPECT_EQ(b.state().particle_cap, 500);
  EXPECT_EQ(b.state().pixel_stride, 8);
  // Switched off: back to the configured values at once.
  s.budget.enabled = false;
  b.configure(s.budget, s.configured);
  EXPECT_EQ(b.state().particle_cap, 3000);
  EXPECT_EQ(b.state().pixel_stride, 4);
  EXPECT_EQ(b.apply(c).filter.num_particles, 3000);
}

}  // namespace
}  // namespace gmm_mcl
