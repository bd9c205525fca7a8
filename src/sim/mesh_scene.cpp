#include "gmm_mcl/sim/mesh_scene.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr int kQuadrature = 12;  // midpoint rule per axis for the tile moments

// A planar rectangle origin + s*u*lu + t*v*lv with its outward normal.
struct Rect {
  Eigen::Vector3d origin, u, v, normal;
  double lu, lv;
};

// The six faces of a box; normals point out of the box (inward for the room).
std::vector<Rect> boxFaces(const Box& b, bool inward) {
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY(),
                        ez = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d s = b.max_m - b.min_m;
  const Eigen::Vector3d& lo = b.min_m;
  const Eigen::Vector3d& hi = b.max_m;
  const double sign = inward ? -1.0 : 1.0;
  return {
      {lo, ey, ez, -sign * ex, s.y(), s.z()},
      {Eigen::Vector3d(hi.x(), lo.y(), lo.z()), ey, ez, sign * ex, s.y(), s.z()},
      {lo, ex, ez, -sign * ey, s.x(), s.z()},
      {Eigen::Vector3d(lo.x(), hi.y(), lo.z()), ex, ez, sign * ey, s.x(), s.z()},
      {lo, ex, ey, -sign * ez, s.x(), s.y()},
      {Eigen::Vector3d(lo.x(), lo.y(), hi.z()), ex, ey, sign * ez, s.x(), s.y()},
  };
}

// True when a face lies in one of the room's six planes (against a wall, floor or ceiling).
bool onRoomBoundary(const Rect& f, const Box& room) {
  for (int k = 0; k < 3; ++k) {
    if (std::abs(f.normal[k]) < 0.5) continue;
    const double c = f.origin[k];
    if (std::abs(c - room.min_m[k]) < 1e-9 || std::abs(c - room.max_m[k]) < 1e-9) return true;
  }
  return false;
}

bool onFloorOrCeiling(double z, const Box& room) {
  return std::abs(z - room.min_m.z()) < 1e-9 || std::abs(z - room.max_m.z()) < 1e-9;
}

void addQuad(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
             const Eigen::Vector3d& d, const Eigen::Vector3d& normal, Mesh* m) {
  const uint32_t i = static_cast<uint32_t>(m->vertices_m.size());
  for (const Eigen::Vector3d* p : {&a, &b, &c, &d}) m->vertices_m.push_back(p->cast<float>());
  // Counter-clockwise seen from the side the normal points to.
  if ((b - a).cross(c - a).dot(normal) >= 0.0) {
    m->triangles.push_back({i, i + 1, i + 2});
    m->triangles.push_back({i, i + 2, i + 3});
  } else {
    m->triangles.push_back({i, i + 2, i + 1});
    m->triangles.push_back({i, i + 3, i + 2});
  }
}

void addRect(const Rect& f, Mesh* m) {
  const Eigen::Vector3d a = f.origin, b = a + f.lu * f.u, c = b + f.lv * f.v, d = a + f.lv * f.v;
  addQuad(a, b, c, d, f.normal, m);
}

Eigen::Vector3d cylPoint(const Cylinder& c, double radius, double theta, double z) {
  return Eigen::Vector3d(c.centre_m.x() + radius * std::cos(theta),
                         c.centre_m.y() + radius * std::sin(theta), z);
}

// One Gaussian with the moments of a surface patch P(s, t), s, t in [0, 1], area element dA,
// plus normal_sigma^2 along `normal`. Appends nothing for a patch of zero area.
void addPatch(const std::function<Eigen::Vector3d(double, double)>& P,
              const std::function<double(double, double)>& dA, const Eigen::Vector3d& normal,
              double normal_sigma, std::vector<GaussianComponent>* out) {
  double w = 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum2 = Eigen::Matrix3d::Zero();
  for (int i = 0; i < kQuadrature; ++i) {
    for (int j = 0; j < kQuadrature; ++j) {
      const double s = (i + 0.5) / kQuadrature, t = (j + 0.5) / kQuadrature;
      const double a = dA(s, t) / (kQuadrature * kQuadrature);
      const Eigen::Vector3d p = P(s, t);
      w += a;
      sum += a * p;
      sum2 += a * p * p.transpose();
    }
  }
  if (!(w > 0.0)) return;
  GaussianComponent g;
  g.weight = w;
  g.mean_m = sum / w;
  Eigen::Matrix3d cov = sum2 / w - g.mean_m * g.mean_m.transpose();
  const Eigen::Vector3d n = normal.normalized();
  cov += normal_sigma * normal_sigma * n * n.transpose();
  g.cov_m2 = 0.5 * (cov + cov.transpose());
  out->push_back(g);
}

