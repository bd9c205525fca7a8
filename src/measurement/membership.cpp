#include "gmm_mcl/measurement/membership.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace gmm_mcl {

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
  // (componentMayTouchGrid, conservative: the same table as without it) skip the projection.
  // (patch, component) pairs found in pass 1, in component order, so pass 2 need not test again.
  static thread_local std::vector<int> pairs;
  static thread_local std::vector<int> cursor;
  pairs.clear();
  for (int i = 0; i < m; ++i) {
    ProjectedComponent& p = (*projected)[i];
    if (!componentMayTouchGrid(components[i], T_cam_map, K, grid.patch_size_px, grid.cols,
                               grid.rows, params.min_component_depth_m, params.sigma_bound,
                               inflate)) {
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
    for (int r = row0; r <= row1; ++r) {
      for (int c = col0; c <= col1; ++c) {
        if (ellipseContains(p, grid.centreU(c), grid.centreV(r))) {
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
