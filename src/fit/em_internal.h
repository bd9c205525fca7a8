// The map builder's EM internals shared by its files: the points in structure-of-arrays
// layout, the fixed work ranges, the k-means initialisation (em_init.cpp) and the pruning grid
// (em_prune_grid.cpp).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/random.h"

namespace gmm_mcl {
namespace em_detail {

// scikit-learn adds 10 * machine epsilon to every component's responsibility sum.
constexpr double kNkFloor = 10.0 * std::numeric_limits<double>::epsilon();

// Points in structure-of-arrays double layout.
struct PointsSoA {
  std::vector<double> x, y, z;
  size_t size() const { return x.size(); }
};

PointsSoA toSoA(const PointCloud& cloud);

// Fixed ranges of work whose partial sums are added in order (determinism for any thread count).
inline std::vector<size_t> splitEven(size_t n, int parts) {
  const size_t p = std::max<size_t>(1, std::min<size_t>(static_cast<size_t>(parts), n));
  std::vector<size_t> bounds(p + 1);
  for (size_t i = 0; i <= p; ++i) bounds[i] = n * i / p;
  return bounds;
}

// The first components (weights, means, covariances plus reg) of params.init on the points:
// k-means++ seeding (on a seeded subsample above params.kmeans_max_points), Lloyd refinement for
// kKMeans, or the given means; then a hard assignment (scikit-learn _initialize).
std::vector<GaussianComponent> initialComponents(const PointsSoA& points, size_t m,
                                                 const EmParams& params, FitRandom* rng);

// Uniform grid over the points, points sorted by cell; per iteration each occupied cell gets the
// list of components whose prune box overlaps it.
struct PruneGrid {
  bool exact = true;
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  double cell_m = 1.0;
  std::vector<size_t> cell_begin;           // occupied cell c holds sorted points [b[c], b[c+1])
  std::vector<Eigen::Vector3i> cell_index;  // integer cell coordinates of occupied cell c
  std::vector<uint64_t> cell_key;           // (x << 42) | (y << 21) | z of cell c, ascending
  std::vector<size_t> cand_begin;           // candidates of cell c: cand[cand_begin[c]..]
  std::vector<int> cand;
  std::vector<size_t> chunk_cells;  // chunk i holds cells [chunk_cells[i], [i+1])

  size_t cellCount() const { return cell_index.size(); }
};

// Sorts points into grid cells (stable, deterministic) and returns the permuted SoA.
PointsSoA buildGrid(const PointCloud& cloud, double cell_m, int chunks, PruneGrid* grid);

// Each occupied cell's candidates (ascending): the components whose box of prune_sigma times
// their 1-sigma half extents overlaps it. Work follows the boxes, not cells x components: each
// component visits the occupied cells under its box (a full scan only for boxes larger than the
// occupied grid).
void updateCandidates(const std::vector<GaussianComponent>& comps,
                      const std::vector<Eigen::Vector3d>& half_extent_1sigma_m, double prune_sigma,
                      PruneGrid* grid);

// The grid's cell size: params.cell_size_m, else the upper median of the components' prune
// extents; kept within 2^21 cells per axis and (unless exact) bounded box-test work.
double pruneCellSize(const PointCloud& points,
                     const std::vector<Eigen::Vector3d>& half_extent_1sigma_m,
                     const EmParams& params, bool exact);

}  // namespace em_detail
}  // namespace gmm_mcl
