// The block fitter (fit/block_fitter.h) against the whole-map EM on a small synthetic room, and
// the tool's large-map options end to end.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "gmm_mcl/fit/block_fitter.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/point_cloud_io.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "test_utils/assertions.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

// Held-out mean log-likelihood of the block fit no worse than the whole-map EM's by more than
// this (nats per point). Measured on this room (seeds 1..5, defaults): the block fit is 0.011
// worse to 0.018 better; the whole-map EM's own seed-to-seed spread is 0.025.
constexpr double kHoldoutTolNats = 0.03;
// Every point lies within this many standard deviations (Mahalanobis) of some component: the
// blocks' borders leave no gap. The whole-map EM's farthest point is 4.0-4.4 sigma away here (the
// noise's tail); a missing component at a border would leave points tens of sigma away.
constexpr double kNoGapSigma = 5.0;

// A room of planes with 3 mm noise: floor 6 x 4 m, two walls 2.5 m high, a table top; points
// in proportion to area.
PointCloud room(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.003f);
  const float floor_a = 24.f, wall_x = 10.f, wall_y = 15.f, table = 1.5f;
  const float total = floor_a + wall_x + wall_y + table;
  PointCloud pts;
  pts.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const float pick = u(rng) * total, a = u(rng), b = u(rng), e = noise(rng);
    if (pick < floor_a) {
      pts.emplace_back(6.f * a, 4.f * b, e);
    } else if (pick < floor_a + wall_x) {
      pts.emplace_back(e, 4.f * a, 2.5f * b);
    } else if (pick < floor_a + wall_x + wall_y) {
      pts.emplace_back(6.f * a, 4.f + e, 2.5f * b);
    } else {
      pts.emplace_back(3.f + 1.5f * a, 1.f + b, 0.75f + e);
    }
  }
  return pts;
}

BlockFitParams roomParams() {
  BlockFitParams p;
  p.em.components = 60;
  p.blocks = 4;
  return p;
}

// Smallest Mahalanobis distance from p to any component.
double nearestSigma(const std::vector<GaussianComponent>& comps, const Eigen::Vector3f& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& c : comps) {
    const Eigen::Vector3d d = p.cast<double>() - c.mean_m;
    best = std::min(best, std::sqrt(d.dot(c.cov_m2.llt().solve(d))));
  }
  return best;
}

TEST(BlockFitParamsTest, DefaultsAreValidAndFaultsNamed) {
  const BlockFitParams d;
  EXPECT_EQ(d.validate(), "");
  EXPECT_EQ(d.blocks, 0);
  EXPECT_EQ(d.components_per_block, kDefaultBlockComponents);
  EXPECT_EQ(d.margin_m, 0.0);  // none
  EXPECT_EQ(d.margin_radii, kDefaultMarginRadii);
  EXPECT_EQ(d.reconcile_iterations, kDefaultReconcileIterations);
  BlockFitParams p;
  p.em.components = 10;
  p.blocks = 11;
  p.margin_radii = -1.0;
  p.reconcile_iterations = -1;
  const std::string f = p.validate();
  EXPECT_NE(f.find("blocks"), std::string::npos) << f;
  EXPECT_NE(f.find("margin_radii"), std::string::npos) << f;
  EXPECT_NE(f.find("reconcile_iterations"), std::string::npos) << f;
  EXPECT_THROW(fitGmmBlocks(room(1000, 1), p), FitError);
}

TEST(BlockFitParamsTest, AutomaticBlockCount) {
  BlockFitParams p;
  p.em.components = 1000;
  EXPECT_EQ(autoBlockCount(250000, p), 1);  // the whole-map EM
  EXPECT_EQ(autoBlockCount(kAutoBlocksAbovePoints + 1, p), 4);
  p.em.components = 100000;
  EXPECT_EQ(autoBlockCount(10000000, p), 400);
  p.em.components = kAutoBlocksAboveComponents + 1;
  EXPECT_EQ(autoBlockCount(100000, p), (kAutoBlocksAboveComponents + 1 + 249) / 250);
}

