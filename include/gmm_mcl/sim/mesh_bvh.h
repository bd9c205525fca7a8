// Ray casting against a triangle mesh: a bounding-volume hierarchy in float32, built with the
// binned surface-area heuristic, traversed nearest child first. No external ray tracer.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gmm_mcl/sim/mesh.h"

namespace gmm_mcl {
namespace sim {

struct RayHit {
  float t = 0.f;           // ray parameter of the hit (distance in units of |dir|)
  uint32_t triangle = 0;   // index into the mesh's triangles
  Eigen::Vector3f normal;  // unit geometric normal of the triangle (either side)
};

class MeshBvh {
 public:
  // Builds the hierarchy (copies the triangles; the mesh need not outlive it). Throws MeshError
  // when the mesh fails Mesh::check() or has no triangles. Degenerate triangles are kept (they
  // are never hit).
  explicit MeshBvh(const Mesh& mesh);

  // First hit of origin + t * dir with t in (t_min, t_max); dir need not be unit length.
  // Returns false when nothing is hit. Thread-safe (const).
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float t_min,
                 float t_max, RayHit* hit) const;
  // True when anything is hit with t in (t_min, t_max) (stops at the first hit found).
  bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float t_min,
                float t_max) const;

  size_t triangleCount() const { return tris_.size(); }
  size_t nodeCount() const { return nodes_.size(); }
  int depth() const { return depth_; }

 private:
  struct Node {
    float lo[3];
    float hi[3];
    uint32_t first;  // leaf: first triangle; inner: index of the right child (left is next)
    uint32_t count;  // leaf: triangle count (> 0); inner: 0
  };
  struct Tri {
    Eigen::Vector3f v0, e1, e2;  // vertex 0 and the two edges from it
    uint32_t id;                 // index in the source mesh
  };

  template <bool kAnyHit>
  bool traverse(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_min, float t_max,
                RayHit* hit) const;
  uint32_t build(std::vector<uint32_t>* order, const std::vector<Eigen::Vector3f>& centroids,
                 const std::vector<Eigen::Vector3f>& lo, const std::vector<Eigen::Vector3f>& hi,
                 uint32_t begin, uint32_t end, int level);

  std::vector<Node> nodes_;
  std::vector<Tri> tris_;  // in leaf order
  int depth_ = 0;
};

}  // namespace sim
}  // namespace gmm_mcl
