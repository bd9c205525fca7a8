// Point clouds and triangle meshes as the map builder reads them (map frame, metres).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace gmm_mcl {

// Unordered points, float32 as in PCD/PLY files.
using PointCloud = std::vector<Eigen::Vector3f>;

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices_m;
  std::vector<std::array<uint32_t, 3>> triangles;  // vertex indices (polygons fan-triangulated)
};

}  // namespace gmm_mcl
