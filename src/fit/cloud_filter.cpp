#include "gmm_mcl/fit/cloud_filter.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/random.h"

namespace gmm_mcl {
namespace {

constexpr int64_t kVoxelKeyBias = int64_t{1} << 20;  // 21 bits per axis: +-2^20 voxels

uint64_t voxelKey(const Eigen::Vector3f& p, float voxel_m) {
  uint64_t key = 0;
  for (int a = 0; a < 3; ++a) {
    const double q = std::floor(static_cast<double>(p[a]) / voxel_m);
    if (!(std::abs(q) < static_cast<double>(kVoxelKeyBias))) {
      std::ostringstream msg;
      msg << "voxel grid: point coordinate " << p[a] << " m is beyond +-" << kVoxelKeyBias
          << " voxels of " << voxel_m << " m";
      throw FitError(msg.str());
    }
    key = (key << 21) | static_cast<uint64_t>(static_cast<int64_t>(q) + kVoxelKeyBias);
  }
  return key;
}

// The rigid motion of tile (ix, iy) for a source whose x, y bounds are [lo, hi].
struct TileLayout {
  Eigen::Vector2d centre_m;
  double spacing_m = 0.0;
  Eigen::Vector3f apply(const Eigen::Vector3f& p, int ix, int iy) const {
    const double dx = p.x() - centre_m.x(), dy = p.y() - centre_m.y();
    double rx = dx, ry = dy;
    switch ((ix + iy) % 4) {  // exact quarter turns
      case 1:
        rx = -dy, ry = dx;
        break;
      case 2:
        rx = -dx, ry = -dy;
        break;
      case 3:
        rx = dy, ry = -dx;
        break;
      default:
        break;
    }
    return Eigen::Vector3f(static_cast<float>(centre_m.x() + rx + ix * spacing_m),
                           static_cast<float>(centre_m.y() + ry + iy * spacing_m), p.z());
  }
};

TileLayout tileLayout(const std::vector<Eigen::Vector3f>& points, const TileParams& params,
                      const char* what) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError(std::string("tiling parameters: ") + fault);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const auto& p : points) {
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p.head<2>().cast<double>());
    hi = hi.cwiseMax(p.head<2>().cast<double>());
  }
  if (!(lo.x() <= hi.x())) throw FitError(std::string("tiling: the ") + what + " has no points");
  const double copies = static_cast<double>(params.nx) * params.ny;
  if (copies * static_cast<double>(points.size()) > 4294967295.0) {
    throw FitError(std::string("tiling: more than 2^32 points in the tiled ") + what);
  }
  TileLayout t;
  t.centre_m = 0.5 * (lo + hi);
  t.spacing_m = params.spacing_m > 0.0 ? params.spacing_m : (hi - lo).maxCoeff() + kTileGapM;
  return t;
}

struct VoxelSum {
  double x = 0, y = 0, z = 0;
  uint64_t n = 0;
};

}  // namespace

std::string CloudFilterParams::validate() const {
  std::ostringstream err;
  if (use_box && !(box_min_m.array() <= box_max_m.array()).all()) {
    err << "box_min_m must be <= box_max_m on every axis; ";
  }
  if (!(min_range_m >= 0.f)) err << "min_range_m must be >= 0; ";
  if (!(max_range_m >= 0.f)) err << "max_range_m must be >= 0 (0 = no limit); ";
  if (max_range_m > 0.f && max_range_m < min_range_m) err << "max_range_m < min_range_m; ";
  if (!range_centre_m.allFinite()) err << "range_centre_m must be finite; ";
  if (!(voxel_m >= 0.f) || !std::isfinite(voxel_m)) err << "voxel_m must be finite and >= 0; ";
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

PointCloud filterCloud(const PointCloud& input, const CloudFilterParams& params,
                       CloudFilterStats* stats) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("cloud filter parameters: " + fault);
  CloudFilterStats s;
  s.input = input.size();
  PointCloud kept;
  kept.reserve(input.size());
  const bool use_range = params.min_range_m > 0.f || params.max_range_m > 0.f;
  for (const auto& p : input) {
    if (!p.allFinite()) {
      ++s.non_finite;
      continue;
    }
    if (params.use_box && !((p.array() >= params.box_min_m.array()).all() &&
                            (p.array() <= params.box_max_m.array()).all())) {
      ++s.cropped;
      continue;
    }
    if (use_range) {
      const float r = (p - params.range_centre_m).norm();
      if (r < params.min_range_m || (params.max_range_m > 0.f && r > params.max_range_m)) {
        ++s.cropped;
        continue;
      }
    }
    kept.push_back(p);
  }
  if (params.voxel_m > 0.f) kept = voxelDownsample(kept, params.voxel_m);
  s.output = kept.size();
  if (stats) *stats = s;
  return kept;
}

struct VoxelAccumulator::Impl {
  std::unordered_map<uint64_t, VoxelSum> voxels;
};

VoxelAccumulator::VoxelAccumulator(float voxel_m) : voxel_m_(voxel_m), impl_(new Impl) {
  if (!(voxel_m > 0.f) || !std::isfinite(voxel_m)) {
    delete impl_;
    throw FitError("voxel grid: voxel size must be finite and > 0");
  }
}

VoxelAccumulator::~VoxelAccumulator() { delete impl_; }

