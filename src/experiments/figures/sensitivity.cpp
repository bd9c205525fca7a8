#include "gmm_mcl/experiments/figures/sensitivity.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>

#include "csv_file.h"
#include "gmm_mcl/common/enum_names.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/sim/step_input.h"

namespace gmm_mcl {
namespace figures {

namespace {

const EnumName<InitMode> kInitModeNames[] = {{"local", InitMode::kLocal},
                                             {"global", InitMode::kGlobal}};

}  // namespace

bool parseInitMode(const std::string& name, InitMode* out) {
  return parseEnumName(name, kInitModeNames, out);
}

const char* initModeName(InitMode mode) { return enumNameOf(mode, kInitModeNames); }

RunTrace runFilter(const Scenario& scenario, const SensorInputs& inputs, const GmmMap& map,
                   const FilterRunParams& params, uint64_t filter_seed) {
  const int n = scenario.size();
  if (static_cast<int>(inputs.T_odom_base.size()) != n) {
    throw std::invalid_argument("runFilter: sensor inputs and scenario differ in length");
  }
  RunTrace trace;
  if (n == 0) return trace;
  LocalizerParams lp = params.localizer;
  lp.T_base_cam = scenario.T_base_cam;
  lp.filter.seed = filter_seed;
  const Particle start = poseToParticle(scenario.T_map_base[0]);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.half_extent_m.setConstant(params.global_half_extent_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  lp.init.yaw_half_range_rad = params.global_yaw_half_range_rad;
  Localizer loc(lp, map);  // uniform over lp.init: the global start and the recovery region
  if (params.init == InitMode::kLocal) {
    loc.resetToPose(start, Eigen::Vector4d(params.local_sigma_m, params.local_sigma_m,
                                           params.local_sigma_m, params.local_sigma_yaw_rad));
  }
  double total_ms = 0.0;
  for (int f = 0; f < n; ++f) {
    const StepResult r = loc.step(sim::frameInput(f / scenario.frame_rate_hz, inputs.T_odom_base[f],
                                                  inputs.roll_rad[f], inputs.pitch_rad[f],
                                                  scenario.depth[f], scenario.intrinsics));
    total_ms += r.timings.total_ms;
    trace.posterior.push_back(stateGaussian(r.estimate));
    const Particle truth = poseToParticle(scenario.T_map_base[f]);
    const Particle& est = r.estimate.mean;
    trace.error_m.push_back(std::sqrt(std::pow(est.x_m - truth.x_m, 2) +
                                      std::pow(est.y_m - truth.y_m, 2) +
                                      std::pow(est.z_m - truth.z_m, 2)));
    trace.error_yaw_rad.push_back(std::abs(wrapAngle(est.yaw_rad - truth.yaw_rad)));
  }
  trace.mean_step_ms = total_ms / n;
  return trace;
}

void collectKl(const RunTrace& reference, const RunTrace& run, const std::string& sweep, int value,
               int run_index, uint64_t seed, int eval_from_frame, double regularisation,
               std::vector<KlSample>* out) {
  const int n = static_cast<int>(std::min(reference.posterior.size(), run.posterior.size()));
  for (int f = std::max(0, eval_from_frame); f < n; ++f) {
    const double kl = stateKl(reference.posterior[f], run.posterior[f], regularisation);
    out->push_back(KlSample{sweep, value, run_index, seed, f, kl, run.error_m[f]});
  }
}

namespace {

double sampleVariance(const std::vector<double>& v) {
  if (v.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= v.size();
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return ss / (v.size() - 1);
}

// The reference run's row: one run, its own error and step time, no KL.
KlSummary referenceRow(const std::string& sweep_name, int value, const RunTrace& reference,
                       const SweepParams& sweep) {
  KlSummary ref;
  ref.sweep = sweep_name;
  ref.value = value;
  ref.runs = 1;
  ref.mean_step_ms = reference.mean_step_ms;
  double err = 0.0;
  int counted = 0;
  for (size_t f = std::max(0, sweep.eval_from_frame); f < reference.error_m.size(); ++f) {
    err += reference.error_m[f];
    ++counted;
  }
  ref.frames = counted;
  ref.mean_error_m = counted ? err / counted : 0.0;
  return ref;
}

}  // namespace

KlSummary summarise(const std::vector<KlSample>& samples, const std::string& sweep, int value) {
  KlSummary s;
  s.sweep = sweep;
  s.value = value;
  std::map<int, std::vector<double>> by_frame;
  std::map<int, bool> runs;
  std::vector<double> all;
  double err = 0.0;
  for (const KlSample& k : samples) {
    if (k.sweep != sweep || k.value != value) continue;
    by_frame[k.frame].push_back(k.kl);
    runs[k.run] = true;
    all.push_back(k.kl);
    err += k.error_m;
  }
  s.runs = static_cast<int>(runs.size());
  s.frames = static_cast<int>(by_frame.size());
  if (all.empty()) return s;
  double var_sum = 0.0;
  for (const auto& f : by_frame) var_sum += sampleVariance(f.second);
  s.variance_kl = var_sum / by_frame.size();
  s.pooled_variance_kl = sampleVariance(all);
  double mean = 0.0;
  for (double x : all) mean += x;
  s.mean_kl = mean / all.size();
  std::vector<double> sorted = all;
  std::sort(sorted.begin(), sorted.end());
  const size_t m = sorted.size();
  s.median_kl = m % 2 ? sorted[m / 2] : 0.5 * (sorted[m / 2 - 1] + sorted[m / 2]);
  s.mean_error_m = err / all.size();
  return s;
}

std::vector<KlSummary> particleSweep(const Scenario& scenario, const SensorInputs& inputs,
                                     const GmmMap& map, const FilterRunParams& run_params,
                                     const std::vector<int>& particle_counts,
                                     int reference_particles, const SweepParams& sweep,
                                     std::vector<KlSample>* samples,
                                     const SweepProgress& progress) {
  FilterRunParams ref_params = run_params;
  ref_params.localizer.filter.num_particles = reference_particles;
  if (progress) progress("reference N=" + std::to_string(reference_particles));
  const RunTrace reference = runFilter(scenario, inputs, map, ref_params, sweep.reference_seed);
  std::vector<KlSummary> out;
  for (int count : particle_counts) {
    FilterRunParams p = run_params;
    p.localizer.filter.num_particles = count;
    double ms = 0.0;
    for (int r = 0; r < sweep.runs; ++r) {
      const uint64_t seed = sweep.first_seed + r;
      if (progress) progress("N=" + std::to_string(count) + " run " + std::to_string(r + 1));
      const RunTrace t = runFilter(scenario, inputs, map, p, seed);
      ms += t.mean_step_ms;
      collectKl(reference, t, "particles", count, r, seed, sweep.eval_from_frame,
                sweep.regularisation, samples);
    }
    KlSummary s = summarise(*samples, "particles", count);
    s.mean_step_ms = sweep.runs > 0 ? ms / sweep.runs : 0.0;
    out.push_back(s);
  }
  KlSummary ref = referenceRow("particles", reference_particles, reference, sweep);
  out.push_back(ref);  // the reference row: its own error and step time, no KL
  return out;
}

std::vector<KlSummary> componentSweep(const Scenario& scenario, const SensorInputs& inputs,
                                      const std::vector<GmmMap>& maps,
                                      const std::vector<int>& counts, const GmmMap& reference_map,
                                      int reference_particles, const FilterRunParams& run_params,
                                      const SweepParams& sweep, std::vector<KlSample>* samples,
                                      const SweepProgress& progress) {
  if (maps.size() != counts.size()) {
    throw std::invalid_argument("componentSweep: maps and counts differ in length");
  }
  FilterRunParams ref_params = run_params;
  ref_params.localizer.filter.num_particles = reference_particles;
  if (progress) {
    progress("reference M=" + std::to_string(reference_map.size()) +
             " N=" + std::to_string(reference_particles));
  }
  const RunTrace reference =
      runFilter(scenario, inputs, reference_map, ref_params, sweep.reference_seed);
  std::vector<KlSummary> out;
  for (size_t i = 0; i < maps.size(); ++i) {
    double ms = 0.0;
    for (int r = 0; r < sweep.runs; ++r) {
      const uint64_t seed = sweep.first_seed + r;
      if (progress) progress("M=" + std::to_string(counts[i]) + " run " + std::to_string(r + 1));
      const RunTrace t = runFilter(scenario, inputs, maps[i], run_params, seed);
      ms += t.mean_step_ms;
      collectKl(reference, t, "components", counts[i], r, seed, sweep.eval_from_frame,
                sweep.regularisation, samples);
    }
    KlSummary s = summarise(*samples, "components", counts[i]);
    s.mean_step_ms = sweep.runs > 0 ? ms / sweep.runs : 0.0;
    out.push_back(s);
  }
  out.push_back(
      referenceRow("components", static_cast<int>(reference_map.size()), reference, sweep));
  return out;
}

void writeKlSamplesCsv(const std::vector<KlSample>& samples, const std::string& path) {
  writeCsvFile(path, "sweep,value,run,seed,frame,kl,error_m", 10, [&samples](std::ostream& out) {
    for (const KlSample& s : samples) {
      out << s.sweep << ',' << s.value << ',' << s.run << ',' << s.seed << ',' << s.frame << ','
          << s.kl << ',' << s.error_m << '\n';
    }
  });
}

void writeKlSummaryCsv(const std::vector<KlSummary>& rows, const std::string& path) {
  const char* header =
      "sweep,value,runs,frames,variance_kl,log10_variance_kl,pooled_variance_kl,mean_kl,"
      "median_kl,mean_error_m,mean_step_ms";
  writeCsvFile(path, header, 8, [&rows](std::ostream& out) {
    for (const KlSummary& r : rows) {
      const bool has_kl = r.runs > 1 && r.variance_kl > 0.0;
      out << r.sweep << ',' << r.value << ',' << r.runs << ',' << r.frames << ',';
      if (has_kl) {
        out << r.variance_kl << ',' << std::log10(r.variance_kl) << ',' << r.pooled_variance_kl
            << ',' << r.mean_kl << ',' << r.median_kl;
      } else {
        out << ",,,,";  // the reference row, or a single run: no variance
      }
      out << ',' << r.mean_error_m << ',' << r.mean_step_ms << '\n';
    }
  });
}

std::string klSummaryMarkdown(const std::vector<KlSummary>& rows) {
  std::string md =
      "| sweep | value | runs | Var KL (mean over frames) | log10 | mean KL | median KL | "
      "mean error (cm) | step (ms) |\n|---|---|---|---|---|---|---|---|---|\n";
  char line[512];
  for (const KlSummary& r : rows) {
    const bool has_kl = r.runs > 1 && r.variance_kl > 0.0;
    if (has_kl) {
      std::snprintf(line, sizeof(line),
                    "| %s | %d | %d | %.3g | %.2f | %.3g | %.3g | %.2f | %.0f |\n", r.sweep.c_str(),
                    r.value, r.runs, r.variance_kl, std::log10(r.variance_kl), r.mean_kl,
                    r.median_kl, 100.0 * r.mean_error_m, r.mean_step_ms);
    } else {
      std::snprintf(line, sizeof(line),
                    "| %s | %d (reference) | %d | - | - | - | - | %.2f | %.0f |\n", r.sweep.c_str(),
                    r.value, r.runs, 100.0 * r.mean_error_m, r.mean_step_ms);
    }
    md += line;
  }
  return md;
}

}  // namespace figures
}  // namespace gmm_mcl
