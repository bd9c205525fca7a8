// Maps of whole buildings (docs/building_scale.md): the component grid finds what brute force
// finds, the mapped surface follows the map, and a room inside a 100-room map scores at the true
// pose what it scores in a map of its own, per pixel, at a cost that follows the view.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/component_grid.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/sim/step_input.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

// 3000 component boxes over 40 x 40 m, a ground plane of 50 m and a component 1 km away.
std::vector<Box3> testBoxes(std::mt19937_64* rng) {
  std::uniform_real_distribution<double> pos(-20.0, 20.0), size(0.01, 1.0);
  std::vector<Box3> boxes;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d c(pos(*rng), pos(*rng), 0.1 * pos(*rng));
    const Eigen::Vector3d h(size(*rng), size(*rng), size(*rng));
    boxes.push_back(Box3{c - h, c + h});
  }
  boxes.push_back(Box3{Eigen::Vector3d(-25, -25, -0.05), Eigen::Vector3d(25, 25, 0.05)});
  boxes.push_back(Box3{Eigen::Vector3d(1000, 0, 0), Eigen::Vector3d(1000.2, 0.2, 0.2)});
  return boxes;
}

TEST(ComponentGridTest, QueryEqualsBruteForce) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> pos(-20.0, 20.0), size(0.01, 1.0);
  const std::vector<Box3> boxes = testBoxes(&rng);
  const ComponentGrid grid(boxes);
  EXPECT_EQ(grid.largeCount(), 1u);
  std::vector<int> got;
  ComponentGrid::Scratch scratch;
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.1);
    const Eigen::Vector3d h = 3.0 * Eigen::Vector3d(size(rng), size(rng), size(rng));
    Box3 region{c - h, c + h};
    if (q == 0) region = Box3{Eigen::Vector3d(999, -1, -1), Eigen::Vector3d(1001, 1, 1)};
    if (q == 1) region = Box3{Eigen::Vector3d::Constant(-2000), Eigen::Vector3d::Constant(2000)};
    grid.query(region, &got);
    std::vector<int> marked;
    grid.query(region, &marked, &scratch);
    EXPECT_EQ(marked, got) << "query " << q << " with marks";
    std::vector<int> want;
    for (size_t i = 0; i < boxes.size(); ++i) {
      if (boxes[i].intersects(region)) want.push_back(static_cast<int>(i));
    }
    ASSERT_EQ(got, want) << "query " << q;
  }
  grid.query(Box3{}, &got);  // an empty region
  EXPECT_TRUE(got.empty());
}

// A query of several regions (the view boxes of a spread cloud's groups) finds what the regions'
// own queries find together, once each and ascending.
TEST(ComponentGridTest, QueryOfSeveralRegionsIsTheUnionOfTheirQueries) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> pos(-20.0, 20.0), size(0.01, 1.0), near(-1.0, 1.0);
  const ComponentGrid grid(testBoxes(&rng));
  ComponentGrid::Scratch scratch;
  for (int q = 0; q < 100; ++q) {
    // Overlapping boxes around one place (a start's groups), sometimes spread over the map, an
    // empty one, the far component's, one of all space.
    const int count = 1 + q % 40;
    const Eigen::Vector3d centre(pos(rng), pos(rng), pos(rng) * 0.1);
    std::vector<Box3> regions;
    for (int r = 0; r < count; ++r) {
      const Eigen::Vector3d c =
          q % 3 == 0 ? Eigen::Vector3d(pos(rng), pos(rng), pos(rng) * 0.1)
                     : Eigen::Vector3d(centre + 3.0 * Eigen::Vector3d(near(rng), near(rng), 0.0));
      const Eigen::Vector3d h = 4.0 * Eigen::Vector3d(size(rng), size(rng), size(rng));
      regions.push_back(Box3{c - h, c + h});
    }
    if (q % 7 == 1) regions.push_back(Box3{});
    if (q == 2) regions.push_back(Box3{Eigen::Vector3d(999, -1, -1), Eigen::Vector3d(1001, 1, 1)});
    if (q == 4) {
      regions.push_back(Box3{Eigen::Vector3d::Constant(-2000), Eigen::Vector3d::Constant(2000)});
    }
    std::vector<int> want, one;
    for (const Box3& region : regions) {
      grid.query(region, &one);
      want.insert(want.end(), one.begin(), one.end());
    }
    std::sort(want.begin(), want.end());
    want.erase(std::unique(want.begin(), want.end()), want.end());
    std::vector<int> got;
    grid.query(regions, &got, &scratch);
    ASSERT_EQ(got, want) << "query " << q << " of " << regions.size() << " regions";
    grid.query(regions, &got, nullptr);
    ASSERT_EQ(got, want) << "query " << q << " without marks";
  }
  std::vector<int> got = {1, 2};
  grid.query(std::vector<Box3>{}, &got, &scratch);
  EXPECT_TRUE(got.empty());
}

