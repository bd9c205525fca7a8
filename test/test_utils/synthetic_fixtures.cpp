#include "test_utils/synthetic_fixtures.h"

#include <sys/stat.h>

#include <cstdlib>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace test {

Intrinsics smallCamera() { return sim::pinholeCamera(320, 240, 290.f, 159.5f, 119.5f); }

Intrinsics vgaCamera() { return sim::sevenScenesCamera(); }

const SyntheticWorld& world() {
  static const SyntheticWorld w = [] {
    sim::BoxScene scene = sim::makeDefaultScene();
    GmmMap map = sim::tileScene(scene, 0.4, 0.015);
    return SyntheticWorld{scene, map, sim::defaultBaseToCamera()};
  }();
  return w;
}

Eigen::Isometry3d referenceBasePose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(0.02, -0.03, -0.6);
  T.translation() = Eigen::Vector3d(2.5, 3.5, 1.4);
  return T;
}

FrameParams frameParams(int pixel_stride) {
  FrameParams fp;
  fp.pixel_stride = pixel_stride;
  fp.max_range_m = 8.f;
  return fp;
}

Particle perturbed(const Particle& truth, std::normal_distribution<double>& n01,
                   std::mt19937_64& rng) {
  Particle p = truth;
  p.x_m += 0.03 * n01(rng);
  p.y_m += 0.03 * n01(rng);
  p.z_m += 0.02 * n01(rng);
  p.yaw_rad += 0.015 * n01(rng);
  return p;
}

DepthImage renderImage(const Eigen::Isometry3d& T_map_base, const Intrinsics& K, double max_range_m,
                       DepthEncoding encoding) {
  const SyntheticWorld& w = world();
  return sim::renderDepth(w.scene, K, T_map_base * w.T_base_cam, encoding, max_range_m);
}

DepthFrame renderFrame(const Eigen::Isometry3d& T_map_base, const Intrinsics& K,
                       const FrameParams& params, DepthEncoding encoding) {
  return prepareFrame(renderImage(T_map_base, K, params.max_range_m + 1.0, encoding), K, params);
}

std::string datasetsRoot() {
  const char* env = std::getenv("GMM_MCL_DATASETS");
  const std::string root = env && *env ? env : GMM_MCL_DEFAULT_DATASETS;
  struct stat st;
  if (stat(root.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return "";
  return root;
}

}  // namespace test
}  // namespace gmm_mcl
