#include "gmm_mcl/map/component_grid.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace gmm_mcl {
namespace {

constexpr int kKeyBits = 21;
constexpr int kKeyHalf = 1 << (kKeyBits - 1);  // cell coordinates in [-kKeyHalf, kKeyHalf)
constexpr double kMinCellM = 0.5;

int clampCell(double c) {
  if (!(c > -kKeyHalf)) return -kKeyHalf;  // NaN to the low end
  if (c > kKeyHalf - 1) return kKeyHalf - 1;
  return static_cast<int>(c);
}

Eigen::Vector3i decode(uint64_t k) {
  const uint64_t mask = (uint64_t{1} << kKeyBits) - 1;
  return Eigen::Vector3i(static_cast<int>((k >> (2 * kKeyBits)) & mask) - kKeyHalf,
                         static_cast<int>((k >> kKeyBits) & mask) - kKeyHalf,
                         static_cast<int>(k & mask) - kKeyHalf);
}

}  // namespace

Eigen::Vector3i ComponentGrid::cellOf(const Eigen::Vector3d& p) const {
  return Eigen::Vector3i(clampCell(std::floor(p.x() / cell_m_)),
                         clampCell(std::floor(p.y() / cell_m_)),
                         clampCell(std::floor(p.z() / cell_m_)));
}

uint64_t ComponentGrid::key(const Eigen::Vector3i& c) {
  return (static_cast<uint64_t>(c.x() + kKeyHalf) << (2 * kKeyBits)) |
         (static_cast<uint64_t>(c.y() + kKeyHalf) << kKeyBits) |
         static_cast<uint64_t>(c.z() + kKeyHalf);
}

