// Parameters of the measurement model (DESIGN.md "Measurement model").
#pragma once

#include <string>

namespace gmm_mcl {

// Default per-pixel floor, nats with densities per cubic metre (DESIGN.md).
constexpr float kDefaultFloorLogDensity = -10.0f;

struct MeasurementParams {
  float min_component_depth_m = 0.1f;  // components whose mean is nearer (or behind) are dropped
  float sigma_bound = 3.0f;            // membership ellipse radius in standard deviations
  // Each pixel's log-likelihood is ln(exp(floor) + sum_j lambda_j N_j): a uniform outlier term
  // that bounds it below by the floor; a pixel whose mixture density is below exp(floor) counts
  // as a floor hit.
  float floor_log_density = kDefaultFloorLogDensity;

  std::string validate() const;
};

}  // namespace gmm_mcl
