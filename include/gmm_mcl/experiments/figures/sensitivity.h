// The paper's Sensitivity Analysis (Sec. Results): filters with fewer particles N (or a map with
// fewer components M) against a ground-truth filter (N = 16200; or the M = 2500 map), compared
// through the KL divergence of their particle sets, each taken as a unimodal Gaussian over
// (x, y, z, yaw) after convergence; the variance of that divergence over repeated runs.
//
// Definition used (docs/evaluation.md): every run sees the same frames, odometry and attitude
// (one data seed); runs differ in the filter seed only. At each evaluated frame t (t >=
// eval_from_frame) KL_{r,t} = KL(G_ref,t || G_r,t), G = the Gaussian of the posterior particle
// set after the frame's update (weighted, before resampling). The reported variance is the
// across-run sample variance of KL_{r,t}, averaged over the evaluated frames.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gmm_mcl/experiments/figures/gaussian_kl.h"
#include "gmm_mcl/experiments/figures/scenario.h"
#include "gmm_mcl/filter/params.h"

namespace gmm_mcl {
namespace figures {

enum class InitMode {
  kLocal,   // Gaussian around the true start (local_sigma_m per axis, local_sigma_yaw_rad)
  kGlobal,  // uniform over the protocol's 4 m cube and yaw range of pi around the true start
};
bool parseInitMode(const std::string& name, InitMode* out);
const char* initModeName(InitMode mode);

struct FilterRunParams {
  LocalizerParams localizer;  // num_particles, stride, weighting; init region set per run
  InitMode init = InitMode::kLocal;
  double local_sigma_m = 0.2;
  double local_sigma_yaw_rad = 0.2;
  double global_half_extent_m = 2.0;  // also the recovery region in both modes
  double global_yaw_half_range_rad = 0.5 * M_PI;
};

struct RunTrace {
  std::vector<StateGaussian> posterior;  // per frame
  std::vector<double> error_m;           // |mean - truth| per frame
  std::vector<double> error_yaw_rad;
  double mean_step_ms = 0.0;
};

// One seeded filter run over the scenario with the given map (in the scenario's map frame).
RunTrace runFilter(const Scenario& scenario, const SensorInputs& inputs, const GmmMap& map,
                   const FilterRunParams& params, uint64_t filter_seed);

struct KlSample {
  std::string sweep;  // "particles" or "components"
  int value = 0;      // N or M
  int run = 0;
  uint64_t seed = 0;
  int frame = 0;
  double kl = 0.0;
  double error_m = 0.0;
};

struct KlSummary {
  std::string sweep;
  int value = 0;
  int runs = 0;
  int frames = 0;                   // evaluated frames
  double variance_kl = 0.0;         // across-run variance per frame, mean over frames (the measure)
  double pooled_variance_kl = 0.0;  // variance over all (run, frame) samples
  double mean_kl = 0.0;
  double median_kl = 0.0;
  double mean_error_m = 0.0;  // over evaluated frames and runs
  double mean_step_ms = 0.0;
};

// Summaries of samples of one (sweep, value) with `runs` runs; samples of other values ignored.
KlSummary summarise(const std::vector<KlSample>& samples, const std::string& sweep, int value);

// KL samples of runs against a reference trace over frames [eval_from_frame, size).
void collectKl(const RunTrace& reference, const RunTrace& run, const std::string& sweep, int value,
               int run_index, uint64_t seed, int eval_from_frame, double regularisation,
               std::vector<KlSample>* out);

struct SweepParams {
  int runs = 5;
  uint64_t first_seed = 1;  // runs use seeds first_seed .. first_seed + runs - 1
  uint64_t reference_seed = 1000003;
  int eval_from_frame = 30;      // the paper evaluates after convergence
  double regularisation = 1e-8;  // added to covariance diagonals (m^2, rad^2) before KL
};

using SweepProgress = std::function<void(const std::string& what)>;

// Particle sweep: a reference run with reference_particles, then `runs` runs for each count.
std::vector<KlSummary> particleSweep(const Scenario& scenario, const SensorInputs& inputs,
                                     const GmmMap& map, const FilterRunParams& run_params,
                                     const std::vector<int>& particle_counts,
                                     int reference_particles, const SweepParams& sweep,
                                     std::vector<KlSample>* samples,
                                     const SweepProgress& progress = nullptr);

// Component sweep: maps[i] has counts[i] components; reference run on reference_map with
// reference_particles; `runs` runs with run_params' particle count on every map.
std::vector<KlSummary> componentSweep(const Scenario& scenario, const SensorInputs& inputs,
                                      const std::vector<GmmMap>& maps,
                                      const std::vector<int>& counts, const GmmMap& reference_map,
                                      int reference_particles, const FilterRunParams& run_params,
                                      const SweepParams& sweep, std::vector<KlSample>* samples,
                                      const SweepProgress& progress = nullptr);

// Writers: every sample (sweep,value,run,seed,frame,kl,error_m) and the summaries (CSV and a
// markdown table).
void writeKlSamplesCsv(const std::vector<KlSample>& samples, const std::string& path);
void writeKlSummaryCsv(const std::vector<KlSummary>& rows, const std::string& path);
std::string klSummaryMarkdown(const std::vector<KlSummary>& rows);

}  // namespace figures
}  // namespace gmm_mcl
