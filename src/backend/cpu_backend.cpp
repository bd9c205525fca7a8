#include "gmm_mcl/backend/cpu_backend.h"

#include <omp.h>

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
  // Membership and likelihood over the components some pose can see (the same members and sums:
  // the list keeps the map's order).
  const double t_cull = omp_get_wtime();
  T_cam_map_.resize(n);
  for (int i = 0; i < n; ++i) T_cam_map_[i] = invertRigid(T_map_cam[i]);
  cullToView(components_, T_cam_map_.data(), n, frame.intrinsics, frame.grid, params, &visible_);
  const int m_view = static_cast<int>(visible_.size());
  view_components_.resize(m_view);
  view_eval_.resize(m_view);
  for (int k = 0; k < m_view; ++k) {
    view_components_[k] = components_[visible_[k]];
    view_eval_[k] = eval_[visible_[k]];
  }
  const double cull_s = omp_get_wtime() - t_cull;
#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num();
    LikelihoodScratch& s = scratch_[tid];
#pragma omp for schedule(dynamic, 8)
    for (int i = 0; i < n; ++i) {
      const double t0 = omp_get_wtime();
      const RigidTransformF& T_cam_map = T_cam_map_[i];
      computeMembership(view_components_, T_cam_map, frame.intrinsics, frame.grid, params,
                        &s.projected, &s.valid, &s.membership);
      const EvalComponentF* eval = noisyEvalComponents(view_components_, view_eval_, s.valid,
                                                       T_cam_map, params.depth_noise, &s.noisy);
      const double t1 = omp_get_wtime();
      const FrameLikelihood fl =
          frameLogLikelihood(eval, frame, T_map_cam[i], s.membership, params.floor_log_density);
      likelihood_s[tid] += omp_get_wtime() - t1;
      membership_s[tid] += t1 - t0;
      out->log_likelihood[i] = fl.log_likelihood;
      out->floor_hits[i] = fl.floor_hits;
      evaluations[tid] += fl.evaluations;
      for (int p = 0; p < frame.grid.count(); ++p) {
        if (frame.patch_begin[p + 1] > frame.patch_begin[p]) pairs[tid] += s.membership.countFor(p);
      }
    }
  }
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
  std::vector<ProjectedComponent> projected;
  std::vector<char> valid;
  computeMembership(components_, invertRigid(T_map_cam), frame.intrinsics, frame.grid, params,
                    &projected, &valid, out);
}

}  // namespace gmm_mcl
