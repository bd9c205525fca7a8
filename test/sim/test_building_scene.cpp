// The building world (sim/building_scene.h) and the walks through it (sim/building_walk.h): size,
// rooms, doors, connectivity, rooms that differ, determinism per seed, closed walls, the visible-
// surface mesh and map, walks that keep clear of walls and furniture and move smoothly, and a
// frame through a door that sees both rooms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/datasets/tum_sequence.h"
#include "gmm_mcl/sim/building_scene.h"
#include "gmm_mcl/sim/building_walk.h"
#include "gmm_mcl/sim/mesh_bvh.h"
#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/trajectory_io.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kMinSideM = 50.0;        // the building protocol: at least 50 m x 50 m
constexpr double kMinComponents = 80000;  // "about 100,000" map components
constexpr double kMaxComponents = 125000;
constexpr double kCameraMarginM = 0.15;          // walk poses: camera this far from any solid
constexpr double kBaseMarginM = 0.25;            // the base (clearance 0.3 m less rounding)
constexpr double kMaxStepM = 1.2 / 30.0;         // at most 1.2 m/s between 30 Hz frames
constexpr double kMaxYawStepRad = 0.08;          // 2.4 rad/s
constexpr double kMinSideFraction = 0.02;        // doorway frame: pixels on each side of the door
constexpr double kDoorwayCameraDistanceM = 1.4;  // in the doors' keep-clear zone (1.6 m)
constexpr double kDoorwayCameraHeightM = 1.75;   // the lintel (2.1 m) in view

const BuildingScene& building1() {
  static const BuildingScene b = makeBuilding(BuildingParams());
  return b;
}

const MeshBvh& bvh1() {
  static const MeshBvh bvh(meshFromBuilding(building1()));
  return bvh;
}

// Spaces reached from the corridor network through doors.
std::vector<char> reachedThroughDoors(const BuildingScene& b) {
  std::vector<char> reached(b.spaces.size(), 0);
  reached[0] = 1;
  for (bool grew = true; grew;) {
    grew = false;
    for (const BuildingDoor& d : b.doors) {
      if (reached[d.space_a] != reached[d.space_b]) {
        reached[d.space_a] = reached[d.space_b] = 1;
        grew = true;
      }
    }
  }
  return reached;
}

std::string describe(const BuildingScene& b) {
  std::ostringstream s;
  s.precision(17);
  for (const Box& x : b.primitives.boxes)
    s << x.min_m.transpose() << ' ' << x.max_m.transpose() << '\n';
  for (const Cylinder& c : b.primitives.cylinders) {
    s << c.centre_m.transpose() << ' ' << c.radius_m << ' ' << c.z_min_m << ' ' << c.z_max_m
      << '\n';
  }
  for (const BuildingDoor& d : b.doors)
    s << d.plane_m << ' ' << d.centre_m << ' ' << d.width_m << '\n';
  for (const BuildingSpace& sp : b.spaces) s << sp.kind << ' ' << sp.cells.size() << '\n';
  return s.str();
}

TEST(BuildingSceneTest, DefaultParametersAreValidAndFaultsAreNamed) {
  EXPECT_EQ(BuildingParams().validate(), "");
  EXPECT_EQ(BuildingWalkParams().validate(), "");
  BuildingParams p;
  p.width_m = 20.0;
  EXPECT_NE(p.validate().find("width_m"), std::string::npos);
  p = BuildingParams();
  p.door_height_m = 3.5;
  EXPECT_NE(p.validate().find("door_height_m"), std::string::npos);
  EXPECT_THROW(makeBuilding(p), std::invalid_argument);
  p = BuildingParams();
  p.room_count = 400;  // cannot fit
  EXPECT_THROW(makeBuilding(p), std::runtime_error);
  BuildingWalkParams w;
  w.clearance_m = 0.0;
  EXPECT_NE(w.validate().find("clearance_m"), std::string::npos);
}

