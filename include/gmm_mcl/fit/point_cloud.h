// Point clouds and triangle meshes as the map builder reads them (map frame, metres).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "gmm_mcl/sim/mesh.h"

namespace gmm_mcl {

// Unordered points, float32 as in PCD/PLY files.
using PointCloud = std::vector<Eigen::Vector3f>;

// The package's one triangle mesh type.
using TriangleMesh = sim::Mesh;

}  // namespace gmm_mcl