void tileRect(const Rect& f, double spacing, double normal_sigma,
              std::vector<GaussianComponent>* out) {
  const int nu = std::max(1, static_cast<int>(std::round(f.lu / spacing)));
  const int nv = std::max(1, static_cast<int>(std::round(f.lv / spacing)));
  const double cu = f.lu / nu, cv = f.lv / nv;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const Eigen::Vector3d o = f.origin + i * cu * f.u + j * cv * f.v;
      addPatch(
          [&](double s, double t) -> Eigen::Vector3d { return o + s * cu * f.u + t * cv * f.v; },
          [&](double, double) { return cu * cv; }, f.normal, normal_sigma, out);
    }
  }
}

// Annulus rho in [r0, r1] of a cap at height z, split into sectors of about spacing.
void tileCap(const Cylinder& c, double z, bool up, double spacing, double normal_sigma,
             std::vector<GaussianComponent>* out) {
  const int nr = std::max(1, static_cast<int>(std::round(c.radius_m / spacing)));
  for (int k = 0; k < nr; ++k) {
    const double r0 = c.radius_m * k / nr, r1 = c.radius_m * (k + 1) / nr;
    const int nt =
        k == 0 ? 1 : std::max(3, static_cast<int>(std::round(kTwoPi * 0.5 * (r0 + r1) / spacing)));
    for (int j = 0; j < nt; ++j) {
      const double t0 = kTwoPi * j / nt, dt = kTwoPi / nt;
      addPatch([&](double s, double t) { return cylPoint(c, r0 + s * (r1 - r0), t0 + t * dt, z); },
               [&](double s, double) { return (r0 + s * (r1 - r0)) * (r1 - r0) * dt; },
               Eigen::Vector3d(0, 0, up ? 1.0 : -1.0), normal_sigma, out);
    }
  }
}

void tileCylinder(const Cylinder& c, const Box& room, double spacing, double normal_sigma,
                  std::vector<GaussianComponent>* out) {
  const double h = c.z_max_m - c.z_min_m;
  const int nt = std::max(6, static_cast<int>(std::round(kTwoPi * c.radius_m / spacing)));
  const int nz = std::max(1, static_cast<int>(std::round(h / spacing)));
  const double dt = kTwoPi / nt, dz = h / nz;
  for (int j = 0; j < nt; ++j) {
    for (int k = 0; k < nz; ++k) {
      const double t0 = j * dt, z0 = c.z_min_m + k * dz;
      const double tm = t0 + 0.5 * dt;
      addPatch(
          [&](double s, double t) { return cylPoint(c, c.radius_m, t0 + s * dt, z0 + t * dz); },
          [&](double, double) { return c.radius_m * dt * dz; },
          Eigen::Vector3d(std::cos(tm), std::sin(tm), 0.0), normal_sigma, out);
    }
  }
  if (!onFloorOrCeiling(c.z_max_m, room)) tileCap(c, c.z_max_m, true, spacing, normal_sigma, out);
  if (!onFloorOrCeiling(c.z_min_m, room)) tileCap(c, c.z_min_m, false, spacing, normal_sigma, out);
}

Cylinder cylinder(double x, double y, double r, double z0, double z1) {
  Cylinder c;
  c.centre_m = Eigen::Vector2d(x, y);
  c.radius_m = r;
  c.z_min_m = z0;
  c.z_max_m = z1;
  return c;
}

}  // namespace

PrimitiveScene makeDefaultPrimitiveScene() {
  const BoxScene boxes = makeDefaultScene();
  PrimitiveScene s;
  s.room = boxes.room;
  s.boxes = boxes.blocks;
  s.cylinders = {
      cylinder(1.0, 4.8, 0.20, 0.0, 3.0),     // column from floor to ceiling, north-west
      cylinder(2.7, 0.95, 0.35, 0.0, 1.0),    // drum beside the low cabinet
      cylinder(6.2, 1.5, 0.25, 0.0, 0.6),     // round stool near the east pillar
      cylinder(7.0, 3.65, 0.45, 0.70, 0.75),  // round side-table top ...
      cylinder(7.0, 3.65, 0.05, 0.0, 0.70),   // ... on one leg
      cylinder(3.8, 2.75, 0.30, 2.6, 3.0),    // ceiling lamp above the table
  };
  return s;
}

