#include "gmm_mcl/sim/mesh_scene.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>

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

// Caps: left out where they lie on the floor or ceiling, or where *_hidden says so.
void tileCylinder(const Cylinder& c, const Box& room, double spacing, double normal_sigma,
                  std::vector<GaussianComponent>* out, bool top_hidden = false,
                  bool bottom_hidden = false) {
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
  if (!top_hidden && !onFloorOrCeiling(c.z_max_m, room)) {
    tileCap(c, c.z_max_m, true, spacing, normal_sigma, out);
  }
  if (!bottom_hidden && !onFloorOrCeiling(c.z_min_m, room)) {
    tileCap(c, c.z_min_m, false, spacing, normal_sigma, out);
  }
}

// ---- visible parts of faces (visibleMeshFromScene, tileVisibleScene) ----

// Faces closer than this to a box's face touch it (the space in front of them is inside it).
constexpr double kTouchM = 1e-4;
// Coordinates closer than this are one in the decomposition of a face.
constexpr double kSnapM = 1e-7;
// Tiles with less than this fraction of their quadrature points visible are left out.
constexpr double kMinVisibleTileFraction = 0.03;

int axisOf(const Eigen::Vector3d& a) {
  int k = 0;
  a.cwiseAbs().maxCoeff(&k);
  return k;
}

// A rectangle [u0, u1] x [v0, v1] in a face's own coordinates (metres along its u and v).
struct Span2 {
  double u0, u1, v0, v1;
};

// The boxes of a scene in a uniform grid over x and y, for the boxes near a face.
class BoxIndex {
 public:
  BoxIndex(const std::vector<Box>& boxes, double cell_m) : boxes_(boxes), cell_m_(cell_m) {
    if (boxes.empty()) return;
    lo_ = boxes[0].min_m.head<2>();
    Eigen::Vector2d hi = boxes[0].max_m.head<2>();
    for (const Box& b : boxes) {
      lo_ = lo_.cwiseMin(b.min_m.head<2>());
      hi = hi.cwiseMax(b.max_m.head<2>());
    }
    nx_ = std::max(1, static_cast<int>(std::ceil((hi.x() - lo_.x()) / cell_m_)) + 1);
    ny_ = std::max(1, static_cast<int>(std::ceil((hi.y() - lo_.y()) / cell_m_)) + 1);
    cells_.resize(static_cast<size_t>(nx_) * ny_);
    for (size_t i = 0; i < boxes.size(); ++i) {
      int x0, x1, y0, y1;
      range(boxes[i].min_m.head<2>(), boxes[i].max_m.head<2>(), &x0, &x1, &y0, &y1);
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) cells_[static_cast<size_t>(y) * nx_ + x].push_back(i);
      }
    }
    stamp_.assign(boxes.size(), 0);
  }

  // Indices of the boxes whose cells meet [lo, hi] (x, y), each once, in increasing order.
  void query(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, std::vector<size_t>* out) {
    out->clear();
    if (boxes_.empty()) return;
    ++visit_;
    int x0, x1, y0, y1;
    range(lo, hi, &x0, &x1, &y0, &y1);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        for (size_t i : cells_[static_cast<size_t>(y) * nx_ + x]) {
          if (stamp_[i] == visit_) continue;
          stamp_[i] = visit_;
          out->push_back(i);
        }
      }
    }
    std::sort(out->begin(), out->end());
  }

 private:
  void range(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, int* x0, int* x1, int* y0,
             int* y1) const {
    auto cell = [&](double v, double origin, int n) {
      return std::min(n - 1, std::max(0, static_cast<int>(std::floor((v - origin) / cell_m_))));
    };
    *x0 = cell(lo.x() - kTouchM, lo_.x(), nx_);
    *x1 = cell(hi.x() + kTouchM, lo_.x(), nx_);
    *y0 = cell(lo.y() - kTouchM, lo_.y(), ny_);
    *y1 = cell(hi.y() + kTouchM, lo_.y(), ny_);
  }

  const std::vector<Box>& boxes_;
  double cell_m_;
  Eigen::Vector2d lo_ = Eigen::Vector2d::Zero();
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<size_t>> cells_;
  std::vector<unsigned> stamp_;
  unsigned visit_ = 0;
};

// Cuts a face into equal pieces no longer than max_m along either side.
std::vector<Rect> cutFace(const Rect& f, double max_m) {
  const int nu = std::max(1, static_cast<int>(std::ceil(f.lu / max_m - 1e-9)));
  const int nv = std::max(1, static_cast<int>(std::ceil(f.lv / max_m - 1e-9)));
  std::vector<Rect> pieces;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      Rect p = f;
      p.lu = f.lu / nu;
      p.lv = f.lv / nv;
      p.origin = f.origin + (i * p.lu) * f.u + (j * p.lv) * f.v;
      pieces.push_back(p);
    }
  }
  return pieces;
}

