// The BVH ray caster against brute force on a random triangle soup, and the mesh renderer
// against the analytic box-scene ray caster (same geometry, two independent implementations).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_bvh.h"
#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/mesh_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kRelTolT = 1e-4;              // float BVH vs double brute force, relative t
constexpr double kMaxMismatchFraction = 1e-3;  // rays grazing an edge may disagree

// Double-precision Moller-Trumbore over every triangle.
bool bruteForce(const Mesh& m, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double* t_best,
                uint32_t* tri) {
  *t_best = std::numeric_limits<double>::infinity();
  bool found = false;
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    const Eigen::Vector3d a = m.vertices_m[m.triangles[i][0]].cast<double>();
    const Eigen::Vector3d e1 = m.vertices_m[m.triangles[i][1]].cast<double>() - a;
    const Eigen::Vector3d e2 = m.vertices_m[m.triangles[i][2]].cast<double>() - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-18) continue;
    const Eigen::Vector3d s = o - a;
    const double u = s.dot(p) / det;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (v < 0 || u + v > 1) continue;
    const double t = e2.dot(q) / det;
    if (t > 1e-6 && t < *t_best) {
      *t_best = t;
      *tri = static_cast<uint32_t>(i);
      found = true;
    }
  }
  return found;
}

TEST(MeshBvhTest, MatchesBruteForceOnATriangleSoup) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> pos(-2.f, 2.f), off(-0.3f, 0.3f);
  Mesh m;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3f c(pos(rng), pos(rng), pos(rng));
    const uint32_t k = static_cast<uint32_t>(m.vertices_m.size());
    for (int j = 0; j < 3; ++j)
      m.vertices_m.push_back(c + Eigen::Vector3f(off(rng), off(rng), off(rng)));
    m.triangles.push_back({k, k + 1, k + 2});
  }
  const MeshBvh bvh(m);
  EXPECT_GT(bvh.nodeCount(), 100u);
  EXPECT_LE(bvh.depth(), 60);
  std::normal_distribution<double> g(0.0, 1.0);
  int mismatches = 0, hits = 0;
  const int rays = 3000;
  for (int r = 0; r < rays; ++r) {
    const Eigen::Vector3d o(3.0 * g(rng), 3.0 * g(rng), 3.0 * g(rng));
    // Towards a random point of the soup's cube (not unit length).
    const Eigen::Vector3d d = (Eigen::Vector3d(pos(rng), pos(rng), pos(rng)) - o) * 0.7;
    double t_ref;
    uint32_t tri_ref = 0;
    const bool ref = bruteForce(m, o, d, &t_ref, &tri_ref);
    RayHit hit;
    const bool got = bvh.intersect(o.cast<float>(), d.cast<float>(), 1e-6f, 1e30f, &hit);
    EXPECT_EQ(got, bvh.occluded(o.cast<float>(), d.cast<float>(), 1e-6f, 1e30f));
    if (ref != got || (ref && hit.triangle != tri_ref)) {
      ++mismatches;
      continue;
    }
    if (!ref) continue;
    ++hits;
    EXPECT_NEAR(hit.t, t_ref, kRelTolT * t_ref);
    EXPECT_NEAR(hit.normal.norm(), 1.f, 1e-5f);
  }
  EXPECT_GT(hits, rays / 4);  // the soup is dense enough that many rays hit
  EXPECT_LE(mismatches, kMaxMismatchFraction * rays) << mismatches << " of " << rays;
}

