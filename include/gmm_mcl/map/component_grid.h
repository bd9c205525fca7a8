// Spatial index over a map's components: a sparse uniform grid of their 3-sigma boxes, so that
// the components a camera may see come from the cells its view volume covers, in time that
// follows what lies there and not the size of the map (docs/building_scale.md).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace gmm_mcl {

// An axis-aligned box (m), empty when lo > hi on some axis.
struct Box3 {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1.0);
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-1.0);

  bool empty() const { return (lo.array() > hi.array()).any(); }
  void extend(const Eigen::Vector3d& p) {
    if (empty()) {
      lo = hi = p;
    } else {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  void extend(const Box3& b) {
    if (b.empty()) return;
    extend(b.lo);
    extend(b.hi);
  }
  bool intersects(const Box3& b) const {
    return !empty() && !b.empty() && (lo.array() <= b.hi.array()).all() &&
           (b.lo.array() <= hi.array()).all();
  }
};

class ComponentGrid {
 public:
  // A component whose box covers more cells than this is kept in a list of its own that every
  // query tests (a 50 m ground plane must not fill thousands of cells).
  static constexpr int kMaxCellsPerComponent = 64;

  ComponentGrid() = default;
  // One box per component; cell_m <= 0 picks the cell edge from the boxes (about twice the
  // median box edge, at least 0.5 m).
  explicit ComponentGrid(const std::vector<Box3>& boxes, double cell_m = 0.0);

  // Reusable marks of one caller (a thread): a query that is given them skips the sort that
  // removes a component listed by several cells.
  struct Scratch {
    std::vector<uint32_t> mark;
    uint32_t epoch = 0;
  };
  // Sets *out to the components (ascending index) whose box intersects `region`.
  void query(const Box3& region, std::vector<int>* out) const;
  void query(const Box3& region, std::vector<int>* out, Scratch* scratch) const;
  // The union of the regions' queries (ascending, each component once): the view boxes of a
  // cloud's groups of poses. Each cell that some region covers is looked up once, not once per
  // region (a start's groups overlap: 27 boxes in a 4 m cube).
  void query(const std::vector<Box3>& regions, std::vector<int>* out, Scratch* scratch) const;

  size_t size() const { return boxes_.size(); }
  double cellSize() const { return cell_m_; }
  size_t cellCount() const { return keys_.size(); }
  size_t entryCount() const { return entries_.size(); }
  size_t largeCount() const { return large_.size(); }
  // Bytes held by the index.
  size_t memoryBytes() const;

 private:
  // Cell coordinates of a point, clamped to the key's range (a far point shares a cell with
  // others; queries stay correct since every candidate is tested against its box).
  Eigen::Vector3i cellOf(const Eigen::Vector3d& p) const;
  static uint64_t key(const Eigen::Vector3i& c);

  double cell_m_ = 1.0;
  std::vector<Box3> boxes_;
  std::vector<uint64_t> keys_;    // occupied cells, ascending
  std::vector<uint32_t> begin_;   // entries of cell k: entries_[begin_[k] .. begin_[k + 1])
  std::vector<int32_t> entries_;  // component indices, ascending within a cell
  std::vector<int32_t> large_;    // components over kMaxCellsPerComponent cells, ascending
};

}  // namespace gmm_mcl
