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

Eigen::Isometry3d turnedCamera(double yaw_rad) {
  Eigen::Isometry3d T = world().T_base_cam;
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * T.linear();
  return T;
}

LongDepthCamera shortSecondCamera() {
  LongDepthCamera c;
  c.T_base_cam = turnedCamera(2.5);
  c.factor = 0.99;
  c.depth_scale_initial = 0.995;
  return c;
}

namespace {

// `exact`'s depths times `factor`, each with the depth noise's N(0, sigma(z)^2) drawn from rng.
DepthImage longDepths(const DepthImage& exact, double factor, const DepthNoiseModel& noise,
                      std::normal_distribution<double>* n01, std::mt19937_64* rng) {
  std::vector<float> z(static_cast<size_t>(exact.width_px) * exact.height_px);
  for (int v = 0; v < exact.height_px; ++v) {
    for (int u = 0; u < exact.width_px; ++u) {
      const float m = exact.depthMetres(u, v);
      z[v * exact.width_px + u] =
          std::isfinite(m) && m > 0.f
              ? static_cast<float>(factor * (m + depthNoiseSigma(noise, m) * (*n01)(*rng)))
              : m;
    }
  }
  return DepthImage::fromMetres(exact.width_px, exact.height_px, z);
}

}  // namespace

LongDepthRun stepLongDepths(Localizer* loc, const LocalizerParams& p, int frames, double factor,
                            double start_s, std::mt19937_64* rng, const LongDepthCamera* second) {
  const Intrinsics K = smallCamera();
  const Eigen::Isometry3d T_map_base = referenceBasePose();
  const DepthImage exact = renderImage(T_map_base, K, 9.0, DepthEncoding::kFloat32Metres);
  DepthImage exact2;
  StepInput in;
  in.intrinsics = K;
  double yaw = 0.0;
  rpyFromRotation(T_map_base.linear(), &in.roll_rad, &in.pitch_rad, &yaw);
  in.has_attitude = true;
  if (second != nullptr) {
    exact2 = renderImage(T_map_base * second->T_base_cam * world().T_base_cam.inverse(), K, 9.0,
                         DepthEncoding::kFloat32Metres);
    CameraInput c;
    c.name = "second";
    c.intrinsics = K;
    c.T_base_cam = second->T_base_cam;
    c.frame = p.frame;
    c.measurement = p.measurement;
    c.depth_scale_initial = second->depth_scale_initial;
    in.more_cameras.push_back(c);
  }
  std::normal_distribution<double> n01(0.0, 1.0);
  LongDepthRun out;
  for (int k = 0; k < frames; ++k) {
    const DepthImage img = longDepths(exact, factor, p.measurement.depth_noise, &n01, rng);
    DepthImage img2;
    if (second != nullptr) {
      img2 = longDepths(exact2, second->factor, p.measurement.depth_noise, &n01, rng);
      in.more_cameras[0].depth = &img2;
    }
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
