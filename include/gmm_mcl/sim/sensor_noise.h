// A structured-light depth sensor (Kinect v1 class) as a noise model applied to an ideal
// z-depth render: axial noise growing with depth and incidence angle, missing pixels at
// grazing incidence, in the projector's shadow and at depth edges, random dropout, disparity
// quantisation and a range window. Sources of the default numbers: docs/sim.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace gmm_mcl {
namespace sim {

struct SensorNoiseParams {
  // Range window of valid returns (Khoshelham and Oude Elberink 2012 evaluate 0.5-5 m).
  double min_range_m = 0.5;
  double max_range_m = 5.0;
  // Axial sigma(z, theta) = a + b (z - z0)^2 + c / sqrt(z) * theta^2 / (pi/2 - theta)^2 in metres
  // (Nguyen, Izadi and Lovell 2012, fitted on a Kinect v1 for 10-70 deg incidence).
  double axial_a_m = 0.0012;
  double axial_b_per_m = 0.0019;
  double axial_z0_m = 0.4;
  double axial_angle_m = 0.0001;
  // Missing returns at grazing incidence: drop probability rises linearly from 0 at the first
  // angle to 1 at the second (Nguyen et al.'s model holds to about 70 deg).
  double grazing_start_rad = 70.0 * 3.14159265358979323846 / 180.0;
  double grazing_end_rad = 85.0 * 3.14159265358979323846 / 180.0;
  // Projector offset along the camera's +x (Kinect v1: 7.5 cm) and whether surfaces the
  // projector cannot see (its shadow beside foreground edges) are missing.
  double baseline_m = 0.075;
  bool projector_shadow = true;
  // Pixels within edge_radius_px of a depth jump larger than edge_jump_fraction x depth are
  // missing (the correlation window straddles two surfaces); radius 0 turns this off.
  int edge_radius_px = 1;
  double edge_jump_fraction = 0.05;
  // Disparity quantisation: disparity = focal * baseline / z in steps of 1/subpixel px
  // (Kinect v1: f about 580 px, 1/8 px steps, so about 3 mm at 1 m and 7 cm at 5 m);
  // subpixel 0 turns it off.
  double disparity_focal_px = 580.0;
  double disparity_subpixel = 8.0;
  // Independent random dropout (speckle that fails to match), probability per pixel.
  double random_dropout = 0.005;
  // The depth the camera reports is (1 + this) times the measured one (a miscalibrated stereo
  // camera: 0.004 reads 0.4% long; RealSense-class cameras are off by 0.5-2% uncalibrated).
  double depth_scale_error = 0.0;

  // Empty when valid, else what is wrong.
  std::string validate() const;
  // All noise and all missing-pixel effects off, only the range window (for tests).
  static SensorNoiseParams noiseFree();
};

// Axial standard deviation (m) at depth z_m and incidence angle theta_rad.
double axialSigma(const SensorNoiseParams& p, double z_m, double theta_rad);
// Depth after disparity quantisation (unchanged when disparity_subpixel is 0).
double quantiseDepth(const SensorNoiseParams& p, double z_m);

// The ideal render the noise model works on (row-major, width x height).
struct IdealDepth {
  int width_px = 0;
  int height_px = 0;
  std::vector<float> z_m;            // z-depth; NaN where the ray hit nothing
  std::vector<float> cos_incidence;  // |cos| of the angle between ray and surface normal
  std::vector<uint8_t> shadowed;     // 1 where the projector cannot see the surface point
};

// Applies the model; returns z-depth in metres with NaN for missing pixels. Deterministic for
// a seed (each pixel draws from its own counter-based stream, independent of threads).
std::vector<float> applySensorNoise(const IdealDepth& ideal, const SensorNoiseParams& params,
                                    uint64_t seed);

}  // namespace sim
}  // namespace gmm_mcl