// The poses grouped by the cell of their camera centre: each group one cell's poses in ascending
// order, the groups in the order of their cells (x, then y, then z), a pose that is not finite
// or lies far away in a cell of its own.
TEST(ViewGroupsTest, PosesAreGroupedByTheCellOfTheirCentre) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    const double cell = trial % 2 == 0 ? 2.0 : 0.7;
    const double extent = trial < 5 ? 1.5 : (trial < 15 ? 8.0 : 60.0);
    std::uniform_real_distribution<double> pos(-extent, extent);
    const int n = 50 + 400 * trial;
    std::vector<RigidTransformF> poses(n);
    for (int i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a)
        poses[i].t[a] = static_cast<float>(a == 2 ? 0.2 * pos(rng) : pos(rng));
    }
    if (trial == 7) poses[3].t[0] = std::numeric_limits<float>::quiet_NaN();
    if (trial == 8) poses[5].t[1] = 3e37f;
    if (trial == 9) poses[9].t[2] = -std::numeric_limits<float>::infinity();
    std::map<std::array<long long, 3>, std::vector<int>> cells;
    for (int i = 0; i < n; ++i) {
      std::array<long long, 3> key;
      for (int a = 0; a < 3; ++a) {
        const double c = std::floor(static_cast<double>(poses[i].t[a]) / cell);
        key[a] = std::isfinite(c) ? static_cast<long long>(std::max(-1e15, std::min(1e15, c))) : 0;
      }
      cells[key].push_back(i);
    }
    std::vector<int> order, begin;
    groupPosesByPlace(poses, cell, &order, &begin);
    ASSERT_EQ(begin.front(), 0);
    ASSERT_EQ(begin.back(), n);
    ASSERT_EQ(order.size(), static_cast<size_t>(n));
    // A cloud within one cell's extent is one group wherever it lies.
    Box3 centres;
    for (const RigidTransformF& T : poses) centres.extend(Eigen::Vector3d(T.t[0], T.t[1], T.t[2]));
    if (((centres.hi - centres.lo).array() <= cell).all()) {
      ASSERT_EQ(begin.size(), 2u) << "trial " << trial;
      for (int i = 0; i < n; ++i) ASSERT_EQ(order[i], i);
      continue;
    }
    ASSERT_EQ(begin.size(), cells.size() + 1) << "trial " << trial;
    size_t g = 0;
    for (const auto& kv : cells) {
      const std::vector<int> got(order.begin() + begin[g], order.begin() + begin[g + 1]);
      ASSERT_EQ(got, kv.second) << "trial " << trial << " group " << g;
      ++g;
    }
  }
}

// A group's view box is the union of its poses' view boxes, to the bit.
TEST(ViewGroupsTest, AGroupsViewBoxIsTheUnionOfItsPosesBoxes) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> pos(-30.0, 30.0), angle(-3.2, 3.2);
  const Intrinsics K = test::vgaCamera();
  const ViewReach reach = viewReach(K, 32, 20, 15, patchInflation(32), 4.f, 3.f, DepthNoiseModel());
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 1 + trial * 7;
    std::vector<RigidTransformF> poses(n);
    std::vector<int> members(n);
    for (int i = 0; i < n; ++i) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(pos(rng), pos(rng), 0.1 * pos(rng));
      T.linear() = (Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(0.3 * angle(rng), Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(0.3 * angle(rng), Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
      poses[i] = toRigidF(T);
      members[i] = n - 1 - i;
    }
    Box3 want;
    for (int i = 0; i < n; ++i) want.extend(viewBox(poses[i], K, reach));
    const Box3 got = groupViewBox(poses, members.data(), n, K, reach);
    ASSERT_EQ(got.lo, want.lo) << "trial " << trial;
    ASSERT_EQ(got.hi, want.hi) << "trial " << trial;
  }
}

