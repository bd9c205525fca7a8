// Patch membership (paper Sec. Fast Localization): component i is relevant to patch p when the
// patch centre lies in the 3-sigma ellipse of its projection inflated by half the patch diagonal.
#pragma once

#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/component_grid.h"
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

// Projects every component for one camera pose and fills the membership table.
// `projected` and `valid` are scratch (resized here); T_cam_map maps map points into the camera.
// With `reach`, a component outside the pose's view volume (projection.h's componentInView) is
// no member, as in the CUDA membership kernel: the likelihood's members (the backends); without
// it, every component whose ellipse reaches a patch centre (the brute-force reference's table).
void computeMembership(const std::vector<ComponentF>& components, const RigidTransformF& T_cam_map,
                       const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                       std::vector<ProjectedComponent>* projected, std::vector<char>* valid,
                       PatchMembership* out, const ViewReach* reach = nullptr);

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

// Brute-force reference: tests every (patch, component) pair with ellipseContains.
void computeMembershipBruteForce(const std::vector<ComponentF>& components,
                                 const RigidTransformF& T_cam_map, const Intrinsics& K,
                                 const PatchGrid& grid, const MeasurementParams& params,
                                 PatchMembership* out);

}  // namespace gmm_mcl
