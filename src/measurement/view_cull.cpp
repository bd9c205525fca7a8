// The per-update view cull: the components that some pose of the cloud may see.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "gmm_mcl/internal/fast_math.h"
#include "gmm_mcl/measurement/membership.h"

namespace gmm_mcl {
namespace {

// keep[j] = componentMayTouchGrid for the m components of the structure of arrays in (mean x, y,
// z, covariance trace: [4][stride]) seen from T, as one loop the compiler vectorises (the same
// arithmetic up to FMA contraction, which the bound's 1% + 1 px slack covers).
__attribute__((noinline)) void mayTouchGridAll(const float* __restrict in, int m, size_t stride,
                                               const RigidTransformF& T, const Intrinsics& K,
                                               const PatchGrid& grid, float min_depth_m,
                                               float sigma_bound, float inflate_px,
                                               const ViewReach& reach, int* __restrict keep) {
  const float* __restrict mx = in;
  const float* __restrict my = in + stride;
  const float* __restrict mz = in + 2 * stride;
  const float* __restrict tr = in + 3 * stride;
  float R[9], t[3];
  for (int k = 0; k < 9; ++k) R[k] = T.R[k];
  for (int k = 0; k < 3; ++k) t[k] = T.t[k];
  const float fx = K.fx_px, fy = K.fy_px, cx = K.cx_px, cy = K.cy_px;
  const float ips = 1.f / static_cast<float>(grid.patch_size_px);
  const float c0 = 0.5f * (static_cast<float>(grid.patch_size_px) - 1.f);
  const float col_hi = static_cast<float>(grid.cols) + 2.f;
  const float row_hi = static_cast<float>(grid.rows) + 2.f;
  const int last_col = grid.cols - 1, last_row = grid.rows - 1;
  const float near = min_depth_m - 1e-4f;
#pragma omp simd
  for (int j = 0; j < m; ++j) {
    const float x = R[0] * mx[j] + R[1] * my[j] + R[2] * mz[j] + t[0];
    const float y = R[3] * mx[j] + R[4] * my[j] + R[5] * mz[j] + t[1];
    const float z = R[6] * mx[j] + R[7] * my[j] + R[8] * mz[j] + t[2];
    const float iz = 1.f / z;
    const float iz2 = iz * iz;
    const float jf2 = fx * fx * iz2 * (1.f + x * x * iz2) + fy * fy * iz2 * (1.f + y * y * iz2);
    const float r = (sigma_bound * sqrtVec(jf2 * tr[j]) + inflate_px) * 1.01f + 1.f;
    const float u = cx + fx * x * iz;
    const float v = cy + fy * y * iz;
    // Clamped as in projectAll (NaN to the low end, which culls); the comparisons with the grid
    // give the unclamped values' answers.
    const int col0 = ceilInt(clampTo((u - r - c0) * ips, -4.f, col_hi));
    const int col1 = floorInt(clampTo((u + r - c0) * ips, -4.f, col_hi));
    const int row0 = ceilInt(clampTo((v - r - c0) * ips, -4.f, row_hi));
    const int row1 = floorInt(clampTo((v + r - c0) * ips, -4.f, row_hi));
    // In the view volume (projection.h's sphereInView, the same arithmetic).
    const float rho = sigma_bound * sqrtVec(tr[j]) + reach.margin_m;
    const bool in_view = (z - rho <= reach.far_m) &
                         (fx * x - reach.u0_px * z >= -rho * reach.n_u0) &
                         (reach.u1_px * z - fx * x >= -rho * reach.n_u1) &
                         (fy * y - reach.v0_px * z >= -rho * reach.n_v0) &
                         (reach.v1_px * z - fy * y >= -rho * reach.n_v1);
    keep[j] = (z >= near) & in_view & (col0 <= col1) & (col0 <= last_col) & (col1 >= 0) &
              (row0 <= row1) & (row0 <= last_row) & (row1 >= 0);
  }
}

}  // namespace

ViewReach viewReach(const DepthFrame& frame, const MeasurementParams& params) {
  return viewReach(frame.intrinsics, frame.grid.patch_size_px, frame.grid.cols, frame.grid.rows,
                   patchInflation(frame.grid.patch_size_px), frame.max_range_m, params.sigma_bound,
                   params.depth_noise);
}

namespace {

// The points whose box is a view's box: the camera centre and the far corners of the planes'
// pyramid (x = u z / fx, y = v z / fy), in the map frame. One function for viewBox and
// groupViewBox, so that both get the same floats (contraction into FMA may differ between call
// sites).
__attribute__((noinline)) void viewPoints(const RigidTransformF& T_map_cam, const Intrinsics& K,
                                          const ViewReach& reach, float (*p_map)[3]) {
  for (int a = 0; a < 3; ++a) p_map[0][a] = T_map_cam.t[a];
  int k = 1;
  for (float u : {reach.u0_px, reach.u1_px}) {
    for (float v : {reach.v0_px, reach.v1_px}) {
      const float p_cam[3] = {u * reach.far_m / K.fx_px, v * reach.far_m / K.fy_px, reach.far_m};
      transformPoint(T_map_cam, p_cam, p_map[k++]);
    }
  }
}

}  // namespace

Box3 viewBox(const RigidTransformF& T_map_cam, const Intrinsics& K, const ViewReach& reach) {
  if (!std::isfinite(reach.far_m)) {  // no depth bound: all of space
    const double inf = std::numeric_limits<double>::infinity();
    return Box3{Eigen::Vector3d::Constant(-inf), Eigen::Vector3d::Constant(inf)};
  }
  Box3 box;
  float p_map[5][3];
  viewPoints(T_map_cam, K, reach, p_map);
  for (const float(&p)[3] : p_map) box.extend(Eigen::Vector3d(p[0], p[1], p[2]));
  box.lo.array() -= reach.margin_m;
  box.hi.array() += reach.margin_m;
  return box;
}

void viewComponents(const GmmMap& map, const RigidTransformF& T_map_cam, const Intrinsics& K,
                    const ViewReach& reach, double grow_m, std::vector<int>* index,
                    std::vector<ComponentF>* out) {
  Box3 box = viewBox(T_map_cam, K, reach);
  box.lo.array() -= grow_m;
  box.hi.array() += grow_m;
  map.grid().query(box, index);
  out->resize(index->size());
  for (size_t k = 0; k < index->size(); ++k) (*out)[k] = map.packed()[(*index)[k]];
}

void groupPosesByPlace(const std::vector<RigidTransformF>& T_map_cam, double cell_m,
                       std::vector<int>* order, std::vector<int>* begin) {
  const int n = static_cast<int>(T_map_cam.size());
  // A cloud within one cell's extent (a tracking cloud) is one group wherever it lies.
  Box3 centres;
  for (const RigidTransformF& T : T_map_cam)
    centres.extend(Eigen::Vector3d(T.t[0], T.t[1], T.t[2]));
  if (n > 0 && ((centres.hi - centres.lo).array() <= cell_m).all()) {
    order->resize(n);
    for (int i = 0; i < n; ++i) (*order)[i] = i;
    begin->assign({0, n});
    return;
  }
  // Each pose's cell (x, y, z); the poses sorted by cell (x first), ascending within a cell.
  std::vector<std::array<long long, 3>> cell(n);
  std::array<long long, 3> lo = {0, 0, 0}, hi = {0, 0, 0};
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double c = std::floor(static_cast<double>(T_map_cam[i].t[a]) / cell_m);
      cell[i][a] =
          std::isfinite(c) ? static_cast<long long>(std::max(-1e15, std::min(1e15, c))) : 0;
      lo[a] = i == 0 ? cell[i][a] : std::min(lo[a], cell[i][a]);
      hi[a] = i == 0 ? cell[i][a] : std::max(hi[a], cell[i][a]);
    }
  }
  // One 64-bit word per pose where the cells' ranges and the index fit: the cell's coordinates
  // from the lowest, then the index. Measured on a 2-core x86-64 for 17,088 start candidates:
  // the sort of triples 3.1 ms, of words 1.3 ms, counted into their cells (below) 0.27 ms.
  int bits[3], index_bits = 1;
  while (index_bits < 63 && (1ll << index_bits) < n) ++index_bits;
  int total = index_bits;
  for (int a = 0; a < 3; ++a) {
    const unsigned long long span = static_cast<unsigned long long>(hi[a] - lo[a]);
    bits[a] = 0;
    while (bits[a] < 63 && (span >> bits[a]) != 0) ++bits[a];
    total += bits[a];
  }
  order->resize(n);
  begin->clear();
  // Few cells (a start's cube, a building's floor at the view's half depth): counted into place,
  // in linear time.
  const double range =
      (static_cast<double>(hi[0] - lo[0]) + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
  if (range <= std::max(65536.0, 2.0 * n)) {
    const long long ny = hi[1] - lo[1] + 1, nz = hi[2] - lo[2] + 1;
    std::vector<int> slot(n), count(static_cast<size_t>(range) + 1, 0);
    for (int i = 0; i < n; ++i) {
      slot[i] = static_cast<int>(((cell[i][0] - lo[0]) * ny + (cell[i][1] - lo[1])) * nz +
                                 (cell[i][2] - lo[2]));
      ++count[slot[i] + 1];
    }
    for (size_t c = 0; c + 1 < count.size(); ++c) {
      if (count[c + 1] > 0) begin->push_back(count[c]);
      count[c + 1] += count[c];
    }
    begin->push_back(n);
    for (int i = 0; i < n; ++i) (*order)[count[slot[i]]++] = i;
    return;
  }
  if (total <= 64) {
    std::vector<uint64_t> word(n);
    for (int i = 0; i < n; ++i) {
      uint64_t w = 0;
      for (int a = 0; a < 3; ++a) w = (w << bits[a]) | static_cast<uint64_t>(cell[i][a] - lo[a]);
      word[i] = (w << index_bits) | static_cast<uint64_t>(i);
    }
    std::sort(word.begin(), word.end());
    const uint64_t index_mask = (uint64_t{1} << index_bits) - 1;
    for (int k = 0; k < n; ++k) {
      (*order)[k] = static_cast<int>(word[k] & index_mask);
      if (k == 0 || (word[k] >> index_bits) != (word[k - 1] >> index_bits)) begin->push_back(k);
    }
    begin->push_back(n);
    return;
  }
  std::vector<std::pair<std::array<long long, 3>, int>> keyed(n);
  for (int i = 0; i < n; ++i) keyed[i] = {cell[i], i};
  std::sort(keyed.begin(), keyed.end());
  for (int k = 0; k < n; ++k) {
    (*order)[k] = keyed[k].second;
    if (k == 0 || keyed[k].first != keyed[k - 1].first) begin->push_back(k);
  }
  begin->push_back(n);
}