TEST(SurfaceAreaTest, FlatComponentIsItsDisc) {
  // A uniform disc of radius r has variance r^2 / 4 along its two axes.
  GaussianComponent c;
  c.weight = 1.0;
  c.cov_m2 = Eigen::Vector3d(0.25, 0.25, 1e-6).asDiagonal();  // r = 1 m
  const GmmMap one({c}, "one component");
  EXPECT_NEAR(one.surfaceArea(), M_PI, 1e-9);
  EXPECT_NEAR(one.logWeightScale(), std::log(M_PI / kReferenceSurfaceAreaM2), 1e-12);
}

TEST(SurfaceAreaTest, GrowsWithTheTilingAndKeepsEveryModelWeight) {
  const GmmMap& room = test::world().map;
  const GmmMap building = tiledMap(room, 4, 3, 12.0);
  ASSERT_EQ(building.size(), 12 * room.size());
  EXPECT_NEAR(building.surfaceArea() / room.surfaceArea(), 12.0, 1e-6);
  for (size_t i = 0; i < room.size(); i += 37) {
    EXPECT_NEAR(building.modelLogWeight(i), room.modelLogWeight(i), 1e-6);
    EXPECT_NEAR(building.packed()[i].log_norm, room.packed()[i].log_norm, 1e-5);
  }
}

// A redraw's coarse map: each cube's components become one with the cube's weight, mean and
// covariance (the second moment of its mixture), a cube of one keeps its component bit for bit,
// and the merged map is a valid mixture of the same total weight.
TEST(MergedByCellTest, KeepsEachCubesMassMeanAndCovariance) {
  const GmmMap& room = test::world().map;
  const double cell = 0.3;
  const std::vector<GaussianComponent> merged = mergedByCell(room.components(), cell);
  ASSERT_LT(merged.size(), room.size());
  ASSERT_GT(merged.size(), 0u);
  // The reference: the moments of each cube's components, summed directly.
  std::map<std::array<long long, 3>, std::vector<size_t>> cubes;
  std::vector<std::array<long long, 3>> order;
  for (size_t i = 0; i < room.size(); ++i) {
    const Eigen::Vector3d& m = room.components()[i].mean_m;
    const std::array<long long, 3> key = {static_cast<long long>(std::floor(m.x() / cell)),
                                          static_cast<long long>(std::floor(m.y() / cell)),
                                          static_cast<long long>(std::floor(m.z() / cell))};
    if (cubes[key].empty()) order.push_back(key);
    cubes[key].push_back(i);
  }
  ASSERT_EQ(order.size(), merged.size());
  int singles = 0;
  double total = 0.0;
  for (size_t k = 0; k < order.size(); ++k) {
    const std::vector<size_t>& members = cubes[order[k]];
    const GaussianComponent& got = merged[k];
    total += got.weight;
    if (members.size() == 1) {
      const GaussianComponent& c = room.components()[members[0]];
      EXPECT_EQ(got.weight, c.weight);
      EXPECT_EQ(got.mean_m, c.mean_m);
      EXPECT_EQ(got.cov_m2, c.cov_m2);
      ++singles;
      continue;
    }
    double w = 0.0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (size_t i : members) {
      w += room.components()[i].weight;
      mean += room.components()[i].weight * room.components()[i].mean_m;
    }
    mean /= w;
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (size_t i : members) {
      const GaussianComponent& c = room.components()[i];
      const Eigen::Vector3d d = c.mean_m - mean;
      cov += c.weight * (c.cov_m2 + d * d.transpose());
    }
    cov /= w;
    EXPECT_NEAR(got.weight, w, 1e-12);
    EXPECT_LT((got.mean_m - mean).norm(), 1e-9);
    EXPECT_LT((got.cov_m2 - cov).norm(), 1e-9 * cov.norm());
  }
  EXPECT_GT(singles, 0);
  EXPECT_NEAR(total, 1.0, 1e-9);
  EXPECT_NO_THROW(GmmMap(merged, "merged"));
  // No cell: the components as they are.
  EXPECT_EQ(mergedByCell(room.components(), 0.0).size(), room.size());
}

