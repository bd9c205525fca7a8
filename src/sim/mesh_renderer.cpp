#include "gmm_mcl/sim/mesh_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace gmm_mcl {
namespace sim {

IdealDepth renderIdealDepth(const MeshBvh& bvh, const Intrinsics& K,
                            const Eigen::Isometry3d& T_map_cam, double max_depth_m,
                            double projector_baseline_m) {
  if (K.width_px <= 0 || K.height_px <= 0 || !(K.fx_px > 0.f) || !(K.fy_px > 0.f)) {
    throw std::invalid_argument("renderIdealDepth: bad intrinsics");
  }
  IdealDepth out;
  const int w = K.width_px, h = K.height_px;
  out.width_px = w;
  out.height_px = h;
  const size_t n = static_cast<size_t>(w) * h;
  out.z_m.assign(n, std::numeric_limits<float>::quiet_NaN());
  out.cos_incidence.assign(n, 0.f);
  const bool shadow = projector_baseline_m != 0.0;
  if (shadow) out.shadowed.assign(n, 0);
  const Eigen::Matrix3f R = T_map_cam.linear().cast<float>();
  const Eigen::Vector3f o = T_map_cam.translation().cast<float>();
  const Eigen::Vector3f projector =
      (T_map_cam * Eigen::Vector3d(projector_baseline_m, 0.0, 0.0)).cast<float>();
  const float t_max = static_cast<float>(max_depth_m);
#pragma omp parallel for schedule(dynamic, 4)
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      // Camera ray with z = 1: the hit parameter t is the z-depth itself.
      const Eigen::Vector3f ray_cam((u - K.cx_px) / K.fx_px, (v - K.cy_px) / K.fy_px, 1.f);
      const Eigen::Vector3f dir = R * ray_cam;
      RayHit hit;
      if (!bvh.intersect(o, dir, 1e-4f, t_max, &hit)) continue;
      const size_t i = static_cast<size_t>(v) * w + u;
      out.z_m[i] = hit.t;
      out.cos_incidence[i] = std::abs(hit.normal.dot(dir)) / dir.norm();
      if (shadow) {
        const Eigen::Vector3f p = o + hit.t * dir;
        const Eigen::Vector3f to_projector = projector - p;
        const float len = to_projector.norm();
        // Start 2 mm off the surface so that the hit triangle itself does not count.
        if (len > 0.f && bvh.occluded(p, to_projector, 2e-3f / len, 1.f)) out.shadowed[i] = 1;
      }
    }
  }
  return out;
}

DepthImage toDepthImage(int width_px, int height_px, const std::vector<float>& z_m,
                        DepthEncoding encoding) {
  if (encoding == DepthEncoding::kFloat32Metres) {
    return DepthImage::fromMetres(width_px, height_px, z_m);
  }
  std::vector<uint16_t> mm(z_m.size(), 0);
  for (size_t i = 0; i < z_m.size(); ++i) {
    if (std::isfinite(z_m[i]) && z_m[i] > 0.f) {
      mm[i] = static_cast<uint16_t>(std::min(65534.0, std::round(1000.0 * z_m[i])));
    }
  }
  return DepthImage::fromMillimetres(width_px, height_px, mm);
}

DepthImage renderDepth(const MeshBvh& bvh, const Intrinsics& K, const Eigen::Isometry3d& T_map_cam,
                       DepthEncoding encoding, double max_range_m, const SensorNoiseParams* noise,
                       uint64_t seed) {
  if (!noise) {
    const IdealDepth ideal = renderIdealDepth(bvh, K, T_map_cam, max_range_m, 0.0);
    return toDepthImage(ideal.width_px, ideal.height_px, ideal.z_m, encoding);
  }
  const std::string why = noise->validate();
  if (!why.empty()) throw std::invalid_argument("sensor noise: " + why);
  SensorNoiseParams p = *noise;
  p.max_range_m = std::min(p.max_range_m, max_range_m);
  // Cast a little beyond the window: noise can bring a return from beyond it inside.
  const double cast_m = p.max_range_m + 5.0 * axialSigma(p, p.max_range_m, 0.0) + 0.05;
  const IdealDepth ideal =
      renderIdealDepth(bvh, K, T_map_cam, cast_m, p.projector_shadow ? p.baseline_m : 0.0);
  return toDepthImage(ideal.width_px, ideal.height_px, applySensorNoise(ideal, p, seed), encoding);
}

}  // namespace sim
}  // namespace gmm_mcl
