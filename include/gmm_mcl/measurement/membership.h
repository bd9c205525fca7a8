// Patch membership (paper Sec. Fast Localization): component i is relevant to patch p when the
// patch centre lies in the 3-sigma ellipse of its projection inflated by half the patch diagonal.
#pragma once

#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/component_grid.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/measurement_params.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {

// Relevant components per patch, compressed rows: patch p's components (ascending index) are
// comps[begin[p] .. begin[p + 1]).
struct PatchMembership {
  std::vector<int> begin;
  std::vector<int> comps;
  int countFor(int patch) const { return begin[patch + 1] - begin[patch]; }
};

// Half the diagonal of a square patch, the inflation of every ellipse (px).
inline float patchInflation(int patch_size_px) { return 0.70710678f * patch_size_px; }

// The frame's depths in the membership (the CPU backend's likelihood members). A component whose
// term is below exp(floor - kDepthPruneNats) at every pixel of a patch is no member of it: with
// a the camera's optical axis, d = p - mu and Sigma' the component's covariance with the depth
// noise, d^T Sigma'^-1 d >= (a^T d)^2 / (a^T Sigma' a) (Cauchy-Schwarz), and a^T d is at least
// the gap dz between the component's depth and the patch's depth range [min_z, max_z]; so
// ln(lambda N) <= log_norm - dz^2 / (2 a^T Sigma' a), log_norm being at most the noise-free one.
// Each such term moves its pixel's log-likelihood by less than e^-26 (5e-12) nats: the sums equal
// those without the prune within float rounding (test_membership), with about a third fewer
// evaluations on the benchmark (docs/benchmark.md).
struct MemberDepthPrune {
  const float* patch_min_z = nullptr;  // per patch (+ 8 slack): the least camera depth of its
  const float* patch_max_z = nullptr;  // points and the greatest (min > max: no points)
  const float* log_norm = nullptr;     // per component: its noise-free log_norm
  float floor_log_density = 0.f;
  DepthNoiseModel noise;  // as in the likelihood (a_m = b_per_m = 0: none)
};
constexpr float kDepthPruneNats = 26.f;

// The prune of `params` (its floor and depth noise) over the given ranges and log_norms.
inline MemberDepthPrune memberDepthPrune(const std::vector<float>& patch_min_z,
                                         const std::vector<float>& patch_max_z,
                                         const float* log_norm, const MeasurementParams& params) {
  MemberDepthPrune prune;
  prune.patch_min_z = patch_min_z.data();
  prune.patch_max_z = patch_max_z.data();
  prune.log_norm = log_norm;
  prune.floor_log_density = params.floor_log_density;
  prune.noise = params.depth_noise;
  return prune;
}

// Each patch's depth range for MemberDepthPrune: min_z and max_z get grid.count() + 8 entries, a
// patch without points min_z = 3e18 > max_z = -3e18.
void patchDepthRanges(const DepthFrame& frame, std::vector<float>* min_z,
                      std::vector<float>* max_z);

// The components as a structure of arrays [10][stride] (computeMembership and
// noisyEvalComponents read it; a backend builds it once per update and component list): mean x,
// y, z, covariance xx xy xz yy yz zz, log_weight; stride = componentSoAStride(m), m rounded up
// to a multiple of kComponentSoALanes (padding lanes hold a placeholder component), so that the
// vectorised loops over it have no remainder and a component's results do not depend on its
// position in the list.
constexpr int kComponentSoARows = 10;
constexpr int kComponentSoALanes = 16;
int componentSoAStride(int m);
void componentSoA(const std::vector<ComponentF>& components, std::vector<float>* soa);