// The hidden parts of face f: where the space just in front of it lies outside the room or
// inside a box. False when the whole face is hidden.
bool hiddenParts(const Rect& f, const PrimitiveScene& scene, BoxIndex* index,
                 std::vector<size_t>* scratch, std::vector<Span2>* hidden) {
  hidden->clear();
  const int k = axisOf(f.normal), a = axisOf(f.u), b = axisOf(f.v);
  const double q = f.origin[k] + (f.normal[k] > 0.0 ? kTouchM : -kTouchM);
  const Box& room = scene.room;
  if (!(q > room.min_m[k] && q < room.max_m[k])) return false;
  const double inf = std::numeric_limits<double>::infinity();
  auto add = [&](double lo_a, double hi_a, double lo_b, double hi_b) {
    Span2 s{std::max(0.0, lo_a - f.origin[a]), std::min(f.lu, hi_a - f.origin[a]),
            std::max(0.0, lo_b - f.origin[b]), std::min(f.lv, hi_b - f.origin[b])};
    if (s.u1 - s.u0 > kSnapM && s.v1 - s.v0 > kSnapM) hidden->push_back(s);
  };
  add(-inf, room.min_m[a], -inf, inf);
  add(room.max_m[a], inf, -inf, inf);
  add(-inf, inf, -inf, room.min_m[b]);
  add(-inf, inf, room.max_m[b], inf);
  const Eigen::Vector3d far = f.origin + f.lu * f.u + f.lv * f.v;
  index->query(f.origin.head<2>().cwiseMin(far.head<2>()),
               f.origin.head<2>().cwiseMax(far.head<2>()), scratch);
  for (size_t i : *scratch) {
    const Box& box = scene.boxes[i];
    if (!(box.min_m[k] < q && q < box.max_m[k])) continue;
    add(box.min_m[a], box.max_m[a], box.min_m[b], box.max_m[b]);
  }
  for (const Span2& s : *hidden) {
    if (s.u0 <= kSnapM && s.u1 >= f.lu - kSnapM && s.v0 <= kSnapM && s.v1 >= f.lv - kSnapM) {
      return false;
    }
  }
  return true;
}

// Sorted coordinates with those closer than kSnapM merged.
std::vector<double> snapped(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  std::vector<double> out;
  for (double x : v) {
    if (out.empty() || x - out.back() > kSnapM) out.push_back(x);
  }
  return out;
}

size_t indexOf(const std::vector<double>& sorted, double x) {
  return static_cast<size_t>(std::lower_bound(sorted.begin(), sorted.end(), x - kSnapM) -
                             sorted.begin());
}

// The visible part of a lu x lv face as rectangles: the face cut along every edge of the hidden
// parts, then the visible cells merged greedily into rows and then rows into rectangles.
std::vector<Span2> visibleRects(double lu, double lv, const std::vector<Span2>& hidden) {
  if (hidden.empty()) return {{0.0, lu, 0.0, lv}};
  std::vector<double> us{0.0, lu}, vs{0.0, lv};
  for (const Span2& s : hidden) {
    us.push_back(s.u0);
    us.push_back(s.u1);
    vs.push_back(s.v0);
    vs.push_back(s.v1);
  }
  us = snapped(us);
  vs = snapped(vs);
  const size_t nu = us.size() - 1, nv = vs.size() - 1;
  std::vector<char> used(nu * nv, 0);
  for (const Span2& s : hidden) {
    const size_t i0 = indexOf(us, s.u0), i1 = indexOf(us, s.u1);
    const size_t j0 = indexOf(vs, s.v0), j1 = indexOf(vs, s.v1);
    for (size_t j = j0; j < j1; ++j) {
      for (size_t i = i0; i < i1; ++i) used[j * nu + i] = 1;
    }
  }
  std::vector<Span2> out;
  for (size_t j = 0; j < nv; ++j) {
    for (size_t i = 0; i < nu; ++i) {
      if (used[j * nu + i]) continue;
      size_t i2 = i;
      while (i2 < nu && !used[j * nu + i2]) ++i2;
      size_t j2 = j + 1;
      while (j2 < nv && std::none_of(used.begin() + j2 * nu + i, used.begin() + j2 * nu + i2,
                                     [](char c) { return c != 0; })) {
        ++j2;
      }
      for (size_t jj = j; jj < j2; ++jj) {
        std::fill(used.begin() + jj * nu + i, used.begin() + jj * nu + i2, 1);
      }
      out.push_back({us[i], us[i2], vs[j], vs[j2]});
    }
  }
  return out;
}

