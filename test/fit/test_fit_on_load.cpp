// A point cloud or mesh given as the map (fit/fit_on_load.h): fitted on the first load and
// cached beside it; the cache read on the next; refitted when the file or the parameters
// change; bad clouds (NaNs, duplicates, one plane, 10 points, too large for the time limit)
// each a clear message or a map.
#include <dirent.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/fit_on_load.h"
#include "gmm_mcl/fit/point_cloud_io.h"
#include "gmm_mcl/fit/random.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/sim/mesh.h"
#include "test_utils/assertions.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

// The surface of a w x d x h box (floor at z = 0), `n` points uniform over its area, 2 mm noise.
PointCloud boxSurface(size_t n, double w, double d, double h, uint64_t seed) {
  const double faces[6] = {w * d, w * d, w * h, w * h, d * h, d * h};
  double total = 0;
  for (double a : faces) total += a;
  FitRandom rng(seed);
  PointCloud out;
  out.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    double pick = rng.uniform() * total;
    int f = 0;
    while (f < 5 && pick >= faces[f]) pick -= faces[f++];
    const double u = rng.uniform(), v = rng.uniform(), e = 0.002 * (rng.uniform() - 0.5);
    Eigen::Vector3d p;
    switch (f) {
      case 0:
        p = {u * w, v * d, e};
        break;
      case 1:
        p = {u * w, v * d, h + e};
        break;
      case 2:
        p = {u * w, e, v * h};
        break;
      case 3:
        p = {u * w, d + e, v * h};
        break;
      case 4:
        p = {e, u * d, v * h};
        break;
      default:
        p = {w + e, u * d, v * h};
        break;
    }
    out.push_back(p.cast<float>());
  }
  return out;
}

bool exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

// The input's cache files in the folder (`<name>.fit-<key>.gmm`).
std::vector<std::string> cachesOf(const test::TempDir& dir, const std::string& name) {
  std::vector<std::string> out;
  DIR* d = opendir(dir.path().c_str());
  if (!d) return out;
  const std::string prefix = name + ".fit-";
  while (const dirent* e = readdir(d)) {
    const std::string f = e->d_name;
    if (f.compare(0, prefix.size(), prefix) == 0 && f.size() > 4 &&
        f.compare(f.size() - 4, 4, ".gmm") == 0) {
      out.push_back(f);
    }
  }
  closedir(d);
  return out;
}

class FitOnLoadTest : public ::testing::Test {
 protected:
  FitOnLoadTest() {
    params_.components = 0;
    log_.info = [this](const std::string& s) { info_.push_back(s); };
    log_.warn = [this](const std::string& s) { warnings_.push_back(s); };
  }
  std::string writeCloud(const std::string& name, const PointCloud& points) {
    const std::string path = dir_ / name;
    writePcd(points, path);
    return path;
  }
  test::TempDir dir_{"fit_on_load"};
  FitOnLoadParams params_;
  FitOnLoadLog log_;  // keeps its lines in info_ and warnings_
  std::vector<std::string> info_, warnings_;
};

TEST_F(FitOnLoadTest, FirstLoadFitsAndCachesSecondReadsTheCache) {
  const std::string path = writeCloud("room.pcd", boxSurface(20000, 2.0, 1.5, 1.0, 1));
  const FitOnLoadResult first = loadOrFitMap(path, params_, log_);
  EXPECT_TRUE(first.fitted);
  EXPECT_FALSE(first.from_cache);
  EXPECT_TRUE(first.cache_written);
  EXPECT_TRUE(first.components_from_extent);
  // 2 x 1.5 x 1 m box: 13 m^2 of surface -> about 130 components (the voxel estimate is a
  // little above the true area).
  EXPECT_NEAR(first.surface_m2, 13.0, 3.0);
  EXPECT_EQ(first.components, static_cast<int>(first.map.size()));
  EXPECT_EQ(first.cache_path.substr(0, path.size() + 5), path + ".fit-");
  EXPECT_TRUE(exists(first.cache_path));
  ASSERT_GE(info_.size(), 2u) << "no progress in the log";
  EXPECT_NE(info_.front().find("20000 points"), std::string::npos) << info_.front();
  EXPECT_NE(info_.back().find("cached as"), std::string::npos) << info_.back();

  const FitOnLoadResult second = loadOrFitMap(path, params_, log_);
  EXPECT_FALSE(second.fitted);
  EXPECT_TRUE(second.from_cache);
  EXPECT_EQ(second.cache_path, first.cache_path);
  EXPECT_EQ(encodeMap(second.map), encodeMap(first.map)) << "the cache holds another map";
  std::printf("[ measured ] 20,000 points, M = %d: fit %.3f s, cache %.3f s\n", first.components,
              first.seconds, second.seconds);
  // The cache is a plain map file.
  EXPECT_EQ(encodeMap(loadMap(first.cache_path)), encodeMap(first.map));
}

