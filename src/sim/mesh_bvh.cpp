#include "gmm_mcl/sim/mesh_bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gmm_mcl {
namespace sim {
namespace {

constexpr int kBins = 16;
constexpr uint32_t kMaxLeafSize = 8;
constexpr int kMaxDepth = 60;           // traversal stack below holds 64
constexpr float kTraversalCost = 1.0f;  // relative to one triangle test
constexpr float kBaryEps = 1e-6f;       // closes cracks between triangles sharing an edge

float halfArea(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  const Eigen::Vector3f e = (hi - lo).cwiseMax(0.f);
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

}  // namespace

MeshBvh::MeshBvh(const Mesh& mesh) {
  const std::string why = mesh.check();
  if (!why.empty()) throw MeshError("MeshBvh: invalid mesh: " + why);
  if (mesh.triangles.empty()) throw MeshError("MeshBvh: mesh has no triangles");
  const size_t n = mesh.triangles.size();
  if (n >= std::numeric_limits<uint32_t>::max()) throw MeshError("MeshBvh: too many triangles");
  std::vector<Eigen::Vector3f> centroids(n), lo(n), hi(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& t = mesh.triangles[i];
    const Eigen::Vector3f& a = mesh.vertices_m[t[0]];
    const Eigen::Vector3f& b = mesh.vertices_m[t[1]];
    const Eigen::Vector3f& c = mesh.vertices_m[t[2]];
    lo[i] = a.cwiseMin(b).cwiseMin(c);
    hi[i] = a.cwiseMax(b).cwiseMax(c);
    centroids[i] = (a + b + c) / 3.f;
  }
  std::vector<uint32_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  nodes_.reserve(n);
  build(&order, centroids, lo, hi, 0, static_cast<uint32_t>(n), 0);
  tris_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& t = mesh.triangles[order[i]];
    const Eigen::Vector3f& a = mesh.vertices_m[t[0]];
    tris_[i].v0 = a;
    tris_[i].e1 = mesh.vertices_m[t[1]] - a;
    tris_[i].e2 = mesh.vertices_m[t[2]] - a;
    tris_[i].id = order[i];
  }
}

uint32_t MeshBvh::build(std::vector<uint32_t>* order, const std::vector<Eigen::Vector3f>& centroids,
                        const std::vector<Eigen::Vector3f>& lo,
                        const std::vector<Eigen::Vector3f>& hi, uint32_t begin, uint32_t end,
                        int level) {
  depth_ = std::max(depth_, level + 1);
  const uint32_t index = static_cast<uint32_t>(nodes_.size());
  nodes_.push_back(Node());
  Eigen::Vector3f blo = lo[(*order)[begin]], bhi = hi[(*order)[begin]];
  Eigen::Vector3f clo = centroids[(*order)[begin]], chi = clo;
  for (uint32_t i = begin; i < end; ++i) {
    const uint32_t k = (*order)[i];
    blo = blo.cwiseMin(lo[k]);
    bhi = bhi.cwiseMax(hi[k]);
    clo = clo.cwiseMin(centroids[k]);
    chi = chi.cwiseMax(centroids[k]);
  }
  const uint32_t count = end - begin;
  auto makeLeaf = [&]() {
    Node& node = nodes_[index];
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = blo[k];
      node.hi[k] = bhi[k];
    }
    node.first = begin;
    node.count = count;
    return index;
  };
  if (count <= 2 || level >= kMaxDepth) return makeLeaf();

  // Binned SAH over the centroid bounds, every axis.
  float best_cost = std::numeric_limits<float>::infinity();
  int best_axis = -1, best_split = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const float extent = chi[axis] - clo[axis];
    if (!(extent > 0.f)) continue;
    const float scale = kBins / extent;
    int bin_count[kBins] = {0};
    Eigen::Vector3f bin_lo[kBins], bin_hi[kBins];
    for (int b = 0; b < kBins; ++b) {
      bin_lo[b].setConstant(std::numeric_limits<float>::infinity());
      bin_hi[b].setConstant(-std::numeric_limits<float>::infinity());
    }
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t k = (*order)[i];
      const int b = std::min(kBins - 1, static_cast<int>((centroids[k][axis] - clo[axis]) * scale));
      ++bin_count[b];
      bin_lo[b] = bin_lo[b].cwiseMin(lo[k]);
      bin_hi[b] = bin_hi[b].cwiseMax(hi[k]);
    }
    // Sweep from the right, then from the left.
    float right_area[kBins];
    int right_count[kBins];
    Eigen::Vector3f rlo, rhi;
    rlo.setConstant(std::numeric_limits<float>::infinity());
    rhi.setConstant(-std::numeric_limits<float>::infinity());
    int rc = 0;
    for (int b = kBins - 1; b > 0; --b) {
      rlo = rlo.cwiseMin(bin_lo[b]);
      rhi = rhi.cwiseMax(bin_hi[b]);
      rc += bin_count[b];
      right_area[b] = rc > 0 ? halfArea(rlo, rhi) : 0.f;
      right_count[b] = rc;
    }
    Eigen::Vector3f llo, lhi;
    llo.setConstant(std::numeric_limits<float>::infinity());
    lhi.setConstant(-std::numeric_limits<float>::infinity());
    int lc = 0;
    for (int b = 0; b < kBins - 1; ++b) {
      llo = llo.cwiseMin(bin_lo[b]);
      lhi = lhi.cwiseMax(bin_hi[b]);
      lc += bin_count[b];
      if (lc == 0 || right_count[b + 1] == 0) continue;
      const float cost = halfArea(llo, lhi) * lc + right_area[b + 1] * right_count[b + 1];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_split = b + 1;
      }
    }
  }
  const float leaf_cost = halfArea(blo, bhi) * count;
  if (best_axis < 0 ||
      (count <= kMaxLeafSize && kTraversalCost * halfArea(blo, bhi) + best_cost >= leaf_cost)) {
    if (best_axis < 0 && count > kMaxLeafSize) {
      // All centroids coincide: split the list in half so that leaves stay small.
      best_axis = 0;
    } else {
      return makeLeaf();
    }
  }
  uint32_t mid;
  if (best_split > 0 && chi[best_axis] > clo[best_axis]) {
    const float scale = kBins / (chi[best_axis] - clo[best_axis]);
    const float c0 = clo[best_axis];
    const int axis = best_axis, split = best_split;
    auto it = std::partition(order->begin() + begin, order->begin() + end, [&](uint32_t k) {
      return std::min(kBins - 1, static_cast<int>((centroids[k][axis] - c0) * scale)) < split;
    });
    mid = static_cast<uint32_t>(it - order->begin());
  } else {
    mid = begin + count / 2;
  }
  if (mid == begin || mid == end) mid = begin + count / 2;

  build(order, centroids, lo, hi, begin, mid, level + 1);
  const uint32_t right = build(order, centroids, lo, hi, mid, end, level + 1);
  Node& node = nodes_[index];
  for (int k = 0; k < 3; ++k) {
    node.lo[k] = blo[k];
    node.hi[k] = bhi[k];
  }
  node.first = right;
  node.count = 0;
  return index;
}

