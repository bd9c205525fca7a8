// PLY mesh reader: ascii and both binary byte orders give the same mesh; each fault class is a
// MeshError naming the file and the fault; write-read round trip.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "gmm_mcl/sim/mesh.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace sim {
namespace {

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "gmm_mcl_test_mesh_" + name;
}

std::string write(const std::string& name, const std::string& content) {
  const std::string p = tempPath(name);
  std::ofstream(p, std::ios::binary) << content;
  return p;
}

// A unit square (one quad, two triangles after fan triangulation) plus a lone triangle.
const char* kAsciiHeader =
    "ply\nformat ascii 1.0\ncomment test\nelement vertex 5\nproperty float x\nproperty float y\n"
    "property float z\nproperty uchar red\nelement face 2\nproperty list uchar int vertex_indices\n"
    "end_header\n";
const char* kAsciiBody = "0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n0 0 2 5\n4 0 1 2 3\n3 0 1 4\n";

template <typename T>
void put(std::string* s, T v, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  s->append(b, sizeof(T));
}

std::string binaryPly(bool big, int vertices_written = 5) {
  std::string s = std::string("ply\nformat ") +
                  (big ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex 5\nproperty double x\nproperty float y\nproperty float z\n"
                  "property uchar red\nelement face 2\nproperty list uchar uint vertex_indices\n"
                  "element extra 1\nproperty list int short stuff\nend_header\n";
  const float v[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 2}};
  for (int i = 0; i < vertices_written; ++i) {
    put<double>(&s, v[i][0], big);
    put<float>(&s, v[i][1], big);
    put<float>(&s, v[i][2], big);
    put<uint8_t>(&s, 7, big);
  }
  if (vertices_written < 5) return s;
  put<uint8_t>(&s, 4, big);
  for (uint32_t k : {0u, 1u, 2u, 3u}) put<uint32_t>(&s, k, big);
  put<uint8_t>(&s, 3, big);
  for (uint32_t k : {0u, 1u, 4u}) put<uint32_t>(&s, k, big);
  put<int32_t>(&s, 2, big);
  put<int16_t>(&s, 1, big);
  put<int16_t>(&s, 2, big);
  return s;
}

void expectTestMesh(const Mesh& m) {
  ASSERT_EQ(m.vertices_m.size(), 5u);
  ASSERT_EQ(m.triangles.size(), 3u);
  EXPECT_EQ(m.vertices_m[2], Eigen::Vector3f(1, 1, 0));
  EXPECT_EQ(m.vertices_m[4], Eigen::Vector3f(0, 0, 2));
  EXPECT_EQ(m.triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangles[1], (std::array<uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangles[2], (std::array<uint32_t, 3>{0, 1, 4}));
  EXPECT_NEAR(m.area_m2(), 1.0 + 1.0, 1e-6);
}

TEST(PlyMeshTest, AsciiAndBothBinaryByteOrdersAgree) {
  expectTestMesh(loadPlyMesh(write("ascii.ply", std::string(kAsciiHeader) + kAsciiBody)));
  expectTestMesh(loadPlyMesh(write("le.ply", binaryPly(false))));
  expectTestMesh(loadPlyMesh(write("be.ply", binaryPly(true))));
  // CRLF line ends in the header.
  std::string crlf = kAsciiHeader;
  for (size_t p = crlf.find('\n'); p != std::string::npos; p = crlf.find('\n', p + 2)) {
    crlf.insert(p, "\r");
  }
  expectTestMesh(loadPlyMesh(write("crlf.ply", crlf + kAsciiBody)));
}

// Loads `content` and expects a MeshError whose message names the file and contains `fault`.
void expectFault(const std::string& name, const std::string& content, const std::string& fault) {
  const std::string p = write(name, content);
  try {
    loadPlyMesh(p);
    ADD_FAILURE() << name << ": no error, expected '" << fault << "'";
  } catch (const MeshError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(p), std::string::npos) << what;
    EXPECT_NE(what.find(fault), std::string::npos) << "expected '" << fault << "' in: " << what;
  }
}