TEST(MeshRendererTest, PlaneInFrontGivesExactZDepthAndIncidence) {
  // A large square at z = 2 m in the camera frame, camera at the origin looking along +z.
  Mesh m;
  m.vertices_m = {{-10, -10, 2}, {10, -10, 2}, {10, 10, 2}, {-10, 10, 2}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  const MeshBvh bvh(m);
  const Intrinsics K = test::smallCamera();
  const IdealDepth d = renderIdealDepth(bvh, K, Eigen::Isometry3d::Identity(), 10.0);
  for (int v = 0; v < K.height_px; v += 7) {
    for (int u = 0; u < K.width_px; u += 7) {
      const size_t i = static_cast<size_t>(v) * K.width_px + u;
      ASSERT_NEAR(d.z_m[i], 2.0, 1e-5);  // z-depth, not range
      const Eigen::Vector3d ray((u - K.cx_px) / K.fx_px, (v - K.cy_px) / K.fy_px, 1.0);
      EXPECT_NEAR(d.cos_incidence[i], 1.0 / ray.norm(), 1e-5);
    }
  }
  // Beyond the maximum depth: nothing.
  const IdealDepth near_only = renderIdealDepth(bvh, K, Eigen::Isometry3d::Identity(), 1.9);
  for (float z : near_only.z_m) EXPECT_TRUE(std::isnan(z));
}

TEST(MeshRendererTest, AgreesWithTheAnalyticBoxScene) {
  const BoxScene boxes = makeDefaultScene();
  PrimitiveScene scene;
  scene.room = boxes.room;
  scene.boxes = boxes.blocks;
  const Mesh mesh = meshFromScene(scene);
  const MeshBvh bvh(mesh);
  const Intrinsics K = test::smallCamera();
  const std::vector<Eigen::Isometry3d> traj = makeTrajectory(300);
  const Eigen::Isometry3d T_base_cam = defaultBaseToCamera();
  size_t pixels = 0, disagree = 0;
  double max_err = 0.0;
  for (int f = 0; f < 300; f += 50) {
    const Eigen::Isometry3d T = traj[f] * T_base_cam;
    const DepthImage a = renderDepth(boxes, K, T, DepthEncoding::kFloat32Metres, 20.0);
    const DepthImage b = renderDepth(bvh, K, T, DepthEncoding::kFloat32Metres, 20.0);
    for (int v = 0; v < K.height_px; ++v) {
      for (int u = 0; u < K.width_px; ++u) {
        const float za = a.depthMetres(u, v), zb = b.depthMetres(u, v);
        ++pixels;
        if (std::isfinite(za) != std::isfinite(zb) ||
            (std::isfinite(za) && std::abs(za - zb) > 1e-3)) {
          ++disagree;
        } else if (std::isfinite(za)) {
          max_err = std::max(max_err, static_cast<double>(std::abs(za - zb)));
        }
      }
    }
  }
  EXPECT_LE(disagree, 1e-3 * pixels) << disagree << " of " << pixels;
  EXPECT_LT(max_err, 1e-4);
}

TEST(MeshSceneTest, DefaultSceneHasCylindersAndAValidMap) {
  const MeshScene s = makeDefaultMeshScene();
  EXPECT_GE(s.primitives.cylinders.size(), 5u);
  EXPECT_TRUE(s.mesh.check().empty());
  // Every tile's weight is its area: the mesh area equals the tiled area only through the
  // normalisation, so check the map against the mesh by its component count and coverage.
  const GmmMap map = tileScene(s.primitives, 0.4, 0.015);
  EXPECT_GT(map.size(), 1000u);
  EXPECT_LT(map.size(), 2000u);
  // Points on the rendered surfaces have a high map density; points in free space do not.
  const Intrinsics K = test::smallCamera();
  const Eigen::Isometry3d T = makeTrajectory(1)[0] * defaultBaseToCamera();
  const IdealDepth d = renderIdealDepth(*s.bvh, K, T, 20.0);
  int on = 0, valid = 0;
  for (int v = 0; v < K.height_px; v += 8) {
    for (int u = 0; u < K.width_px; u += 8) {
      const float z = d.z_m[static_cast<size_t>(v) * K.width_px + u];
      if (!std::isfinite(z)) continue;
      ++valid;
      const Eigen::Vector3d p =
          T * Eigen::Vector3d((u - K.cx_px) / K.fx_px * z, (v - K.cy_px) / K.fy_px * z, z);
      const Eigen::Vector3d free_space = T * Eigen::Vector3d(0, 0, 0.5 * z);
      if (map.logDensity(p) > map.logDensity(free_space) + 5.0) ++on;
    }
  }
  EXPECT_EQ(valid, (K.width_px / 8) * (K.height_px / 8));  // closed room: every ray hits
  EXPECT_GE(on, 0.98 * valid);
}

}  // namespace
}  // namespace sim
}  // namespace gmm_mcl