Mesh meshFromScene(const PrimitiveScene& scene, int segments) {
  segments = std::max(3, segments);
  Mesh m;
  for (const Rect& f : boxFaces(scene.room, true)) addRect(f, &m);
  for (const Box& b : scene.boxes) {
    for (const Rect& f : boxFaces(b, false)) {
      if (!onRoomBoundary(f, scene.room)) addRect(f, &m);
    }
  }
  for (const Cylinder& c : scene.cylinders) {
    for (int j = 0; j < segments; ++j) {
      const double t0 = kTwoPi * j / segments, t1 = kTwoPi * (j + 1) / segments;
      const double tm = 0.5 * (t0 + t1);
      addQuad(cylPoint(c, c.radius_m, t0, c.z_min_m), cylPoint(c, c.radius_m, t1, c.z_min_m),
              cylPoint(c, c.radius_m, t1, c.z_max_m), cylPoint(c, c.radius_m, t0, c.z_max_m),
              Eigen::Vector3d(std::cos(tm), std::sin(tm), 0.0), &m);
    }
    for (int cap = 0; cap < 2; ++cap) {
      const double z = cap == 0 ? c.z_max_m : c.z_min_m;
      if (onFloorOrCeiling(z, scene.room)) continue;
      const uint32_t centre = static_cast<uint32_t>(m.vertices_m.size());
      m.vertices_m.push_back(Eigen::Vector3f(static_cast<float>(c.centre_m.x()),
                                             static_cast<float>(c.centre_m.y()),
                                             static_cast<float>(z)));
      for (int j = 0; j < segments; ++j) {
        m.vertices_m.push_back(cylPoint(c, c.radius_m, kTwoPi * j / segments, z).cast<float>());
      }
      for (int j = 0; j < segments; ++j) {
        const uint32_t a = centre + 1 + j, b = centre + 1 + (j + 1) % segments;
        if (cap == 0)
          m.triangles.push_back({centre, a, b});  // normal up
        else
          m.triangles.push_back({centre, b, a});  // normal down
      }
    }
  }
  return m;
}

GmmMap tileScene(const PrimitiveScene& scene, double spacing_m, double normal_sigma_m) {
  if (!(spacing_m > 0.0) || !(normal_sigma_m > 0.0)) {
    throw std::invalid_argument("tileScene: spacing and normal sigma must be positive");
  }
  std::vector<GaussianComponent> comps;
  for (const Rect& f : boxFaces(scene.room, true)) tileRect(f, spacing_m, normal_sigma_m, &comps);
  for (const Box& b : scene.boxes) {
    for (const Rect& f : boxFaces(b, false)) {
      if (!onRoomBoundary(f, scene.room)) tileRect(f, spacing_m, normal_sigma_m, &comps);
    }
  }
  for (const Cylinder& c : scene.cylinders) {
    tileCylinder(c, scene.room, spacing_m, normal_sigma_m, &comps);
  }
  double total = 0.0;
  for (const auto& c : comps) total += c.weight;
  for (auto& c : comps) c.weight /= total;
  return GmmMap(std::move(comps), "synthetic mesh scene");
}

MeshScene makeDefaultMeshScene() {
  MeshScene s;
  s.primitives = makeDefaultPrimitiveScene();
  s.mesh = meshFromScene(s.primitives);
  s.bvh = std::make_shared<const MeshBvh>(s.mesh);
  return s;
}

Intrinsics pinholeCamera(int width_px, int height_px, float f_px, float cx_px, float cy_px) {
  Intrinsics K;
  K.fx_px = K.fy_px = f_px;
  K.cx_px = cx_px;
  K.cy_px = cy_px;
  K.width_px = width_px;
  K.height_px = height_px;
  return K;
}

Intrinsics defaultCamera(int width_px) {
  const int height_px = width_px * 3 / 4;
  return pinholeCamera(width_px, height_px, 585.f * (width_px / 640.f), 0.5f * (width_px - 1),
                       0.5f * (height_px - 1));
}

Intrinsics sevenScenesCamera() { return pinholeCamera(640, 480, 585.f, 320.f, 240.f); }

uint64_t frameSeed(uint64_t seed, int frame) {
  return seed * 0x9e3779b97f4a7c15ull + static_cast<uint64_t>(frame) + 1;
}

}  // namespace sim
}  // namespace gmm_mcl