TEST(PlyMeshTest, EachFaultIsAClearError) {
  const std::string h = kAsciiHeader, b = kAsciiBody;
  try {
    loadPlyMesh(tempPath("does_not_exist.ply"));
    ADD_FAILURE() << "missing file loaded";
  } catch (const MeshError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos);
  }
  expectFault("empty.ply", "", "not a PLY file");
  expectFault("magic.ply", "plx\n" + h.substr(4) + b, "not a PLY file");
  expectFault("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown format");
  expectFault("noformat.ply", "ply\nelement vertex 0\nend_header\n", "no format line");
  expectFault("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
              "no end_header");
  expectFault("proptype.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
              "unknown type");
  expectFault("propfirst.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
              "property before any element");
  expectFault("count.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
              "bad element count");
  expectFault("huge.ply", "ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n",
              "implausibly large");
  expectFault("noxyz.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n",
              "no x, y, z");
  expectFault("trunc_ascii.ply", h + "0 0 0 1\n1 0 0 2\n", "truncated ascii data");
  expectFault("trunc_le.ply", binaryPly(false, 3), "truncated");
  expectFault("trunc_faces.ply", binaryPly(false).substr(0, binaryPly(false).size() - 15),
              "truncated binary data");
  // The good file with one line of its body replaced.
  const auto edited = [&](const std::string& line, const std::string& by) {
    std::string body = b;
    body.replace(body.find(line), line.size(), by);
    return h + body;
  };
  expectFault("index.ply", edited("3 0 1 4\n", "3 0 1 5\n"), "face 1 has vertex index 5");
  expectFault("negindex.ply", edited("3 0 1 4\n", "3 0 -1 4\n"), "vertex index -1");
  expectFault("twovert.ply", edited("4 0 1 2 3\n", "2 0 1\n"), "face 0 has 2 vertices");
  expectFault("nan.ply", edited("1 0 0 2\n", "1 nan 0 2\n"), "vertex 1 has a non-finite");
  expectFault("word.ply", edited("1 0 0 2\n", "1 abc 0 2\n"), "bad number 'abc'");
  expectFault("floatindex.ply", edited("3 0 1 4\n", "3 0 1.5 4\n"), "non-integer");
  expectFault("points.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0 0 0\n",
              "no face element");
  expectFault("nofaces.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nelement face 0\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n",
              "no triangles");
  expectFault("facefirst.ply",
              "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
              "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
              "end_header\n3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n",
              "face element comes before the vertex element");
}

TEST(PlyMeshTest, RoundTripOfTheSceneMeshIsExact) {
  const Mesh m = meshFromScene(makeDefaultPrimitiveScene());
  const std::string p = tempPath("scene.ply");
  savePlyMesh(m, p);
  const Mesh r = loadPlyMesh(p);
  ASSERT_EQ(r.vertices_m.size(), m.vertices_m.size());
  ASSERT_EQ(r.triangles.size(), m.triangles.size());
  for (size_t i = 0; i < m.vertices_m.size(); ++i) EXPECT_EQ(r.vertices_m[i], m.vertices_m[i]);
  for (size_t i = 0; i < m.triangles.size(); ++i) EXPECT_EQ(r.triangles[i], m.triangles[i]);
}

// Per-vertex colours (the map inspector's ellipsoids) beside the coordinates: the reader skips
// them and reads the same mesh; colours not one per vertex are refused.
TEST(PlyMeshTest, ColouredMeshReadsBackTheSameMesh) {
  const Mesh m = meshFromScene(makeDefaultPrimitiveScene());
  std::vector<VertexColour> colours(m.vertices_m.size());
  for (size_t i = 0; i < colours.size(); ++i) {
    colours[i] = {static_cast<uint8_t>(i), static_cast<uint8_t>(3 * i), 7};
  }
  const std::string p = tempPath("coloured.ply");
  savePlyMesh(m, p, colours, "coloured test mesh");
  const Mesh r = loadPlyMesh(p);
  ASSERT_EQ(r.vertices_m.size(), m.vertices_m.size());
  ASSERT_EQ(r.triangles.size(), m.triangles.size());
  for (size_t i = 0; i < m.vertices_m.size(); ++i) EXPECT_EQ(r.vertices_m[i], m.vertices_m[i]);
  for (size_t i = 0; i < m.triangles.size(); ++i) EXPECT_EQ(r.triangles[i], m.triangles[i]);
  colours.pop_back();
  EXPECT_THROW(savePlyMesh(m, tempPath("short.ply"), colours), MeshError);
}

TEST(PlyMeshTest, InvalidMeshIsRefusedByWriterAndBvh) {
  Mesh m;
  m.vertices_m = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 0, 0)};
  m.triangles = {{0, 1, 2}};
  EXPECT_NE(m.check().find("vertex index 2"), std::string::npos);
  EXPECT_THROW(savePlyMesh(m, tempPath("bad.ply")), MeshError);
  EXPECT_THROW(MeshBvh bvh(m), MeshError);
  EXPECT_THROW(MeshBvh bvh{Mesh()}, MeshError);
}

}  // namespace
}  // namespace sim
}  // namespace gmm_mcl