TEST(BlockFitTest, ValidMapCloseToWholeMapEmAndNoGaps) {
  PointCloud train, held;
  splitHoldout(room(30000, 1), 0.1, 1, &train, &held);
  const BlockFitParams p = roomParams();
  const BlockFitResult blocks = fitGmmBlocks(train, p);
  ASSERT_EQ(blocks.components.size(), 60u);
  ASSERT_EQ(blocks.blocks.size(), 4u);
  double weight_sum = 0.0;
  for (const auto& c : blocks.components) weight_sum += c.weight;
  EXPECT_NEAR(weight_sum, 1.0, 1e-12);
  size_t own = 0;
  for (const BlockInfo& b : blocks.blocks) {
    own += b.own_points;
    EXPECT_EQ(b.margin_points, 0u);
    EXPECT_TRUE(b.converged);
  }
  EXPECT_EQ(own, train.size());
  EXPECT_TRUE(blocks.reconcile.converged);
  const GmmMap map = makeStorableMap(blocks.components, p.em.reg_covar_m2, "<blocks>");
  EXPECT_NO_THROW(decodeMap(encodeMap(map), "<blocks>"));

  const EmResult whole = fitGmm(train, p.em);
  const double ll_blocks = meanLogLikelihood(blocks.components, held);
  const double ll_whole = meanLogLikelihood(whole.components, held);
  EXPECT_GT(ll_blocks, ll_whole - kHoldoutTolNats)
      << "blocks " << ll_blocks << " whole " << ll_whole;
  // The reported training log-likelihood is the returned map's.
  EXPECT_NEAR(blocks.final_mean_log_likelihood, meanLogLikelihood(blocks.components, train), 1e-9);

  double worst = 0.0;
  for (const PointCloud* pts : {&train, &held}) {
    for (const auto& q : *pts) worst = std::max(worst, nearestSigma(blocks.components, q));
  }
  EXPECT_LT(worst, kNoGapSigma);
}

TEST(BlockFitTest, MarginOrNoReconciliationStillCoverTheBorders) {
  const PointCloud pts = room(20000, 2);
  BlockFitParams p = roomParams();
  p.reconcile_iterations = 0;  // the blocks as fitted
  const BlockFitResult bare = fitGmmBlocks(pts, p);
  EXPECT_EQ(bare.kept_outside + bare.dropped_inside, 0);  // without a margin means stay inside
  p.margin_m = -1.0;                                      // automatic
  p.reconcile_iterations = 1;
  const BlockFitResult margin = fitGmmBlocks(pts, p);
  for (const BlockInfo& b : margin.blocks) {
    EXPECT_GT(b.margin_m, 0.0);
    EXPECT_GT(b.margin_points, 0u);
    EXPECT_GE(b.fitted_components, b.components);
  }
  for (const BlockFitResult* r : {&bare, &margin}) {
    ASSERT_EQ(r->components.size(), 60u);
    double worst = 0.0;
    for (const auto& q : pts) worst = std::max(worst, nearestSigma(r->components, q));
    EXPECT_LT(worst, kNoGapSigma);
    EXPECT_NEAR(r->final_mean_log_likelihood, meanLogLikelihood(r->components, pts), 1e-9);
    const GmmMap map = makeStorableMap(r->components, p.em.reg_covar_m2, "<blocks>");
    EXPECT_NO_THROW(decodeMap(encodeMap(map), "<blocks>"));
  }
}

TEST(BlockFitTest, DeterministicForSeedAndThreadCount) {
  const PointCloud pts = room(12000, 3);
  BlockFitParams p = roomParams();
  p.em.max_iterations = 20;
  omp_set_num_threads(1);
  const BlockFitResult one = fitGmmBlocks(pts, p);
  omp_set_num_threads(2);
  const BlockFitResult two = fitGmmBlocks(pts, p);
  ASSERT_TRUE(test::sameComponents(one.components, two.components));
  p.em.seed = 2;
  const BlockFitResult other = fitGmmBlocks(pts, p);
  EXPECT_NE(other.components[0].mean_m, one.components[0].mean_m);
}

