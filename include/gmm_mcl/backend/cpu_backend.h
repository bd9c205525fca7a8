// CPU likelihood backend: OpenMP over particles, a vectorised float32 kernel per patch.
#pragma once

#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/measurement/likelihood.h"

namespace gmm_mcl {

class CpuBackend : public LikelihoodBackend {
 public:
  // num_threads <= 0: OpenMP's default.
  explicit CpuBackend(int num_threads = 0) : num_threads_(num_threads) {}
  std::string name() const override { return "cpu"; }
  void setMap(const GmmMap& map) override {
    components_ = map.packed();
    makeEvalComponents(components_, &eval_);
    map_grid_ = map.grid();
  }
  void evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                const MeasurementParams& params, BackendOutput* out) override;
  void membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                  const MeasurementParams& params, PatchMembership* out) override;

 private:
  int num_threads_;
  std::vector<ComponentF> components_;
  std::vector<EvalComponentF> eval_;        // the likelihood kernel's form of components_ (nats)
  std::vector<LikelihoodScratch> scratch_;  // one per thread
  ComponentGrid map_grid_;                  // the map's components by place (the view's candidates)
  ComponentGrid::Scratch grid_scratch_;
  // Per update: the poses' inverses, the poses grouped by where their cameras are, and per
  // group the map grid's candidates, the view cull's list and the compact tables it selects.
  std::vector<RigidTransformF> T_cam_map_;
  std::vector<int> group_order_, group_begin_;
  std::vector<RigidTransformF> group_T_cam_map_;
  std::vector<int> candidates_, visible_;
  std::vector<char> visible_any_;
  std::vector<ComponentF> view_components_;
  std::vector<EvalComponentF> view_eval_;
  std::vector<float> view_soa_;                   // componentSoA(view_components_)
  std::vector<float> view_log_norm_;              // view_eval_'s log_norm (the depth prune)
  std::vector<float> patch_min_z_, patch_max_z_;  // the frame's patch depth ranges
};

}  // namespace gmm_mcl