// The reference frame of the synthetic room and camera poses around its truth: the truth first,
// then perturbed ones (seeded), with the frame's true roll and pitch.
struct RoomView {
  DepthFrame frame;
  std::vector<RigidTransformF> poses;
};
RoomView roomView(int poses, uint64_t seed) {
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  RoomView v;
  v.frame = test::renderFrame(T_map_base, test::smallCamera(), test::frameParams(4));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Particle truth = poseToParticle(T_map_base);
  double roll_rad = 0.0, pitch_rad = 0.0, yaw_rad = 0.0;
  rpyFromRotation(T_map_base.linear(), &roll_rad, &pitch_rad, &yaw_rad);
  for (int i = 0; i < poses; ++i) {
    const Particle p = i == 0 ? truth : test::perturbed(truth, n01, rng);
    v.poses.push_back(toRigidF(particleToPose(p, roll_rad, pitch_rad) * test::world().T_base_cam));
  }
  return v;
}

// The same room, the same frame, the true pose and a converged cloud around it: the room's own
// map and the room as one of 100 in a 10 x 10 building. Without the surface normalisation the
// building would score ln(100) = 4.6 nats per pixel lower wherever a pixel's density is above
// the floor.
TEST(BuildingScaleTest, RoomInsideAHundredRoomMapScoresAsTheRoomAlone) {
  const GmmMap& room = test::world().map;
  const GmmMap building = tiledMap(room, 10, 10, 14.0);
  const RoomView v = roomView(16, 3);
  const DepthFrame& frame = v.frame;
  const std::vector<RigidTransformF>& poses = v.poses;
  ASSERT_GT(frame.size(), 1000u);
  MeasurementParams params;
  CpuBackend cpu(2);
  BackendOutput own, inside;
  cpu.setMap(room);
  cpu.evaluate(frame, poses, params, &own);
  cpu.setMap(building);
  cpu.evaluate(frame, poses, params, &inside);
  const double pixels = static_cast<double>(frame.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_NEAR(inside.log_likelihood[i] / pixels, own.log_likelihood[i] / pixels, 0.05)
        << "pose " << i;
    EXPECT_EQ(inside.floor_hits[i], own.floor_hits[i]) << "pose " << i;
  }
  // The cost follows the view: what the building's cull keeps is the room's view and at most
  // the parts of its neighbours within the frame's depth, not the map.
  EXPECT_LE(inside.visible_components, 3 * own.visible_components);
  EXPECT_LT(inside.visible_components, static_cast<int>(room.size()) * 3);
}

// A pose's sums over the components near its view (viewComponents: gmm_mcl_score, the
// refinement) are its sums over the whole building, and the list is about the room's view, not
// the map's 100 rooms.
TEST(BuildingScaleTest, APoseScoresOverItsViewsComponentsAsOverTheMap) {
  const GmmMap& room = test::world().map;
  const GmmMap building = tiledMap(room, 10, 10, 14.0);
  const RoomView v = roomView(4, 5);
  const DepthFrame& frame = v.frame;
  ASSERT_GT(frame.size(), 1000u);
  const MeasurementParams params;
  const ViewReach reach = viewReach(frame, params);
  std::vector<int> index;
  std::vector<ComponentF> near, grown;
  for (size_t i = 0; i < v.poses.size(); ++i) {
    const RigidTransformF& T = v.poses[i];
    LikelihoodScratch s_all, s_near;
    const FrameLikelihood all = poseLogLikelihood(building.packed(), frame, T, params, &s_all);
    viewComponents(building, T, frame.intrinsics, reach, 0.0, &index, &near);
    const FrameLikelihood view = poseLogLikelihood(near, frame, T, params, &s_near);
    EXPECT_NEAR(view.log_likelihood, all.log_likelihood, 1e-9 * std::abs(all.log_likelihood))
        << "pose " << i;
    EXPECT_EQ(view.floor_hits, all.floor_hits) << "pose " << i;
    EXPECT_LT(near.size(), 2 * room.size()) << "pose " << i;
    viewComponents(building, T, frame.intrinsics, reach, refinementReach(RefinementParams(), reach),
                   &index, &grown);
    EXPECT_GE(grown.size(), near.size());
    EXPECT_LT(grown.size(), 4 * room.size()) << "pose " << i;
  }
}

