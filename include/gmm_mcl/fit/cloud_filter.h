// Point-cloud preparation before fitting: drop non-finite points, crop, voxel-downsample,
// sample triangle meshes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "gmm_mcl/fit/point_cloud.h"

namespace gmm_mcl {

struct CloudFilterParams {
  // Box crop (inclusive); disabled while use_box is false.
  bool use_box = false;
  Eigen::Vector3f box_min_m = Eigen::Vector3f::Constant(-1e30f);
  Eigen::Vector3f box_max_m = Eigen::Vector3f::Constant(1e30f);
  // Range crop: keep points with min_range_m <= |p - range_centre_m| <= max_range_m.
  float min_range_m = 0.f;
  float max_range_m = 0.f;  // 0 = no upper limit
  Eigen::Vector3f range_centre_m = Eigen::Vector3f::Zero();
  // Voxel grid edge (m); 0 = no downsampling. Each occupied voxel becomes its centroid.
  float voxel_m = 0.f;

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

struct CloudFilterStats {
  size_t input = 0;
  size_t non_finite = 0;  // dropped NaN/Inf points
  size_t cropped = 0;     // dropped by box or range crop
  size_t output = 0;
};

// Drops non-finite points, crops, then downsamples. Output order is deterministic (voxels in
// lexicographic key order). Throws FitError when the parameters are invalid.
PointCloud filterCloud(const PointCloud& input, const CloudFilterParams& params,
                       CloudFilterStats* stats = nullptr);

// Voxel-grid centroids (PCL VoxelGrid semantics), sorted by voxel key; voxel_m > 0.
PointCloud voxelDownsample(const PointCloud& input, float voxel_m);

// Incremental voxel grid: add points from many sources (e.g. depth frames) without keeping them.
class VoxelAccumulator {
 public:
  explicit VoxelAccumulator(float voxel_m);
  void add(const Eigen::Vector3f& p_m);
  size_t voxelCount() const;
  PointCloud centroids() const;  // sorted by voxel key
  ~VoxelAccumulator();
  VoxelAccumulator(const VoxelAccumulator&) = delete;
  VoxelAccumulator& operator=(const VoxelAccumulator&) = delete;

 private:
  struct Impl;
  float voxel_m_;
  Impl* impl_;
};

// Samples `count` points area-uniformly on the triangles (degenerate triangles never chosen),
// deterministic for `seed`. Throws FitError for an empty mesh, zero total area or a triangle
// index out of range.
PointCloud sampleMeshSurface(const TriangleMesh& mesh, size_t count, uint64_t seed);

// Splits points into a training and a held-out set: each point is held out with probability
// `fraction` (in [0, 1)), deterministic for `seed`; both keep the input order. Throws FitError
// for a fraction outside [0, 1).
void splitHoldout(const PointCloud& points, double fraction, uint64_t seed, PointCloud* train,
                  PointCloud* held_out);

// A synthetic large scene from a small one (measurements at building scale): nx x ny copies on
// a grid in x, y, copy (ix, iy) turned by (ix + iy) * 90 degrees about the vertical axis through
// the centre of the source's x, y bounds, then shifted by (ix, iy) * spacing_m (as tiledMap in
// map/gmm_map.h lays out copies of a fitted map).
constexpr double kTileGapM = 2.0;  // automatic spacing: larger x, y extent of the source + this
struct TileParams {
  int nx = 1, ny = 1;
  double spacing_m = 0.0;  // 0 = automatic

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

// The tiled copies of a cloud (copy after copy; non-finite points stay so) or of a mesh
// (vertices and triangles, sampled afterwards so that copies get independent samples). Throws
// FitError for invalid parameters, an empty input, or more than 2^32 points/vertices.
PointCloud tileCloud(const PointCloud& cloud, const TileParams& params);
TriangleMesh tileMesh(const TriangleMesh& mesh, const TileParams& params);

}  // namespace gmm_mcl
