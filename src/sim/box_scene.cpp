#include "gmm_mcl/sim/box_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Slab test: entry and exit distances of a ray through a box.
bool slabs(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double* t_in,
           double* t_out) {
  double lo = -kInf, hi = kInf;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (o[k] < b.min_m[k] || o[k] > b.max_m[k]) return false;
      continue;
    }
    double t0 = (b.min_m[k] - o[k]) / d[k];
    double t1 = (b.max_m[k] - o[k]) / d[k];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0);
    hi = std::min(hi, t1);
  }
  *t_in = lo;
  *t_out = hi;
  return lo <= hi;
}

// Adds flat Gaussians tiling the rectangle origin + s*u + t*v, s in [0, lu], t in [0, lv].
void tileRect(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double lu,
              const Eigen::Vector3d& v, double lv, double spacing, double normal_sigma,
              std::vector<GaussianComponent>* out) {
  const int nu = std::max(1, static_cast<int>(std::round(lu / spacing)));
  const int nv = std::max(1, static_cast<int>(std::round(lv / spacing)));
  const double cu = lu / nu, cv = lv / nv;
  const Eigen::Vector3d n = u.cross(v);
  Eigen::Matrix3d basis;
  basis << u, v, n;
  const Eigen::Vector3d sigma(0.3 * cu, 0.3 * cv, normal_sigma);  // about cell / sqrt(12)
  const Eigen::Matrix3d cov = basis * sigma.cwiseAbs2().asDiagonal() * basis.transpose();
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      GaussianComponent c;
      c.mean_m = origin + (i + 0.5) * cu * u + (j + 0.5) * cv * v;
      c.cov_m2 = 0.5 * (cov + cov.transpose());
      c.weight = cu * cv;  // normalised later
      out->push_back(c);
    }
  }
}

void tileBoxFaces(const Box& b, bool skip_bottom, double spacing, double normal_sigma,
                  std::vector<GaussianComponent>* out) {
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY(),
                        ez = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d s = b.max_m - b.min_m;
  const Eigen::Vector3d& lo = b.min_m;
  const Eigen::Vector3d& hi = b.max_m;
  tileRect(lo, ey, s.y(), ez, s.z(), spacing, normal_sigma, out);  // x = min
  tileRect(Eigen::Vector3d(hi.x(), lo.y(), lo.z()), ey, s.y(), ez, s.z(), spacing, normal_sigma,
           out);
  tileRect(lo, ex, s.x(), ez, s.z(), spacing, normal_sigma, out);  // y = min
  tileRect(Eigen::Vector3d(lo.x(), hi.y(), lo.z()), ex, s.x(), ez, s.z(), spacing, normal_sigma,
           out);
  if (!skip_bottom) tileRect(lo, ex, s.x(), ey, s.y(), spacing, normal_sigma, out);  // z = min
  tileRect(Eigen::Vector3d(lo.x(), lo.y(), hi.z()), ex, s.x(), ey, s.y(), spacing, normal_sigma,
           out);
}

}  // namespace

BoxScene makeDefaultScene() {
  BoxScene s;
  s.room = makeBox(0.0, 0.0, 0.0, 8.0, 6.0, 3.0);
  s.blocks = {
      makeBox(0.0, 0.0, 0.0, 2.2, 0.6, 0.9),   // long low cabinet along the south wall
      makeBox(5.6, 4.2, 0.0, 8.0, 6.0, 2.1),   // tall wardrobe in the north-east corner
      makeBox(3.2, 2.4, 0.0, 4.4, 3.1, 0.75),  // table in the middle
      makeBox(0.0, 3.6, 0.0, 0.5, 5.2, 1.6),   // shelf on the west wall
      makeBox(6.7, 0.8, 0.0, 7.3, 1.4, 1.1),   // pillar-like box near the east wall
      makeBox(2.0, 5.5, 0.0, 3.4, 6.0, 1.9),   // bookcase on the north wall
      makeBox(7.6, 1.9, 0.9, 8.0, 3.3, 1.6),   // wall-mounted cupboard on the east wall
      makeBox(1.0, 1.9, 0.0, 1.5, 2.3, 0.45),  // low stool
      makeBox(4.6, 0.0, 1.2, 5.8, 0.35, 1.5),  // shelf board on the south wall
      makeBox(0.0, 1.2, 2.3, 0.3, 3.0, 3.0),   // beam under the ceiling
  };
  return s;
}

BoxScene makeCorridorScene() {
  BoxScene s;
  s.room = makeBox(0.0, 0.0, 0.0, 30.0, 2.0, 3.0);
  // x0, length, y0, width: irregular gaps (0.4-1.3 m) and sizes, none a copy of another.
  const double boxes[][4] = {
      {1.0, 0.7, 0.2, 0.6},   {2.4, 0.5, 1.1, 0.7},  {3.5, 1.1, 0.4, 0.5},  {5.3, 0.4, 0.9, 0.9},
      {6.2, 0.9, 0.1, 0.8},   {7.9, 0.6, 1.2, 0.5},  {8.9, 0.5, 0.3, 1.2},  {10.3, 1.0, 1.0, 0.6},
      {11.8, 0.45, 0.5, 0.5}, {12.9, 0.8, 0.2, 0.4}, {13.8, 0.6, 1.3, 0.6}, {15.2, 1.2, 0.6, 0.7},
      {16.9, 0.5, 0.15, 0.5}, {17.8, 0.7, 0.9, 0.9}, {19.1, 0.9, 0.3, 0.6}, {20.6, 0.4, 1.2, 0.6},
      {21.5, 1.0, 0.5, 0.8},  {23.0, 0.6, 0.1, 0.5}, {24.1, 0.8, 1.0, 0.8}, {25.5, 0.5, 0.4, 1.1},
      {26.6, 1.1, 1.2, 0.6},  {28.2, 0.6, 0.3, 0.7},
  };
  for (const auto& b : boxes)
    s.blocks.push_back(makeBox(b[0], b[2], 0.0, b[0] + b[1], b[2] + b[3], 0.2));
  return s;
}