void VoxelAccumulator::add(const Eigen::Vector3f& p_m) {
  VoxelSum& v = impl_->voxels[voxelKey(p_m, voxel_m_)];
  v.x += p_m.x();
  v.y += p_m.y();
  v.z += p_m.z();
  ++v.n;
}

size_t VoxelAccumulator::voxelCount() const { return impl_->voxels.size(); }

PointCloud VoxelAccumulator::centroids() const {
  std::vector<std::pair<uint64_t, const VoxelSum*>> sorted;
  sorted.reserve(impl_->voxels.size());
  for (const auto& kv : impl_->voxels) sorted.emplace_back(kv.first, &kv.second);
  std::sort(sorted.begin(), sorted.end(),
            [](const std::pair<uint64_t, const VoxelSum*>& a,
               const std::pair<uint64_t, const VoxelSum*>& b) { return a.first < b.first; });
  PointCloud out;
  out.reserve(sorted.size());
  for (const auto& kv : sorted) {
    const VoxelSum& v = *kv.second;
    const double n = static_cast<double>(v.n);
    out.emplace_back(static_cast<float>(v.x / n), static_cast<float>(v.y / n),
                     static_cast<float>(v.z / n));
  }
  return out;
}

PointCloud voxelDownsample(const PointCloud& input, float voxel_m) {
  VoxelAccumulator acc(voxel_m);
  for (const auto& p : input) {
    if (p.allFinite()) acc.add(p);
  }
  return acc.centroids();
}

PointCloud sampleMeshSurface(const TriangleMesh& mesh, size_t count, uint64_t seed) {
  if (mesh.triangles.empty()) throw FitError("mesh sampling: the mesh has no triangles");
  const size_t nv = mesh.vertices_m.size();
  std::vector<double> cumulative(mesh.triangles.size());
  double total = 0.0;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (uint32_t v : tri) {
      if (v >= nv) {
        throw FitError("mesh sampling: triangle " + std::to_string(t) + " has vertex index " +
                       std::to_string(v) + " out of range (" + std::to_string(nv) + " vertices)");
      }
    }
    const Eigen::Vector3d a = mesh.vertices_m[tri[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices_m[tri[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices_m[tri[2]].cast<double>();
    double area = 0.5 * (b - a).cross(c - a).norm();
    if (!std::isfinite(area)) area = 0.0;  // a non-finite vertex: never sampled
    total += area;
    cumulative[t] = total;
  }
  if (!(total > 0.0)) throw FitError("mesh sampling: the mesh has zero total area");
  FitRandom rng(seed);
  PointCloud out;
  out.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    const double u = rng.uniform() * total;
    size_t t = static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), u) -
                                   cumulative.begin());
    t = std::min(t, cumulative.size() - 1);
    // Degenerate triangles have empty intervals and are never chosen.
    const auto& tri = mesh.triangles[t];
    const double r1 = std::sqrt(rng.uniform()), r2 = rng.uniform();
    const Eigen::Vector3d a = mesh.vertices_m[tri[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices_m[tri[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices_m[tri[2]].cast<double>();
    const Eigen::Vector3d p = (1.0 - r1) * a + r1 * (1.0 - r2) * b + r1 * r2 * c;
    out.push_back(p.cast<float>());
  }
  return out;
}

void splitHoldout(const PointCloud& points, double fraction, uint64_t seed, PointCloud* train,
                  PointCloud* held_out) {
  if (!(fraction >= 0.0 && fraction < 1.0)) {
    throw FitError("hold-out fraction must be in [0, 1) (got " + std::to_string(fraction) + ")");
  }
  train->clear();
  held_out->clear();
  train->reserve(static_cast<size_t>((1.0 - fraction) * static_cast<double>(points.size())) + 16);
  FitRandom rng(seed ^ 0x486F6C644F757431ull);  // a stream of its own, not the fit's
  for (const auto& p : points) (rng.uniform() < fraction ? held_out : train)->push_back(p);
}

std::string TileParams::validate() const {
  std::ostringstream err;
  if (nx < 1 || ny < 1) err << "nx and ny must be >= 1 (got " << nx << ", " << ny << "); ";
  if (!(spacing_m >= 0.0) || !std::isfinite(spacing_m)) {
    err << "spacing_m must be finite and >= 0 (0 = automatic); ";
  }
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

PointCloud tileCloud(const PointCloud& cloud, const TileParams& params) {
  const TileLayout layout = tileLayout(cloud, params, "cloud");
  PointCloud out;
  out.reserve(cloud.size() * static_cast<size_t>(params.nx) * static_cast<size_t>(params.ny));
  for (int iy = 0; iy < params.ny; ++iy) {
    for (int ix = 0; ix < params.nx; ++ix) {
      for (const auto& p : cloud) out.push_back(layout.apply(p, ix, iy));
    }
  }
  return out;
}

TriangleMesh tileMesh(const TriangleMesh& mesh, const TileParams& params) {
  const TileLayout layout = tileLayout(mesh.vertices_m, params, "mesh");
  TriangleMesh out;
  for (int iy = 0; iy < params.ny; ++iy) {
    for (int ix = 0; ix < params.nx; ++ix) {
      TriangleMesh copy;
      copy.triangles = mesh.triangles;
      copy.vertices_m.reserve(mesh.vertices_m.size());
      for (const auto& v : mesh.vertices_m) {
        copy.vertices_m.push_back(v.allFinite() ? layout.apply(v, ix, iy) : v);
      }
      out.append(copy);
    }
  }
  return out;
}

}  // namespace gmm_mcl