double viewGroupCell(const ViewReach& reach) {
  return std::isfinite(reach.far_m) ? std::max(1.0, 0.5 * static_cast<double>(reach.far_m)) : 1e300;
}

Box3 groupViewBox(const std::vector<RigidTransformF>& T_map_cam, const int* members, int count,
                  const Intrinsics& K, const ViewReach& reach) {
  Box3 region;
  if (count <= 0) return region;
  if (!std::isfinite(reach.far_m)) return viewBox(T_map_cam[members[0]], K, reach);
  // viewBox's points (the same floats) boxed at once; margin off the box as in viewBox (its
  // subtraction is monotonic, so the union of the grown boxes is the grown box of the union).
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = T_map_cam[members[0]].t[a];
  bool finite = true;
  for (int k = 0; k < count; ++k) {
    float p_map[5][3];
    viewPoints(T_map_cam[members[k]], K, reach, p_map);
    for (const float(&p)[3] : p_map) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
        finite = finite && std::isfinite(p[a]);
      }
    }
  }
  if (!finite) {  // viewBox's own comparisons for what is not a number
    for (int k = 0; k < count; ++k) region.extend(viewBox(T_map_cam[members[k]], K, reach));
    return region;
  }
  region.lo = Eigen::Vector3d(lo[0], lo[1], lo[2]);
  region.hi = Eigen::Vector3d(hi[0], hi[1], hi[2]);
  region.lo.array() -= reach.margin_m;
  region.hi.array() += reach.margin_m;
  return region;
}

