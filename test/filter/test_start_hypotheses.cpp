// The places a wide start follows over its first frames (start_hypotheses.h), on a synthetic
// per-pixel score: a narrow true basin and a wide, lower decoy.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "gmm_mcl/filter/start_hypotheses.h"

namespace gmm_mcl {
namespace {

constexpr int kPixels = 1000;

double distance(const Particle& a, const Particle& b) {
  return std::hypot(std::hypot(a.x_m - b.x_m, a.y_m - b.y_m), a.z_m - b.z_m);
}

// Per-pixel score of a pose: the truth's basin is narrow (0.1 m, 0.05 rad) and peaks at -1.4;
// a decoy 6 m away is wide (1 m) and peaks at -1.7, so that a pose 0.25 m from the truth scores
// below the decoy's whole neighbourhood.
double perPixel(const Particle& p, const Particle& truth, const Particle& decoy) {
  const double dt = distance(p, truth), yt = wrapAngle(p.yaw_rad - truth.yaw_rad);
  const double dd = distance(p, decoy), yd = wrapAngle(p.yaw_rad - decoy.yaw_rad);
  const double t = -1.4 - 0.5 * (dt * dt / 0.01 + yt * yt / 0.0025);
  const double d = -1.7 - 0.5 * (dd * dd + yd * yd / 0.25);
  return std::max({t, d, -8.0});
}

std::vector<double> scores(const std::vector<Particle>& poses, const Particle& truth,
                           const Particle& decoy) {
  std::vector<double> ll;
  for (const Particle& p : poses) ll.push_back(kPixels * perPixel(p, truth, decoy));
  return ll;
}

TEST(StartHypothesesTest, SeedsTheBestDistinctPlaces) {
  StartHypothesesParams params;
  params.places = 3;
  StartHypotheses places(params, 1);
  // Two poses 0.1 m apart are one place; the third best distinct pose is the fourth scored.
  const std::vector<Particle> poses = {
      {0, 0, 1, 0}, {0.1, 0, 1, 0}, {5, 0, 1, 0}, {5, 0, 1, 3.0}, {9, 9, 1, 0}};
  places.seed(poses, {-1.0, -1.1, -2.0, -2.5, -3.0});
  ASSERT_EQ(places.places().size(), 3u);
  EXPECT_DOUBLE_EQ(places.places()[0].pose.x_m, 0.0);
  EXPECT_DOUBLE_EQ(places.places()[1].pose.x_m, 5.0);
  EXPECT_DOUBLE_EQ(places.places()[2].pose.yaw_rad, 3.0);  // same position, another heading
  EXPECT_FALSE(places.finished());
}

TEST(StartHypothesesTest, APlaceOutsideItsBasinClimbsInAndOvertakesTheDecoy) {
  const Particle truth{2.0, 3.0, 1.2, 0.4}, decoy{8.0, 3.0, 1.2, 0.4};
  StartHypothesesParams params;
  params.frames = 60;
  StartHypotheses places(params, 7);
  // The first update: the decoy's neighbourhood scores best, the truth's nearest pose is 0.25 m
  // and 0.05 rad off (outside its basin, below every decoy pose listed).
  const std::vector<Particle> seeds = {
      {8.1, 3.0, 1.2, 0.4}, {7.4, 3.2, 1.2, 0.5}, {2.25, 3.0, 1.2, 0.45}, {20.0, 5.0, 1.2, 0.0}};
  const std::vector<double> seed_scores = scores(seeds, truth, decoy);
  ASSERT_LT(seed_scores[2], seed_scores[1]);
  places.seed(seeds, seed_scores);
  ASSERT_EQ(places.places().size(), 4u);
  EXPECT_LT(distance(places.places()[0].pose, decoy), 0.2);
  // The camera moves 0.02 m forward and turns 0.01 rad per frame; so do the truth and the decoy.
  PlanarDelta delta;
  delta.translation_m = Eigen::Vector3d(0.02, 0.0, 0.0);
  delta.yaw_rad = 0.01;
  Particle t = truth, d = decoy;
  auto move = [&delta](Particle* p) {
    p->x_m += std::cos(p->yaw_rad) * delta.translation_m.x();
    p->y_m += std::sin(p->yaw_rad) * delta.translation_m.x();
    p->yaw_rad = wrapAngle(p->yaw_rad + delta.yaw_rad);
  };
  for (int k = 0; k < params.frames; ++k) {
    places.predict(delta);
    move(&t);
    move(&d);
    places.update(scores(places.proposals(), t, d), kPixels);
  }
  EXPECT_TRUE(places.finished());
  // The 0.7 m decoy seed merged into the other decoy place; the truth's place climbed into its
  // basin and won.
  EXPECT_EQ(places.places().size(), 3u);
  const StartHypotheses::Place& best = places.best();
  EXPECT_LT(distance(best.pose, t), 0.03);
  EXPECT_LT(std::abs(wrapAngle(best.pose.yaw_rad - t.yaw_rad)), 0.02);
  EXPECT_GT(best.last_loglik, -1.45);
}

TEST(StartHypothesesTest, WithoutLocalDrawsTheDecoyWins) {
  // The same run with one draw per place (the place itself: no climb) keeps the truth's place
  // outside its basin, and the decoy wins: the climb is what finds the truth.
  const Particle truth{2.0, 3.0, 1.2, 0.4}, decoy{8.0, 3.0, 1.2, 0.4};
  StartHypothesesParams params;
  params.frames = 60;
  params.draws = 1;
  StartHypotheses places(params, 7);
  const std::vector<Particle> seeds = {{8.1, 3.0, 1.2, 0.4}, {2.25, 3.0, 1.2, 0.45}};
  places.seed(seeds, scores(seeds, truth, decoy));
  for (int k = 0; k < params.frames; ++k) {
    places.update(scores(places.proposals(), truth, decoy), kPixels);
  }
  EXPECT_LT(distance(places.best().pose, decoy), 0.2);
}

TEST(StartHypothesesTest, APlaceThatLeavesTheMapIsDropped) {
  StartHypothesesParams params;
  StartHypotheses places(params, 3);
  places.seed({{0, 0, 1, 0}, {4, 0, 1, 0}}, {-1.0, -2.0});
  const std::vector<Particle>& proposals = places.proposals();
  std::vector<double> ll(proposals.size(), -1500.0);
  for (size_t i = 0; i < ll.size() / 2; ++i) ll[i] = -INFINITY;  // the first place's draws
  places.update(ll, kPixels);
  ASSERT_EQ(places.places().size(), 1u);
  EXPECT_DOUBLE_EQ(places.best().last_loglik, -1.5);
  // A frame no draw of which scores ends the stage.
  places.update(std::vector<double>(places.proposals().size(), -INFINITY), kPixels);
  EXPECT_FALSE(places.active());
}

// The distinct places of many scored poses: the best first, each kept unless a kept one is the
// same place. Found through cells of the separation's size, the same set and order as comparing
// every pair (the reference here), which cost O(places^2) per frame: 16.7 million distance tests
// at 4096 places. Poses on a grid of about the separation, so that many pairs are borderline.
TEST(StartHypothesesTest, TheDistinctPlacesAreThoseOfComparingEveryPair) {
  StartHypothesesParams params;
  params.places = 100000;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Particle> poses;
  std::vector<double> ll;
  for (int i = 0; i < 6000; ++i) {
    Particle p;
    p.x_m = 0.5 * std::round(8.0 * u(rng)) + 0.02 * u(rng) - 3.0;
    p.y_m = 0.5 * std::round(8.0 * u(rng)) + 0.02 * u(rng);
    p.z_m = 1.0 + 0.3 * u(rng);
    p.yaw_rad = 3.0 * u(rng);
    poses.push_back(p);
    ll.push_back(std::round(50.0 * u(rng)));  // ties: the earlier pose first
  }
  std::vector<size_t> order(poses.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return ll[a] > ll[b]; });
  std::vector<Particle> expected;
  for (size_t i : order) {
    const bool taken = std::any_of(expected.begin(), expected.end(), [&](const Particle& q) {
      return distance(q, poses[i]) < params.separation_m &&
             std::abs(wrapAngle(q.yaw_rad - poses[i].yaw_rad)) < params.separation_rad;
    });
    if (!taken) expected.push_back(poses[i]);
  }
  StartHypotheses places(params, 1);
  places.seed(poses, ll);
  ASSERT_EQ(places.places().size(), expected.size());
  for (size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(places.places()[k].pose.x_m, expected[k].x_m) << k;
    EXPECT_EQ(places.places()[k].pose.yaw_rad, expected[k].yaw_rad) << k;
  }
  EXPECT_GT(expected.size(), 500u);  // many places, and many poses merged into them
  EXPECT_LT(expected.size(), 4000u);
}

}  // namespace
}  // namespace gmm_mcl
