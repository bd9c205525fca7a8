#include "gmm_mcl/measurement/membership.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace gmm_mcl {
namespace {

// componentMayTouchGrid for m components at once, over structure-of-arrays inputs (mean x, y,
// z and covariance trace), written as one branch-free loop that the compiler vectorises (8
// components per AVX2 instruction). The same arithmetic as componentMayTouchGrid; the result
// only has to be conservative (a kept component that touches no patch is dropped later).
__attribute__((noinline)) void cullComponents(const float* __restrict mx,
                                              const float* __restrict my,
                                              const float* __restrict mz,
                                              const float* __restrict trace, int m,
                                              const RigidTransformF& T, const Intrinsics& K,
                                              const PatchGrid& grid, float min_depth_m,
                                              float sigma_bound, float inflate_px,
                                              int* __restrict keep) {
  const float r0 = T.R[0], r1 = T.R[1], r2 = T.R[2], r3 = T.R[3], r4 = T.R[4], r5 = T.R[5];
  const float r6 = T.R[6], r7 = T.R[7], r8 = T.R[8], t0 = T.t[0], t1 = T.t[1], t2 = T.t[2];
  const float fx = K.fx_px, fy = K.fy_px, cx = K.cx_px, cy = K.cy_px;
  const float near = min_depth_m - 1e-4f;
  const float ips = 1.f / static_cast<float>(grid.patch_size_px);
  const float c0 = 0.5f * (static_cast<float>(grid.patch_size_px) - 1.f);
  const float last_col = static_cast<float>(grid.cols - 1);
  const float last_row = static_cast<float>(grid.rows - 1);
#pragma omp simd
  for (int i = 0; i < m; ++i) {
    const float x = r0 * mx[i] + r1 * my[i] + r2 * mz[i] + t0;
    const float y = r3 * mx[i] + r4 * my[i] + r5 * mz[i] + t1;
    const float z = r6 * mx[i] + r7 * my[i] + r8 * mz[i] + t2;
    const bool in_front = z >= near;
    const float zs = in_front ? z : 1.f;  // no division by zero or a negative depth
    const float iz = 1.f / zs;
    const float iz2 = iz * iz;
    const float jf2 = fx * fx * iz2 * (1.f + x * x * iz2) + fy * fy * iz2 * (1.f + y * y * iz2);
    const float r = (sigma_bound * std::sqrt(jf2 * trace[i]) + inflate_px) * 1.01f + 1.f;
    const float u = cx + fx * x * iz;
    const float v = cy + fy * y * iz;
    const float col0 = std::ceil((u - r - c0) * ips), col1 = std::floor((u + r - c0) * ips);
    const float row0 = std::ceil((v - r - c0) * ips), row1 = std::floor((v + r - c0) * ips);
    keep[i] = (in_front && col0 <= col1 && col0 <= last_col && col1 >= 0.f && row0 <= row1 &&
               row0 <= last_row && row1 >= 0.f)
                  ? 1
                  : 0;
  }
}

}  // namespace

std::string MeasurementParams::validate() const {
  std::ostringstream err;
  if (!(min_component_depth_m > 0.f) || !std::isfinite(min_component_depth_m)) {
    err << "min_component_depth_m must be positive (got " << min_component_depth_m << "); ";
  }
  if (!(sigma_bound > 0.f) || !std::isfinite(sigma_bound)) {
    err << "sigma_bound must be positive (got " << sigma_bound << "); ";
  }
  if (!std::isfinite(floor_log_density) || floor_log_density < -80.f) {
    err << "floor_log_density must be finite and >= -80 nats (got " << floor_log_density << "); ";
  }
  return err.str();
}

