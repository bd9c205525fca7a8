// gmm_mcl_bench: the DESIGN.md benchmark workloads (paper, cpu, full, scale, large, building) on
// both backends. Per (backend, workload): warm-up frames, then timed updates (frame preparation +
// backend), median updates per second, per-stage milliseconds, Gaussian evaluations per update
// and per second, for CUDA the likelihood kernel's fraction of the GPU's FP32 peak, and the
// relative error of the backend's log-likelihood against the exact sum (every component, double
// precision) at a few particles. One table out.
// --step: the whole filter step per stage instead (predict, frame preparation, likelihood,
// weights, estimate, resampling, recovery, lost detector), the particle set on the host
// (ParticleFilter) and, with CUDA, on the device (CudaParticleFilter); and the localizer's own
// step (Localizer::step with its stage times) with either filter.
#include <omp.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_tool.h"
#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace bench {
namespace {

bool exists(const std::string& p) {
  struct stat st;
  return !p.empty() && stat(p.c_str(), &st) == 0;
}

const char* kUsage =
    "gmm_mcl_bench [options]\n"
    "  --backend cpu|cuda|all      (all: cpu, and cuda when built and a device is present)\n"
    "  --workload paper|cpu|full|scale|large|building|all   (comma-separated list accepted)\n"
    "  --map FILE                  GMM map (default $GMM_MCL_MAP, "
    "build/maps/7scenes_redkitchen_m1000.gmm)\n"
    "  --large-map FILE            the `large` workload's M=4000 map of the same scene (default\n"
    "                              $GMM_MCL_LARGE_MAP, build/maps/7scenes_redkitchen_m4000.gmm)\n"
    "  --building-map FILE         the `building` workload's map of the building world (M about\n"
    "                              100,000; default $GMM_MCL_BUILDING_DIR/building_s1.gmm,\n"
    "                              GMM_MCL_BUILDING_DIR defaulting to build/building, where\n"
    "                              scripts/make_building.sh writes it)\n"
    "  --building-dataset DIR      its frames: a TUM RGB-D folder of that building (needs libpng;\n"
    "                              default $GMM_MCL_BUILDING_DIR/building_s1_walk1)\n"
    "  --building-frames-raw FILE  its frames as a raw file (--export-building-frames writes one)\n"
    "                              `building` named in --workload: missing inputs are an error;\n"
    "                              listed by `all`, the workload is skipped with the reason\n"
    "  --patch PX                  membership patch size (default 32)\n"
    "  --exact N --exact-frames F  relative error against the exact sum at N particles (the\n"
    "                              true pose first) of the first F timed frames (2, 2; 0: off)\n"
    "  --frames-dir DIR            7-Scenes sequence folder (needs libpng)\n"
    "  --frames-raw FILE           raw frame file (bench --export-frames writes one)\n"
    "  --synthetic                 synthetic box scene and its map instead of 7-Scenes\n"
    "  --frames N (100) --warmup N (3) --budget-s S (20) --min-timed N (3)\n"
    "  --threads N (CPU)  --num-particles N (override; --particles also)  --seed S\n"
    "  --spread-m M (0.5) --spread-rad R (0.3)\n"
    "  --cuda-host-prep            CUDA: prepare frames on the host and upload the points\n"
    "                              (default: the raw image is uploaded and prepared on the GPU)\n"
    "  --export-frames FILE        write the loaded frames as a raw file and exit\n"
    "  --export-building-frames FILE  write the building's frames as a raw file and exit\n"
    "  --no-depth-noise            the paper's model: no depth-noise convolution (one evaluation\n"
    "                              form for all particles)\n"
    "  --step                      the whole filter step per stage at each workload's N (scale:\n"
    "                              100,000; cpu: 1068; not `large`): the particle set on the\n"
    "                              host and, with CUDA, on the GPU; then Localizer::step with\n"
    "                              either filter\n"
    "  --cuda-likelihood-shape GxP, --cuda-band-patches N, ...: the CUDA backend's tuning (the\n"
    "                              parameter table's cuda_* parameters, listed under --help)\n";

Options parseOptions(int argc, char** argv) {
  Options opt;
  cli::CommandLine cl("gmm_mcl_bench", kUsage);
  // clang-format off
  cl.flags({{"backend", &opt.backends}, {"workload", &opt.workloads}, {"map", &opt.map_path},
            {"large-map", &opt.large_map_path}, {"building-map", &opt.building_map_path},
            {"building-dataset", &opt.building_dataset},
            {"building-frames-raw", &opt.building_frames_raw},
            {"export-building-frames", &opt.export_building_frames}, {"patch", &opt.patch_px},
            {"exact", &opt.exact_particles}, {"exact-frames", &opt.exact_frames},
            {"frames-dir", &opt.frames_dir}, {"frames-raw", &opt.frames_raw},
            {"export-frames", &opt.export_frames}, {"frames", &opt.frames}, {"warmup", &opt.warmup},
            {"budget-s", &opt.budget_s}, {"min-timed", &opt.min_timed}, {"threads", &opt.threads},
            {"num-particles", &opt.particles}, {"seed", &opt.seed},
            {"no-depth-noise", cli::Clear{&opt.depth_noise}}, {"spread-m", &opt.spread_m},
            {"spread-rad", &opt.spread_rad}, {"synthetic", &opt.synthetic},
            {"cuda-host-prep", &opt.cuda_host_prep}, {"step", &opt.step}});
  // clang-format on
  cl.alias("particles", "num-particles");
  LocalizerParams tuning;  // only its cuda_* group is read
  cl.addLocalizerParams(&tuning, {}, {"cuda"});
  cl.parse(argc, argv);
  opt.cuda = tuning.cuda;
  if (opt.frames < 1 || opt.warmup < 0) throw std::invalid_argument("--frames >= 1, --warmup >= 0");
  if (opt.patch_px < 1) throw std::invalid_argument("--patch must be >= 1");
  if (opt.exact_particles < 0 || opt.exact_frames < 0) {
    throw std::invalid_argument("--exact and --exact-frames must be >= 0");
  }
  if (opt.workloads != "all") {
    size_t pos = 0;
    while (pos <= opt.workloads.size()) {
      const size_t comma = opt.workloads.find(',', pos);
      const std::string item =
          opt.workloads.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
      bool known = false;
      for (const Workload& w : kWorkloads) known |= item == w.name;
      if (!known) {
        throw std::invalid_argument("--workload: unknown workload '" + item +
                                    "' (paper, cpu, full, scale, large, building or all)");
      }
      if (comma == std::string::npos) break;
      pos = comma + 1;
    }
  }
  return opt;
}

// Whether a listed workload runs on `input`.
bool wanted(const Options& opt, WorkloadInput input) {
  for (const Workload& w : kWorkloads) {
    if (w.input == input && listed(opt.workloads, w.name)) return true;
  }
  return false;
}

// The 7-Scenes M=1000 map and frames, else the synthetic scene (said so in the output);
// *map_source names the map.
void loadData(Options* opt_io, GmmMap* map, FrameSet* frames, std::string* map_source) {
  Options& opt = *opt_io;
  const char* env_ds = std::getenv("GMM_MCL_DATASETS");
  const std::string default_dir =
      std::string(env_ds && *env_ds ? env_ds : "../shared/datasets") + "/7scenes_redkitchen/data";
  const char* env_map = std::getenv("GMM_MCL_MAP");
  if (opt.map_path.empty()) {
    if (env_map && *env_map)
      opt.map_path = env_map;
    else if (exists("build/maps/7scenes_redkitchen_m1000.gmm"))
      opt.map_path = "build/maps/7scenes_redkitchen_m1000.gmm";
  }
  if (!opt.synthetic) {
    if (!opt.frames_raw.empty()) {
      *frames = bench::loadFrameSet(opt.frames_raw);
      if (static_cast<int>(frames->images.size()) > opt.frames) {
        frames->images.resize(opt.frames);
        frames->T_map_cam.resize(opt.frames);
      }
    } else {
      const std::string dir = opt.frames_dir.empty() ? default_dir : opt.frames_dir;
#if defined(GMM_MCL_HAVE_PNG)
      if (exists(dir + "/frame-000000.depth.png"))
        *frames = bench::loadSevenScenes(dir, 0, opt.frames);
#endif
      if (frames->images.empty() && !opt.frames_dir.empty()) {
        throw std::runtime_error("cannot read 7-Scenes frames from " + dir);
      }
    }
    if (!frames->images.empty() && exists(opt.map_path)) {
      *map = loadMap(opt.map_path);
      *map_source = opt.map_path;
    } else {
      std::printf("# 7-Scenes map or frames absent (map '%s'): using the synthetic scene\n",
                  opt.map_path.c_str());
      *frames = FrameSet();
    }
  }
  if (frames->images.empty()) {
    makeSyntheticScene(std::min(opt.frames, 100), map, frames);
    *map_source = "synthetic box scene (tiled)";
  }
}

// The `large` workload's map: the same scene fitted with M=4000 (DESIGN.md), only with the
// 7-Scenes frames. Sets data->large_absent to why it is absent ("" when loaded or not wanted).
void loadLargeMap(Options* opt_io, BenchData* data) {
  Options& opt = *opt_io;
  std::string& large_absent = data->large_absent;
  if (wanted(opt, WorkloadInput::kLargeMap) && !opt.step) {
    const char* env_large = std::getenv("GMM_MCL_LARGE_MAP");
    if (opt.large_map_path.empty()) {
      opt.large_map_path =
          env_large && *env_large ? env_large : "build/maps/7scenes_redkitchen_m4000.gmm";
    }
    if (data->map_source.compare(0, 9, "synthetic") == 0) {
      large_absent = "the synthetic scene has no M=4000 map";
    } else if (!exists(opt.large_map_path)) {
      large_absent = "no map at '" + opt.large_map_path +
                     "' (scripts/build_map_7scenes.sh with -m 4000, see docs/benchmark.md)";
    } else {
      data->large_map = loadMap(opt.large_map_path);
      std::printf("# large: map %s (M = %zu)\n", opt.large_map_path.c_str(),
                  data->large_map.size());
    }
    if (!large_absent.empty()) std::printf("# large: skipped (%s)\n", large_absent.c_str());
  }
}

// The `building` workload's map and frames: the building world of scripts/make_building.sh (a
// ~100,000-component map of 36 rooms, the camera in one), its first --frames frames. Named in
// --workload (or with --export-building-frames), a missing input is an error; listed by `all`,
// the workload is skipped with the reason (data->building_absent).
void loadBuilding(Options* opt_io, BenchData* data) {
  Options& opt = *opt_io;
  const bool exporting = !opt.export_building_frames.empty();
  if (!exporting && !wanted(opt, WorkloadInput::kBuilding)) return;
  const char* env_dir = std::getenv("GMM_MCL_BUILDING_DIR");
  const std::string dir = env_dir && *env_dir ? env_dir : "build/building";
  if (opt.building_map_path.empty()) opt.building_map_path = dir + "/building_s1.gmm";
  if (opt.building_dataset.empty()) opt.building_dataset = dir + "/building_s1_walk1";
  const std::string hint =
      " (scripts/make_building.sh writes the building world; see docs/benchmark.md)";
  std::string& absent = data->building_absent;
  if (!exporting && !exists(opt.building_map_path)) {
    absent = "no map at '" + opt.building_map_path + "'; give --building-map FILE" + hint;
  } else if (!opt.building_frames_raw.empty()) {
    if (!exists(opt.building_frames_raw)) {
      absent = "no frame file at '" + opt.building_frames_raw + "' (--building-frames-raw)";
    }
  } else if (!exists(opt.building_dataset + "/depth.txt")) {
    absent = "no TUM RGB-D folder at '" + opt.building_dataset +
             "'; give --building-dataset DIR or --building-frames-raw FILE" + hint;
  } else {
#if !defined(GMM_MCL_HAVE_PNG)
    absent = "built without libpng: cannot read the depth PNGs of '" + opt.building_dataset +
             "'; give --building-frames-raw FILE (--export-building-frames writes one)";
#endif
  }
  if (!absent.empty()) {
    if (exporting || opt.workloads != "all") throw std::runtime_error("building: " + absent);
    std::printf("# building: skipped (%s)\n", absent.c_str());
    return;
  }
  FrameSet& frames = data->building_frames;
  if (!opt.building_frames_raw.empty()) {
    frames = loadFrameSet(opt.building_frames_raw);
    if (static_cast<int>(frames.images.size()) > opt.frames) {
      frames.images.resize(opt.frames);
      frames.T_map_cam.resize(opt.frames);
    }
    if (frames.images.empty()) {
      throw std::runtime_error("building: no frames in " + opt.building_frames_raw);
    }
  } else {
    frames = loadTumFrames(opt.building_dataset, 0, opt.frames);
  }
  if (exporting) return;
  data->building_map = loadMap(opt.building_map_path);
  std::printf("# building: map %s (M = %zu), frames: %s (%zu)\n", opt.building_map_path.c_str(),
              data->building_map.size(), frames.source.c_str(), frames.images.size());
}

// The run's settings and the host, as comment lines.
void printSettings(const Options& opt) {
  std::printf(
      "# patches %dx%d px; relative error against the exact sum at %d particle(s) of "
      "the first %d timed frame(s)\n",
      opt.patch_px, opt.patch_px, opt.exact_particles, opt.exact_frames);
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) == 3) {
    std::printf(
        "# host load average %.2f %.2f %.2f on %d CPUs (CPU ms/update = process CPU time, "
        "all threads, per update)\n",
        load[0], load[1], load[2], omp_get_num_procs());
  }
  std::printf(
      "# particles: uniform +-%.2f m per axis and +-%.2f rad of yaw around the true camera "
      "pose (particle 0 = the true pose), seed %u\n",
      opt.spread_m, opt.spread_rad, opt.seed);
  std::printf(
      "# timing: %d warm-up updates, then up to %d timed (>= %d, stop after %.0f s); "
      "update = frame preparation + backend (wall clock); medians. CUDA stage times are "
      "events; transfer = upload + download\n",
      opt.warmup, opt.frames, opt.min_timed, opt.budget_s);
}

