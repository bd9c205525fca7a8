// Shared synthetic fixtures for the core tests: the box scene, its tiled GMM, a camera, frames.
#pragma once

#include <string>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/sim/box_scene.h"

namespace gmm_mcl {
namespace test {

// 320x240 pinhole, f = 290 px (about 58 deg horizontal field of view, like a Kinect).
Intrinsics smallCamera();
// 640x480, f = 585 px (the 7-Scenes camera).
Intrinsics vgaCamera();

struct SyntheticWorld {
  sim::BoxScene scene;
  GmmMap map;
  Eigen::Isometry3d T_base_cam;
};
// The default box scene tiled at 0.4 m spacing, 1.5 cm normal sigma (about 1100 components).
const SyntheticWorld& world();

// A base pose inside the room looking at furniture (x forward, z up).
Eigen::Isometry3d referenceBasePose();

DepthFrame renderFrame(const Eigen::Isometry3d& T_map_base, const Intrinsics& K,
                       const FrameParams& params,
                       DepthEncoding encoding = DepthEncoding::kMono16Millimetres);

// Root of ../shared/datasets ($GMM_MCL_DATASETS overrides); empty when absent.
std::string datasetsRoot();

}  // namespace test
}  // namespace gmm_mcl
