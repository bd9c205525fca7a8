// Parameters of the measurement model (DESIGN.md "Measurement model").
#pragma once

#include <string>

namespace gmm_mcl {

// Default per-pixel floor, nats with densities per cubic metre (DESIGN.md).
constexpr float kDefaultFloorLogDensity = -10.0f;

// Axial depth noise of the camera, sigma(z) = a + b (z - z0)^2 in metres (DESIGN.md "Sensor
// noise"; gmm_mcl/measurement/depth_noise.h says how it enters the likelihood). The defaults are
// Nguyen, Izadi and Lovell's fit for a Kinect v1 (structured light, 0.5-4 m); a = b = 0 turns
// the model off (the paper's model: the map alone).
struct DepthNoiseModel {
  float a_m = 0.0012f;
  float b_per_m = 0.0019f;  // per m^2 of (z - z0)^2: metres of sigma per square metre
  float z0_m = 0.4f;

  bool enabled() const { return a_m > 0.f || b_per_m > 0.f; }
};

struct MeasurementParams {
  float min_component_depth_m = 0.1f;  // components whose mean is nearer (or behind) are dropped
  float sigma_bound = 3.0f;            // membership ellipse radius in standard deviations
  // Each pixel's log-likelihood is ln(exp(floor) + sum_j lambda_j N_j): a uniform outlier term
  // that bounds it below by the floor; a pixel whose mixture density is below exp(floor) counts
  // as a floor hit.
  float floor_log_density = kDefaultFloorLogDensity;
  DepthNoiseModel depth_noise;
  // The camera whose noise depth_noise holds, by name (depth_noise_preset.h): "custom" = the
  // numbers as given. The parameter tables write a preset's numbers into depth_noise when it is
  // set; numbers given after it (depth_noise_a_m, ...) override them.
  std::string depth_noise_preset = "custom";

  std::string validate() const;
};

}  // namespace gmm_mcl