struct Candidate {
  std::unique_ptr<LikelihoodBackend> backend;
  double peak = 0.0;  // FP32 peak, GFLOP/s (a device backend)
};

// The listed backends that can run here (each said on stdout), made by the core's factory.
std::vector<Candidate> makeBackends(const Options& opt) {
  BackendOptions options;
  options.cpu_threads = opt.threads;
  options.cuda = opt.cuda;
  std::vector<Candidate> backends;
  if (listed(opt.backends, "cpu")) {
    Candidate c;
    c.backend = makeBackend("cpu", nullptr, options);
    std::printf("# cpu: %d OpenMP threads\n",
                opt.threads > 0 ? opt.threads : omp_get_max_threads());
    backends.push_back(std::move(c));
  }
  if (listed(opt.backends, "cuda")) {
    std::string why;
    Candidate c;
    c.backend = makeBackend("cuda", &why, options);
    if (const DeviceBackend* device = c.backend->device()) {
      const BackendDeviceInfo& d = device->deviceInfo();
      std::printf(
          "# cuda: %s, sm_%d, %d SMs x %d FP32 lanes at %.2f GHz = %.1f TFLOP/s FP32 peak; "
          "%g FLOP counted per evaluation\n",
          d.name.c_str(), d.compute_capability, d.multiprocessors, d.fp32_lanes_per_sm, d.clock_ghz,
          d.fp32_peak_gflops * 1e-3, d.flops_per_evaluation);
      c.peak = d.fp32_peak_gflops;
      backends.push_back(std::move(c));
    } else {
      std::printf("# cuda: skipped (%s)\n", why.c_str());
    }
  }
  return backends;
}

