// gmm_mcl_replay: the DESIGN.md accuracy protocol on a data-set folder (7-Scenes, TUM RGB-D /
// ICL-NUIM, Stanford), offline and seeded. Writes per trial a TUM trajectory (estimate and
// ground truth) and a per-frame CSV, and a summary table (markdown and CSV) over all trials.
// --make-fixture writes the synthetic scene as a TUM or Stanford folder with its map.
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/cli/sequence_flags.h"
#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"

namespace gmm_mcl {
namespace {

const char* kUsage =
    "usage: gmm_mcl_replay --map MAP.gmm [--format 7scenes|tum|stanford] [--dataset DIR]\n"
    "                      [--trials N] [--first-seed S] [--frames N] [--pixel-stride PX]\n"
    "                      [--num-particles MAX] [--min-particles MIN]\n"
    "                      [--weighting paper|tempered]\n"
    "                      [--temperature T]\n"
    "                      [--backend cpu|cuda] [--host-filter]\n"
    "                      [--neff-floor-fraction F] [--init-half-extent M]\n"
    "                      [--init-yaw-half-range RAD] [--init cube|map] [--depth-noise A,B,Z0]\n"
    "                      [--min-range-m M] [--max-range-m M] [--floor-log-density NATS]\n"
    "                      [--lost-margin-nats NATS] [--lost-grace-frames FRAMES]\n"
    "                      [--lost-candidates-per-particle K]\n"
    "                      [--hold-frames N (30)] [--tail-frames N (100)]\n"
    "                      [--odometry truth|none] [--imu truth|attitude|none] [--frame-step K]\n"
    "                      [--nearest-particle] [--out DIR] [--quiet]\n"
    "       folder options: [--intrinsics fr1|fr2|fr3|icl|kinect|fx,fy,cx,cy|FILE]\n"
    "                      [--depth-scale UNITS_PER_M] [--tolerance S] [--gravity z-up|\n"
    "                      first-camera|gx,gy,gz] [--trajectory FILE.log] [--rate HZ]\n"
    "       gmm_mcl_replay --make-fixture tum|stanford DIR [--frames N] [--width PX] [--seed S]\n"
    "       gmm_mcl_replay --format F --dataset DIR --convert tum|stanford OUT_DIR [--frames N]\n"
    "                      [--convert-stride PX]\n"
    "DIR defaults to $GMM_MCL_DATASETS/7scenes_redkitchen/data, else\n"
    "../shared/datasets/7scenes_redkitchen/data. Runs trials with seeds S..S+N-1 (1..10).\n"
    "MAP is in the data set's world frame; it is rotated into the gravity-aligned frame.\n"
    "Particles: between MIN and MAX, adapted by KLD-sampling (default 1068..3000 on the CPU,\n"
    "1068..100000 with CUDA; MIN = MAX: a fixed count).\n"
    "--host-filter keeps the particle set on the host with the CUDA backend (by default the\n"
    "whole filter step runs on the GPU there).\n"
    "--init map starts uniform over the whole map (its bounds, full yaw) instead of the cube\n"
    "around the true start. --depth-noise: the camera's depth noise sigma(z) = A + B (z - Z0)^2\n"
    "in metres (default 0.0012,0.0019,0.4, a Kinect v1; 0,0,0 turns it off).\n"
    "--make-fixture writes the synthetic scene as a folder of that format and DIR/map.gmm;\n"
    "--convert writes the data set in another folder format (with intrinsics.txt and\n"
    "gravity-direction.txt); --convert-stride keeps only the pixels on that stride's grid (the\n"
    "same input for a filter of that stride, a fraction of the bytes; TUM only).\n"
    "--odometry none withholds the odometry (the filter's constant-velocity model predicts, its\n"
    "yaw change from the synthesised IMU gyro's heading), --imu attitude the gyro (the model's\n"
    "own yaw rate), --imu none the attitude too (roll and pitch held from the refined\n"
    "estimates); --frame-step K replays every K-th frame (2: 15 Hz, 3: 10 Hz from 30 Hz;\n"
    "--frames counts the sequence's frames; the hold and tail windows shrink by K unless\n"
    "given): docs/no_odometry.md.\n"
    "--nearest-particle adds each frame's distance from the truth to the nearest particle (yaw\n"
    "within 0.2 rad) to the CSV (nearest_particle_m): whether the set still holds the truth.\n"
    "Filter parameters: every one as --name-with-dashes (the list under --help).\n";

int makeFixture(const std::string& format, const std::string& dir, int frames, int width,
                uint64_t seed) {
  SimSequenceParams sp;
  sp.frames = frames > 0 ? frames : 120;
  sp.width_px = width;
  sp.seed = seed;
  sp.start_s = format == "tum" ? 1305031102.175304 : 0.0;  // a TUM-like epoch stamp
  const SimSequence seq(sp);
  if (format == "tum") {
    writeTumFolder(seq, dir);
  } else if (format == "stanford") {
    writeStanfordFolder(seq, dir);
  } else {
    std::fprintf(stderr, "--make-fixture: format must be tum or stanford\n");
    return 2;
  }
  saveMap(seq.map(), dir + "/map.gmm");
  std::printf("wrote %s (%s, %d frames %dx%d) and %s/map.gmm\n", dir.c_str(), format.c_str(),
              seq.size(), seq.intrinsics().width_px, seq.intrinsics().height_px, dir.c_str());
  return 0;
}

constexpr const char* kMetricsHeader =
    "seed,converged,converge_time_s,ate_cm,ate_yaw_deg,refined_ate_cm,refined_ate_yaw_deg,"
    "refined_fraction,lost_events,success,mean_step_ms,frames,converged_frames\n";

int lostEvents(const TrialResult& r) {
  int lost_events = 0;
  for (const ReplayFrame& rf : r.frames) lost_events += rf.step.lost ? 1 : 0;
  return lost_events;
}

// One trial's row of summary.csv (and of trial_<seed>_metrics.csv).
std::string metricsRow(const TrialResult& r) {
  const TrialMetrics& m = r.metrics;
  char row[320];
  std::snprintf(row, sizeof(row), "%llu,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%.2f,%d,%d\n",
                static_cast<unsigned long long>(r.seed), m.converged ? 1 : 0, m.converge_time_s,
                100.0 * m.ate_translation_m, m.ate_yaw_rad * 180 / M_PI,
                100.0 * m.refined_ate_translation_m, m.refined_ate_yaw_rad * 180 / M_PI,
                m.refined_fraction, lostEvents(r), m.success ? 1 : 0, r.mean_step_ms, m.frames,
                m.converged ? m.frames - m.converge_frame : 0);
  return row;
}

std::string defaultDataset() {
  const char* env = std::getenv("GMM_MCL_DATASETS");
  const std::string root = env && *env ? env : "../shared/datasets";
  return root + "/7scenes_redkitchen/data";
}

// The command line.
struct Options {
  std::string dataset, map_path, out_dir, format = "7scenes";
  std::string backend = "cpu";
  std::vector<std::string> fixture, convert;
  int trials = 10, frames = -1, width = 160, convert_stride = 1;
  uint64_t first_seed = 1;
  double init_half_extent_m = 2.0, init_yaw_half_range_rad = 0.5 * M_PI;
  SequenceOptions so;
  int hold_frames = -1, tail_frames = -1, frame_step = 1;
  std::string odometry = "truth", imu = "truth";
  bool quiet = false;
  bool host_filter = false;
  bool nearest_particle = false;
  std::string init = "cube";
  LocalizerParams lp;  // the filter parameters given on the command line
};

Options parseOptions(int argc, char** argv, cli::CommandLine* cl_out) {
  Options o;
  cli::CommandLine& cl = *cl_out;
  // clang-format off
  cl.flags({{"map", &o.map_path}, {"dataset", &o.dataset}, {"trials", &o.trials},
            {"first-seed", &o.first_seed}, {"frames", &o.frames}, {"backend", &o.backend}, {"out", &o.out_dir}, {"format", &o.format},
            {"init-half-extent", &o.init_half_extent_m},
            {"init-yaw-half-range", &o.init_yaw_half_range_rad}, {"init", &o.init},
            {"width", &o.width}, {"hold-frames", &o.hold_frames}, {"tail-frames", &o.tail_frames},
            {"convert-stride", &o.convert_stride}, {"convert", &o.convert},
            {"make-fixture", &o.fixture}, {"quiet", &o.quiet}, {"host-filter", &o.host_filter},
            {"odometry", &o.odometry}, {"imu", &o.imu}, {"frame-step", &o.frame_step},
            {"nearest-particle", &o.nearest_particle}});
  // clang-format on
  cli::addSequenceFlags(&cl, &o.so);
  cl.addLocalizerParams(&o.lp, {"backend", "device_filter", "seed", "init_centre",
                                "init_half_extent", "init_yaw_centre", "init_yaw_half_range"});
  cl.particleRangeByBackend(&o.backend);
  cl.addDepthNoise(&o.lp.measurement.depth_noise);
  cl.alias("seed", "first-seed");
  cl.alias("stride", "pixel-stride");
  cl.alias("particles", "num-particles");
  cl.parse(argc, argv);
  if (o.fixture.size() == 1 || o.fixture.size() > 2) cl.fail("--make-fixture: expected FORMAT DIR");
  if (o.convert.size() == 1 || o.convert.size() > 2) cl.fail("--convert: expected FORMAT DIR");
  if (o.odometry != "truth" && o.odometry != "none") cl.fail("--odometry: truth or none");
  if (o.imu != "truth" && o.imu != "attitude" && o.imu != "none")
    cl.fail("--imu: truth, attitude or none");
  if (o.frame_step < 1) cl.fail("--frame-step: an integer >= 1");
  return o;
}

// --convert: the sequence written as a folder of another format.
int convertSequence(const Sequence& seq, const Options& o) {
  const std::string& convert_format = o.convert[0];
  const std::string& convert_dir = o.convert[1];
  TumWriteOptions tum_options;  // the ground truth exactly at the depth stamps
  tum_options.truth_offset_s = 0.0;
  tum_options.truth_per_frame = 1;
  tum_options.keep_stride_px = o.convert_stride;
  if (o.convert_stride < 1 || (o.convert_stride > 1 && convert_format != "tum")) {
    throw std::runtime_error("--convert-stride: a stride >= 1, for --convert tum only");
  }
  if (convert_format == "tum")
    writeTumFolder(seq, convert_dir, tum_options);
  else if (convert_format == "stanford")
    writeStanfordFolder(seq, convert_dir);
  else
    throw std::runtime_error("--convert: format must be tum or stanford");
  std::printf("wrote %s (%s) from %s (%s, %d frames)\n", convert_dir.c_str(),
              convert_format.c_str(), o.dataset.c_str(), seq.format(), seq.size());
  return 0;
}

// The replay's parameters from the options.
ReplayParams replayParams(const Options& o) {
  ReplayParams rp;
  rp.max_frames = o.frames;
  rp.init_half_extent_m = o.init_half_extent_m;
  rp.init_yaw_half_range_rad = o.init_yaw_half_range_rad;
  // The windows keep their duration at a lower frame rate (30 and 100 frames at 30 Hz).
  const int k = o.frame_step;
  rp.evaluation.hold_frames = (rp.evaluation.hold_frames + k - 1) / k;
  rp.evaluation.tail_frames = (rp.evaluation.tail_frames + k - 1) / k;
  if (o.hold_frames > 0) rp.evaluation.hold_frames = o.hold_frames;
  if (o.tail_frames > 0) rp.evaluation.tail_frames = o.tail_frames;
  rp.frame_step = k;
  rp.odometry = o.odometry != "none";
  rp.attitude = o.imu != "none";
  rp.gyro = o.imu == "truth";
  rp.whole_map_start = o.init == "map";
  rp.nearest_particle = o.nearest_particle;
  rp.localizer = o.lp;
  rp.localizer.backend = o.backend;
  rp.localizer.device_filter = !o.host_filter;
  return rp;
}

void printSettings(const Sequence& seq, const GmmMap& map, const ReplayParams& rp,
                   const Options& o) {
  const MeasurementParams& measurement = rp.localizer.measurement;
  const Intrinsics& K = seq.intrinsics();
  std::printf(
      "gmm_mcl replay: %s (%s), %d frames %dx%d (fx %.1f fy %.1f cx %.1f cy %.1f), "
      "gravity: %s; map %s (%zu components), %d particles (min %d), start %s, "
      "odometry %s, IMU %s, depth noise %.4g + %.4g (z - %.2g)^2 m, "
      "stride %d, %s weighting (T %.3g, Neff floor %.2f), %s backend with the particle "
      "set %s, %d trials from seed %llu\n",
      o.dataset.c_str(), seq.format(), seq.size(), K.width_px, K.height_px, K.fx_px, K.fy_px,
      K.cx_px, K.cy_px, seq.gravitySource().c_str(), o.map_path.c_str(), map.size(),
      rp.localizer.filter.num_particles,
      rp.localizer.filter.min_particles > 0 ? rp.localizer.filter.min_particles
                                            : rp.localizer.filter.num_particles,
      o.init == "map" ? "whole map" : "cube", o.odometry.c_str(),
      o.imu == "truth" ? "attitude and gyro" : o.imu.c_str(), measurement.depth_noise.a_m,
      measurement.depth_noise.b_per_m, measurement.depth_noise.z0_m,
      rp.localizer.frame.pixel_stride, weightingModeName(rp.localizer.filter.weighting),
      rp.localizer.filter.temperature, rp.localizer.filter.neff_floor_fraction, o.backend.c_str(),
      o.backend == "cuda" && !o.host_filter ? "on the GPU" : "on the host", o.trials,
      static_cast<unsigned long long>(o.first_seed));
  std::fflush(stdout);
}

// Every frame decoded once up front, so that trials time the filter only.
std::vector<DepthImage> decodeAll(const Sequence& seq, bool quiet) {
  std::vector<DepthImage> depth(seq.size());
  for (int f = 0; f < seq.size(); ++f) {
    depth[f] = seq.loadDepth(f);
    if (!quiet && (f % 50 == 0 || f == seq.size() - 1)) {
      std::fprintf(stderr, "\r  reading depth %d/%d  ", f + 1, seq.size());
      if (f == seq.size() - 1) std::fprintf(stderr, "\n");
    }
  }
  return depth;
}

// One trial: a progress bar (unless quiet), its line on stdout and, with an output folder, its
// files.
TrialResult runOneTrial(const Sequence& seq, const DepthProvider& provider, const GmmMap& map,
                        const ReplayParams& rp, uint64_t seed, const Options& o) {
  const ProgressCallback progress = [&](int f, int total, const ReplayFrame& rf) {
    if (o.quiet) return;
    if (f % 25 == 0 || f == total - 1) {
      const int bar = 30, done = (f + 1) * bar / total;
      std::fprintf(stderr, "\r  seed %2llu [%.*s%*s] %4d/%d  error %6.3f m  Neff %5.0f  %5.0f ms  ",
                   static_cast<unsigned long long>(seed), done,
                   "==============================", bar - done, "", f + 1, total,
                   rf.error.translation_m, rf.step.neff, rf.step.timings.total_ms);
      if (f == total - 1) std::fprintf(stderr, "\n");
    }
  };
  TrialResult r = runTrial(seq, provider, map, rp, seed, progress);
  const TrialMetrics& m = r.metrics;
  std::printf(
      "trial seed %2llu: %s, converged at %.2f s, ATE %.2f cm / %.2f deg, refined "
      "%.2f cm / %.2f deg (%.0f%% of frames), %d lost events, mean step %.0f ms\n",
      static_cast<unsigned long long>(seed), m.success ? "success" : "FAILURE",
      m.converged ? m.converge_time_s : NAN, 100.0 * m.ate_translation_m,
      m.ate_yaw_rad * 180.0 / M_PI, 100.0 * m.refined_ate_translation_m,
      m.refined_ate_yaw_rad * 180.0 / M_PI, 100.0 * m.refined_fraction, lostEvents(r),
      r.mean_step_ms);
  std::fflush(stdout);
  if (!o.out_dir.empty()) {
    const std::string base = o.out_dir + "/trial_" + std::to_string(seed);
    writeTum(r, false, base + "_estimate.tum");
    writeTum(r, true, base + "_truth.tum");
    writeFrameCsv(r, base + ".csv");
    std::ofstream(base + "_metrics.csv") << kMetricsHeader << metricsRow(r);
  }
  return r;
}

// The summary: per trial and overall (ATE pooled over the converged frames of all trials), on
// stdout and, with an output folder, as summary.md and summary.csv. Returns the successes.
int writeSummary(const std::vector<TrialResult>& results, const std::string& out_dir) {
  int successes = 0, converged = 0, within5 = 0;
  double sum_sq_t = 0.0, sum_sq_y = 0.0, sum_sq_rt = 0.0, sum_sq_ry = 0.0, sum_conv = 0.0;
  long long pooled = 0;
  std::string md =
      "| seed | converged at (s) | ATE (cm) | yaw ATE (deg) | refined ATE (cm) | refined yaw "
      "(deg) | refined frames | lost events | success |\n|---|---|---|---|---|---|---|---|---|\n";
  std::string csv = kMetricsHeader;
  for (const TrialResult& r : results) {
    const TrialMetrics& m = r.metrics;
    char row[320];
    std::snprintf(row, sizeof(row),
                  "| %llu | %s | %.2f | %.2f | %.2f | %.2f | %.0f%% | %d | %s |\n",
                  static_cast<unsigned long long>(r.seed),
                  m.converged ? std::to_string(m.converge_time_s).substr(0, 5).c_str() : "never",
                  100.0 * m.ate_translation_m, m.ate_yaw_rad * 180.0 / M_PI,
                  100.0 * m.refined_ate_translation_m, m.refined_ate_yaw_rad * 180.0 / M_PI,
                  100.0 * m.refined_fraction, lostEvents(r), m.success ? "yes" : "no");
    md += row;
    csv += metricsRow(r);
    successes += m.success ? 1 : 0;
    if (m.converged) {
      ++converged;
      within5 += m.converge_time_s <= 5.0 ? 1 : 0;
      sum_conv += m.converge_time_s;
      const int count = m.frames - m.converge_frame;
      sum_sq_t += m.ate_translation_m * m.ate_translation_m * count;
      sum_sq_y += m.ate_yaw_rad * m.ate_yaw_rad * count;
      sum_sq_rt += m.refined_ate_translation_m * m.refined_ate_translation_m * count;
      sum_sq_ry += m.refined_ate_yaw_rad * m.refined_ate_yaw_rad * count;
      pooled += count;
    }
  }
  char overall[320];
  std::snprintf(overall, sizeof(overall),
                "| all | mean %.2f, %d/%d within 5 s | %.2f | %.2f | %.2f | %.2f | | | %d/%d |\n",
                converged ? sum_conv / converged : NAN, within5, static_cast<int>(results.size()),
                pooled ? 100.0 * std::sqrt(sum_sq_t / pooled) : NAN,
                pooled ? std::sqrt(sum_sq_y / pooled) * 180.0 / M_PI : NAN,
                pooled ? 100.0 * std::sqrt(sum_sq_rt / pooled) : NAN,
                pooled ? std::sqrt(sum_sq_ry / pooled) * 180.0 / M_PI : NAN, successes,
                static_cast<int>(results.size()));
  md += overall;
  std::printf("\n%s", md.c_str());
  if (!out_dir.empty()) {
    std::ofstream(out_dir + "/summary.md") << md;
    std::ofstream(out_dir + "/summary.csv") << csv;
    std::printf(
        "wrote %s/{summary.md,summary.csv,trial_*_estimate.tum,trial_*_truth.tum,trial_*.csv}\n",
        out_dir.c_str());
  }
  return successes;
}

int run(Options o, const cli::CommandLine& cl) {
  const bool fixture = !o.fixture.empty() && !o.fixture[1].empty();
  const bool convert = !o.convert.empty() && !o.convert[1].empty();
  if (fixture) return makeFixture(o.fixture[0], o.fixture[1], o.frames, o.width, o.first_seed);
  if (o.map_path.empty() && !convert) cl.fail("--map is needed");
  if (o.dataset.empty()) {
    if (o.format != "7scenes") {
      std::fprintf(stderr, "--format %s needs --dataset DIR\n", o.format.c_str());
      return 2;
    }
    o.dataset = defaultDataset();
  }
  o.so.max_frames = o.frames;
  const std::unique_ptr<Sequence> seq_ptr = openSequence(o.format, o.dataset, o.so);
  const Sequence& seq = *seq_ptr;
  if (convert) return convertSequence(seq, o);
  if (seq.gravitySource().find("assumed") != std::string::npos) {
    std::fprintf(stderr, "warning: gravity %s\n", seq.gravitySource().c_str());
  }
  const GmmMap map_world = loadMap(o.map_path);
  const GmmMap map = rotateMap(map_world, seq.R_aligned_world(), o.map_path + " (gravity-aligned)");
  if (o.init != "cube" && o.init != "map") {
    std::fprintf(stderr, "--init: cube or map (got '%s')\n", o.init.c_str());
    return 2;
  }
  const ReplayParams rp = replayParams(o);
  if (!o.out_dir.empty()) mkdir(o.out_dir.c_str(), 0755);
  printSettings(seq, map, rp, o);
  if (!rp.odometry || !rp.attitude || rp.frame_step > 1) {
    std::printf("inputs: odometry %s, attitude %s, every %d. frame (hold %d, tail %d frames)\n",
                rp.odometry ? "from the truth" : "withheld",
                rp.attitude ? "from the truth" : "withheld", rp.frame_step,
                rp.evaluation.hold_frames, rp.evaluation.tail_frames);
  }
  const std::vector<DepthImage> depth = decodeAll(seq, o.quiet);
  const DepthProvider provider = [&depth](int f) -> const DepthImage& { return depth[f]; };
  std::vector<TrialResult> results;
  for (int t = 0; t < o.trials; ++t) {
    results.push_back(runOneTrial(seq, provider, map, rp, o.first_seed + t, o));
  }
  const int successes = writeSummary(results, o.out_dir);
  return successes == static_cast<int>(results.size()) ? 0 : 1;
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  gmm_mcl::cli::CommandLine cl("gmm_mcl_replay", gmm_mcl::kUsage);
  const gmm_mcl::Options o = gmm_mcl::parseOptions(argc, argv, &cl);
  return gmm_mcl::cli::reportErrors("gmm_mcl_replay", [&] { return gmm_mcl::run(o, cl); });
}