// Every face of the room and of the boxes, cut into pieces, with the hidden parts of each piece;
// pieces hidden wholly are left out.
template <typename Visit>
void forEachVisibleFacePiece(const PrimitiveScene& scene, double max_face_m, Visit visit) {
  BoxIndex index(scene.boxes, 2.0);
  std::vector<size_t> scratch;
  std::vector<Span2> hidden;
  auto face = [&](const Rect& f) {
    for (const Rect& piece : cutFace(f, max_face_m)) {
      if (hiddenParts(piece, scene, &index, &scratch, &hidden)) visit(piece, hidden);
    }
  };
  for (const Rect& f : boxFaces(scene.room, true)) face(f);
  for (const Box& b : scene.boxes) {
    for (const Rect& f : boxFaces(b, false)) face(f);
  }
}

// True when a box holds the space just beyond a cylinder's cap (top: above it) over the whole
// cap: a cylinder standing on a box, or hanging from one.
bool capOnBox(const Cylinder& c, bool top, const std::vector<Box>& boxes) {
  const double q = top ? c.z_max_m + kTouchM : c.z_min_m - kTouchM;
  for (const Box& b : boxes) {
    if (b.min_m.z() < q && q < b.max_m.z() && b.min_m.x() <= c.centre_m.x() - c.radius_m &&
        b.max_m.x() >= c.centre_m.x() + c.radius_m && b.min_m.y() <= c.centre_m.y() - c.radius_m &&
        b.max_m.y() >= c.centre_m.y() + c.radius_m) {
      return true;
    }
  }
  return false;
}

// One Gaussian with the moments of the visible part of tile [u0, u0 + cu] x [v0, v0 + cv] of
// face f (quadrature points inside a hidden span are left out), plus the variance of a
// quadrature cell in the plane and normal_sigma^2 along the normal.
void addVisibleTile(const Rect& f, double u0, double v0, double cu, double cv,
                    const std::vector<Span2>& hidden, double normal_sigma,
                    std::vector<GaussianComponent>* out) {
  const int n = kQuadrature;
  const double a = cu * cv / (n * n);
  double w = 0.0;
  int count = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum2 = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double su = u0 + (i + 0.5) / n * cu, sv = v0 + (j + 0.5) / n * cv;
      const bool is_hidden = std::any_of(hidden.begin(), hidden.end(), [&](const Span2& s) {
        return su > s.u0 && su < s.u1 && sv > s.v0 && sv < s.v1;
      });
      if (is_hidden) continue;
      const Eigen::Vector3d p = f.origin + su * f.u + sv * f.v;
      ++count;
      w += a;
      sum += a * p;
      sum2 += a * p * p.transpose();
    }
  }
  if (count < kMinVisibleTileFraction * n * n) return;
  GaussianComponent g;
  g.weight = w;
  g.mean_m = sum / w;
  Eigen::Matrix3d cov = sum2 / w - g.mean_m * g.mean_m.transpose();
  const double du = cu / n, dv = cv / n;
  cov += (du * du / 12.0) * f.u * f.u.transpose() + (dv * dv / 12.0) * f.v * f.v.transpose();
  cov += normal_sigma * normal_sigma * f.normal * f.normal.transpose();
  g.cov_m2 = 0.5 * (cov + cov.transpose());
  out->push_back(g);
}

// A cylinder as a `segments`-sided prism, its caps left out where they lie on the room's floor
// or ceiling, or where *_hidden says so.
void addCylinder(const Cylinder& c, const Box& room, int segments, Mesh* m, bool top_hidden = false,
                 bool bottom_hidden = false) {
  for (int j = 0; j < segments; ++j) {
    const double t0 = kTwoPi * j / segments, t1 = kTwoPi * (j + 1) / segments;
    const double tm = 0.5 * (t0 + t1);
    addQuad(cylPoint(c, c.radius_m, t0, c.z_min_m), cylPoint(c, c.radius_m, t1, c.z_min_m),
            cylPoint(c, c.radius_m, t1, c.z_max_m), cylPoint(c, c.radius_m, t0, c.z_max_m),
            Eigen::Vector3d(std::cos(tm), std::sin(tm), 0.0), m);
  }
  for (int cap = 0; cap < 2; ++cap) {
    const double z = cap == 0 ? c.z_max_m : c.z_min_m;
    if (onFloorOrCeiling(z, room) || (cap == 0 ? top_hidden : bottom_hidden)) continue;
    const uint32_t centre = static_cast<uint32_t>(m->vertices_m.size());
    m->vertices_m.push_back(Eigen::Vector3f(static_cast<float>(c.centre_m.x()),
                                            static_cast<float>(c.centre_m.y()),
                                            static_cast<float>(z)));
    for (int j = 0; j < segments; ++j) {
      m->vertices_m.push_back(cylPoint(c, c.radius_m, kTwoPi * j / segments, z).cast<float>());
    }
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = centre + 1 + j, b = centre + 1 + (j + 1) % segments;
      if (cap == 0)
        m->triangles.push_back({centre, a, b});  // normal up
      else
        m->triangles.push_back({centre, b, a});  // normal down
    }
  }
}

}  // namespace