// Every listed workload on every backend, then the table.
void runWorkloads(std::vector<Candidate>* backends, const BenchData& data, const Options& opt) {
  std::vector<Row> rows;
  for (Candidate& c : *backends) {
    const GmmMap* current = nullptr;
    for (const Workload& w : kWorkloads) {
      if (!listed(opt.workloads, w.name) || !data.absent(w).empty()) continue;
      const GmmMap& m = data.mapFor(w);
      if (current != &m) c.backend->setMap(m);
      current = &m;
      try {
        rows.push_back(runWorkload(c.backend.get(), c.peak, w, m, data.framesFor(w), opt));
      } catch (const BackendError& e) {  // e.g. a bitmask beyond the GPU's shared memory
        std::printf("# %s/%s: skipped (%s)\n", c.backend->name().c_str(), w.name, e.what());
        current = nullptr;
        continue;
      }
      const Row& r = rows.back();
      std::fprintf(stderr, "# done %s/%s: %.2f updates/s\n", r.backend.c_str(), r.workload.c_str(),
                   r.updates_per_s);
    }
  }
  printWorkloadTable(rows);
}

int run(int argc, char** argv) {
  Options opt = parseOptions(argc, argv);
  BenchData data;
  // The scene (7-Scenes or synthetic) only where its export or a listed workload needs it.
  const bool exporting = !opt.export_frames.empty() || !opt.export_building_frames.empty();
  const bool scene = exporting ? !opt.export_frames.empty()
                               : wanted(opt, WorkloadInput::kScene) ||
                                     (wanted(opt, WorkloadInput::kLargeMap) && !opt.step);
  if (scene) loadData(&opt, &data.map, &data.frames, &data.map_source);
  if (!opt.export_frames.empty()) {
    saveFrameSet(data.frames, opt.export_frames);
    std::printf("wrote %zu frames to %s\n", data.frames.images.size(), opt.export_frames.c_str());
  }
  if (!opt.export_building_frames.empty()) {
    loadBuilding(&opt, &data);
    saveFrameSet(data.building_frames, opt.export_building_frames);
    std::printf("wrote %zu building frames to %s\n", data.building_frames.images.size(),
                opt.export_building_frames.c_str());
  }
  if (exporting) return 0;
  if (scene) {
    std::printf("# frames: %s (%zu), map: %s (M = %zu)\n", data.frames.source.c_str(),
                data.frames.images.size(), data.map_source.c_str(), data.map.size());
  }
  loadLargeMap(&opt, &data);
  loadBuilding(&opt, &data);
  printSettings(opt);
  std::vector<Candidate> backends = makeBackends(opt);
  if (opt.step) {
    std::vector<LikelihoodBackend*> list;
    for (Candidate& c : backends) list.push_back(c.backend.get());
    runSteps(list, data, opt);
    return 0;
  }
  runWorkloads(&backends, data, opt);
  return 0;
}

}  // namespace
}  // namespace bench
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  return gmm_mcl::cli::reportErrors("gmm_mcl_bench",
                                    [&] { return gmm_mcl::bench::run(argc, argv); });
}