void viewCandidates(const ComponentGrid& grid, const std::vector<RigidTransformF>& T_map_cam,
                    const std::vector<int>& order, const std::vector<int>& begin,
                    const Intrinsics& K, const ViewReach& reach, std::vector<int>* candidates) {
  // One query of all the groups' boxes: a cell that several boxes cover is looked up once.
  std::vector<Box3> boxes;
  boxes.reserve(begin.size());
  for (size_t g = 0; g + 1 < begin.size(); ++g) {
    boxes.push_back(
        groupViewBox(T_map_cam, order.data() + begin[g], begin[g + 1] - begin[g], K, reach));
  }
  static thread_local ComponentGrid::Scratch scratch;
  grid.query(boxes, candidates, &scratch);
}

void cullToView(const std::vector<ComponentF>& components, const RigidTransformF* T_cam_map,
                int num_poses, const Intrinsics& K, const PatchGrid& grid,
                const MeasurementParams& params, std::vector<int>* visible) {
  cullToView(
      components, nullptr, -1, T_cam_map, num_poses, K, grid, params,
      viewReach(K, grid.patch_size_px, grid.cols, grid.rows, patchInflation(grid.patch_size_px),
                std::numeric_limits<float>::infinity(), params.sigma_bound, params.depth_noise),
      visible);
}