TEST(BlockFitTest, BadInputIsAClearErrorOrAValidMap) {
  BlockFitParams p = roomParams();
  p.em.components = 50;
  EXPECT_TRUE(test::throwsWith<FitError>([&] { fitGmmBlocks(room(10, 1), p); }, {"fewer"}));
  PointCloud nan = room(1000, 1);
  nan[3].y() = NAN;
  EXPECT_TRUE(test::throwsWith<FitError>([&] { fitGmmBlocks(nan, p); }, {"NaN"}));
  // The tool's path: the filter drops NaN points, then the fit works.
  CloudFilterStats fs;
  const PointCloud clean = filterCloud(nan, CloudFilterParams(), &fs);
  EXPECT_EQ(fs.non_finite, 1u);
  p.em.components = 20;
  EXPECT_EQ(fitGmmBlocks(clean, p).components.size(), 20u);

  // All points identical, and 10 points for 10 components: valid maps.
  const PointCloud same(2000, Eigen::Vector3f(1.f, 2.f, 3.f));
  p.em.components = 10;
  for (const PointCloud& pts : {same, room(10, 4)}) {
    BlockFitResult r;
    ASSERT_NO_THROW(r = fitGmmBlocks(pts, p));
    ASSERT_EQ(r.components.size(), 10u);
    const GmmMap map = makeStorableMap(r.components, p.em.reg_covar_m2, "<degenerate>");
    EXPECT_NO_THROW(decodeMap(encodeMap(map), "<degenerate>"));
  }
}

#ifdef GMM_MCL_FIT_TOOL
// gmm_mcl_fit with --tile, --blocks, --holdout and --stats-json on a small cloud file.
TEST(BlockFitToolTest, TiledCloudBlocksAndHoldout) {
  test::TempDir dir("block_fit_tool");
  writeXyz(room(4000, 5), dir / "room.xyz");
  const std::string cmd = std::string(GMM_MCL_FIT_TOOL) + " " + (dir / "room.xyz") +
                          " --tile 2,2 -m 100 --blocks 4 --holdout 0.1 --max-iter 30 -o " +
                          (dir / "map.gmm") + " --stats-json " + (dir / "stats.json") + " 2> " +
                          (dir / "log.txt");
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const GmmMap map = loadMap(dir / "map.gmm");
  EXPECT_EQ(map.size(), 100u);
  // Four copies of a 6 x 4 m room, 8 m apart (6 m + 2 m gap).
  EXPECT_GT(map.maxBound().x() - map.minBound().x(), 10.0);
  EXPECT_GT(map.maxBound().y() - map.minBound().y(), 8.0);
  std::ifstream js(dir / "stats.json");
  std::stringstream text;
  text << js.rdbuf();
  EXPECT_NE(text.str().find("\"blocks\": {\"count\": 4"), std::string::npos) << text.str();
  const size_t holdout = text.str().find("\"holdout_mean_log_likelihood\": ");
  ASSERT_NE(holdout, std::string::npos) << text.str();
  EXPECT_NE(text.str().substr(holdout + 31, 4), "null") << text.str();
  std::ifstream log(dir / "log.txt");
  std::stringstream lines;
  lines << log.rdbuf();
  EXPECT_NE(lines.str().find("blocks 4/4"), std::string::npos) << lines.str();
  EXPECT_NE(lines.str().find("held-out mean log-lik"), std::string::npos) << lines.str();
  // A bad --blocks value is a usage error (status 2).
  const std::string bad = std::string(GMM_MCL_FIT_TOOL) + " " + (dir / "room.xyz") +
                          " --blocks many -o " + (dir / "bad.gmm") + " 2> /dev/null";
  EXPECT_EQ(WEXITSTATUS(std::system(bad.c_str())), 2);
}
#endif

}  // namespace
}  // namespace gmm_mcl