void computeMembership(const std::vector<ComponentF>& components, const RigidTransformF& T_cam_map,
                       const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                       std::vector<ProjectedComponent>* projected, std::vector<char>* valid,
                       PatchMembership* out) {
  const int m = static_cast<int>(components.size());
  const int num_patches = grid.count();
  const float inflate = patchInflation(grid.patch_size_px);
  const float ps = static_cast<float>(grid.patch_size_px);
  const float c0 = 0.5f * (ps - 1.f);  // centre of patch 0
  projected->resize(m);
  valid->resize(m);
  out->begin.assign(num_patches + 1, 0);
  // Pass 1: project, and count candidates per patch. Components that cannot touch any patch
  // (cullComponents, the vectorised componentMayTouchGrid, conservative: the same table as
  // without it) skip the projection.
  // (patch, component) pairs found in pass 1, in component order, so pass 2 need not test again.
  static thread_local std::vector<int> pairs;
  static thread_local std::vector<int> cursor;
  pairs.clear();
  static thread_local std::vector<float> soa;  // mean x, y, z, trace: [4][m]
  static thread_local std::vector<int> keep;
  soa.resize(4 * static_cast<size_t>(m));
  keep.resize(m);
  for (int i = 0; i < m; ++i) {
    const ComponentF& c = components[i];
    soa[i] = c.mean_m[0];
    soa[m + i] = c.mean_m[1];
    soa[2 * m + i] = c.mean_m[2];
    soa[3 * m + i] = c.cov_m2[0] + c.cov_m2[3] + c.cov_m2[5];
  }
  cullComponents(soa.data(), soa.data() + m, soa.data() + 2 * m, soa.data() + 3 * m, m,
                 T_cam_map, K, grid, params.min_component_depth_m, params.sigma_bound, inflate,
                 keep.data());
  for (int i = 0; i < m; ++i) {
    ProjectedComponent& p = (*projected)[i];
    if (!keep[i]) {
      (*valid)[i] = 0;
      continue;
    }
    (*valid)[i] = projectComponent(components[i], T_cam_map, K, params.min_component_depth_m,
                                   params.sigma_bound, inflate, &p);
    if (!(*valid)[i]) continue;
    const int col0 = std::max(0, static_cast<int>(std::ceil((p.u_px - p.half_w_px - c0) / ps)));
    const int col1 = std::min(grid.cols - 1,
                              static_cast<int>(std::floor((p.u_px + p.half_w_px - c0) / ps)));
    const int row0 = std::max(0, static_cast<int>(std::ceil((p.v_px - p.half_h_px - c0) / ps)));
    const int row1 = std::min(grid.rows - 1,
                              static_cast<int>(std::floor((p.v_px + p.half_h_px - c0) / ps)));
    bool any = false;
    // Patch centres are integers + 0.5 (or integers): exact in float, so stepping by the patch
    // size gives the same values as centreU(c) / centreV(r) without a conversion per test.
    float v = grid.centreV(row0);
    for (int r = row0; r <= row1; ++r, v += ps) {
      float u = grid.centreU(col0);
      for (int c = col0; c <= col1; ++c, u += ps) {
        if (ellipseContains(p, u, v)) {
          const int patch = r * grid.cols + c;
          ++out->begin[patch + 1];
          pairs.push_back(patch);
          pairs.push_back(i);
          any = true;
        }
      }
    }
    if (!any) (*valid)[i] = 0;
  }
  for (int p = 0; p < num_patches; ++p) out->begin[p + 1] += out->begin[p];
  out->comps.resize(out->begin[num_patches]);
  // Pass 2: scatter the pairs of pass 1 (components ascending within each patch).
  cursor.assign(out->begin.begin(), out->begin.end() - 1);
  for (size_t k = 0; k < pairs.size(); k += 2) out->comps[cursor[pairs[k]]++] = pairs[k + 1];
}

void computeMembershipBruteForce(const std::vector<ComponentF>& components,
                                 const RigidTransformF& T_cam_map, const Intrinsics& K,
                                 const PatchGrid& grid, const MeasurementParams& params,
                                 PatchMembership* out) {
  const float inflate = patchInflation(grid.patch_size_px);
  out->begin.assign(1, 0);
  out->comps.clear();
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      for (size_t i = 0; i < components.size(); ++i) {
        ProjectedComponent p;
        if (projectComponent(components[i], T_cam_map, K, params.min_component_depth_m,
                             params.sigma_bound, inflate, &p) &&
            ellipseContains(p, grid.centreU(c), grid.centreV(r))) {
          out->comps.push_back(static_cast<int>(i));
        }
      }
      out->begin.push_back(static_cast<int>(out->comps.size()));
    }
  }
}

}  // namespace gmm_mcl
