// Shared synthetic fixtures for the core tests: the box scene, its tiled GMM, a camera, frames.
#pragma once

#include <cmath>
#include <random>
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

// Frame parameters of the tests on the synthetic scene: every pixel_stride-th pixel, ranges up
// to 8 m (the room's far walls), the rest default.
FrameParams frameParams(int pixel_stride);

// The synthetic world's depth image from the base pose T_map_base, ranges up to max_range_m.
DepthImage renderImage(const Eigen::Isometry3d& T_map_base, const Intrinsics& K, double max_range_m,
                       DepthEncoding encoding = DepthEncoding::kMono16Millimetres);
// Its frame (rendered 1 m beyond params.max_range_m, then prepared with params).
DepthFrame renderFrame(const Eigen::Isometry3d& T_map_base, const Intrinsics& K,
                       const FrameParams& params,
                       DepthEncoding encoding = DepthEncoding::kMono16Millimetres);

// The distance between two particles' positions (m).
inline double distance(const Particle& a, const Particle& b) {
  return std::sqrt(std::pow(a.x_m - b.x_m, 2) + std::pow(a.y_m - b.y_m, 2) +
                   std::pow(a.z_m - b.z_m, 2));
}

// `truth` moved about as far as a converged particle set spreads (the filter's process noise is
// 2 cm): Gaussian offsets of 3 cm in x and y, 2 cm in z and 0.015 rad in yaw, drawn from n01 in
// that order.
Particle perturbed(const Particle& truth, std::normal_distribution<double>& n01,
                   std::mt19937_64& rng);

// `frames` steps of `loc` at the reference pose of a camera (smallCamera) whose depths read
// `factor` long, each depth with the measurement model's noise (p.measurement) drawn anew per
// frame from `rng`, the attitude given, stamps from start_s at 30 Hz: the last step, and how many
// steps were refined (with the pixel sums on the backend's evaluator).
struct LongDepthRun {
  StepResult last;
  int refined = 0;
  int refined_on_backend = 0;
};
// The world's camera turned by yaw_rad about the base's vertical (a rig's second camera).
Eigen::Isometry3d turnedCamera(double yaw_rad);

// A rig's second camera in stepLongDepths: its extrinsics, its depths' factor and the
// localizer's initial estimate of its scale (CameraInput::depth_scale_initial).
struct LongDepthCamera {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  double factor = 1.0;
  double depth_scale_initial = 1.0;
};
// The rig's second camera of the depth-scale tests: turnedCamera(2.5), its depths 1% short, its
// estimate begun at 0.995.
LongDepthCamera shortSecondCamera();
LongDepthRun stepLongDepths(Localizer* loc, const LocalizerParams& p, int frames, double factor,
                            double start_s, std::mt19937_64* rng,
                            const LongDepthCamera* second = nullptr);

// Root of ../shared/datasets ($GMM_MCL_DATASETS overrides); empty when absent.
std::string datasetsRoot();

}  // namespace test
}  // namespace gmm_mcl