// Projects every component for one camera pose and fills the membership table.
// `projected` (may be null: not kept) and `valid` are scratch (resized here); T_cam_map maps map
// points into the camera. With `reach`, a component outside the pose's view volume (projection.h's
// componentInView) is no member, as in the CUDA membership kernel: the likelihood's members (the
// backends); without it, every component whose ellipse reaches a patch centre (the brute-force
// reference's table). With `prune`, a pair that MemberDepthPrune rules out is no member either.
// `component_soa`: componentSoA(components) when the caller keeps it (else built here).
void computeMembership(const std::vector<ComponentF>& components, const RigidTransformF& T_cam_map,
                       const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                       std::vector<ProjectedComponent>* projected, std::vector<char>* valid,
                       PatchMembership* out, const ViewReach* reach = nullptr,
                       const MemberDepthPrune* prune = nullptr,
                       const float* component_soa = nullptr);

// The per-update view cull: the components (ascending map indices) that componentMayTouchGrid
// keeps for at least one of the num_poses camera poses T_cam_map and whose sphere meets that
// pose's view volume (projection.h's componentInView, without a depth bound). Every other
// component lies outside the patch grid's reach for every pose, or further than sigma_bound
// standard deviations from every pixel ray, so the likelihood over this list equals that over
// the whole map within float rounding.
void cullToView(const std::vector<ComponentF>& components, const RigidTransformF* T_cam_map,
                int num_poses, const Intrinsics& K, const PatchGrid& grid,
                const MeasurementParams& params, std::vector<int>* visible);
// The same over `candidates` (ascending map indices, num_candidates of them: the map grid's
// components near the poses' views; null: every component) with the view volume `reach` (its
// depth bound too): the cull that follows the view in a map of a building.
void cullToView(const std::vector<ComponentF>& components, const int* candidates,
                int num_candidates, const RigidTransformF* T_cam_map, int num_poses,
                const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                const ViewReach& reach, std::vector<int>* visible);

// The view volume of a frame's camera (its range window's far end; projection.h).
ViewReach viewReach(const DepthFrame& frame, const MeasurementParams& params);
// The map-frame box around a camera's view volume at T_map_cam: its centre and the far corners,
// grown by the reach's margin (all of space without a depth bound).
Box3 viewBox(const RigidTransformF& T_map_cam, const Intrinsics& K, const ViewReach& reach);
// The poses grouped by the cell (edge cell_m) of their camera centre: group g is
// order[begin[g] .. begin[g + 1]), ascending pose indices within it.
void groupPosesByPlace(const std::vector<RigidTransformF>& T_map_cam, double cell_m,
                       std::vector<int>* order, std::vector<int>* begin);
// The cell edge by which the view culls group poses: half the view's depth, at least 1 m.
double viewGroupCell(const ViewReach& reach);
// The box around the views of poses T_map_cam[members[0 .. count)] (viewBox's union).
Box3 groupViewBox(const std::vector<RigidTransformF>& T_map_cam, const int* members, int count,
                  const Intrinsics& K, const ViewReach& reach);
// The components (ascending map indices) that `grid` places near the views of the poses: the
// union over their groups (groupPosesByPlace's order and begin) of the grid's query of each
// group's view box.
void viewCandidates(const ComponentGrid& grid, const std::vector<RigidTransformF>& T_map_cam,
                    const std::vector<int>& order, const std::vector<int>& begin,
                    const Intrinsics& K, const ViewReach& reach, std::vector<int>* candidates);

// The components (in the map's order) that the map's grid places near the view of a camera at
// T_map_cam with the view volume `reach`, the view's box grown by grow_m (the view of a pose up
// to that far from it). A pose's likelihood over them equals its likelihood over the whole map
// (test_building_scale), at a cost that follows the view, not the map (docs/building_scale.md).
// `index` is scratch (the components' map indices on return).
void viewComponents(const GmmMap& map, const RigidTransformF& T_map_cam, const Intrinsics& K,
                    const ViewReach& reach, double grow_m, std::vector<int>* index,
                    std::vector<ComponentF>* out);

// Brute-force reference: tests every (patch, component) pair with ellipseContains.
void computeMembershipBruteForce(const std::vector<ComponentF>& components,
                                 const RigidTransformF& T_cam_map, const Intrinsics& K,
                                 const PatchGrid& grid, const MeasurementParams& params,
                                 PatchMembership* out);

}  // namespace gmm_mcl