Eigen::Isometry3d corridorForwardCamera() {
  return baseToCamera(Eigen::Vector3d(0.1, 0.0, 0.0), Eigen::Vector3d::UnitX(),
                      -Eigen::Vector3d::UnitY());
}

Eigen::Isometry3d corridorDownCamera() {
  return baseToCamera(Eigen::Vector3d(0.0, 0.0, -0.1), -Eigen::Vector3d::UnitZ(),
                      Eigen::Vector3d::UnitX());
}

std::vector<Eigen::Isometry3d> corridorTrajectory(int n) {
  std::vector<Eigen::Isometry3d> poses(std::max(n, 0), Eigen::Isometry3d::Identity());
  for (int f = 0; f < n; ++f) {
    const double t = f / 30.0;
    poses[f].linear() = rotationFromRpy(0.0, 0.0, 0.05 * std::sin(0.7 * t));
    poses[f].translation() = Eigen::Vector3d(11.0 + 0.6 * t, 1.0 + 0.15 * std::sin(0.5 * t), 1.5);
  }
  return poses;
}

Eigen::Isometry3d baseToCamera(const Eigen::Vector3d& position_m, const Eigen::Vector3d& view,
                               const Eigen::Vector3d& right) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d z = view.normalized(), x = right.normalized();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = position_m;
  return T;
}

double castRay(const BoxScene& scene, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t_in, t_out;
  double best = kInf;
  if (slabs(scene.room, o, d, &t_in, &t_out) && t_out > 0.0) best = t_out;
  for (const Box& b : scene.blocks) {
    if (slabs(b, o, d, &t_in, &t_out) && t_in > 1e-9 && t_in < best) best = t_in;
  }
  return best;
}

DepthImage renderDepth(const BoxScene& scene, const Intrinsics& K,
                       const Eigen::Isometry3d& T_map_cam, DepthEncoding encoding,
                       double max_range_m, const DepthNoise& noise, std::mt19937_64* rng) {
  const int w = K.width_px, h = K.height_px;
  std::vector<float> depth(static_cast<size_t>(w) * h, std::numeric_limits<float>::quiet_NaN());
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const Eigen::Vector3d o = T_map_cam.translation();
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector3d ray_cam((u - K.cx_px) / K.fx_px, (v - K.cy_px) / K.fy_px, 1.0);
      const Eigen::Vector3d dir = T_map_cam.linear() * ray_cam.normalized();
      const double t = castRay(scene, o, dir);
      if (!std::isfinite(t)) continue;
      double z = t / ray_cam.norm();  // z-depth
      if (rng && noise.dropout > 0.0 && uni(*rng) < noise.dropout) continue;
      if (rng && noise.sigma_at_1m_m > 0.0) z += noise.sigma_at_1m_m * z * z * gauss(*rng);
      if (z > max_range_m || z <= 0.0) continue;
      depth[static_cast<size_t>(v) * w + u] = static_cast<float>(z);
    }
  }
  if (encoding == DepthEncoding::kFloat32Metres) return DepthImage::fromMetres(w, h, depth);
  std::vector<uint16_t> mm(depth.size(), 0);
  for (size_t i = 0; i < depth.size(); ++i) {
    if (std::isfinite(depth[i])) {
      mm[i] = static_cast<uint16_t>(std::min(65534.0, std::round(1000.0 * depth[i])));
    }
  }
  return DepthImage::fromMillimetres(w, h, mm);
}

GmmMap tileScene(const BoxScene& scene, double spacing_m, double normal_sigma_m) {
  std::vector<GaussianComponent> comps;
  tileBoxFaces(scene.room, false, spacing_m, normal_sigma_m, &comps);
  for (const Box& b : scene.blocks) tileBoxFaces(b, true, spacing_m, normal_sigma_m, &comps);
  double total = 0.0;
  for (const auto& c : comps) total += c.weight;
  for (auto& c : comps) c.weight /= total;
  return GmmMap(std::move(comps), "synthetic box scene");
}

std::vector<Eigen::Isometry3d> makeTrajectory(int n) {
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(n);
  const double dt = 1.0 / 30.0;
  for (int i = 0; i < n; ++i) {
    const double t = i * dt;
    // A slow loop around the table: ellipse centred at (4, 3), 0.25 rad/s.
    const double a = 0.25 * t;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(4.0 + 2.2 * std::cos(a), 3.0 + 1.4 * std::sin(a),
                                      1.5 + 0.2 * std::sin(0.6 * t));
    const double yaw = a + 0.5 * M_PI + 0.3 * std::sin(0.4 * t);  // roughly along the path
    const double roll = 0.03 * std::sin(1.1 * t), pitch = 0.04 * std::sin(0.9 * t + 0.3);
    T.linear() = rotationFromRpy(roll, pitch, yaw);
    poses.push_back(T);
  }
  return poses;
}

Eigen::Isometry3d defaultBaseToCamera() {
  // Optical frame (x right, y down, z forward) on a base with x forward, z up, pitched 10 deg
  // down, 10 cm ahead of the base origin.
  Eigen::Matrix3d R_base_optical;
  R_base_optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix() *
               R_base_optical;
  T.translation() = Eigen::Vector3d(0.1, 0.0, 0.0);
  return T;
}

}  // namespace sim
}  // namespace gmm_mcl