TEST(BuildingSceneTest, SizeRoomsAndDoorsAreAsRequested) {
  const BuildingScene& b = building1();
  const BuildingParams& p = b.params;
  const Eigen::Vector3d size = b.bounds().max_m - b.bounds().min_m;
  EXPECT_GE(size.x(), kMinSideM);
  EXPECT_GE(size.y(), kMinSideM);
  EXPECT_DOUBLE_EQ(size.z(), p.height_m);
  EXPECT_EQ(b.roomCount(), p.room_count);
  EXPECT_EQ(static_cast<int>(b.doors.size()), p.room_count + p.extra_doors);
  int merged = 0, corridors = 0;
  for (const BuildingSpace& s : b.spaces) {
    corridors += s.corridor ? 1 : 0;
    merged += !s.corridor && s.cells.size() == 2 ? 1 : 0;
    for (const PlanRect& c : s.cells) {
      EXPECT_GE((c.hi_m - c.lo_m).minCoeff(),
                s.corridor ? p.corridor_min_width_m : p.min_room_side_m);
    }
  }
  EXPECT_EQ(corridors, 1);  // one network of corridor strips
  EXPECT_GE(b.spaces[0].cells.size(), 3u);
  EXPECT_EQ(merged, p.merged_rooms);
  for (const BuildingDoor& d : b.doors) {
    EXPECT_NE(d.space_a, d.space_b);
    EXPECT_GE(d.width_m, p.door_min_width_m);
    EXPECT_LE(d.width_m, p.door_max_width_m);
  }
  const std::vector<char> reached = reachedThroughDoors(b);
  EXPECT_EQ(std::count(reached.begin(), reached.end(), 1), static_cast<long>(b.spaces.size()));
  EXPECT_GT(b.wall_box_count, 0u);
  EXPECT_GT(b.primitives.boxes.size(), 4 * b.wall_box_count);  // furniture beyond the walls
  EXPECT_GT(b.primitives.cylinders.size(), 50u);
}

TEST(BuildingSceneTest, RoomsDifferInShapeKindAndContent) {
  const BuildingScene& b = building1();
  std::set<std::string> kinds, signatures;
  int rooms = 0;
  for (size_t i = 0; i < b.spaces.size(); ++i) {
    const BuildingSpace& s = b.spaces[i];
    if (s.corridor) continue;
    ++rooms;
    kinds.insert(s.kind);
    // Size of each cell (cm) and what stands in the room: no two rooms alike.
    std::ostringstream sig;
    for (const PlanRect& c : s.cells) {
      sig << std::lround(100 * (c.hi_m.x() - c.lo_m.x())) << 'x'
          << std::lround(100 * (c.hi_m.y() - c.lo_m.y())) << ' ';
    }
    int boxes = 0, cylinders = 0;
    for (size_t k = b.wall_box_count; k < b.primitives.boxes.size(); ++k) {
      const Box& x = b.primitives.boxes[k];
      boxes += b.spaceAt(0.5 * (x.min_m + x.max_m).head<2>()) == static_cast<int>(i) ? 1 : 0;
    }
    for (const Cylinder& c : b.primitives.cylinders) {
      cylinders += b.spaceAt(c.centre_m) == static_cast<int>(i) ? 1 : 0;
    }
    EXPECT_GT(boxes + cylinders, 0) << "room " << i << " (" << s.kind << ") is empty";
    sig << boxes << ' ' << cylinders;
    signatures.insert(sig.str());
  }
  EXPECT_GE(kinds.size(), 8u);
  EXPECT_EQ(static_cast<int>(signatures.size()), rooms);
}

TEST(BuildingSceneTest, DeterministicForASeedAndDifferentBetweenSeeds) {
  BuildingParams p;
  const std::string a = describe(makeBuilding(p));
  EXPECT_EQ(a, describe(building1()));
  p.seed = 2;
  const BuildingScene b2 = makeBuilding(p);
  EXPECT_NE(a, describe(b2));
  EXPECT_EQ(b2.roomCount(), p.room_count);
  // Different plans, not just different furniture: the doors are elsewhere.
  EXPECT_NE(building1().doors[0].centre2d(), b2.doors[0].centre2d());
}

