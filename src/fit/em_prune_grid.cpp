// The map builder's pruning grid: points sorted by cell, per-cell candidate components.
#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include "em_internal.h"
#include "gmm_mcl/common/timing.h"

namespace gmm_mcl {
namespace em_detail {
namespace {

// Pruning grid: at most this many (component, cell under its box) visits per iteration.
constexpr double kMaxCellTests = 4e8;
// Cell coordinates take 21 bits per axis.
constexpr double kMaxCellIndex = 2097151.0;

}  // namespace

// Sorts points into grid cells (stable, deterministic) and returns the permuted SoA.
PointsSoA buildGrid(const PointCloud& cloud, double cell_m, int chunks, PruneGrid* grid) {
  const size_t n = cloud.size();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& p : cloud) lo = lo.cwiseMin(p.cast<double>());
  grid->origin_m = lo;
  grid->cell_m = cell_m;
  std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d q = (cloud[i].cast<double>() - lo) / cell_m;
    const uint64_t cx = static_cast<uint64_t>(q.x()), cy = static_cast<uint64_t>(q.y()),
                   cz = static_cast<uint64_t>(q.z());
    keyed[i] = {(cx << 42) | (cy << 21) | cz, static_cast<uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  PointsSoA pts;
  pts.x.resize(n);
  pts.y.resize(n);
  pts.z.resize(n);
  grid->cell_begin.clear();
  grid->cell_index.clear();
  grid->cell_key.clear();
  for (size_t i = 0; i < n; ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first) {
      grid->cell_begin.push_back(i);
      const uint64_t k = keyed[i].first;
      grid->cell_key.push_back(k);
      grid->cell_index.emplace_back(static_cast<int>(k >> 42),
                                    static_cast<int>((k >> 21) & 0x1FFFFF),
                                    static_cast<int>(k & 0x1FFFFF));
    }
    const Eigen::Vector3f& p = cloud[keyed[i].second];
    pts.x[i] = p.x();
    pts.y[i] = p.y();
    pts.z[i] = p.z();
  }
  grid->cell_begin.push_back(n);
  // Chunks of whole cells with about n / chunks points each.
  grid->chunk_cells.assign(1, 0);
  const size_t target = std::max<size_t>(1, n / static_cast<size_t>(std::max(1, chunks)));
  size_t acc = 0;
  for (size_t c = 0; c < grid->cellCount(); ++c) {
    acc += grid->cell_begin[c + 1] - grid->cell_begin[c];
    if (acc >= target) {
      grid->chunk_cells.push_back(c + 1);
      acc = 0;
    }
  }
  if (grid->chunk_cells.back() != grid->cellCount()) grid->chunk_cells.push_back(grid->cellCount());
  return pts;
}

void updateCandidates(const std::vector<GaussianComponent>& comps,
                      const std::vector<Eigen::Vector3d>& half_extent_1sigma_m, double prune_sigma,
                      PruneGrid* grid) {
  const size_t m = comps.size();
  const size_t cells = grid->cellCount();
  std::vector<double> lo(3 * m), hi(3 * m);
  for (size_t k = 0; k < m; ++k) {
    for (int a = 0; a < 3; ++a) {
      const double e = prune_sigma * half_extent_1sigma_m[k][a];
      lo[3 * k + a] = (comps[k].mean_m[a] - e - grid->origin_m[a]) / grid->cell_m;
      hi[3 * k + a] = (comps[k].mean_m[a] + e - grid->origin_m[a]) / grid->cell_m;
    }
  }
  auto overlaps = [&](size_t c, size_t k) {
    const Eigen::Vector3i& ci = grid->cell_index[c];
    for (int a = 0; a < 3; ++a) {
      if (hi[3 * k + a] < ci[a] || lo[3 * k + a] > ci[a] + 1.0) return false;
    }
    return true;
  };
  // The occupied cells under component k's box, ascending, appended to *out.
  const std::vector<uint64_t>& keys = grid->cell_key;
  auto cellsOf = [&](size_t k, std::vector<uint32_t>* out) {
    int64_t c0[3], c1[3];
    double columns = 1.0;
    for (int a = 0; a < 3; ++a) {
      // Cells i with i <= hi and i + 1 >= lo, within the grid's 21 bits per axis.
      const double first = std::max(0.0, std::ceil(std::max(lo[3 * k + a], -2.0)) - 1.0);
      const double last = std::min(kMaxCellIndex, std::floor(std::min(hi[3 * k + a], 3e6)));
      if (!(first <= last)) return;
      c0[a] = static_cast<int64_t>(first);
      c1[a] = static_cast<int64_t>(last);
      if (a < 2) columns *= last - first + 1.0;
    }
    if (columns > static_cast<double>(cells) / 8.0) {  // a box wider than the grid: scan it
      for (size_t c = 0; c < cells; ++c) {
        if (overlaps(c, k)) out->push_back(static_cast<uint32_t>(c));
      }
      return;
    }
    for (int64_t x = c0[0]; x <= c1[0]; ++x) {
      for (int64_t y = c0[1]; y <= c1[1]; ++y) {
        const uint64_t column = (static_cast<uint64_t>(x) << 42) | (static_cast<uint64_t>(y) << 21);
        const uint64_t key_end = column | static_cast<uint64_t>(c1[2]);
        size_t c = static_cast<size_t>(
            std::lower_bound(keys.begin(), keys.end(), column | static_cast<uint64_t>(c0[2])) -
            keys.begin());
        for (; c < cells && keys[c] <= key_end; ++c) {
          if (overlaps(c, k)) out->push_back(static_cast<uint32_t>(c));
        }
      }
    }
  };
  // Per fixed range of components: each component's cell count, then its cells.
  const std::vector<size_t> bounds = splitEven(m, 64);
  const size_t parts = bounds.size() - 1;
  std::vector<std::vector<uint32_t>> part_cells(parts), part_counts(parts);
#pragma omp parallel for schedule(dynamic, 1)
  for (long p = 0; p < static_cast<long>(parts); ++p) {
    for (size_t k = bounds[p]; k < bounds[p + 1]; ++k) {
      const size_t before = part_cells[p].size();
      cellsOf(k, &part_cells[p]);
      part_counts[p].push_back(static_cast<uint32_t>(part_cells[p].size() - before));
    }
  }
  // Counting sort by cell in component order: each cell's candidates ascend.
  grid->cand_begin.assign(cells + 1, 0);
  for (const auto& list : part_cells) {
    for (uint32_t c : list) ++grid->cand_begin[c + 1];
  }
  for (size_t c = 0; c < cells; ++c) grid->cand_begin[c + 1] += grid->cand_begin[c];
  grid->cand.resize(grid->cand_begin[cells]);
  std::vector<size_t> next(grid->cand_begin.begin(), grid->cand_begin.end() - 1);
  for (size_t p = 0; p < parts; ++p) {
    size_t i = 0;
    for (size_t j = 0; j < part_counts[p].size(); ++j) {
      const int k = static_cast<int>(bounds[p] + j);
      for (uint32_t q = 0; q < part_counts[p][j]; ++q) grid->cand[next[part_cells[p][i++]]++] = k;
    }
  }
}

double pruneCellSize(const PointCloud& points,
                     const std::vector<Eigen::Vector3d>& half_extent_1sigma_m,
                     const EmParams& params, bool exact) {
  const size_t m = half_extent_1sigma_m.size();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  double cell_m = params.cell_size_m;
  if (cell_m <= 0.0) {
    std::vector<double> extent(m);
    for (size_t k = 0; k < m; ++k) {
      extent[k] = params.prune_sigma * half_extent_1sigma_m[k].maxCoeff();
    }
    cell_m = std::max(upperMedian(extent), 1e-3);
  }
  // Keep the grid within 2^21 cells per axis and bounded box-test work.
  const double span = std::max((hi - lo).maxCoeff(), 1e-9);
  cell_m = std::max(cell_m, span / 2.0e6);
  if (!exact) {
    // Each component visits at most the cells under its box, at most the occupied ones.
    while (true) {
      const Eigen::Vector3d dims = ((hi - lo) / cell_m).array().floor() + 1.0;
      const double max_cells = dims.prod();
      const double occupied = std::min(max_cells, static_cast<double>(points.size()));
      double visits = 0.0;
      for (size_t k = 0; k < m && visits <= kMaxCellTests; ++k) {
        const Eigen::Vector3d box =
            (2.0 * params.prune_sigma * half_extent_1sigma_m[k] / cell_m).array().floor() + 2.0;
        visits += std::min(box.cwiseMin(dims).prod(), occupied);
      }
      if (visits <= kMaxCellTests) break;
      cell_m *= 1.5;
    }
  }
  return cell_m;
}

}  // namespace em_detail
}  // namespace gmm_mcl
