#include "gmm_mcl/sim/sensor_noise.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kHalfPi = 1.57079632679489661923;

// splitmix64 finaliser: a counter-based generator, one stream per (seed, pixel, draw).
uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

double uniform(uint64_t seed, uint64_t pixel, uint64_t draw) {
  const uint64_t h = mix(mix(seed ^ 0x5851f42d4c957f2dull) + mix(pixel * 8 + draw));
  return ((h >> 11) + 0.5) * (1.0 / 9007199254740992.0);  // (0, 1)
}

double gaussian(uint64_t seed, uint64_t pixel) {
  const double u1 = uniform(seed, pixel, 2), u2 = uniform(seed, pixel, 3);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace

std::string SensorNoiseParams::validate() const {
  std::ostringstream e;
  if (!(min_range_m >= 0.0) || !(max_range_m > min_range_m) || !std::isfinite(max_range_m)) {
    e << "range window [" << min_range_m << ", " << max_range_m
      << "] m must satisfy 0 <= min < max; ";
  }
  if (!(axial_a_m >= 0.0) || !(axial_b_per_m >= 0.0) || !(axial_angle_m >= 0.0) ||
      !std::isfinite(axial_z0_m)) {
    e << "axial noise coefficients must be finite and non-negative; ";
  }
  if (!(std::abs(depth_scale_error) < 0.5)) e << "depth scale error must be in (-0.5, 0.5); ";
  if (!(grazing_start_rad > 0.0) || !(grazing_end_rad >= grazing_start_rad) ||
      !(grazing_end_rad <= kHalfPi)) {
    e << "grazing angles must satisfy 0 < start <= end <= pi/2; ";
  }
  if (!(baseline_m >= 0.0) || !std::isfinite(baseline_m)) e << "baseline must be >= 0; ";
  if (projector_shadow && !(baseline_m > 0.0)) e << "projector shadow needs a baseline > 0; ";
  if (edge_radius_px < 0 || edge_radius_px > 16) e << "edge radius must be in [0, 16] px; ";
  if (!(edge_jump_fraction > 0.0)) e << "edge jump fraction must be > 0; ";
  if (!(disparity_subpixel >= 0.0) || !std::isfinite(disparity_subpixel)) {
    e << "disparity subpixel must be >= 0; ";
  }
  if (disparity_subpixel > 0.0 && !(disparity_focal_px > 0.0 && baseline_m > 0.0)) {
    e << "disparity quantisation needs focal > 0 and baseline > 0; ";
  }
  if (!(random_dropout >= 0.0 && random_dropout <= 1.0)) e << "random dropout must be in [0, 1]; ";
  std::string s = e.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

SensorNoiseParams SensorNoiseParams::noiseFree() {
  SensorNoiseParams p;
  p.min_range_m = 0.0;
  p.max_range_m = 1e6;
  p.axial_a_m = p.axial_b_per_m = p.axial_angle_m = 0.0;
  p.grazing_start_rad = p.grazing_end_rad = kHalfPi;
  p.projector_shadow = false;
  p.edge_radius_px = 0;
  p.disparity_subpixel = 0.0;
  p.random_dropout = 0.0;
  return p;
}

double axialSigma(const SensorNoiseParams& p, double z_m, double theta_rad) {
  const double th = std::min(std::max(theta_rad, 0.0), std::min(p.grazing_end_rad, kHalfPi - 1e-3));
  const double dz = z_m - p.axial_z0_m;
  const double g = th / (kHalfPi - th);
  return p.axial_a_m + p.axial_b_per_m * dz * dz +
         p.axial_angle_m / std::sqrt(std::max(z_m, 1e-3)) * g * g;
}

double quantiseDepth(const SensorNoiseParams& p, double z_m) {
  if (!(p.disparity_subpixel > 0.0) || !(z_m > 0.0)) return z_m;
  const double fb = p.disparity_focal_px * p.baseline_m;
  const double d = std::round(fb / z_m * p.disparity_subpixel);
  if (d <= 0.0) return std::numeric_limits<double>::infinity();  // beyond the last step
  return fb * p.disparity_subpixel / d;
}

std::vector<float> applySensorNoise(const IdealDepth& ideal, const SensorNoiseParams& p,
                                    uint64_t seed) {
  const int w = ideal.width_px, h = ideal.height_px;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> out(static_cast<size_t>(w) * h, nan);
  const bool have_cos = ideal.cos_incidence.size() == out.size();
  const bool have_shadow = ideal.shadowed.size() == out.size();
  const double graze_span = p.grazing_end_rad - p.grazing_start_rad;
#pragma omp parallel for schedule(static)
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const float z0 = ideal.z_m[i];
      if (!std::isfinite(z0)) continue;
      if (p.projector_shadow && have_shadow && ideal.shadowed[i]) continue;
      if (p.random_dropout > 0.0 && uniform(seed, i, 0) < p.random_dropout) continue;
      const double theta =
          have_cos ? std::acos(std::min(1.0f, std::max(0.0f, ideal.cos_incidence[i]))) : 0.0;
      if (theta >= p.grazing_end_rad && p.grazing_end_rad < kHalfPi) continue;
      if (theta > p.grazing_start_rad && graze_span > 0.0 &&
          uniform(seed, i, 1) < (theta - p.grazing_start_rad) / graze_span) {
        continue;
      }
      bool edge = false;
      const int r = p.edge_radius_px;
      for (int dv = -r; dv <= r && !edge; ++dv) {
        const int vv = v + dv;
        if (vv < 0 || vv >= h) continue;
        for (int du = -r; du <= r; ++du) {
          const int uu = u + du;
          if (uu < 0 || uu >= w || (du == 0 && dv == 0)) continue;
          const float zq = ideal.z_m[static_cast<size_t>(vv) * w + uu];
          if (std::isfinite(zq) && std::abs(zq - z0) > p.edge_jump_fraction * std::min(zq, z0)) {
            edge = true;
            break;
          }
        }
      }
      if (edge) continue;
      double z = z0 + axialSigma(p, z0, theta) * gaussian(seed, i);
      z = (1.0 + p.depth_scale_error) * quantiseDepth(p, z);
      if (!(z >= p.min_range_m && z <= p.max_range_m)) continue;
      out[i] = static_cast<float>(z);
    }
  }
  return out;
}

}  // namespace sim
}  // namespace gmm_mcl
