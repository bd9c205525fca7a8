// The per-update view cull: the components that some pose of the cloud may see.
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
                                               int* __restrict keep) {
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
    keep[j] = (z >= near) & (col0 <= col1) & (col0 <= last_col) & (col1 >= 0) & (row0 <= row1) &
              (row0 <= last_row) & (row1 >= 0);
  }
}

}  // namespace

void cullToView(const std::vector<ComponentF>& components, const RigidTransformF* T_cam_map,
                int num_poses, const Intrinsics& K, const PatchGrid& grid,
                const MeasurementParams& params, std::vector<int>* visible) {
  const int m = static_cast<int>(components.size());
  const size_t ms = static_cast<size_t>(m);
  const float inflate = patchInflation(grid.patch_size_px);
  // The components not yet seen by any pose, structure of arrays, compacted after each pose, so
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
    for (int a = 0; a < 3; ++a) in[a * ms + i] = components[i].mean_m[a];
    const float* S = components[i].cov_m2;
    in[3 * ms + i] = S[0] + S[3] + S[5];
    index[i] = i;
  }
  int rest = m;
  for (int k = 0; k < num_poses && rest > 0; ++k) {
    mayTouchGridAll(in, rest, ms, T_cam_map[k], K, grid, params.min_component_depth_m,
                    params.sigma_bound, inflate, keep.data());
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
    if (seen[i]) visible->push_back(i);
  }
}

}  // namespace gmm_mcl
