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
void computeMembership(const std::vector<ComponentF>& components, const RigidTransformF& T_cam_map,
                       const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                       std::vector<ProjectedComponent>* projected, std::vector<char>* valid,
                       PatchMembership* out);

// The per-update view cull: the components (ascending map indices) that componentMayTouchGrid
// keeps for at least one of the num_poses camera poses T_cam_map. Every other component lies
// outside the patch grid's reach for every pose (no patch of any pose would list it), so the
// membership and likelihood over this list equal those over the whole map.
void cullToView(const std::vector<ComponentF>& components, const RigidTransformF* T_cam_map,
                int num_poses, const Intrinsics& K, const PatchGrid& grid,
                const MeasurementParams& params, std::vector<int>* visible);
// The same over `candidates` (ascending map indices, num_candidates of them: the map grid's
// components near the poses' views), also dropping the components that lie beyond far_m (the
// frame's deepest pixel plus the noise's reach) by more than sigma_bound standard deviations
// along the optical axis: the cull that follows the view in a map of a building.
void cullToView(const std::vector<ComponentF>& components, const int* candidates,
                int num_candidates, const RigidTransformF* T_cam_map, int num_poses,
                const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                float far_m, std::vector<int>* visible);

// How deep the view reaches: the frame's deepest pixel plus sigma_bound standard deviations of
// the depth noise there (0 for an empty frame).
float viewFarDepth(const DepthFrame& frame, const MeasurementParams& params);
// The map-frame box around what a camera at T_map_cam sees up to far_m: its centre and the patch
// grid's corners, grown by the membership's inflation, at depth far_m.
Box3 viewBox(const RigidTransformF& T_map_cam, const Intrinsics& K, const PatchGrid& grid,
             float far_m);
// The poses grouped by the cell (edge cell_m) of their camera centre: group g is
// order[begin[g] .. begin[g + 1]), ascending pose indices within it.
void groupPosesByPlace(const std::vector<RigidTransformF>& T_map_cam, double cell_m,
                       std::vector<int>* order, std::vector<int>* begin);

// Brute-force reference: tests every (patch, component) pair with ellipseContains.
void computeMembershipBruteForce(const std::vector<ComponentF>& components,
                                 const RigidTransformF& T_cam_map, const Intrinsics& K,
                                 const PatchGrid& grid, const MeasurementParams& params,
                                 PatchMembership* out);

}  // namespace gmm_mcl
