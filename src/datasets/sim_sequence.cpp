#include "gmm_mcl/datasets/sim_sequence.h"

#include <random>
#include <stdexcept>

#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {

namespace {

std::string describe(const SimSequenceParams& params) {
  if (params.frames < 1 || params.width_px < 16) {
    throw std::invalid_argument("SimSequence: need at least 1 frame and 16 px width");
  }
  return "synthetic box scene (" + std::to_string(params.frames) + " frames, " +
         std::to_string(params.width_px) + " px, seed " + std::to_string(params.seed) + ")";
}

}  // namespace

SimSequence::SimSequence(const SimSequenceParams& params)
    : Sequence("sim", describe(params)), params_(params), scene_(sim::makeDefaultScene()) {
  intrinsics_ = sim::defaultCamera(params.width_px);
  const Eigen::Isometry3d T_base_cam = sim::defaultBaseToCamera();
  for (const Eigen::Isometry3d& T : sim::makeTrajectory(params.frames)) {
    stamps_s_.push_back(params_.start_s + size() / 30.0);
    depth_paths_.push_back(source_ + " frame " + std::to_string(size()));
    T_world_cam_.push_back(T * T_base_cam);
  }
  gravity_source_ = "z-up";
}

DepthImage SimSequence::loadDepth(int i) const {
  std::mt19937_64 rng(params_.seed * 1000003ULL + static_cast<uint64_t>(i));
  const sim::DepthNoise noise{params_.sigma_at_1m_m, params_.dropout};
  return sim::renderDepth(scene_, intrinsics_, T_world_cam_[i], DepthEncoding::kMono16Millimetres,
                          params_.max_range_m, noise, &rng);
}

GmmMap SimSequence::map() const { return sim::tileScene(scene_, 0.4, 0.015); }

}  // namespace gmm_mcl
