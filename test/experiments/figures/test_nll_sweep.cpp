// Paper Fig. 2 on the synthetic scene: the sweep's minimum is at the true pose along every
// axis, and the approximation (patch membership) agrees with the exact sum near the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "gmm_mcl/experiments/figures/nll_sweep.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace figures {
namespace {

// The approximation drops components, so its NLL can only be higher than the exact one, up to
// the float32 kernel's rounding (DESIGN.md: about 1e-4 nats per pixel; test_likelihood 2e-4).
constexpr double kFloatTolPerPixel = 2e-4;
// Near the truth (|offset| <= kNearOffset) both agree within 1% (test_membership's tolerance).
constexpr double kNearOffset = 0.1;
constexpr double kNearRelTol = 0.01;
constexpr double kStep = 0.05;

class NllSweepTest : public ::testing::Test {
 protected:
  static void SetUpTestCase() {
    const auto& w = test::world();
    FrameParams fp = test::frameParams(8);
    frame_ = new DepthFrame(test::renderFrame(test::referenceBasePose(), test::smallCamera(), fp));
    NllSweepParams p;
    p.half_range_m = 0.3;
    p.step_m = kStep;
    p.half_range_rad = 0.3;
    p.step_rad = kStep;
    rows_ = new std::vector<NllSweepRow>(
        nllSweep(w.map, *frame_, test::referenceBasePose(), w.T_base_cam, p));
  }
  static void TearDownTestCase() {
    delete rows_;
    delete frame_;
  }
  static DepthFrame* frame_;
  static std::vector<NllSweepRow>* rows_;
};
DepthFrame* NllSweepTest::frame_ = nullptr;
std::vector<NllSweepRow>* NllSweepTest::rows_ = nullptr;

TEST(SweepOffsetsTest, SymmetricIncludesZeroAndEnds) {
  const std::vector<double> o = sweepOffsets(0.5, 0.025);
  ASSERT_EQ(o.size(), 41u);
  EXPECT_DOUBLE_EQ(o.front(), -0.5);
  EXPECT_DOUBLE_EQ(o[20], 0.0);
  EXPECT_DOUBLE_EQ(o.back(), 0.5);
  EXPECT_EQ(sweepOffsets(0.0, 0.1).size(), 1u);
}

TEST(SweepOffsetsTest, InvalidParametersAreRejected) {
  NllSweepParams p;
  p.step_m = 0.0;
  EXPECT_FALSE(p.validate().empty());
  const auto& w = test::world();
  EXPECT_THROW(nllSweep(w.map, DepthFrame(), test::referenceBasePose(), w.T_base_cam, p),
               std::invalid_argument);
}

TEST_F(NllSweepTest, RowsCoverEveryAxis) {
  ASSERT_EQ(rows_->size(), 4u * 13u);
  for (int a = 0; a < 4; ++a) {
    EXPECT_EQ((*rows_)[a * 13].axis, kAllSweepAxes[a]);
    EXPECT_NEAR((*rows_)[a * 13 + 6].offset, 0.0, 1e-12);
  }
  for (const NllSweepRow& r : *rows_) {
    EXPECT_EQ(r.pixels, static_cast<int>(frame_->size()));
    EXPECT_TRUE(std::isfinite(r.approx_nll));
    EXPECT_TRUE(std::isfinite(r.exact_nll));
    EXPECT_LT(r.approx_evaluations, r.exact_evaluations);
  }
}

TEST_F(NllSweepTest, MinimumAtZeroDisplacement) {
  for (SweepAxis axis : kAllSweepAxes) {
    double best_a = 1e300, best_e = 1e300, at_a = 1, at_e = 1;
    std::printf("[ measured ] %-3s:", sweepAxisName(axis));
    for (const NllSweepRow& r : *rows_) {
      if (r.axis != axis) continue;
      std::printf(" %+.2f:%.0f/%.0f", r.offset, r.approx_nll, r.exact_nll);
      if (r.approx_nll < best_a) best_a = r.approx_nll, at_a = r.offset;
      if (r.exact_nll < best_e) best_e = r.exact_nll, at_e = r.offset;
    }
    std::printf("\n");
    EXPECT_NEAR(at_a, 0.0, 1e-9) << sweepAxisName(axis) << " approximate";
    EXPECT_NEAR(at_e, 0.0, 1e-9) << sweepAxisName(axis) << " exact";
  }
}

TEST_F(NllSweepTest, ApproximationNeverBelowExactAndCloseNearTheTruth) {
  double worst_near = 0.0;
  for (const NllSweepRow& r : *rows_) {
    EXPECT_GE(r.approx_nll, r.exact_nll - kFloatTolPerPixel * r.pixels)
        << sweepAxisName(r.axis) << " " << r.offset;
    if (std::abs(r.offset) <= kNearOffset + 1e-9) {
      const double rel = std::abs(r.approx_nll - r.exact_nll) / std::abs(r.exact_nll);
      worst_near = std::max(worst_near, rel);
      EXPECT_LT(rel, kNearRelTol) << sweepAxisName(r.axis) << " " << r.offset;
    }
  }
  std::printf("[ measured ] worst relative |approx - exact| within %.1f: %.2e\n", kNearOffset,
              worst_near);
}

TEST_F(NllSweepTest, CsvHasAHeaderAndOneLinePerRow) {
  const std::string path = ::testing::TempDir() + "nll_sweep_test.csv";
  writeNllSweepCsv(*rows_, path);
  std::ifstream in(path);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line.rfind("axis,offset,unit,pixels,approx_nll,exact_nll", 0), 0u);
  size_t n = 0;
  while (std::getline(in, line)) {
    if (!line.empty()) ++n;
  }
  EXPECT_EQ(n, rows_->size());
  std::remove(path.c_str());
}

}  // namespace
}  // namespace figures
}  // namespace gmm_mcl
