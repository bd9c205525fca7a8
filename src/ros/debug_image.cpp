#include "gmm_mcl/ros/debug_image.h"

#include <sensor_msgs/image_encodings.h>

#include <algorithm>
#include <cmath>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {

void renderDebugImage(const DepthImage& depth, const Intrinsics& K, const GmmMap& map,
                      const Eigen::Isometry3d& T_map_cam, const FrameParams& frame_params,
                      const MeasurementParams& measurement, sensor_msgs::Image* out) {
  const int w = depth.width_px, h = depth.height_px;
  out->width = w;
  out->height = h;
  out->encoding = sensor_msgs::image_encodings::RGB8;
  out->is_bigendian = 0;
  out->step = 3 * w;
  out->data.assign(static_cast<size_t>(out->step) * h, 0);
  const float max_m = std::max(0.1f, frame_params.max_range_m);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const float z = depth.depthMetres(u, v);
      uint8_t g = 0;
      if (std::isfinite(z) && z > 0.f)
        g = static_cast<uint8_t>(255.f * (1.f - std::min(z / max_m, 1.f)) * 0.8f + 30.f);
      uint8_t* px = &out->data[static_cast<size_t>(v) * out->step + 3 * u];
      px[0] = px[1] = px[2] = g;
    }
  }
  const RigidTransformF T_cam_map = toRigidF(T_map_cam.inverse());
  const PatchGrid grid = PatchGrid::forImage(w, h, frame_params.patch_size_px);
  std::vector<ProjectedComponent> projected;
  std::vector<char> valid;
  PatchMembership membership;
  computeMembership(map.packed(), T_cam_map, K, grid, measurement, &projected, &valid, &membership);
  // Patch tint: green channel raised with the member count (saturates at 80).
  for (int pr = 0; pr < grid.rows; ++pr) {
    for (int pc = 0; pc < grid.cols; ++pc) {
      const int n = membership.countFor(pr * grid.cols + pc);
      const float a = 0.6f * std::min(1.f, n / 80.f);
      for (int v = pr * grid.patch_size_px; v < std::min(h, (pr + 1) * grid.patch_size_px); ++v) {
        for (int u = pc * grid.patch_size_px; u < std::min(w, (pc + 1) * grid.patch_size_px); ++u) {
          uint8_t* px = &out->data[static_cast<size_t>(v) * out->step + 3 * u];
          const bool border = (u % grid.patch_size_px == 0) || (v % grid.patch_size_px == 0);
          px[1] = static_cast<uint8_t>(std::min(255.f, px[1] * (1.f - 0.5f * a) + 127.f * a));
          if (border) px[0] = px[1] = px[2] = 60;
        }
      }
    }
  }
  // 3-sigma ellipses (not inflated) in red.
  for (size_t i = 0; i < map.size(); ++i) {
    ProjectedComponent p;
    if (!projectComponent(map.packed()[i], T_cam_map, K, measurement.min_component_depth_m,
                          measurement.sigma_bound, 0.f, &p)) {
      continue;
    }
    const float half_tr = 0.5f * (p.cov_uu + p.cov_vv);
    const float diff = 0.5f * (p.cov_uu - p.cov_vv);
    const float rad = std::sqrt(diff * diff + p.cov_uv * p.cov_uv);
    const float a = measurement.sigma_bound * std::sqrt(std::max(half_tr + rad, 0.f));
    const float b = measurement.sigma_bound * std::sqrt(std::max(half_tr - rad, 0.f));
    const float ang = 0.5f * std::atan2(p.cov_uv, diff);
    if (p.u_px + a < 0 || p.u_px - a >= w || p.v_px + a < 0 || p.v_px - a >= h) continue;
    const int steps = std::max(12, std::min(200, static_cast<int>(2.f * a)));
    for (int k = 0; k < steps; ++k) {
      const float t = 2.f * static_cast<float>(M_PI) * k / steps;
      const float eu = a * std::cos(t), ev = b * std::sin(t);
      const int u = static_cast<int>(std::lround(p.u_px + eu * std::cos(ang) - ev * std::sin(ang)));
      const int v = static_cast<int>(std::lround(p.v_px + eu * std::sin(ang) + ev * std::cos(ang)));
      if (u < 0 || u >= w || v < 0 || v >= h) continue;
      uint8_t* px = &out->data[static_cast<size_t>(v) * out->step + 3 * u];
      px[0] = 255;
      px[1] = 40;
      px[2] = 40;
    }
  }
}

}  // namespace gmm_mcl
