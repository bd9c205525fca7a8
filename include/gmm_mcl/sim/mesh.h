// The package's triangle mesh (the synthetic scenes, the depth renderer, the map builder's mesh
// input; map frame, metres) and its one PLY reader/writer (ascii, binary little- and big-endian).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace gmm_mcl {
namespace sim {

struct Mesh {
  std::vector<Eigen::Vector3f> vertices_m;
  std::vector<std::array<uint32_t, 3>> triangles;  // vertex indices (polygons fan-triangulated)

  // Appends another mesh (its indices offset by the current vertex count).
  void append(const Mesh& other);
  // Total area of the triangles (m^2).
  double area_m2() const;
  // Axis-aligned bounds of the vertices; both zero for an empty mesh.
  void bounds(Eigen::Vector3f* min_m, Eigen::Vector3f* max_m) const;
  // Empty string when every index is in range and every vertex finite, else the first fault.
  std::string check() const;
};

// A PLY file that cannot be read as a mesh: the message names the file and the fault.
class MeshError : public std::runtime_error {
 public:
  explicit MeshError(const std::string& what) : std::runtime_error(what) {}
};

// What a PLY file holds: its vertices in file order and, with a face element, its triangles.
struct PlyContents {
  Mesh mesh;
  bool has_faces = false;           // a face element (possibly with no faces)
  long long first_bad_vertex = -1;  // the first vertex with a non-finite or huge (> 1e9) coordinate
};

// The package's one PLY reader, for meshes and point clouds: a `vertex` element with x, y, z
// (any numeric type; other properties ignored), an optional `face` element with a
// `vertex_indices` (or `vertex_index`) list of 3 to 1000 in-range indices (fan-triangulated);
// other elements are skipped. Throws MeshError naming the file and the fault for a missing or
// unreadable file, a bad header, truncated data, a malformed number or a bad face.
PlyContents readPlyFile(const std::string& path);

// Reads a PLY mesh (readPlyFile) and also throws MeshError for a non-finite or huge
// coordinate, no face element, or no triangles at all.
Mesh loadPlyMesh(const std::string& path);

// Per-vertex colour (red, green, blue) of a PLY file.
using VertexColour = std::array<uint8_t, 3>;

// Writes a binary little-endian PLY (float x y z, with `colours` also uchar red green blue per
// vertex; uchar-count int vertex_indices) with `comment` in its header; throws MeshError on
// failure, for an invalid mesh, or for colours not one per vertex.
void savePlyMesh(const Mesh& mesh, const std::string& path,
                 const std::vector<VertexColour>& colours = {},
                 const std::string& comment = "gmm_mcl sim mesh");

}  // namespace sim
}  // namespace gmm_mcl
