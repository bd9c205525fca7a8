#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/map_inspect.h"
#include "gmm_mcl/fit/point_cloud_io.h"

namespace gmm_mcl {
namespace {

GmmMap twoComponentMap() {
  GaussianComponent a, b;
  a.weight = 0.25;
  a.mean_m = Eigen::Vector3d(1, 2, 3);
  a.cov_m2 = Eigen::Vector3d(0.01, 0.04, 0.0001).asDiagonal();
  b.weight = 0.75;
  b.mean_m = Eigen::Vector3d(-1, 0, 0);
  b.cov_m2 = 0.09 * Eigen::Matrix3d::Identity();
  return GmmMap({a, b});
}

TEST(MapInspectTest, Summary) {
  const MapSummary s = summarizeMap(twoComponentMap());
  EXPECT_EQ(s.components, 2u);
  EXPECT_DOUBLE_EQ(s.weight.min, 0.25);
  EXPECT_DOUBLE_EQ(s.weight.max, 0.75);
  EXPECT_DOUBLE_EQ(s.weight.sum, 1.0);
  EXPECT_NEAR(s.sigma_min_m.min, 0.01, 1e-12);
  EXPECT_NEAR(s.sigma_max_m.max, 0.3, 1e-12);
  EXPECT_NEAR(s.condition.max, 400.0, 1e-6);
  // 3-sigma ellipsoid volume 4/3 pi 27 sqrt(det): 0.1*0.2*0.01 and 0.3^3.
  EXPECT_NEAR(s.volume_m3.min, 4.0 / 3.0 * M_PI * 27 * 0.0002, 1e-12);
  EXPECT_NEAR(s.volume_m3.max, 4.0 / 3.0 * M_PI * 27 * 0.027, 1e-9);
  EXPECT_NEAR(s.extent_min_m.x(), -1.9, 1e-12);
  EXPECT_NEAR(s.extent_max_m.z(), 3.03, 1e-12);
  std::ostringstream out;
  printMapSummary(s, out, 108);
  EXPECT_NE(out.str().find("108 bytes"), std::string::npos);
}

TEST(MapInspectTest, EllipsoidPlyReadsBackOnTheEllipsoids) {
  const std::string path = ::testing::TempDir() + "ell_" + std::to_string(::getpid()) + ".ply";
  EllipsoidExportParams p;
  writeEllipsoidsPly(twoComponentMap(), path, p);
  const CloudFile f = readPly(path);
  const size_t verts = static_cast<size_t>((p.rings - 1) * p.segments + 2);
  ASSERT_EQ(f.points.size(), 2 * verts);
  EXPECT_EQ(f.mesh.triangles.size(), 2u * 2 * p.segments * (p.rings - 1));
  // Every vertex of ellipsoid 1 lies at Mahalanobis distance 3 (float rounding).
  for (size_t i = verts; i < 2 * verts; ++i) {
    const double r = (f.points[i].cast<double>() - Eigen::Vector3d(-1, 0, 0)).norm() / 0.3;
    EXPECT_NEAR(r, 3.0, 1e-5);
  }
  std::remove(path.c_str());
}

TEST(MapInspectTest, EllipsoidCsv) {
  const std::string path = ::testing::TempDir() + "ell_" + std::to_string(::getpid()) + ".csv";
  writeEllipsoidsCsv(twoComponentMap(), path);
  std::ifstream in(path);
  std::string header, row0;
  std::getline(in, header);
  std::getline(in, row0);
  EXPECT_EQ(header.substr(0, 15), "index,weight,me");
  EXPECT_EQ(row0.substr(0, 7), "0,0.25,");
  // semi-axis 1 of component 0 at 3 sigma: 3 * 0.2 = 0.6
  EXPECT_NE(row0.find(",0.6"), std::string::npos) << row0;
  std::remove(path.c_str());
  EllipsoidExportParams bad;
  bad.sigma = 0.0;
  EXPECT_THROW(writeEllipsoidsCsv(twoComponentMap(), path, bad), FitError);
}

}  // namespace
}  // namespace gmm_mcl