ComponentGrid::ComponentGrid(const std::vector<Box3>& boxes, double cell_m) : boxes_(boxes) {
  if (cell_m > 0.0) {
    cell_m_ = cell_m;
  } else {
    std::vector<double> edge;
    edge.reserve(boxes_.size());
    for (const Box3& b : boxes_) {
      if (!b.empty()) edge.push_back((b.hi - b.lo).maxCoeff());
    }
    double median = 0.0;
    if (!edge.empty()) {
      std::nth_element(edge.begin(), edge.begin() + edge.size() / 2, edge.end());
      median = edge[edge.size() / 2];
    }
    cell_m_ = std::max(kMinCellM, 2.0 * median);
  }
  std::vector<std::pair<uint64_t, int32_t>> pairs;
  pairs.reserve(2 * boxes_.size());
  for (size_t i = 0; i < boxes_.size(); ++i) {
    const Box3& b = boxes_[i];
    if (b.empty()) continue;
    const Eigen::Vector3i c0 = cellOf(b.lo), c1 = cellOf(b.hi);
    const Eigen::Vector3i n = c1 - c0 + Eigen::Vector3i::Ones();
    if (static_cast<long long>(n.x()) * n.y() * n.z() > kMaxCellsPerComponent) {
      large_.push_back(static_cast<int32_t>(i));
      continue;
    }
    for (int x = c0.x(); x <= c1.x(); ++x) {
      for (int y = c0.y(); y <= c1.y(); ++y) {
        for (int z = c0.z(); z <= c1.z(); ++z) {
          pairs.emplace_back(key(Eigen::Vector3i(x, y, z)), static_cast<int32_t>(i));
        }
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
  entries_.resize(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    entries_[k] = pairs[k].second;
    if (k == 0 || pairs[k].first != pairs[k - 1].first) {
      keys_.push_back(pairs[k].first);
      begin_.push_back(static_cast<uint32_t>(k));
    }
  }
  begin_.push_back(static_cast<uint32_t>(entries_.size()));
}

void ComponentGrid::query(const Box3& region, std::vector<int>* out) const {
  query(region, out, nullptr);
}

void ComponentGrid::query(const Box3& region, std::vector<int>* out, Scratch* scratch) const {
  out->clear();
  if (region.empty() || boxes_.empty()) return;
  if (scratch) {
    if (scratch->mark.size() != boxes_.size() || ++scratch->epoch == 0) {
      scratch->mark.assign(boxes_.size(), 0);
      scratch->epoch = 1;
    }
  }
  // Each component once: marked when taken (with scratch), else sorted and made unique below.
  auto add = [&](int32_t i) {
    if (scratch) {
      if (scratch->mark[i] == scratch->epoch) return;
      scratch->mark[i] = scratch->epoch;
      if (!boxes_[i].intersects(region)) return;
    }
    out->push_back(i);
  };
  const Eigen::Vector3i c0 = cellOf(region.lo), c1 = cellOf(region.hi);
  const Eigen::Vector3i n = c1 - c0 + Eigen::Vector3i::Ones();
  const double cells = static_cast<double>(n.x()) * n.y() * n.z();
  auto take = [&](size_t k) {
    for (uint32_t e = begin_[k]; e < begin_[k + 1]; ++e) add(entries_[e]);
  };
  if (cells > static_cast<double>(keys_.size())) {
    // A region larger than the occupied part of the map: walk the occupied cells.
    for (size_t k = 0; k < keys_.size(); ++k) {
      const Eigen::Vector3i c = decode(keys_[k]);
      if ((c.array() >= c0.array()).all() && (c.array() <= c1.array()).all()) take(k);
    }
  } else {
    for (int x = c0.x(); x <= c1.x(); ++x) {
      for (int y = c0.y(); y <= c1.y(); ++y) {
        // Cells (x, y, c0.z .. c1.z) are consecutive keys: one search per column.
        const uint64_t lo = key(Eigen::Vector3i(x, y, c0.z()));
        const uint64_t hi = key(Eigen::Vector3i(x, y, c1.z()));
        for (auto it = std::lower_bound(keys_.begin(), keys_.end(), lo);
             it != keys_.end() && *it <= hi; ++it) {
          take(static_cast<size_t>(it - keys_.begin()));
        }
      }
    }
  }
  for (int32_t i : large_) add(i);
  std::sort(out->begin(), out->end());
  if (scratch) return;
  out->erase(std::unique(out->begin(), out->end()), out->end());
  // Only the boxes that reach the region itself (a cell is larger than the region's edge).
  out->erase(std::remove_if(out->begin(), out->end(),
                            [&](int i) { return !boxes_[i].intersects(region); }),
             out->end());
}

void ComponentGrid::query(const std::vector<Box3>& regions, std::vector<int>* out,
                          Scratch* scratch) const {
  out->clear();
  std::vector<const Box3*> live;
  for (const Box3& r : regions) {
    if (!r.empty()) live.push_back(&r);
  }
  if (live.empty() || boxes_.empty()) return;
  Scratch own;
  if (!scratch) scratch = &own;
  if (live.size() == 1) {
    query(*live[0], out, scratch);
    return;
  }
  // The regions' cells; the columns (x, y) of their bounding rectangle, each with the regions
  // that cover it.
  const int num = static_cast<int>(live.size());
  std::vector<Eigen::Vector3i> lo(num), hi(num);
  Eigen::Vector3i all_lo = Eigen::Vector3i::Constant(kKeyHalf);
  Eigen::Vector3i all_hi = Eigen::Vector3i::Constant(-kKeyHalf);
  double covered = 0.0;  // columns summed over the regions
  for (int r = 0; r < num; ++r) {
    lo[r] = cellOf(live[r]->lo);
    hi[r] = cellOf(live[r]->hi);
    all_lo = all_lo.cwiseMin(lo[r]);
    all_hi = all_hi.cwiseMax(hi[r]);
    covered += (static_cast<double>(hi[r].x()) - lo[r].x() + 1) * (hi[r].y() - lo[r].y() + 1);
  }
  const double nx = static_cast<double>(all_hi.x()) - all_lo.x() + 1;
  const double ny = static_cast<double>(all_hi.y()) - all_lo.y() + 1;
  // Regions spread far apart, or so large that a list per column would not pay (a region of
  // all space): each on its own.
  if (nx * ny > 4.0 * covered + 4096.0 || covered > 4e6) {
    std::vector<int> one;
    for (const Box3* r : live) {
      query(*r, &one, nullptr);
      out->insert(out->end(), one.begin(), one.end());
    }
    std::sort(out->begin(), out->end());
    out->erase(std::unique(out->begin(), out->end()), out->end());
    return;
  }
  const int cols_x = static_cast<int>(nx), cols = static_cast<int>(nx * ny);
  // Regions per column, compressed rows.
  std::vector<int> begin(static_cast<size_t>(cols) + 1, 0);
  for (int r = 0; r < num; ++r) {
    for (int y = lo[r].y(); y <= hi[r].y(); ++y) {
      for (int x = lo[r].x(); x <= hi[r].x(); ++x) {
        ++begin[(y - all_lo.y()) * cols_x + (x - all_lo.x()) + 1];
      }
    }
  }
  for (int c = 0; c < cols; ++c) begin[c + 1] += begin[c];
  std::vector<int> at(begin.begin(), begin.end() - 1), covering(begin[cols]);
  for (int r = 0; r < num; ++r) {
    for (int y = lo[r].y(); y <= hi[r].y(); ++y) {
      for (int x = lo[r].x(); x <= hi[r].x(); ++x) {
        covering[at[(y - all_lo.y()) * cols_x + (x - all_lo.x())]++] = r;
      }
    }
  }
  if (scratch->mark.size() != boxes_.size() || ++scratch->epoch == 0) {
    scratch->mark.assign(boxes_.size(), 0);
    scratch->epoch = 1;
  }
  // A component is taken once (marked), when its box meets a region that covers a cell of it.
  auto take = [&](int32_t i, const int* rs, int count) {
    if (scratch->mark[i] == scratch->epoch) return;
    for (int k = 0; k < count; ++k) {
      if (boxes_[i].intersects(*live[rs[k]])) {
        scratch->mark[i] = scratch->epoch;
        out->push_back(i);
        return;
      }
    }
  };
  for (int c = 0; c < cols; ++c) {
    const int b = begin[c], count = begin[c + 1] - b;
    if (count == 0) continue;
    const int x = all_lo.x() + c % cols_x, y = all_lo.y() + c / cols_x;
    int z0 = kKeyHalf, z1 = -kKeyHalf;
    for (int k = b; k < b + count; ++k) {
      z0 = std::min(z0, lo[covering[k]].z());
      z1 = std::max(z1, hi[covering[k]].z());
    }
    const uint64_t key_lo = key(Eigen::Vector3i(x, y, z0));
    const uint64_t key_hi = key(Eigen::Vector3i(x, y, z1));
    for (auto it = std::lower_bound(keys_.begin(), keys_.end(), key_lo);
         it != keys_.end() && *it <= key_hi; ++it) {
      const size_t cell = static_cast<size_t>(it - keys_.begin());
      for (uint32_t e = begin_[cell]; e < begin_[cell + 1]; ++e) {
        take(entries_[e], covering.data() + b, count);
      }
    }
  }
  std::vector<int> all(num);
  for (int r = 0; r < num; ++r) all[r] = r;
  for (int32_t i : large_) take(i, all.data(), num);
  std::sort(out->begin(), out->end());
}

size_t ComponentGrid::memoryBytes() const {
  return boxes_.capacity() * sizeof(Box3) + keys_.capacity() * sizeof(uint64_t) +
         begin_.capacity() * sizeof(uint32_t) + entries_.capacity() * sizeof(int32_t) +
         large_.capacity() * sizeof(int32_t);
}

}  // namespace gmm_mcl
