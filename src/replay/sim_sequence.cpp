#include "gmm_mcl/replay/sim_sequence.h"

#include <random>
#include <stdexcept>

namespace gmm_mcl {

SimSequence::SimSequence(const SimSequenceParams& params)
    : params_(params), scene_(sim::makeDefaultScene()) {
  if (params.frames < 1 || params.width_px < 16) {
    throw std::invalid_argument("SimSequence: need at least 1 frame and 16 px width");
  }
  source_ = "synthetic box scene (" + std::to_string(params.frames) + " frames, " +
            std::to_string(params.width_px) + " px, seed " + std::to_string(params.seed) + ")";
  const double scale = params.width_px / 640.0;
  intrinsics_.fx_px = intrinsics_.fy_px = static_cast<float>(585.0 * scale);
  intrinsics_.width_px = params.width_px;
  intrinsics_.height_px = params.width_px * 3 / 4;
  intrinsics_.cx_px = 0.5f * (intrinsics_.width_px - 1);
  intrinsics_.cy_px = 0.5f * (intrinsics_.height_px - 1);
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