TEST(BuildingSceneTest, DoorsAreOpenBelowTheLintelAndClosedAbove) {
  const BuildingScene& b = building1();
  const MeshBvh& bvh = bvh1();
  const double t = b.params.wall_thickness_m;
  for (const BuildingDoor& d : b.doors) {
    Eigen::Vector3f dir = Eigen::Vector3f::Zero();
    dir[d.normal_axis] = 1.f;
    Eigen::Vector3f o;
    o.head<2>() = d.centre2d().cast<float>();
    o[d.normal_axis] -= 1.5f;
    o.z() = 1.0f;
    RayHit hit;
    // Nothing within 1.5 m either side of the door (furniture is kept out of its way).
    EXPECT_FALSE(bvh.intersect(o, dir, 0.f, 3.0f, &hit))
        << "door at " << d.centre2d().transpose() << " blocked at " << hit.t - 1.5f;
    o.z() = static_cast<float>(0.5 * (d.height_m + b.params.height_m));
    ASSERT_TRUE(bvh.intersect(o, dir, 0.f, 3.0f, &hit));
    EXPECT_NEAR(hit.t, 1.5 - 0.5 * t, 1e-4);  // the lintel
  }
}

// Rays from inside each cell of each space (rooms, parts of merged rooms, corridor strips)
// towards the cell's corners, at three heights: every hit lies in a cell of the same space
// (grown by half a wall). Doors are away from corners, so a ray that gets out found a gap in
// the walls (at corners seen from a corridor or across an L-shaped room, too).
TEST(BuildingSceneTest, WallsCloseEverySpace) {
  const BuildingScene& b = building1();
  const MeshBvh& bvh = bvh1();
  const double half = 0.5 * b.params.wall_thickness_m + 1e-3;
  int rays = 0;
  for (size_t i = 0; i < b.spaces.size(); ++i) {
    const BuildingSpace& s = b.spaces[i];
    auto inSpace = [&](const Eigen::Vector3f& p) {
      for (const PlanRect& c : s.cells) {
        if (p.x() >= c.lo_m.x() - half && p.x() <= c.hi_m.x() + half &&
            p.y() >= c.lo_m.y() - half && p.y() <= c.hi_m.y() + half) {
          return true;
        }
      }
      return false;
    };
    for (const PlanRect& c : s.cells) {
      const Eigen::Vector2d centre = 0.5 * (c.lo_m + c.hi_m);
      for (int corner = 0; corner < 4; ++corner) {
        const Eigen::Vector2d k(corner & 1 ? c.hi_m.x() : c.lo_m.x(),
                                corner & 2 ? c.hi_m.y() : c.lo_m.y());
        // Start near the corner (furniture in the middle would stop the ray early), not inside
        // furniture (its faces against the wall are gone, so a ray from inside would leave
        // through them).
        const Eigen::Vector2d from = k + 0.9 * (centre - k).normalized();
        for (double off : {-0.04, 0.0, 0.04}) {
          for (double z : {0.3, 1.0, 2.5}) {
            if (insideSolid(b.primitives, Eigen::Vector3d(from.x(), from.y(), z), 0.01)) continue;
            const Eigen::Vector2d aim = k + Eigen::Vector2d(off, -off);
            const Eigen::Vector3f o(static_cast<float>(from.x()), static_cast<float>(from.y()),
                                    static_cast<float>(z));
            const Eigen::Vector3f dir(static_cast<float>(aim.x() - from.x()),
                                      static_cast<float>(aim.y() - from.y()), 0.f);
            RayHit hit;
            ASSERT_TRUE(bvh.intersect(o, dir, 0.f, 200.f, &hit)) << "ray out of space " << i;
            const Eigen::Vector3f p = o + hit.t * dir;
            EXPECT_TRUE(inSpace(p)) << "space " << i << " (" << s.kind << ") corner "
                                    << k.transpose() << " z " << z << ": hit at " << p.transpose();
            ++rays;
          }
        }
      }
    }
  }
  EXPECT_GT(rays, 600);
}

