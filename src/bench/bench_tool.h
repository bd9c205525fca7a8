// gmm_mcl_bench's pieces: the DESIGN.md workloads, the options, the per-workload likelihood
// benchmark (bench_workload.cpp) and the whole filter step per stage (bench_step.cpp).
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/bench/frame_set.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace bench {

// Where a workload's map and frames come from.
enum class WorkloadInput {
  kScene,     // --map and the scene's frames (7-Scenes, --frames-raw, or the synthetic scene)
  kLargeMap,  // the M=4000 map of the same scene (--large-map) and the scene's frames
  kBuilding,  // the building world's map (--building-map) and its own frames (--building-dataset)
};

struct Workload {
  const char* name;
  int particles;
  int stride_px;
  WorkloadInput input;
};
// clang-format off
constexpr Workload kWorkloads[] = {{"paper",    1068,   4, WorkloadInput::kScene},
                                   {"cpu",      1068,   8, WorkloadInput::kScene},
                                   {"full",     1068,   1, WorkloadInput::kScene},
                                   {"scale",    100000, 8, WorkloadInput::kScene},
                                   {"large",    1068,   4, WorkloadInput::kLargeMap},
                                   {"building", 1068,   4, WorkloadInput::kBuilding}};
// clang-format on

struct Options {
  std::string backends = "all";
  std::string workloads = "all";
  std::string map_path;
  std::string large_map_path;
  std::string building_map_path;
  std::string building_dataset;     // a TUM RGB-D folder of the building world
  std::string building_frames_raw;  // or its frames as a raw file (--export-building-frames)
  std::string export_building_frames;
  std::string frames_dir;
  std::string frames_raw;
  std::string export_frames;
  int frames = 100;
  int warmup = 3;
  double budget_s = 20.0;  // timed seconds per (backend, workload), at least min_timed frames
  int min_timed = 3;
  int threads = 0;
  int particles = 0;  // override (--num-particles)
  int patch_px = FrameParams().patch_size_px;
  int exact_particles = 2;  // per checked frame: particle 0 (the true pose) and spread ones
  int exact_frames = 2;     // the first timed frames
  unsigned seed = 1;
  double spread_m = 0.5;
  double spread_rad = 0.3;
  bool synthetic = false;
  bool cuda_host_prep = false;  // CUDA: prepare frames on the host (prepareFrame) and upload points
  bool depth_noise = true;      // the depth-noise model (per-particle evaluation forms)
  bool step = false;            // the whole filter step per stage (--step)
  CudaTuningParams cuda;        // the CUDA backend's tuning (the table's cuda_* flags)
};

// Whether `name` is in the comma-separated list (or the list is "all").
bool listed(const std::string& list, const std::string& name);

// The maps and frames the listed workloads run on. A workload whose own input is missing has
// the reason in absent(w) and is skipped.
struct BenchData {
  GmmMap map;  // the scene's (--map, or the synthetic scene's)
  FrameSet frames;
  std::string map_source;
  GmmMap large_map;
  std::string large_absent;
  GmmMap building_map;
  FrameSet building_frames;
  std::string building_absent;

  const GmmMap& mapFor(const Workload& w) const {
    if (w.input == WorkloadInput::kLargeMap) return large_map;
    if (w.input == WorkloadInput::kBuilding) return building_map;
    return map;
  }
  const FrameSet& framesFor(const Workload& w) const {
    return w.input == WorkloadInput::kBuilding ? building_frames : frames;
  }
  // Why w cannot run ("" when it can).
  const std::string& absent(const Workload& w) const {
    static const std::string kNone;
    if (w.input == WorkloadInput::kLargeMap) return large_absent;
    if (w.input == WorkloadInput::kBuilding) return building_absent;
    return kNone;
  }
};

// The iterations of a timed loop: opt.warmup warm-up ones, then timed ones until opt.frames are
// timed, or at least opt.min_timed once opt.budget_s seconds are.
class TimedLoop {
 public:
  explicit TimedLoop(const Options& opt) : opt_(opt) {}
  // Starts the next iteration; false when the loop is over (timed_s: the seconds timed so far).
  bool next(double timed_s);
  int iteration() const { return it_; }
  bool warm() const { return warm_; }

 private:
  const Options& opt_;
  int it_ = -1;
  bool warm_ = false;
};

struct Row {
  std::string backend, workload;
  int particles = 0, stride = 0, timed = 0;
  double pixels = 0, comps_per_patch = 0, evals_per_update = 0, updates_per_s = 0;
  double prep_ms = 0, membership_ms = 0, likelihood_ms = 0, transfer_ms = 0, total_ms = 0;
  double cpu_ms = 0;  // process CPU time per update (all threads)
  double gevals_per_s = 0, kernel_gevals_per_s = 0, peak_fraction = -1, floor_hit_fraction = 0;
  // |L - L_exact| / |L_exact| of the backend's log-likelihood against the exact sum, at the true
  // pose (worst checked frame) and worst over every checked particle; -1: not checked.
  double rel_err_truth = -1, rel_err_max = -1;
  double visible_components = -1;  // mean after the per-update view cull; -1: not culled
};

// The backend's likelihood on workload w: timed updates (frame preparation + backend), then the
// relative error against the exact sum. fp32_peak_gflops > 0: the CUDA kernel's peak fraction.
Row runWorkload(LikelihoodBackend* backend, double fp32_peak_gflops, const Workload& w,
                const GmmMap& map, const FrameSet& frames, const Options& opt);

// The table of runWorkload rows (markdown, stdout).
void printWorkloadTable(const std::vector<Row>& rows);

// --step: the filter's stages (host filter, and device filter with CUDA) and Localizer::step at
// each listed workload's N on its map and frames (`large` excepted), one table (markdown,
// stdout). Sets each backend's map.
void runSteps(const std::vector<LikelihoodBackend*>& backends, const BenchData& data,
              const Options& opt);

}  // namespace bench
}  // namespace gmm_mcl