PrimitiveScene makeDefaultPrimitiveScene() {
  const BoxScene boxes = makeDefaultScene();
  PrimitiveScene s;
  s.room = boxes.room;
  s.boxes = boxes.blocks;
  s.cylinders = {
      makeCylinder(1.0, 4.8, 0.20, 0.0, 3.0),     // column from floor to ceiling, north-west
      makeCylinder(2.7, 0.95, 0.35, 0.0, 1.0),    // drum beside the low cabinet
      makeCylinder(6.2, 1.5, 0.25, 0.0, 0.6),     // round stool near the east pillar
      makeCylinder(7.0, 3.65, 0.45, 0.70, 0.75),  // round side-table top ...
      makeCylinder(7.0, 3.65, 0.05, 0.0, 0.70),   // ... on one leg
      makeCylinder(3.8, 2.75, 0.30, 2.6, 3.0),    // ceiling lamp above the table
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
  for (const Cylinder& c : scene.cylinders) addCylinder(c, scene.room, segments, &m);
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

Mesh visibleMeshFromScene(const PrimitiveScene& scene, int segments, double max_face_m) {
  if (!(max_face_m > 0.0)) throw std::invalid_argument("visibleMeshFromScene: max_face_m <= 0");
  segments = std::max(3, segments);
  Mesh m;
  forEachVisibleFacePiece(scene, max_face_m, [&](const Rect& f, const std::vector<Span2>& hidden) {
    for (const Span2& r : visibleRects(f.lu, f.lv, hidden)) {
      const Eigen::Vector3d a = f.origin + r.u0 * f.u + r.v0 * f.v;
      const Eigen::Vector3d b = f.origin + r.u1 * f.u + r.v0 * f.v;
      const Eigen::Vector3d c = f.origin + r.u1 * f.u + r.v1 * f.v;
      const Eigen::Vector3d d = f.origin + r.u0 * f.u + r.v1 * f.v;
      addQuad(a, b, c, d, f.normal, &m);
    }
  });
  for (const Cylinder& c : scene.cylinders) {
    addCylinder(c, scene.room, segments, &m, capOnBox(c, true, scene.boxes),
                capOnBox(c, false, scene.boxes));
  }
  return m;
}

GmmMap tileVisibleScene(const PrimitiveScene& scene, double spacing_m, double normal_sigma_m,
                        double max_face_m) {
  if (!(spacing_m > 0.0) || !(normal_sigma_m > 0.0) || !(max_face_m > 0.0)) {
    throw std::invalid_argument(
        "tileVisibleScene: spacing, normal sigma and face size must be > 0");
  }
  std::vector<GaussianComponent> comps;
  std::vector<Span2> in_tile;
  forEachVisibleFacePiece(scene, max_face_m, [&](const Rect& f, const std::vector<Span2>& hidden) {
    const int nu = std::max(1, static_cast<int>(std::round(f.lu / spacing_m)));
    const int nv = std::max(1, static_cast<int>(std::round(f.lv / spacing_m)));
    const double cu = f.lu / nu, cv = f.lv / nv;
    for (int i = 0; i < nu; ++i) {
      for (int j = 0; j < nv; ++j) {
        const double u0 = i * cu, v0 = j * cv;
        in_tile.clear();
        for (const Span2& s : hidden) {
          if (s.u1 > u0 && s.u0 < u0 + cu && s.v1 > v0 && s.v0 < v0 + cv) in_tile.push_back(s);
        }
        addVisibleTile(f, u0, v0, cu, cv, in_tile, normal_sigma_m, &comps);
      }
    }
  });
  for (const Cylinder& c : scene.cylinders) {
    tileCylinder(c, scene.room, spacing_m, normal_sigma_m, &comps, capOnBox(c, true, scene.boxes),
                 capOnBox(c, false, scene.boxes));
  }
  if (comps.empty()) throw std::invalid_argument("tileVisibleScene: no visible surface");
  double total = 0.0;
  for (const auto& c : comps) total += c.weight;
  for (auto& c : comps) c.weight /= total;
  return GmmMap(std::move(comps), "synthetic primitive scene (visible surfaces)");
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
