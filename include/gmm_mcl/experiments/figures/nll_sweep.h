// Paper Fig. 2 as data: the frame negative log-likelihood of camera poses displaced from the true
// pose along x, y, z (map frame) and yaw, with the paper's approximation (patch membership) and
// the exact sum over all components.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {
namespace figures {

enum class SweepAxis { kX, kY, kZ, kYaw };
const char* sweepAxisName(SweepAxis axis);
constexpr SweepAxis kAllSweepAxes[4] = {SweepAxis::kX, SweepAxis::kY, SweepAxis::kZ,
                                        SweepAxis::kYaw};

struct NllSweepParams {
  double half_range_m = 0.5;  // x, y, z offsets in [-half_range_m, half_range_m]
  double step_m = 0.025;
  double half_range_rad = 0.5;  // yaw offsets
  double step_rad = 0.025;
  bool exact = true;  // also evaluate the exact likelihood (all components, double)
  MeasurementParams measurement;

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

struct NllSweepRow {
  SweepAxis axis = SweepAxis::kX;
  double offset = 0.0;      // m (x, y, z) or rad (yaw)
  double approx_nll = 0.0;  // nats, whole frame
  double exact_nll = 0.0;   // nats; NaN when not evaluated
  int pixels = 0;
  int approx_floor_hits = 0;
  int exact_floor_hits = 0;
  long long approx_evaluations = 0;  // Gaussian evaluations
  long long exact_evaluations = 0;
};

// Offsets of one axis: 0 and +-k * step up to the half range, ascending.
std::vector<double> sweepOffsets(double half_range, double step);

// Displaces the true base pose T_map_base in its 4-DoF state (x, y, z in the map frame, yaw
// about map z; roll and pitch kept) and evaluates the frame (camera optical points) at each
// camera pose T_map_base' * T_base_cam. Rows ordered by axis, then offset.
std::vector<NllSweepRow> nllSweep(const GmmMap& map, const DepthFrame& frame,
                                  const Eigen::Isometry3d& T_map_base,
                                  const Eigen::Isometry3d& T_base_cam,
                                  const NllSweepParams& params);

// CSV: axis,offset,unit,pixels,approx_nll,exact_nll,approx_nll_per_px,exact_nll_per_px,
// approx_floor_hits,exact_floor_hits,approx_evaluations,exact_evaluations. Throws
// std::runtime_error when the file cannot be written.
void writeNllSweepCsv(const std::vector<NllSweepRow>& rows, const std::string& path);

}  // namespace figures
}  // namespace gmm_mcl