namespace {

// Slab test of a ray (origin times inverse direction precomputed) against a node's box; the
// entry distance when the box is hit within (t_min, t_max), else +inf.
inline float enterBox(const float lo[3], const float hi[3], const float inv[3], const float oi[3],
                      float t_min, float t_max) {
  float t0 = t_min, t1 = t_max;
  for (int k = 0; k < 3; ++k) {
    float a = lo[k] * inv[k] - oi[k];
    float b = hi[k] * inv[k] - oi[k];
    if (a > b) std::swap(a, b);
    t0 = a > t0 ? a : t0;
    t1 = b < t1 ? b : t1;
  }
  return t0 <= t1 ? t0 : std::numeric_limits<float>::infinity();
}

}  // namespace

template <bool kAnyHit>
bool MeshBvh::traverse(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_min, float t_max,
                       RayHit* hit) const {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  float inv[3], oi[3];
  for (int k = 0; k < 3; ++k) {
    const float a = std::abs(d[k]) > 1e-30f ? d[k] : std::copysign(1e-30f, d[k]);
    inv[k] = 1.f / a;
    oi[k] = o[k] * inv[k];
  }
  bool found = false;
  uint32_t best_tri = 0;
  float best_t = t_max;
  if (enterBox(nodes_[0].lo, nodes_[0].hi, inv, oi, t_min, best_t) == kInf) return false;
  // Nodes on the stack were hit by the ray on the way down, at the entry distance stored.
  uint32_t stack[64];
  float stack_t[64];
  int sp = 0;
  uint32_t current = 0;
  for (;;) {
    const Node& node = nodes_[current];
    if (node.count > 0) {
      for (uint32_t i = node.first; i < node.first + node.count; ++i) {
        const Tri& tri = tris_[i];
        const Eigen::Vector3f p = d.cross(tri.e2);
        const float det = tri.e1.dot(p);
        if (det == 0.f) continue;
        const float inv_det = 1.f / det;
        const Eigen::Vector3f s = o - tri.v0;
        const float u = s.dot(p) * inv_det;
        if (u < -kBaryEps || u > 1.f + kBaryEps) continue;
        const Eigen::Vector3f q = s.cross(tri.e1);
        const float v = d.dot(q) * inv_det;
        if (v < -kBaryEps || u + v > 1.f + kBaryEps) continue;
        const float t = tri.e2.dot(q) * inv_det;
        if (t > t_min && t < best_t) {
          best_t = t;
          best_tri = i;
          found = true;
          if (kAnyHit) return true;
        }
      }
    } else {
      const uint32_t left = current + 1, right = node.first;
      const float tl = enterBox(nodes_[left].lo, nodes_[left].hi, inv, oi, t_min, best_t);
      const float tr = enterBox(nodes_[right].lo, nodes_[right].hi, inv, oi, t_min, best_t);
      if (tl != kInf && tr != kInf) {
        // Visit the nearer child now, the other later.
        const bool left_first = tl <= tr;
        stack[sp] = left_first ? right : left;
        stack_t[sp++] = left_first ? tr : tl;
        current = left_first ? left : right;
        continue;
      }
      if (tl != kInf) {
        current = left;
        continue;
      }
      if (tr != kInf) {
        current = right;
        continue;
      }
    }
    // Pop the next node that can still hold a nearer hit.
    bool next = false;
    while (sp > 0) {
      --sp;
      if (stack_t[sp] < best_t) {
        current = stack[sp];
        next = true;
        break;
      }
    }
    if (!next) break;
  }
  if (found && hit) {
    const Tri& tri = tris_[best_tri];
    hit->t = best_t;
    hit->triangle = tri.id;
    Eigen::Vector3f n = tri.e1.cross(tri.e2);
    const float len = n.norm();
    hit->normal = len > 0.f ? Eigen::Vector3f(n / len) : Eigen::Vector3f::UnitZ();
  }
  return found;
}

bool MeshBvh::intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float t_min,
                        float t_max, RayHit* hit) const {
  return traverse<false>(origin, dir, t_min, t_max, hit);
}

bool MeshBvh::occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float t_min,
                       float t_max) const {
  return traverse<true>(origin, dir, t_min, t_max, nullptr);
}

}  // namespace sim
}  // namespace gmm_mcl