TEST_F(FitOnLoadTest, ChangedContentRefitsAndReplacesTheCache) {
  PointCloud points = boxSurface(10000, 2.0, 1.5, 1.0, 2);
  const std::string path = writeCloud("room.pcd", points);
  const FitOnLoadResult first = loadOrFitMap(path, params_);
  ASSERT_TRUE(first.fitted);
  points[17].x() += 0.01f;  // one point moved by 1 cm
  writeCloud("room.pcd", points);
  const FitOnLoadResult second = loadOrFitMap(path, params_);
  EXPECT_TRUE(second.fitted) << "a changed file must be fitted again";
  EXPECT_NE(second.cache_path, first.cache_path);
  EXPECT_FALSE(exists(first.cache_path)) << "the stale cache was left";
  EXPECT_EQ(cachesOf(dir_, "room.pcd").size(), 1u);
  EXPECT_TRUE(loadOrFitMap(path, params_).from_cache);
}

TEST_F(FitOnLoadTest, ChangedParametersRefit) {
  const std::string path = writeCloud("room.pcd", boxSurface(10000, 2.0, 1.5, 1.0, 3));
  const FitOnLoadResult automatic = loadOrFitMap(path, params_);
  ASSERT_TRUE(automatic.fitted);
  FitOnLoadParams given = params_;
  given.components = 40;
  const FitOnLoadResult forty = loadOrFitMap(path, given);
  EXPECT_TRUE(forty.fitted);
  EXPECT_FALSE(forty.components_from_extent);
  EXPECT_EQ(forty.map.size(), 40u);
  EXPECT_NE(forty.cache_path, automatic.cache_path);
  EXPECT_TRUE(loadOrFitMap(path, given).from_cache);
  FitOnLoadParams seeded = given;
  seeded.seed = 7;
  EXPECT_TRUE(loadOrFitMap(path, seeded).fitted) << "the seed changes the map: a new key";
  // The time limit and the cache switch do not change the map: the same key.
  FitOnLoadParams slower = seeded;
  slower.time_limit_s = 1000;
  EXPECT_TRUE(loadOrFitMap(path, slower).from_cache);
  FitOnLoadParams no_cache = seeded;
  no_cache.cache = false;
  const FitOnLoadResult uncached = loadOrFitMap(path, no_cache);
  EXPECT_TRUE(uncached.fitted);
  EXPECT_FALSE(uncached.cache_written);
}

TEST_F(FitOnLoadTest, MapFileLoadedAsItIs) {
  const std::string cloud = writeCloud("room.pcd", boxSurface(5000, 2.0, 1.5, 1.0, 4));
  FitOnLoadParams p = params_;
  p.components = 20;
  const FitOnLoadResult fitted = loadOrFitMap(cloud, p);
  const std::string map_path = dir_ / "room.gmm";
  saveMap(fitted.map, map_path);
  const FitOnLoadResult r = loadOrFitMap(map_path, p);
  EXPECT_FALSE(r.fitted);
  EXPECT_FALSE(r.from_cache);
  EXPECT_TRUE(r.cache_path.empty());
  EXPECT_EQ(r.map.size(), 20u);
  EXPECT_THROW(loadOrFitMap(dir_ / "missing.gmm", p), MapError);
  EXPECT_TRUE(test::throwsWith<FitError>([&] { loadOrFitMap(dir_ / "missing.pcd", p); },
                                         {"missing.pcd: cannot open"}));
}