TEST(BuildingSceneTest, MeshAndMapCoverOnlyVisibleSurfaces) {
  const BuildingScene& b = building1();
  const Mesh mesh = meshFromBuilding(b);
  EXPECT_EQ(mesh.check(), "");
  EXPECT_GT(mesh.triangles.size(), 10000u);
  // Every triangle faces free space: a point just in front of it lies in no box and in the shell.
  size_t facing_solid = 0;
  for (const auto& tri : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices_m[tri[0]].cast<double>(),
                          v1 = mesh.vertices_m[tri[1]].cast<double>(),
                          v2 = mesh.vertices_m[tri[2]].cast<double>();
    const Eigen::Vector3d n = (v1 - a).cross(v2 - a);
    if (n.norm() < 1e-12) continue;
    const Eigen::Vector3d p = (a + v1 + v2) / 3.0 + 5e-4 * n.normalized();
    bool inside = ((p - b.bounds().min_m).array() < 0.0).any() ||
                  ((b.bounds().max_m - p).array() < 0.0).any();
    for (const Box& x : b.primitives.boxes) {
      inside =
          inside || (((p - x.min_m).array() > 0.0).all() && ((x.max_m - p).array() > 0.0).all());
    }
    facing_solid += inside ? 1 : 0;
  }
  EXPECT_EQ(facing_solid, 0u);
  const GmmMap map = tileBuilding(b);
  EXPECT_GE(map.size(), kMinComponents);
  EXPECT_LE(map.size(), kMaxComponents);
  double total = 0.0;
  for (const GaussianComponent& g : map.components()) {
    total += g.weight;
    EXPECT_TRUE(((g.mean_m - b.bounds().min_m).array() >= -1e-9).all());
    EXPECT_TRUE(((b.bounds().max_m - g.mean_m).array() >= -1e-9).all());
  }
  EXPECT_NEAR(total, 1.0, 1e-9);
  // The hidden faces are gone: less surface than all faces of all primitives together.
  EXPECT_LT(mesh.area_m2(), 0.95 * meshFromScene(b.primitives, 24).area_m2());
}

// The visible-surface mesher on two boxes against each other in a room: the touching faces and
// the part of the floor under them vanish.
TEST(BuildingSceneTest, VisibleMeshDropsTouchingFaces) {
  PrimitiveScene s;
  s.room.min_m = Eigen::Vector3d(0, 0, 0);
  s.room.max_m = Eigen::Vector3d(4, 4, 2);
  Box a, c;
  a.min_m = Eigen::Vector3d(1, 1, 0);
  a.max_m = Eigen::Vector3d(2, 2, 1);
  c.min_m = Eigen::Vector3d(2, 1, 0);
  c.max_m = Eigen::Vector3d(3, 2, 1);
  s.boxes = {a, c};
  const Mesh m = visibleMeshFromScene(s, 24);
  // Room 2*16 + 4*8 = 64, less the 2 m^2 footprint; boxes: tops 2, sides 6 (the 1 m^2 faces
  // against each other and the bottoms gone).
  EXPECT_NEAR(m.area_m2(), 64.0 - 2.0 + 2.0 + 6.0, 1e-9);
  const GmmMap g = tileVisibleScene(s, 0.5, 0.01);
  double area = 0.0;
  for (const GaussianComponent& x : g.components()) area += x.weight;
  EXPECT_NEAR(area, 1.0, 1e-9);
}

TEST(BuildingWalkTest, WalksKeepClearAndMoveSmoothlyBetweenRooms) {
  const BuildingScene& b = building1();
  const MeshBvh& bvh = bvh1();
  for (uint64_t seed : {1u, 2u}) {
    BuildingWalkParams p;
    p.seed = seed;
    p.frames = 900;
    const BuildingWalk w = makeBuildingWalk(b, p);
    ASSERT_EQ(w.T_world_cam.size(), 900u);
    ASSERT_EQ(w.T_world_base.size(), 900u);
    int rooms = 0;
    for (int s : w.spaces) rooms += b.spaces[s].corridor ? 0 : 1;
    EXPECT_GE(rooms, 2) << "walk " << seed;
    EXPECT_GE(w.spaces.size(), 3u) << "walk " << seed;
    EXPECT_GT(w.length_m, 12.0);
    for (size_t i = 0; i < w.T_world_cam.size(); ++i) {
      const Eigen::Vector3d cam = w.T_world_cam[i].translation();
      const Eigen::Vector3d base = w.T_world_base[i].translation();
      EXPECT_FALSE(insideSolid(b.primitives, cam, kCameraMarginM)) << "frame " << i;
      EXPECT_FALSE(insideSolid(b.primitives, base, kBaseMarginM)) << "frame " << i;
      EXPECT_GE(base.z(), p.min_height_m - 1e-9);
      EXPECT_LE(base.z(), p.max_height_m + 1e-9);
      EXPECT_NEAR(w.stamps_s[i], i / p.rate_hz, 1e-9);
      if (i == 0) continue;
      const Eigen::Vector3d prev = w.T_world_cam[i - 1].translation();
      EXPECT_LT((cam - prev).norm(), kMaxStepM) << "frame " << i;
      const Eigen::Vector3d f0 = w.T_world_base[i - 1].linear().col(0),
                            f1 = w.T_world_base[i].linear().col(0);
      EXPECT_LT(std::acos(std::min(1.0, f0.dot(f1))), kMaxYawStepRad) << "frame " << i;
      // No surface between consecutive camera positions (never through a wall).
      RayHit hit;
      EXPECT_FALSE(bvh.intersect(prev.cast<float>(), (cam - prev).cast<float>(), 0.f, 1.f, &hit))
          << "frame " << i;
    }
  }
}