void cullToView(const std::vector<ComponentF>& components, const int* candidates,
                int num_candidates, const RigidTransformF* T_cam_map, int num_poses,
                const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                const ViewReach& reach, std::vector<int>* visible) {
  const int m = candidates ? num_candidates : static_cast<int>(components.size());
  const size_t ms = static_cast<size_t>(std::max(m, 0));
  const float inflate = patchInflation(grid.patch_size_px);
  // The candidates not yet seen by any pose, structure of arrays, compacted after each pose, so
  // that the poses after the first test only what is still outside every view so far.
  static thread_local std::vector<float> soa;  // mean x, y, z, covariance trace: [4][m]
  static thread_local std::vector<int> index, keep;
  static thread_local std::vector<char> seen;
  soa.resize(4 * ms);
  index.resize(ms);
  keep.resize(ms);
  seen.assign(ms, 0);
  float* in = soa.data();
  for (int i = 0; i < m; ++i) {
    const ComponentF& c = components[candidates ? candidates[i] : i];
    for (int a = 0; a < 3; ++a) in[a * ms + i] = c.mean_m[a];
    const float* S = c.cov_m2;
    in[3 * ms + i] = S[0] + S[3] + S[5];
    index[i] = i;
  }
  int rest = m;
  for (int k = 0; k < num_poses && rest > 0; ++k) {
    mayTouchGridAll(in, rest, ms, T_cam_map[k], K, grid, params.min_component_depth_m,
                    params.sigma_bound, inflate, reach, keep.data());
    int w = 0;
    for (int j = 0; j < rest; ++j) {
      if (keep[j]) {
        seen[index[j]] = 1;
        continue;
      }
      for (int a = 0; a < 4; ++a) in[a * ms + w] = in[a * ms + j];
      index[w++] = index[j];
    }
    rest = w;
  }
  visible->clear();
  for (int i = 0; i < m; ++i) {
    if (seen[i]) visible->push_back(candidates ? candidates[i] : i);
  }
}

}  // namespace gmm_mcl
