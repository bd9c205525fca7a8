// gmm_mcl_figures: the paper's evaluation figures as data (CSV) for scripts/plot_figures.py.
//   nll-sweep    Fig. 2: frame NLL vs displacement along x, y, z and yaw, approximate vs exact
//   sensitivity  Sec. Sensitivity Analysis: KL-divergence variance vs particle count N and vs
//                component count M against a ground-truth filter
// Runs on 7-Scenes redkitchen when the shared data is found, else on the synthetic box scene.
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/experiments/figures/nll_sweep.h"
#include "gmm_mcl/experiments/figures/scenario.h"
#include "gmm_mcl/experiments/figures/sensitivity.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"
#if defined(GMM_MCL_FIGURES_HAVE_FIT)
#include "gmm_mcl/experiments/figures/map_series.h"
#endif

namespace gmm_mcl {
namespace figures {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

const char* kUsage =
    "usage: gmm_mcl_figures nll-sweep   [common] [--frame F] [--pixel-stride PX (8)]\n"
    "                                   [--range-m R]\n"
    "                                   [--step-m S] [--range-rad R] [--step-rad S] [--no-exact]\n"
    "       gmm_mcl_figures sensitivity [common] [--sweep particles|components|both]\n"
    "                                   [--particles-list 50,100,...] [--reference-particles N]\n"
    "                                   [--components-list 50,100,...] [--reference-components M]\n"
    "                                   [--component-particles N] [--component-reference-particles "
    "N]\n"
    "                                   [--runs R] [--frames F] [--first-frame F] [--eval-from F]\n"
    "                                   [--pixel-stride PX (16)] [--init local|global]\n"
    "                                   [--data-seed S]\n"
    "                                   [--max-iter I (component sweep fits, 30)]\n"
    "common: [--scene auto|7scenes|synthetic] [--dataset DIR] [--map MAP.gmm] [--width PX]\n"
    "        [--out DIR] [--quiet]\n"
    "--scene auto (default) uses 7-Scenes redkitchen ($GMM_MCL_DATASETS, else\n"
    "../shared/datasets) when found, else the synthetic box scene. --map: a 7-Scenes map in\n"
    "the data set's world frame (scripts/build_map_7scenes.sh); without it the M=1000 map is\n"
    "fitted in-process as that script does. --width: synthetic image width (640).\n"
    "Writes OUT/nll_sweep.{csv,txt} or OUT/sensitivity_{samples,summary}.csv and\n"
    "sensitivity_summary.md; plot them with scripts/plot_figures.py OUT.\n";

std::vector<int> parseList(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (*end != '\0' || v <= 0 || v > 1000000000)
      throw std::invalid_argument("bad list entry '" + item + "' in '" + s + "'");
    out.push_back(static_cast<int>(v));
  }
  if (out.empty()) throw std::invalid_argument("empty list '" + s + "'");
  return out;
}

std::string listString(const std::vector<int>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + std::to_string(v[i]);
  return s;
}

struct Options {
  std::string command;
  std::string scene = "auto";
  std::string dataset;
  std::string map_path;
  std::string out_dir = ".";
  int width_px = 640;
  bool quiet = false;
  // nll-sweep
  int frame = -1;  // 7-Scenes 300, synthetic 120
  bool frame_given = false;
  int stride = 8;
  bool stride_given = false;
  NllSweepParams sweep;
  // sensitivity
  std::string which = "both";
  // Defaults: the measured configuration of docs/evaluation.md (minutes on a 2-core CPU).
  std::vector<int> particle_counts = {50, 100, 200, 500, 1068};
  int reference_particles = 16200;
  std::vector<int> component_counts = {50, 250, 1000};
  int reference_components = 2500;
  int component_particles = kDefaultParticleCount;
  int component_reference_particles = -1;  // default: component_particles (paper: N = 1068)
  int runs = 3;
  int frames = 36;
  int first_frame = 0;
  int eval_from = 22;
  std::string init = "local";
  uint64_t data_seed = 1;
  int max_iter = 30;  // EM iterations of the component sweep's maps
};

void parseArgs(int argc, char** argv, Options* o) {
  std::string particle_list, component_list;
  cli::CommandLine cl("gmm_mcl_figures", kUsage);
  // clang-format off
  cl.flags({{"command", &o->command}, {"scene", &o->scene}, {"dataset", &o->dataset},
           {"map", &o->map_path}, {"out", &o->out_dir}, {"width", &o->width_px},
           {"quiet", &o->quiet}, {"frame", &o->frame}, {"pixel-stride", &o->stride},
           {"range-m", &o->sweep.half_range_m}, {"step-m", &o->sweep.step_m},
           {"range-rad", &o->sweep.half_range_rad}, {"step-rad", &o->sweep.step_rad},
           {"no-exact", cli::Clear{&o->sweep.exact}}, {"sweep", &o->which},
           {"particles-list", &particle_list}, {"reference-particles", &o->reference_particles},
           {"components-list", &component_list}, {"reference-components", &o->reference_components},
           {"component-particles", &o->component_particles},
           {"component-reference-particles", &o->component_reference_particles}, {"runs", &o->runs},
           {"frames", &o->frames}, {"first-frame", &o->first_frame}, {"eval-from", &o->eval_from},
           {"init", &o->init}, {"data-seed", &o->data_seed}, {"max-iter", &o->max_iter}});
  // clang-format on
  cl.positional("command");
  cl.alias("stride", "pixel-stride");
  cl.parse(argc, argv);
  if (o->command.empty()) cl.fail("a command is needed (nll-sweep or sensitivity)");
  o->frame_given = cl.given("frame");
  o->stride_given = cl.given("pixel-stride");
  auto list = [&cl](const char* flag, const std::string& text, std::vector<int>* out) {
    if (text.empty()) return;
    try {
      *out = parseList(text);
    } catch (const std::invalid_argument& e) {
      cl.fail(std::string("--") + flag + ": " + e.what());
    }
  };
  list("particles-list", particle_list, &o->particle_counts);
  list("components-list", component_list, &o->component_counts);
}

std::string exeDir(const char* argv0) {
  const std::string s = argv0;
  const size_t slash = s.rfind('/');
  return slash == std::string::npos ? "." : s.substr(0, slash);
}

// Resolves --scene auto to a data folder or "" (synthetic); exits on an impossible request.
std::string resolveDataset(const Options& o, const char* argv0) {
  if (o.scene == "synthetic") return "";
  const std::string dir = o.dataset.empty() ? findSevenScenes(exeDir(argv0)) : o.dataset;
  if (o.scene == "7scenes" && dir.empty()) {
    throw std::runtime_error(
        "7-Scenes redkitchen not found (set GMM_MCL_DATASETS or pass --dataset DIR)");
  }
  if (o.scene != "auto" && o.scene != "7scenes") {
    throw std::invalid_argument("--scene must be auto, 7scenes or synthetic");
  }
  if (dir.empty()) {
    std::printf("7-Scenes data not found: using the synthetic box scene\n");
  }
  return dir;
}

// The scenario's M = 1000 map in its map frame: --map (world frame) or an in-process fit for
// 7-Scenes; the tiled analytic map for the synthetic scene.
GmmMap defaultMap(const Options& o, const Scenario& s) {
  if (!o.map_path.empty()) {
    const GmmMap world = loadMap(o.map_path);
    return s.R_map_world.isIdentity(0.0)
               ? world
               : rotateMap(world, s.R_map_world, o.map_path + " (map frame)");
  }
  if (s.dataset_dir.empty()) return syntheticTiledMap();
#if defined(GMM_MCL_FIGURES_HAVE_FIT)
  std::printf("fitting the 7-Scenes M=1000 map in-process (as scripts/build_map_7scenes.sh)...\n");
  std::fflush(stdout);
  const Clock::time_point t0 = Clock::now();
  EmParams ep;  // the script's settings (max 100 iterations), not --max-iter
  const GmmMap map = fitScenarioMap(s, scenarioCloud(s), kDefaultMapComponents, ep);
  std::printf("  fitted in %.1f s\n", secondsSince(t0));
  return map;
#else
  throw std::runtime_error("this build has no map builder (gmm_mcl_fit): pass --map MAP.gmm");
#endif
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << text;
}

int runNllSweep(const Options& o, const char* argv0) {
  const std::string dataset = resolveDataset(o, argv0);
  const int frame_index = o.frame_given ? o.frame : (dataset.empty() ? 120 : 300);
  const Scenario s = dataset.empty() ? syntheticScenario(frame_index, 1, o.width_px, 1)
                                     : sevenScenesScenario(dataset, frame_index, 1);
  const GmmMap map = defaultMap(o, s);
  FrameParams fp;
  fp.pixel_stride = o.stride;
  fp.max_range_m = s.max_range_m;
  const std::string fault = fp.validate();
  if (!fault.empty()) throw std::invalid_argument("frame parameters: " + fault);
  const DepthFrame frame = prepareFrame(s.depth[0], s.intrinsics, fp);
  std::printf(
      "nll-sweep: %s, frame %d, map %zu components, stride %d, %zu pixels, "
      "+-%.3g m step %.3g m, +-%.3g rad step %.3g rad, exact %s\n",
      s.name.c_str(), frame_index, map.size(), o.stride, frame.size(), o.sweep.half_range_m,
      o.sweep.step_m, o.sweep.half_range_rad, o.sweep.step_rad, o.sweep.exact ? "yes" : "no");
  std::fflush(stdout);
  const Clock::time_point t0 = Clock::now();
  const std::vector<NllSweepRow> rows =
      nllSweep(map, frame, s.T_map_base[0], s.T_base_cam, o.sweep);
  const double elapsed = secondsSince(t0);

  mkdir(o.out_dir.c_str(), 0755);
  writeNllSweepCsv(rows, o.out_dir + "/nll_sweep.csv");
  const Particle truth = poseToParticle(s.T_map_base[0]);
  std::ostringstream meta;
  meta << "scene=" << s.name << "\nframe=" << frame_index << "\ncomponents=" << map.size()
       << "\nstride_px=" << o.stride << "\npixels=" << frame.size()
       << "\nimage=" << s.intrinsics.width_px << "x" << s.intrinsics.height_px
       << "\ntrue_pose_xyz_yaw=" << truth.x_m << "," << truth.y_m << "," << truth.z_m << ","
       << truth.yaw_rad << "\nfloor_log_density=" << o.sweep.measurement.floor_log_density << "\n";
  writeText(o.out_dir + "/nll_sweep.txt", meta.str());

  // Summary per axis: where each curve has its minimum, and the approximation's gap.
  std::printf("%-4s %-12s %-12s %-22s %-22s\n", "axis", "argmin apx", "argmin exact",
              "max |apx-exact|/px", "(within +-0.1 m/rad)");
  for (SweepAxis axis : kAllSweepAxes) {
    double best_a = 1e300, best_e = 1e300, at_a = 0, at_e = 0, gap = 0, gap_near = 0;
    for (const NllSweepRow& r : rows) {
      if (r.axis != axis) continue;
      if (r.approx_nll < best_a) best_a = r.approx_nll, at_a = r.offset;
      if (o.sweep.exact && r.exact_nll < best_e) best_e = r.exact_nll, at_e = r.offset;
      if (o.sweep.exact && r.pixels > 0) {
        const double g = std::abs(r.approx_nll - r.exact_nll) / r.pixels;
        gap = std::max(gap, g);
        if (std::abs(r.offset) <= 0.1 + 1e-9) gap_near = std::max(gap_near, g);
      }
    }
    std::printf("%-4s %+-12.3f %+-12.3f %-22.4g %-22.4g\n", sweepAxisName(axis), at_a,
                o.sweep.exact ? at_e : NAN, o.sweep.exact ? gap : NAN,
                o.sweep.exact ? gap_near : NAN);
  }
  std::printf("%zu poses in %.1f s; wrote %s/nll_sweep.csv and nll_sweep.txt\n", rows.size(),
              elapsed, o.out_dir.c_str());
  return 0;
}

int runSensitivity(const Options& o, const char* argv0) {
  if (o.which != "particles" && o.which != "components" && o.which != "both") {
    throw std::invalid_argument("--sweep must be particles, components or both");
  }
#if !defined(GMM_MCL_FIGURES_HAVE_FIT)
  if (o.which != "particles") {
    throw std::runtime_error("the component sweep needs the map builder (gmm_mcl_fit)");
  }
#endif
  const std::string dataset = resolveDataset(o, argv0);
  FilterRunParams run;
  if (!parseInitMode(o.init, &run.init))
    throw std::invalid_argument("--init must be local or global");
  run.localizer.frame.pixel_stride = o.stride_given ? o.stride : 16;
  SweepParams sweep;
  sweep.runs = o.runs;
  sweep.eval_from_frame = o.eval_from;
  if (o.runs < 2) throw std::invalid_argument("--runs must be >= 2 (a variance over runs)");
  if (o.eval_from >= o.frames) throw std::invalid_argument("--eval-from must be below --frames");

  const Clock::time_point t_load = Clock::now();
  const Scenario s = dataset.empty()
                         ? syntheticScenario(o.first_frame, o.frames, o.width_px, o.data_seed)
                         : sevenScenesScenario(dataset, o.first_frame, o.frames);
  run.localizer.frame.max_range_m = s.max_range_m;
  const SensorInputs inputs = synthesiseInputs(s, SensorNoise(), o.data_seed);
  std::printf(
      "sensitivity: %s, %dx%d, stride %d, init %s, %d runs, KL over frames %d..%d, "
      "data seed %llu (loaded in %.1f s)\n",
      s.name.c_str(), s.intrinsics.width_px, s.intrinsics.height_px,
      run.localizer.frame.pixel_stride, initModeName(run.init), o.runs, o.eval_from, o.frames - 1,
      static_cast<unsigned long long>(o.data_seed), secondsSince(t_load));
  std::fflush(stdout);
  const SweepProgress progress = [&](const std::string& what) {
    if (!o.quiet) std::fprintf(stderr, "  %s\n", what.c_str());
  };

  std::vector<KlSample> samples;
  std::vector<KlSummary> rows;
  mkdir(o.out_dir.c_str(), 0755);
  std::ostringstream meta;
  meta << "scene=" << s.name << "\nimage=" << s.intrinsics.width_px << "x" << s.intrinsics.height_px
       << "\nstride_px=" << run.localizer.frame.pixel_stride << "\ninit=" << initModeName(run.init)
       << "\nruns=" << o.runs << "\nframes=" << o.frames << "\nfirst_frame=" << o.first_frame
       << "\neval_from=" << o.eval_from << "\ndata_seed=" << o.data_seed << "\n";

  if (o.which != "components") {
    const Clock::time_point t0 = Clock::now();
    const GmmMap map = defaultMap(o, s);
    std::printf("particle sweep: N = %s against N = %d, map %zu components\n",
                listString(o.particle_counts).c_str(), o.reference_particles, map.size());
    std::fflush(stdout);
    const std::vector<KlSummary> r = particleSweep(
        s, inputs, map, run, o.particle_counts, o.reference_particles, sweep, &samples, progress);
    rows.insert(rows.end(), r.begin(), r.end());
    std::printf("  %.1f s\n", secondsSince(t0));
    meta << "particle_counts=" << listString(o.particle_counts)
         << "\nreference_particles=" << o.reference_particles
         << "\nparticle_sweep_components=" << map.size()
         << "\nparticle_sweep_s=" << secondsSince(t0) << "\n";
  }
#if defined(GMM_MCL_FIGURES_HAVE_FIT)
  if (o.which != "particles") {
    const Clock::time_point t0 = Clock::now();
    const PointCloud cloud = scenarioCloud(s);
    EmParams ep;
    ep.max_iterations = o.max_iter;
    std::vector<GmmMap> maps;
    std::vector<int> counts;
    for (int m : o.component_counts) {
      const Clock::time_point tf = Clock::now();
      maps.push_back(fitScenarioMap(s, cloud, m, ep));
      counts.push_back(static_cast<int>(maps.back().size()));
      progress("fitted M=" + std::to_string(m) + " in " + std::to_string(secondsSince(tf)) + " s");
    }
    const Clock::time_point tf = Clock::now();
    const GmmMap reference = fitScenarioMap(s, cloud, o.reference_components, ep);
    progress("fitted reference M=" + std::to_string(o.reference_components) + " in " +
             std::to_string(secondsSince(tf)) + " s");
    const double fit_s = secondsSince(t0);
    const int ref_n = o.component_reference_particles > 0 ? o.component_reference_particles
                                                          : o.component_particles;
    FilterRunParams p = run;
    p.localizer.filter.num_particles = o.component_particles;
    std::printf(
        "component sweep: M = %s (N = %d) against M = %d (N = %d); %zu cloud points, "
        "maps fitted in %.1f s\n",
        listString(o.component_counts).c_str(), o.component_particles, o.reference_components,
        ref_n, cloud.size(), fit_s);
    std::fflush(stdout);
    const std::vector<KlSummary> r =
        componentSweep(s, inputs, maps, counts, reference, ref_n, p, sweep, &samples, progress);
    rows.insert(rows.end(), r.begin(), r.end());
    std::printf("  %.1f s\n", secondsSince(t0));
    meta << "component_counts=" << listString(o.component_counts)
         << "\nreference_components=" << o.reference_components
         << "\ncomponent_particles=" << o.component_particles
         << "\ncomponent_reference_particles=" << ref_n << "\ncloud_points=" << cloud.size()
         << "\nfit_max_iterations=" << o.max_iter << "\nfit_s=" << fit_s
         << "\ncomponent_sweep_s=" << secondsSince(t0) << "\n";
  }
#endif
  writeKlSamplesCsv(samples, o.out_dir + "/sensitivity_samples.csv");
  writeKlSummaryCsv(rows, o.out_dir + "/sensitivity_summary.csv");
  const std::string md = klSummaryMarkdown(rows);
  writeText(o.out_dir + "/sensitivity_summary.md", md);
  writeText(o.out_dir + "/sensitivity.txt", meta.str());
  std::printf(
      "\n%s\nwrote %s/sensitivity_{samples,summary}.csv, sensitivity_summary.md, "
      "sensitivity.txt\n",
      md.c_str(), o.out_dir.c_str());
  return 0;
}

}  // namespace

int run(int argc, char** argv) {
  Options o;
  parseArgs(argc, argv, &o);
  return cli::reportErrors("gmm_mcl_figures", [&] {
    if (o.command == "nll-sweep") return runNllSweep(o, argv[0]);
    if (o.command == "sensitivity") return runSensitivity(o, argv[0]);
    std::fprintf(stderr, "gmm_mcl_figures: unknown command '%s'\n\n%s", o.command.c_str(), kUsage);
    return 2;
  });
}

}  // namespace figures
}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::figures::run(argc, argv); }
