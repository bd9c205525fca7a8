#include "gmm_mcl/backend/cpu_backend.h"

#include <omp.h>

#include <algorithm>

namespace gmm_mcl {

void CpuBackend::evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                          const MeasurementParams& params, BackendOutput* out) {
  if (components_.empty()) throw BackendError("cpu backend: no map set");
  const int n = static_cast<int>(T_map_cam.size());
  const int threads = num_threads_ > 0 ? num_threads_ : omp_get_max_threads();
  if (static_cast<int>(scratch_.size()) < threads) scratch_.resize(threads);
  out->log_likelihood.assign(n, 0.0);
  out->floor_hits.assign(n, 0);
  std::vector<double> membership_s(threads, 0.0), likelihood_s(threads, 0.0);
  std::vector<long long> evaluations(threads, 0), pairs(threads, 0);
  long long patches_with_pixels = 0;
  for (int p = 0; p < frame.grid.count(); ++p) {
    patches_with_pixels += frame.patch_begin[p + 1] > frame.patch_begin[p] ? 1 : 0;
  }
  // The poses by the cell of their camera centre; per group, the components that the map grid
  // places near the group's views, culled to what some pose of the group can see within the
  // frame's depth, then membership and likelihood over that list (in the map's order: the sums
  // over the whole map within float rounding, test_membership). A tracking cloud is one group; a
  // start spread over a building is many, each paying for its own view.
  const double t_cull = omp_get_wtime();
  T_cam_map_.resize(n);
  for (int i = 0; i < n; ++i) T_cam_map_[i] = invertRigid(T_map_cam[i]);
  const ViewReach reach = viewReach(frame, params);
  // The frame's depths bound the members (membership.h's MemberDepthPrune).
  patchDepthRanges(frame, &patch_min_z_, &patch_max_z_);
  MemberDepthPrune prune = memberDepthPrune(patch_min_z_, patch_max_z_, nullptr, params);
  groupPosesByPlace(T_map_cam, viewGroupCell(reach), &group_order_, &group_begin_);
  const int groups = static_cast<int>(group_begin_.size()) - 1;
  visible_any_.assign(components_.size(), 0);
  double cull_s = omp_get_wtime() - t_cull;
  for (int g = 0; g < groups; ++g) {
    const double t0 = omp_get_wtime();
    const int first = group_begin_[g], count = group_begin_[g + 1] - group_begin_[g];
    group_T_cam_map_.resize(count);
    for (int k = 0; k < count; ++k) group_T_cam_map_[k] = T_cam_map_[group_order_[first + k]];
    map_grid_.query(
        groupViewBox(T_map_cam, group_order_.data() + first, count, frame.intrinsics, reach),
        &candidates_, &grid_scratch_);
    cullToView(components_, candidates_.data(), static_cast<int>(candidates_.size()),
               group_T_cam_map_.data(), count, frame.intrinsics, frame.grid, params, reach,
               &visible_);
    const int m_view = static_cast<int>(visible_.size());
    view_components_.resize(m_view);
    view_eval_.resize(m_view);
    view_log_norm_.resize(m_view);
    for (int k = 0; k < m_view; ++k) {
      view_components_[k] = components_[visible_[k]];
      view_eval_[k] = eval_[visible_[k]];
      view_log_norm_[k] = eval_[visible_[k]].log_norm;
      visible_any_[visible_[k]] = 1;
    }
    prune.log_norm = view_log_norm_.data();
    componentSoA(view_components_, &view_soa_);
    cull_s += omp_get_wtime() - t0;
#pragma omp parallel num_threads(count > 1 ? threads : 1)
    {
      const int tid = omp_get_thread_num();
      LikelihoodScratch& s = scratch_[tid];
#pragma omp for schedule(dynamic, 8)
      for (int k = 0; k < count; ++k) {
        const int i = group_order_[first + k];
        const double t1 = omp_get_wtime();
        const RigidTransformF& T_cam_map = T_cam_map_[i];
        computeMembership(view_components_, T_cam_map, frame.intrinsics, frame.grid, params,
                          nullptr, &s.valid, &s.membership, &reach, &prune, view_soa_.data());
        const EvalComponentF* eval =
            noisyEvalComponents(view_components_, view_eval_, s.valid, T_cam_map,
                                params.depth_noise, &s.noisy, &view_soa_);
        const double t2 = omp_get_wtime();
        const FrameLikelihood fl =
            frameLogLikelihood(eval, frame, T_map_cam[i], s.membership, params.floor_log_density);
        likelihood_s[tid] += omp_get_wtime() - t2;
        membership_s[tid] += t2 - t1;
        out->log_likelihood[i] = fl.log_likelihood;
        out->floor_hits[i] = fl.floor_hits;
        evaluations[tid] += fl.evaluations;
        for (int p = 0; p < frame.grid.count(); ++p) {
          if (frame.patch_begin[p + 1] > frame.patch_begin[p]) {
            pairs[tid] += s.membership.countFor(p);
          }
        }
      }
    }
  }
  int m_view = 0;
  for (char v : visible_any_) m_view += v;
  // Stage times: thread-summed time divided by the thread count (wall-equivalent).
  out->projection_membership_ms = 1e3 * cull_s;  // one thread
  out->likelihood_ms = 0.0;
  out->visible_components = m_view;
  out->evaluations = out->relevant_pairs = 0;
  for (int t = 0; t < threads; ++t) {
    out->projection_membership_ms += 1e3 * membership_s[t] / threads;
    out->likelihood_ms += 1e3 * likelihood_s[t] / threads;
    out->evaluations += evaluations[t];
    out->relevant_pairs += pairs[t];
  }
  out->patches_with_pixels = patches_with_pixels;
}

void CpuBackend::membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                            const MeasurementParams& params, PatchMembership* out) {
  // As evaluate() sees it: the members within the pose's view volume.
  const ViewReach reach = viewReach(frame, params);
  std::vector<ProjectedComponent> projected;
  std::vector<char> valid;
  computeMembership(components_, invertRigid(T_map_cam), frame.intrinsics, frame.grid, params,
                    &projected, &valid, out, &reach);
}

}  // namespace gmm_mcl
