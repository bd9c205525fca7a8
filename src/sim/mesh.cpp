#include "gmm_mcl/sim/mesh.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <utility>

namespace gmm_mcl {
namespace sim {

void Mesh::append(const Mesh& other) {
  const uint32_t offset = static_cast<uint32_t>(vertices_m.size());
  vertices_m.insert(vertices_m.end(), other.vertices_m.begin(), other.vertices_m.end());
  for (const auto& t : other.triangles) {
    triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
}

double Mesh::area_m2() const {
  double a = 0.0;
  for (const auto& t : triangles) {
    const Eigen::Vector3d p0 = vertices_m[t[0]].cast<double>();
    const Eigen::Vector3d p1 = vertices_m[t[1]].cast<double>();
    const Eigen::Vector3d p2 = vertices_m[t[2]].cast<double>();
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

void Mesh::bounds(Eigen::Vector3f* min_m, Eigen::Vector3f* max_m) const {
  if (vertices_m.empty()) {
    min_m->setZero();
    max_m->setZero();
    return;
  }
  *min_m = *max_m = vertices_m[0];
  for (const auto& v : vertices_m) {
    *min_m = min_m->cwiseMin(v);
    *max_m = max_m->cwiseMax(v);
  }
}

std::string Mesh::check() const {
  for (size_t i = 0; i < vertices_m.size(); ++i) {
    if (!vertices_m[i].allFinite()) return "vertex " + std::to_string(i) + " is not finite";
  }
  for (size_t i = 0; i < triangles.size(); ++i) {
    for (uint32_t k : triangles[i]) {
      if (k >= vertices_m.size()) {
        return "triangle " + std::to_string(i) + " has vertex index " + std::to_string(k) +
               " (mesh has " + std::to_string(vertices_m.size()) + " vertices)";
      }
    }
  }
  return "";
}

Mesh loadPlyMesh(const std::string& path) {
  PlyContents ply = readPlyFile(path);
  auto fail = [&](const std::string& what) { throw MeshError(path + ": " + what); };
  if (ply.first_bad_vertex >= 0) {
    fail("vertex " + std::to_string(ply.first_bad_vertex) + " has a non-finite or huge coordinate");
  }
  if (!ply.has_faces) fail("no face element (a point cloud, not a mesh)");
  if (ply.mesh.triangles.empty()) fail("no triangles");
  return std::move(ply.mesh);
}

void savePlyMesh(const Mesh& mesh, const std::string& path,
                 const std::vector<VertexColour>& colours, const std::string& comment) {
  const std::string why = mesh.check();
  if (!why.empty()) throw MeshError(path + ": refusing to write an invalid mesh: " + why);
  const bool coloured = !colours.empty();
  if (coloured && colours.size() != mesh.vertices_m.size()) {
    throw MeshError(path + ": " + std::to_string(colours.size()) + " colours for " +
                    std::to_string(mesh.vertices_m.size()) + " vertices");
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) throw MeshError(path + ": cannot open for writing: " + std::strerror(errno));
  out << "ply\nformat binary_little_endian 1.0\ncomment " << comment << "\n"
      << "element vertex " << mesh.vertices_m.size() << "\nproperty float x\nproperty float y\n"
      << "property float z\n"
      << (coloured ? "property uchar red\nproperty uchar green\nproperty uchar blue\n" : "")
      << "element face " << mesh.triangles.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  // Little-endian on every platform this package targets (x86-64, aarch64).
  for (size_t i = 0; i < mesh.vertices_m.size(); ++i) {
    out.write(reinterpret_cast<const char*>(mesh.vertices_m[i].data()), 12);
    if (coloured) out.write(reinterpret_cast<const char*>(colours[i].data()), 3);
  }
  for (const auto& t : mesh.triangles) {
    const unsigned char n = 3;
    out.write(reinterpret_cast<const char*>(&n), 1);
    const int32_t idx[3] = {static_cast<int32_t>(t[0]), static_cast<int32_t>(t[1]),
                            static_cast<int32_t>(t[2])};
    out.write(reinterpret_cast<const char*>(idx), 12);
  }
  if (!out) throw MeshError(path + ": write error");
}

}  // namespace sim
}  // namespace gmm_mcl
