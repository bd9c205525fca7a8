#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/point_cloud_io.h"
#include "test_utils/assertions.h"
#include "test_utils/synthetic_fixtures.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

// Each case's files in a temporary folder, removed with it.
class PointCloudIoTest : public ::testing::Test {
 protected:
  std::string tempPath(const std::string& name) const { return dir_ / name; }
  // Writes `bytes` to a file named `name` in the folder; returns its path.
  std::string writeTemp(const std::string& name, const std::string& bytes) const {
    const std::string path = tempPath(name);
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

 private:
  test::TempDir dir_{"fit_io"};
};

std::string floatBytes(std::initializer_list<float> v) {
  std::string s;
  for (float f : v) s.append(reinterpret_cast<const char*>(&f), 4);
  return s;
}

TEST_F(PointCloudIoTest, PcdBinaryRoundTrip) {
  const PointCloud pts = {{1.f, 2.f, 3.f}, {-4.5f, 0.25f, 1e-3f}};
  const std::string path = tempPath("rt.pcd");
  writePcd(pts, path);
  const PointCloud back = readCloudFile(path).points;
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0], pts[0]);
  EXPECT_EQ(back[1], pts[1]);
}

TEST_F(PointCloudIoTest, PcdAsciiWithExtraFieldsAndNan) {
  const PointCloud p = readPcd(
      writeTemp("a.pcd",
                "VERSION .7\nFIELDS intensity x y z\nSIZE 4 4 4 4\nTYPE U F F F\nCOUNT 1 1 1 1\n"
                "WIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n7 1 2 3\n8 nan 0 0\n9 -1 -2 -3.5\n"));
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_FALSE(p[1].allFinite());  // kept: the caller drops non-finite points
  EXPECT_EQ(p[2], Eigen::Vector3f(-1, -2, -3.5f));
}

TEST_F(PointCloudIoTest, PcdBinaryCompressedLzf) {
  // Two points, fields x y z stored field-major after LZF: x0 x1 y0 y1 z0 z1 (24 bytes).
  // Literal run of the first 12 bytes, then a 12-byte back-reference at distance 12 (the
  // y and z arrays repeat x: both points are (1,2)).
  const std::string raw = floatBytes({1.f, 2.f, 1.f, 2.f, 1.f, 2.f});
  std::string lzf;
  lzf += static_cast<char>(7);  // literal, 8 bytes
  lzf += raw.substr(0, 8);
  // back-reference: length 16 = 7 + 7 + 2 -> ctrl (7 << 5) | hi(offset-1), extra 7, lo(offset-1)
  lzf += static_cast<char>(7 << 5);
  lzf += static_cast<char>(7);
  lzf += static_cast<char>(7);  // offset 8
  std::string body;
  const uint32_t csize = static_cast<uint32_t>(lzf.size()), usize = 24;
  body.append(reinterpret_cast<const char*>(&csize), 4);
  body.append(reinterpret_cast<const char*>(&usize), 4);
  body += lzf;
  const PointCloud p =
      readPcd(writeTemp("c.pcd",
                        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
                        "HEIGHT 1\nPOINTS 2\nDATA binary_compressed\n" +
                            body));
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0], Eigen::Vector3f(1, 1, 1));
  EXPECT_EQ(p[1], Eigen::Vector3f(2, 2, 2));
}

TEST_F(PointCloudIoTest, PlyAsciiQuadIsTwoTriangles) {
  const CloudFile f = readCloudFile(
      writeTemp("q.ply",
                "ply\nformat ascii 1.0\ncomment unit square\nelement vertex 4\nproperty float x\n"
                "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
                "property list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 2\n1 1 0 3\n"
                "0 1 0 4\n4 0 1 2 3\n"));
  ASSERT_EQ(f.points.size(), 4u);
  ASSERT_TRUE(f.hasFaces());
  ASSERT_EQ(f.mesh.triangles.size(), 2u);
  const PointCloud s = sampleMeshSurface(f.mesh, 1000, 3);
  for (const auto& p : s) {
    EXPECT_GE(p.x(), 0.f);
    EXPECT_LE(p.x(), 1.f);
    EXPECT_GE(p.y(), 0.f);
    EXPECT_LE(p.y(), 1.f);
    EXPECT_EQ(p.z(), 0.f);
  }
}

