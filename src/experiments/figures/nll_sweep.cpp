#include "gmm_mcl/experiments/figures/nll_sweep.h"

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "csv_file.h"
#include "gmm_mcl/common/enum_names.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/likelihood.h"

namespace gmm_mcl {
namespace figures {

namespace {

const EnumName<SweepAxis> kSweepAxisNames[] = {
    {"x", SweepAxis::kX}, {"y", SweepAxis::kY}, {"z", SweepAxis::kZ}, {"yaw", SweepAxis::kYaw}};

}  // namespace

const char* sweepAxisName(SweepAxis axis) { return enumNameOf(axis, kSweepAxisNames); }

std::string NllSweepParams::validate() const {
  std::ostringstream err;
  if (!(step_m > 0.0)) err << "step_m must be > 0; ";
  if (!(step_rad > 0.0)) err << "step_rad must be > 0; ";
  if (!(half_range_m >= 0.0)) err << "half_range_m must be >= 0; ";
  if (!(half_range_rad >= 0.0)) err << "half_range_rad must be >= 0; ";
  if (step_m > 0.0 && half_range_m / step_m > 10000) err << "more than 10000 steps in x/y/z; ";
  if (step_rad > 0.0 && half_range_rad / step_rad > 10000) err << "more than 10000 yaw steps; ";
  const std::string m = measurement.validate();
  if (!m.empty()) err << "measurement: " << m;
  return err.str();
}

std::vector<double> sweepOffsets(double half_range, double step) {
  // A small slack so that a half range that is a multiple of the step includes its end.
  const int k = static_cast<int>(std::floor(half_range / step + 1e-9));
  std::vector<double> out;
  for (int i = -k; i <= k; ++i) out.push_back(i * step);
  return out;
}

std::vector<NllSweepRow> nllSweep(const GmmMap& map, const DepthFrame& frame,
                                  const Eigen::Isometry3d& T_map_base,
                                  const Eigen::Isometry3d& T_base_cam,
                                  const NllSweepParams& params) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw std::invalid_argument("nll sweep parameters: " + fault);
  double roll, pitch, yaw;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  const Particle truth = poseToParticle(T_map_base);

  std::vector<NllSweepRow> rows;
  std::vector<Eigen::Isometry3d> poses;  // camera poses, one per row
  for (SweepAxis axis : kAllSweepAxes) {
    const bool angular = axis == SweepAxis::kYaw;
    for (double off : angular ? sweepOffsets(params.half_range_rad, params.step_rad)
                              : sweepOffsets(params.half_range_m, params.step_m)) {
      Particle p = truth;
      if (axis == SweepAxis::kX) p.x_m += off;
      if (axis == SweepAxis::kY) p.y_m += off;
      if (axis == SweepAxis::kZ) p.z_m += off;
      if (axis == SweepAxis::kYaw) p.yaw_rad = wrapAngle(p.yaw_rad + off);
      NllSweepRow row;
      row.axis = axis;
      row.offset = off;
      rows.push_back(row);
      poses.push_back(particleToPose(p, roll, pitch) * T_base_cam);
    }
  }

  const std::vector<ComponentF>& packed = map.packed();
  const int n = static_cast<int>(rows.size());
#pragma omp parallel
  {
    LikelihoodScratch scratch;
#pragma omp for schedule(dynamic)
    for (int i = 0; i < n; ++i) {
      const FrameLikelihood a =
          poseLogLikelihood(packed, frame, toRigidF(poses[i]), params.measurement, &scratch);
      rows[i].approx_nll = -a.log_likelihood;
      rows[i].pixels = a.pixels;
      rows[i].approx_floor_hits = a.floor_hits;
      rows[i].approx_evaluations = a.evaluations;
    }
  }
  for (int i = 0; i < n; ++i) {
    if (!params.exact) {
      rows[i].exact_nll = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    // Parallel over pixels inside.
    const FrameLikelihood e = exactFrameLogLikelihood(map, frame, poses[i], params.measurement);
    rows[i].exact_nll = -e.log_likelihood;
    rows[i].exact_floor_hits = e.floor_hits;
    rows[i].exact_evaluations = e.evaluations;
  }
  return rows;
}

void writeNllSweepCsv(const std::vector<NllSweepRow>& rows, const std::string& path) {
  const char* header =
      "axis,offset,unit,pixels,approx_nll,exact_nll,approx_nll_per_px,exact_nll_per_px,"
      "approx_floor_hits,exact_floor_hits,approx_evaluations,exact_evaluations";
  writeCsvFile(path, header, 10, [&rows](std::ostream& out) {
    for (const NllSweepRow& r : rows) {
      const double px = r.pixels > 0 ? r.pixels : 1;
      out << sweepAxisName(r.axis) << ',' << r.offset << ','
          << (r.axis == SweepAxis::kYaw ? "rad" : "m") << ',' << r.pixels << ',' << r.approx_nll
          << ',' << r.exact_nll << ',' << r.approx_nll / px << ',' << r.exact_nll / px << ','
          << r.approx_floor_hits << ',' << r.exact_floor_hits << ',' << r.approx_evaluations << ','
          << r.exact_evaluations << '\n';
    }
  });
}

}  // namespace figures
}  // namespace gmm_mcl