// Odd maps and views (the building issue's bad input): two copies of the room 1 km apart, a map
// of one component, the room under a 50 m ground plane, and a camera that sees no map at all.
// Each loads, steps on the room's frames with a finite estimate and the grid's memory bounded
// by the component count; the camera that sees nothing gets the floor for every pixel.
TEST(BuildingScaleTest, OddMapsAndAnEmptyViewStepCleanly) {
  const GmmMap& room = test::world().map;
  std::vector<GaussianComponent> far_apart = tiledMap(room, 2, 1, 1000.0).components();
  GaussianComponent one;
  one.weight = 1.0;
  one.mean_m = Eigen::Vector3d(3, 3, 1.5);
  one.cov_m2 = Eigen::Vector3d(0.5, 0.5, 0.01).asDiagonal();
  std::vector<GaussianComponent> ground = room.components();
  GaussianComponent plane;
  plane.mean_m = Eigen::Vector3d(4, 3, -0.05);
  plane.cov_m2 = Eigen::Vector3d(25.0 * 25.0 / 4.0, 25.0 * 25.0 / 4.0, 1e-4).asDiagonal();
  plane.weight = 0.2;
  for (GaussianComponent& c : ground) c.weight *= 0.8;
  ground.push_back(plane);
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const Intrinsics K = test::smallCamera();
  const DepthImage depth =
      sim::renderDepth(test::world().scene, K, T_map_base * test::world().T_base_cam,
                       DepthEncoding::kMono16Millimetres, 9.0);
  double roll = 0.0, pitch = 0.0, yaw = 0.0;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  struct Case {
    const char* what;
    GmmMap map;
    Eigen::Isometry3d T_odom_base;
  };
  Eigen::Isometry3d away = T_map_base;
  away.translation() += Eigen::Vector3d(0, 0, 500.0);  // high above every component
  const std::vector<Case> cases = {
      {"two buildings 1 km apart", GmmMap(far_apart, "far apart"), T_map_base},
      {"one component", GmmMap({one}, "one"), T_map_base},
      {"a 50 m ground plane", GmmMap(ground, "ground plane"), T_map_base},
      {"a view of no map", room, away}};
  for (const Case& c : cases) {
    LocalizerParams p;
    p.filter.num_particles = 200;
    p.frame.pixel_stride = 8;
    p.frame.max_range_m = 8.f;
    p.T_base_cam = test::world().T_base_cam;
    const Particle s = poseToParticle(c.T_odom_base);
    p.init.centre_m = Eigen::Vector3d(s.x_m, s.y_m, s.z_m);
    p.init.half_extent_m.setConstant(0.3);
    p.init.yaw_centre_rad = s.yaw_rad;
    Localizer loc(p, c.map);
    EXPECT_LE(loc.map().grid().entryCount(), 64 * loc.map().size()) << c.what;
    for (int f = 0; f < 3; ++f) {
      const StepResult r =
          loc.step(sim::frameInput(f / 30.0, c.T_odom_base, roll, pitch, depth, K));
      ASSERT_EQ(r.status, StepStatus::kOk) << c.what << ": " << r.message;
      EXPECT_TRUE(std::isfinite(r.estimate.mean.x_m) && std::isfinite(r.estimate.mean.yaw_rad))
          << c.what;
      if (&c == &cases.back()) {
        EXPECT_EQ(r.floor_hit_fraction, 1.0) << c.what << ": no component in view";
      }
    }
  }
}

}  // namespace
}  // namespace gmm_mcl