TEST_F(PointCloudIoTest, PlyBinaryBigEndianVertices) {
  std::string body;
  for (float v : {1.5f, -2.f, 3.25f}) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    for (int k = 3; k >= 0; --k) body += static_cast<char>((bits >> (8 * k)) & 0xFF);
  }
  const CloudFile f = readCloudFile(
      writeTemp("be.ply",
                "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n" +
                    body));
  ASSERT_EQ(f.points.size(), 1u);
  EXPECT_EQ(f.points[0], Eigen::Vector3f(1.5f, -2.f, 3.25f));
  EXPECT_FALSE(f.hasFaces());
}

TEST_F(PointCloudIoTest, BadFilesAreClearErrors) {
  EXPECT_THROW(readCloudFile(tempPath("missing.pcd")), FitError);
  const std::string empty = writeTemp("empty.pcd", "");
  EXPECT_TRUE(test::throwsWith<FitError>([&] { readCloudFile(empty); }, {empty}));
  const std::string trunc = writeTemp(
      "trunc.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 10\nHEIGHT 1\nDATA binary\n" +
                       floatBytes({1, 2, 3}));
  EXPECT_THROW(readPcd(trunc), FitError);
  const std::string badface =
      writeTemp("badface.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  EXPECT_THROW(readPly(badface), FitError);
  EXPECT_THROW(readCloudFile(tempPath("cloud.las")), FitError);
}

TEST_F(PointCloudIoTest, ReplicaMeshWhenAvailable) {
  const std::string path = test::datasetsRoot() + "/replica_office0/office0_mesh.ply";
  if (!std::ifstream(path)) GTEST_SKIP() << "data set not found: " << path;
  const CloudFile f = readCloudFile(path);
  EXPECT_EQ(f.points.size(), 25149u);
  EXPECT_EQ(f.mesh.triangles.size(), 50000u);
}

TEST(CloudFilterTest, VoxelCentroidsAndCrops) {
  const PointCloud pts = {{0.01f, 0.01f, 0.01f},
                          {0.03f, 0.03f, 0.03f},
                          {0.5f, 0.5f, 0.5f},
                          {NAN, 0.f, 0.f},
                          {5.f, 5.f, 5.f}};
  CloudFilterParams p;
  p.use_box = true;
  p.box_min_m.setConstant(-1.f);
  p.box_max_m.setConstant(1.f);
  p.voxel_m = 0.1f;
  CloudFilterStats st;
  const PointCloud out = filterCloud(pts, p, &st);
  EXPECT_EQ(st.non_finite, 1u);
  EXPECT_EQ(st.cropped, 1u);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_NEAR(out[0].x(), 0.02f, 1e-6f);
  EXPECT_NEAR(out[1].x(), 0.5f, 1e-6f);
  CloudFilterParams r;
  r.min_range_m = 0.1f;
  r.max_range_m = 1.0f;
  EXPECT_EQ(filterCloud(pts, r).size(), 1u);
  CloudFilterParams bad;
  bad.voxel_m = -1.f;
  EXPECT_FALSE(bad.validate().empty());
  EXPECT_TRUE(CloudFilterParams().validate().empty());
}

TEST(MeshSamplingTest, AreaUniform) {
  TriangleMesh mesh;
  mesh.vertices_m = {
      {0, 0, 0},  {1, 0, 0},  {0, 1, 0},  {10, 0, 0}, {13, 0, 0},
      {10, 1, 0}, {20, 0, 0}, {20, 0, 0}, {20, 0, 0}};  // areas 0.5, 1.5 and degenerate 0
  mesh.triangles = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
  const PointCloud s = sampleMeshSurface(mesh, 40000, 11);
  size_t small = 0, degenerate = 0;
  for (const auto& p : s) {
    small += p.x() < 5.f ? 1 : 0;
    degenerate += p.x() >= 19.f ? 1 : 0;
  }
  EXPECT_EQ(degenerate, 0u);
  EXPECT_NEAR(static_cast<double>(small) / s.size(), 0.25, 0.01);
  EXPECT_EQ(sampleMeshSurface(mesh, 100, 11), sampleMeshSurface(mesh, 100, 11));
  TriangleMesh flat;
  flat.vertices_m = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  flat.triangles = {{0, 1, 2}};
  EXPECT_THROW(sampleMeshSurface(flat, 10, 1), FitError);
  EXPECT_THROW(sampleMeshSurface(TriangleMesh(), 10, 1), FitError);
}

TEST(HoldoutTest, SeededSplitKeepsEveryPointOnce) {
  PointCloud pts;
  for (int i = 0; i < 20000; ++i) pts.emplace_back(static_cast<float>(i), 0.f, 0.f);
  PointCloud train, held, train2, held2;
  splitHoldout(pts, 0.1, 7, &train, &held);
  EXPECT_EQ(train.size() + held.size(), pts.size());
  EXPECT_NEAR(static_cast<double>(held.size()) / pts.size(), 0.1, 0.01);
  for (size_t i = 1; i < held.size(); ++i) EXPECT_LT(held[i - 1].x(), held[i].x());  // in order
  splitHoldout(pts, 0.1, 7, &train2, &held2);
  EXPECT_EQ(held, held2);
  splitHoldout(pts, 0.1, 8, &train2, &held2);
  EXPECT_NE(held, held2);
  splitHoldout(pts, 0.0, 7, &train2, &held2);
  EXPECT_TRUE(held2.empty());
  EXPECT_THROW(splitHoldout(pts, 1.0, 7, &train2, &held2), FitError);
  EXPECT_THROW(splitHoldout(pts, -0.1, 7, &train2, &held2), FitError);
}

TEST(TileTest, CopiesTurnedAndShifted) {
  // An L of two points in a 2 x 1 m box centred at (1, 0.5).
  const PointCloud l = {{0.f, 0.f, 1.f}, {2.f, 1.f, 2.f}};
  TileParams t;
  t.nx = 2;
  t.ny = 2;
  const PointCloud out = tileCloud(l, t);
  ASSERT_EQ(out.size(), 8u);
  // Spacing: the larger extent (2 m) + kTileGapM.
  const float s = static_cast<float>(2.0 + kTileGapM);
  EXPECT_TRUE(out[0].isApprox(l[0]));                                  // (0, 0) as is
  EXPECT_TRUE(out[2].isApprox(Eigen::Vector3f(1.5f + s, -0.5f, 1.f)))  // (1, 0): a quarter turn
      << out[2].transpose();
  EXPECT_TRUE(out[6].isApprox(Eigen::Vector3f(2.f + s, 1.f + s, 1.f)))  // (1, 1): a half turn
      << out[6].transpose();
  EXPECT_EQ(out[7].z(), 2.f);
  t.spacing_m = 10.0;
  EXPECT_NEAR(tileCloud(l, t)[2].x(), 11.5f, 1e-5);
  t.nx = 0;
  EXPECT_NE(t.validate(), "");
  EXPECT_THROW(tileCloud(l, t), FitError);
  EXPECT_THROW(tileCloud(PointCloud(), TileParams()), FitError);

  TriangleMesh mesh;
  mesh.vertices_m = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}};
  TileParams three;
  three.nx = 3;
  const TriangleMesh tiled = tileMesh(mesh, three);
  EXPECT_EQ(tiled.triangles.size(), 3u);
  EXPECT_EQ(tiled.vertices_m.size(), 9u);
  EXPECT_NEAR(tiled.area_m2(), 3.0 * mesh.area_m2(), 1e-6);
  EXPECT_EQ(tiled.check(), "");
}

}  // namespace
}  // namespace gmm_mcl
