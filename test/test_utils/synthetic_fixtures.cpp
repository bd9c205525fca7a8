#include "test_utils/synthetic_fixtures.h"

#include <sys/stat.h>

#include <cstdlib>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/depth_noise.h"
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

LongDepthRun stepLongDepths(Localizer* loc, const LocalizerParams& p, int frames, double factor,
                            double start_s, std::mt19937_64* rng) {
  const Intrinsics K = smallCamera();
  const Eigen::Isometry3d T_map_base = referenceBasePose();
  const DepthImage exact = renderImage(T_map_base, K, 9.0, DepthEncoding::kFloat32Metres);
  StepInput in;
  in.intrinsics = K;
  double yaw = 0.0;
  rpyFromRotation(T_map_base.linear(), &in.roll_rad, &in.pitch_rad, &yaw);
  in.has_attitude = true;
  std::normal_distribution<double> n01(0.0, 1.0);
  LongDepthRun out;
  for (int k = 0; k < frames; ++k) {
    std::vector<float> z(static_cast<size_t>(exact.width_px) * exact.height_px);
    for (int v = 0; v < exact.height_px; ++v) {
      for (int u = 0; u < exact.width_px; ++u) {
        const float m = exact.depthMetres(u, v);
        z[v * exact.width_px + u] =
            std::isfinite(m) && m > 0.f
                ? static_cast<float>(
                      factor * (m + depthNoiseSigma(p.measurement.depth_noise, m) * n01(*rng)))
                : m;
      }
    }
    const DepthImage img = DepthImage::fromMetres(exact.width_px, exact.height_px, z);
    in.depth = &img;
    in.stamp_s = start_s + k / 30.0;
    out.last = loc->step(in);
    out.refined += out.last.refinement.refined ? 1 : 0;
    out.refined_on_backend +=
        out.last.refinement.refined && out.last.refinement.sums_on_backend ? 1 : 0;
  }
  return out;
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