TEST(BuildingWalkTest, TrajectoryFileRoundTrips) {
  BuildingWalkParams p;
  p.frames = 60;
  const BuildingWalk w = makeBuildingWalk(building1(), p);
  test::TempDir dir("building_walk");
  const std::string path = dir / "walk.txt";
  writeTumTrajectory(path, w.stamps_s, w.T_world_cam, "walk 1\nbuilding seed 1");
  const std::vector<StampedPose> back = readTumTrajectory(path);
  ASSERT_EQ(back.size(), w.T_world_cam.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_NEAR(back[i].stamp_s, w.stamps_s[i], 1e-6);
    EXPECT_LT((back[i].T.translation() - w.T_world_cam[i].translation()).norm(), 1e-8);
    EXPECT_LT((back[i].T.linear() - w.T_world_cam[i].linear()).norm(), 1e-8);
  }
  const BuildingWalk again = makeBuildingWalk(building1(), p);
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(again.T_world_cam[i].matrix(), w.T_world_cam[i].matrix());
  }
}

// A camera in front of a door, facing through it (with the sensor model): it sees the wall of its
// own room around the door (jambs and lintel) and the room beyond.
TEST(BuildingWalkTest, FrameThroughADoorSeesBothRooms) {
  const BuildingScene& b = building1();
  const MeshBvh& bvh = bvh1();
  const Intrinsics K = defaultCamera(320);
  SensorNoiseParams noise;
  const double half = 0.5 * b.params.wall_thickness_m;
  int checked = 0;
  for (size_t di = 0; di < b.doors.size() && checked < 8; di += 5) {
    const BuildingDoor& d = b.doors[di];
    for (double side : {-1.0, 1.0}) {
      // Optical frame: z along the door's normal (towards -side), x right, y down.
      Eigen::Vector3d z = Eigen::Vector3d::Zero();
      z[d.normal_axis] = -side;
      const Eigen::Vector3d y(0, 0, -1), x = y.cross(z);
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear().col(0) = x;
      T.linear().col(1) = y;
      T.linear().col(2) = z;
      T.translation() << d.centre2d(), kDoorwayCameraHeightM;
      T.translation()[d.normal_axis] += side * kDoorwayCameraDistanceM;
      const DepthImage img =
          renderDepth(bvh, K, T, DepthEncoding::kFloat32Metres, 10.0, &noise, 7 + di);
      int near = 0, far = 0, valid = 0;
      for (int v = 0; v < K.height_px; ++v) {
        for (int u = 0; u < K.width_px; ++u) {
          const float zm = reinterpret_cast<const float*>(img.data.data() + v * img.row_bytes)[u];
          if (!std::isfinite(zm) || zm <= 0.f) continue;
          ++valid;
          const Eigen::Vector3d p_cam((u - K.cx_px) / K.fx_px * zm, (v - K.cy_px) / K.fy_px * zm,
                                      zm);
          // Signed distance past the door plane, along the view.
          const double past = -side * ((T * p_cam)[d.normal_axis] - d.plane_m);
          near += past < -half + 0.02 ? 1 : 0;  // this side: the wall face and anything before
          far += past > 0.5 ? 1 : 0;            // at least 0.5 m into the next room
        }
      }
      ASSERT_GT(valid, 0);
      EXPECT_GT(near, kMinSideFraction * valid) << "door " << di << " side " << side;
      EXPECT_GT(far, kMinSideFraction * valid) << "door " << di << " side " << side;
      ++checked;
    }
  }
  EXPECT_GE(checked, 8);
}

}  // namespace
}  // namespace sim
}  // namespace gmm_mcl