TEST_F(FitOnLoadTest, MeshSampledOnItsSurface) {
  // A closed 2 x 1.5 x 1 m box as 12 triangles: 13 m^2 -> 130 components.
  sim::Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices_m.emplace_back(i & 1 ? 2.f : 0.f, i & 2 ? 1.5f : 0.f, i & 4 ? 1.f : 0.f);
  }
  mesh.triangles = {{0, 1, 3}, {0, 3, 2}, {4, 7, 5}, {4, 6, 7}, {0, 5, 1}, {0, 4, 5},
                    {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
  const std::string path = dir_ / "box.ply";
  sim::savePlyMesh(mesh, path);
  const FitOnLoadResult r = loadOrFitMap(path, params_);
  EXPECT_TRUE(r.fitted);
  EXPECT_NEAR(r.surface_m2, 13.0, 1e-3);
  EXPECT_EQ(r.components, 130);
  EXPECT_EQ(r.points_fitted, kFitPointsPerComponent * 130);
  EXPECT_TRUE(loadOrFitMap(path, params_).from_cache);
}

TEST_F(FitOnLoadTest, NanPointsDroppedAndCounted) {
  PointCloud points = boxSurface(8000, 2.0, 1.5, 1.0, 5);
  for (size_t i = 0; i < points.size(); i += 16) points[i].y() = std::nanf("");
  const std::string path = writeCloud("nan.pcd", points);
  const FitOnLoadResult r = loadOrFitMap(path, params_, log_);
  EXPECT_TRUE(r.fitted);
  EXPECT_EQ(r.non_finite, 500u);
  EXPECT_EQ(r.points_fitted, 7500u);
  ASSERT_FALSE(info_.empty());
  EXPECT_NE(info_.front().find("500 NaN/Inf dropped"), std::string::npos) << info_.front();
}

TEST_F(FitOnLoadTest, DuplicatedPointsKept) {
  PointCloud points = boxSurface(5000, 2.0, 1.5, 1.0, 6);
  const PointCloud copy = points;
  points.insert(points.end(), copy.begin(), copy.end());  // every point twice
  const FitOnLoadResult r = loadOrFitMap(writeCloud("twice.pcd", points), params_);
  EXPECT_TRUE(r.fitted);
  EXPECT_EQ(r.duplicates, 5000u);
  EXPECT_NE(r.summary.find("fitted"), std::string::npos);
  // One position repeated: too few distinct points, named as such.
  const PointCloud same(1000, Eigen::Vector3f(1.f, 2.f, 3.f));
  EXPECT_TRUE(
      test::throwsWith<FitError>([&] { loadOrFitMap(writeCloud("same.pcd", same), params_); },
                                 {"1 distinct valid points", "999 duplicates"}));
}

TEST_F(FitOnLoadTest, SinglePlaneFitsAndSaysSo) {
  FitRandom rng(7);
  PointCloud plane;
  for (int i = 0; i < 8000; ++i) {
    plane.emplace_back(static_cast<float>(4 * rng.uniform()), static_cast<float>(3 * rng.uniform()),
                       0.f);
  }
  const FitOnLoadResult r = loadOrFitMap(writeCloud("floor.pcd", plane), params_);
  EXPECT_TRUE(r.fitted);
  EXPECT_NEAR(r.surface_m2, 12.0, 1.5);
  EXPECT_NE(r.summary.find("single plane"), std::string::npos) << r.summary;
  // The stored map is valid (loadMap validates it).
  EXPECT_EQ(loadMap(r.cache_path).size(), r.map.size());
}

TEST_F(FitOnLoadTest, TenPointsIsAClearError) {
  const std::string path = writeCloud("ten.pcd", boxSurface(10, 2.0, 1.5, 1.0, 8));
  EXPECT_TRUE(test::throwsWith<FitError>(
      [&] { loadOrFitMap(path, params_); },
      {path + ": 10 distinct valid points", "too few to fit a map, at least 100"}));
  EXPECT_TRUE(cachesOf(dir_, "ten.pcd").empty());
  // A given component count needs 10 points each.
  FitOnLoadParams p = params_;
  p.components = 50;
  EXPECT_TRUE(test::throwsWith<FitError>(
      [&] { loadOrFitMap(writeCloud("few.pcd", boxSurface(300, 2.0, 1.5, 1.0, 9)), p); },
      {"too few for 50 components"}));
}

TEST_F(FitOnLoadTest, TooLargeForTheTimeLimitNamesGmmMclFit) {
  const std::string path = writeCloud("big.pcd", boxSurface(5000, 2.0, 1.5, 1.0, 10));
  FitOnLoadParams p = params_;
  p.time_limit_s = 1e-4;
  EXPECT_TRUE(test::throwsWith<FitError>(
      [&] { loadOrFitMap(path, p); },
      {"more than map_fit_time_limit", "`gmm_mcl_fit " + path + " -o MAP.gmm -m "}));
  // The estimate grows with the points and the components; 300,000 points of a room-sized
  // cloud (M about 1000) are estimated within the 10 s of docs/map_builder.md.
  EXPECT_LT(estimateFitSeconds(100000, 1000, 2), estimateFitSeconds(300000, 1000, 2));
  EXPECT_LT(estimateFitSeconds(300000, 1000, 2), estimateFitSeconds(300000, 3000, 2));
  EXPECT_LT(estimateFitSeconds(300000, 1100, 2), 10.0);
  EXPECT_GT(estimateFitSeconds(10000000, 100000, 2), 60.0);
}

TEST_F(FitOnLoadTest, UnusableCacheWarnsAndGoesOn) {
  const std::string path = writeCloud("room.pcd", boxSurface(5000, 2.0, 1.5, 1.0, 11));
  const FitOnLoadResult first = loadOrFitMap(path, params_);
  ASSERT_TRUE(first.cache_written);
  // The cache's name taken by a folder: it can neither be read nor replaced.
  ASSERT_EQ(std::remove(first.cache_path.c_str()), 0);
  ASSERT_EQ(mkdir(first.cache_path.c_str(), 0755), 0);
  const FitOnLoadResult r = loadOrFitMap(path, params_, log_);
  EXPECT_TRUE(r.fitted);
  EXPECT_FALSE(r.cache_written);
  EXPECT_EQ(encodeMap(r.map), encodeMap(first.map)) << "the same input and seed, another map";
  ASSERT_EQ(warnings_.size(), 2u);
  EXPECT_NE(warnings_[0].find("cache not used"), std::string::npos) << warnings_[0];
  EXPECT_NE(warnings_[1].find("not cached"), std::string::npos) << warnings_[1];
}

TEST(FitOnLoad, CloudPathsByExtension) {
  EXPECT_TRUE(isCloudMapPath("/a/building.pcd"));
  EXPECT_TRUE(isCloudMapPath("b.PLY"));
  EXPECT_TRUE(isCloudMapPath("c.xyz"));
  EXPECT_TRUE(isCloudMapPath("d.txt"));
  EXPECT_FALSE(isCloudMapPath("map.gmm"));
  EXPECT_FALSE(isCloudMapPath("/dir.pcd/map"));
  EXPECT_FALSE(isCloudMapPath("noextension"));
  FitOnLoadParams p;
  EXPECT_EQ(p.components, 0) << "the default is from the extent";
  EXPECT_TRUE(p.cache);
  EXPECT_EQ(p.time_limit_s, kDefaultFitTimeLimitS);
  EXPECT_EQ(p.validate(), "");
  p.components = -1;
  p.time_limit_s = 0;
  EXPECT_NE(p.validate().find("components"), std::string::npos);
  EXPECT_NE(p.validate().find("time_limit_s"), std::string::npos);
}

}  // namespace
}  // namespace gmm_mcl
