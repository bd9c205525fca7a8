#include "gmm_mcl/replay/sim_sequence.h"

#include <random>
#include <stdexcept>

#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {

SimSequence::SimSequence(const SimSequenceParams& params)
    : params_(params), scene_(sim::makeDefaultScene()) {
  if (params.frames < 1 || params.width_px < 16) {
    throw std::invalid_argument("SimSequence: need at least 1 frame and 16 px width");
  }
  source_ = "synthetic box scene (" + std::to_string(params.frames) + " frames, " +
            std::to_string(params.width_px) + " px, seed " + std::to_string(params.seed) + ")";
  intrinsics_ = sim::defaultCamera(params.width_px);
  const Eigen::Isometry3d T_base_cam = sim::defaultBaseToCamera();
  for (const Eigen::Isometry3d& T : sim::makeTrajectory(params.frames)) {
    T_world_cam_.push_back(T * T_base_cam);
  }
}

DepthImage SimSequence::loadDepth(int i) const {
  std::mt19937_64 rng(params_.seed * 1000003ULL + static_cast<uint64_t>(i));
  const sim::DepthNoise noise{params_.sigma_at_1m_m, params_.dropout};
  return sim::renderDepth(scene_, intrinsics_, T_world_cam_[i], DepthEncoding::kMono16Millimetres,
                          params_.max_range_m, noise, &rng);
}

std::string SimSequence::depthPath(int i) const {
  return source_ + " frame " + std::to_string(i);
}

GmmMap SimSequence::map() const { return sim::tileScene(scene_, 0.4, 0.015); }

}  // namespace gmm_mcl
