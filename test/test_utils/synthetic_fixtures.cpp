#include "test_utils/synthetic_fixtures.h"

#include <cstdlib>
#include <sys/stat.h>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace test {

Intrinsics smallCamera() {
  Intrinsics K;
  K.fx_px = K.fy_px = 290.f;
  K.cx_px = 159.5f;
  K.cy_px = 119.5f;
  K.width_px = 320;
  K.height_px = 240;
  return K;
}

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

DepthFrame renderFrame(const Eigen::Isometry3d& T_map_base, const Intrinsics& K,
                       const FrameParams& params, DepthEncoding encoding) {
  const SyntheticWorld& w = world();
  const DepthImage img =
      sim::renderDepth(w.scene, K, T_map_base * w.T_base_cam, encoding, params.max_range_m + 1.0);
  return prepareFrame(img, K, params);
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
