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

#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/tools/sequence_flags.h"

using namespace gmm_mcl;

namespace {

const char* kUsage =
      "usage: gmm_mcl_replay --map MAP.gmm [--format 7scenes|tum|stanford] [--dataset DIR]\n"
      "                      [--trials N] [--first-seed S] [--frames N] [--stride PX]\n"
      "                      [--particles MAX] [--min-particles MIN] [--weighting paper|tempered]\n"
      "                      [--temperature T]\n"
      "                      [--backend cpu|cuda] [--host-filter]\n"
      "                      [--neff-floor-fraction F] [--init-half-extent M]\n"
      "                      [--init-yaw-half-range RAD] [--init cube|map] [--depth-noise A,B,Z0]\n"
      "                      [--min-range-m M] [--max-range-m M] [--floor-log-density NATS]\n"
      "                      [--lost-margin-nats NATS] [--lost-grace-frames FRAMES]\n"
      "                      [--lost-candidates-per-particle K]\n"
      "                      [--hold-frames N (30)] [--tail-frames N (100)]\n"
      "                      [--out DIR] [--quiet]\n"
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

// One trial's row of summary.csv (and of trial_<seed>_metrics.csv).
std::string metricsRow(const TrialResult& r) {
  const TrialMetrics& m = r.metrics;
  int lost_events = 0;
  for (const ReplayFrame& rf : r.frames) lost_events += rf.step.lost ? 1 : 0;
  char row[320];
  std::snprintf(row, sizeof(row), "%llu,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%.2f,%d,%d\n",
                static_cast<unsigned long long>(r.seed), m.converged ? 1 : 0, m.converge_time_s,
                100.0 * m.ate_translation_m, m.ate_yaw_rad * 180 / M_PI,
                100.0 * m.refined_ate_translation_m, m.refined_ate_yaw_rad * 180 / M_PI,
                m.refined_fraction, lost_events, m.success ? 1 : 0, r.mean_step_ms, m.frames,
                m.converged ? m.frames - m.converge_frame : 0);
  return row;
}

std::string defaultDataset() {
  const char* env = std::getenv("GMM_MCL_DATASETS");
  const std::string root = env && *env ? env : "../shared/datasets";
  return root + "/7scenes_redkitchen/data";
}

}  // namespace

int main(int argc, char** argv) {
  std::string dataset, map_path, out_dir, format = "7scenes";
  std::string backend = "cpu";
  std::vector<std::string> fixture, convert;
  int trials = 10, frames = -1, stride = 4, particles = -1, width = 160;
  int min_particles = -1, convert_stride = 1;
  uint64_t first_seed = 1;
  double init_half_extent_m = 2.0, init_yaw_half_range_rad = 0.5 * M_PI;
  SequenceOptions so;
  int hold_frames = -1, tail_frames = -1;
  bool quiet = false;
  bool host_filter = false;
  std::string init = "cube";
  LocalizerParams lp;  // the filter parameters given on the command line
  cli::CommandLine cl("gmm_mcl_replay", kUsage);
  cl.flags({{"map", &map_path}, {"dataset", &dataset}, {"trials", &trials},
            {"first-seed", &first_seed}, {"frames", &frames}, {"stride", &stride},
            {"particles", &particles}, {"min-particles", &min_particles}, {"backend", &backend},
            {"out", &out_dir}, {"format", &format}, {"init-half-extent", &init_half_extent_m},
            {"init-yaw-half-range", &init_yaw_half_range_rad}, {"init", &init}, {"width", &width},
            {"hold-frames", &hold_frames}, {"tail-frames", &tail_frames},
            {"convert-stride", &convert_stride}, {"convert", &convert}, {"make-fixture", &fixture},
            {"quiet", &quiet}, {"host-filter", &host_filter}});
  cli::addSequenceFlags(&cl, &so);
  cl.addLocalizerParams(&lp, {"num_particles", "min_particles", "pixel_stride", "backend",
                              "device_filter", "seed", "init_centre", "init_half_extent",
                              "init_yaw_centre", "init_yaw_half_range"});
  cl.addDepthNoise(&lp.measurement.depth_noise);
  cl.alias("seed", "first-seed");
  cl.parse(argc, argv);
  if (fixture.size() == 1 || fixture.size() > 2) cl.fail("--make-fixture: expected FORMAT DIR");
  if (convert.size() == 1 || convert.size() > 2) cl.fail("--convert: expected FORMAT DIR");
  const std::string fixture_format = fixture.empty() ? "" : fixture[0];
  const std::string fixture_dir = fixture.empty() ? "" : fixture[1];
  const std::string convert_format = convert.empty() ? "" : convert[0];
  const std::string convert_dir = convert.empty() ? "" : convert[1];
  try {
    if (!fixture_dir.empty()) return makeFixture(fixture_format, fixture_dir, frames, width, first_seed);
    if (map_path.empty() && convert_dir.empty()) cl.fail("--map is needed");
    if (dataset.empty()) {
      if (format != "7scenes") {
        std::fprintf(stderr, "--format %s needs --dataset DIR\n", format.c_str());
        return 2;
      }
      dataset = defaultDataset();
    }
    so.max_frames = frames;
    const std::unique_ptr<Sequence> seq_ptr = openSequence(format, dataset, so);
    const Sequence& seq = *seq_ptr;
    if (!convert_dir.empty()) {
      TumWriteOptions tum_options;  // the ground truth exactly at the depth stamps
      tum_options.truth_offset_s = 0.0;
      tum_options.truth_per_frame = 1;
      tum_options.keep_stride_px = convert_stride;
      if (convert_stride < 1 || (convert_stride > 1 && convert_format != "tum")) {
        throw std::runtime_error("--convert-stride: a stride >= 1, for --convert tum only");
      }
      if (convert_format == "tum") writeTumFolder(seq, convert_dir, tum_options);
      else if (convert_format == "stanford") writeStanfordFolder(seq, convert_dir);
      else throw std::runtime_error("--convert: format must be tum or stanford");
      std::printf("wrote %s (%s) from %s (%s, %d frames)\n", convert_dir.c_str(),
                  convert_format.c_str(), dataset.c_str(), seq.format(), seq.size());
      return 0;
    }
    if (seq.gravitySource().find("assumed") != std::string::npos) {
      std::fprintf(stderr, "warning: gravity %s\n", seq.gravitySource().c_str());
    }
    const GmmMap map_world = loadMap(map_path);
    const GmmMap map = rotateMap(map_world, seq.R_aligned_world(), map_path + " (gravity-aligned)");
    ReplayParams rp;
    rp.max_frames = frames;
    rp.init_half_extent_m = init_half_extent_m;
    rp.init_yaw_half_range_rad = init_yaw_half_range_rad;
    if (hold_frames > 0) rp.evaluation.hold_frames = hold_frames;
    if (tail_frames > 0) rp.evaluation.tail_frames = tail_frames;
    if (init != "cube" && init != "map") {
      std::fprintf(stderr, "--init: cube or map (got '%s')\n", init.c_str());
      return 2;
    }
    rp.whole_map_start = init == "map";
    rp.localizer = lp;
    int default_min, default_max;
    defaultParticleRange(backend, &default_min, &default_max);
    if (particles < 0) particles = default_max;
    if (min_particles < 0) min_particles = std::min(default_min, particles);
    rp.localizer.filter.num_particles = particles;
    rp.localizer.filter.min_particles = min_particles;
    rp.localizer.backend = backend;
    rp.localizer.device_filter = !host_filter;
    rp.localizer.frame.pixel_stride = stride;
    const MeasurementParams& measurement = rp.localizer.measurement;
    if (!out_dir.empty()) mkdir(out_dir.c_str(), 0755);

    const Intrinsics& K = seq.intrinsics();
    std::printf("gmm_mcl replay: %s (%s), %d frames %dx%d (fx %.1f fy %.1f cx %.1f cy %.1f), "
                "gravity: %s; map %s (%zu components), %d particles (min %d), start %s, "
                "depth noise %.4g + %.4g (z - %.2g)^2 m, "
                "stride %d, %s weighting (T %.3g, Neff floor %.2f), %s backend with the particle "
                "set %s, %d trials from seed %llu\n",
                dataset.c_str(), seq.format(), seq.size(), K.width_px, K.height_px, K.fx_px,
                K.fy_px, K.cx_px, K.cy_px, seq.gravitySource().c_str(), map_path.c_str(),
                map.size(), particles, min_particles > 0 ? min_particles : particles,
                init == "map" ? "whole map" : "cube", measurement.depth_noise.a_m,
                measurement.depth_noise.b_per_m, measurement.depth_noise.z0_m, stride,
                weightingModeName(rp.localizer.filter.weighting), rp.localizer.filter.temperature,
                rp.localizer.filter.neff_floor_fraction, backend.c_str(),
                backend == "cuda" && !host_filter ? "on the GPU" : "on the host", trials,
                static_cast<unsigned long long>(first_seed));
    std::fflush(stdout);
    // Every frame is decoded once up front, so that trials time the filter only.
    std::vector<DepthImage> depth(seq.size());
    for (int f = 0; f < seq.size(); ++f) {
      depth[f] = seq.loadDepth(f);
      if (!quiet && (f % 50 == 0 || f == seq.size() - 1)) {
        std::fprintf(stderr, "\r  reading depth %d/%d  ", f + 1, seq.size());
        if (f == seq.size() - 1) std::fprintf(stderr, "\n");
      }
    }
    const DepthProvider provider = [&depth](int f) -> const DepthImage& { return depth[f]; };

    std::vector<TrialResult> results;
    for (int t = 0; t < trials; ++t) {
      const uint64_t seed = first_seed + t;
      const ProgressCallback progress = [&](int f, int total, const ReplayFrame& rf) {
        if (quiet) return;
        if (f % 25 == 0 || f == total - 1) {
          const int bar = 30, done = (f + 1) * bar / total;
          std::fprintf(stderr,
                       "\r  seed %2llu [%.*s%*s] %4d/%d  error %6.3f m  Neff %5.0f  %5.0f ms  ",
                       static_cast<unsigned long long>(seed), done,
                       "==============================", bar - done, "", f + 1, total,
                       rf.error.translation_m, rf.step.neff, rf.step.timings.total_ms);
          if (f == total - 1) std::fprintf(stderr, "\n");
        }
      };
      results.push_back(runTrial(seq, provider, map, rp, seed, progress));
      const TrialResult& r = results.back();
      const TrialMetrics& m = r.metrics;
      int lost_events = 0;
      for (const ReplayFrame& rf : r.frames) lost_events += rf.step.lost ? 1 : 0;
      std::printf("trial seed %2llu: %s, converged at %.2f s, ATE %.2f cm / %.2f deg, refined "
                  "%.2f cm / %.2f deg (%.0f%% of frames), %d lost events, mean step %.0f ms\n",
                  static_cast<unsigned long long>(seed), m.success ? "success" : "FAILURE",
                  m.converged ? m.converge_time_s : NAN, 100.0 * m.ate_translation_m,
                  m.ate_yaw_rad * 180.0 / M_PI, 100.0 * m.refined_ate_translation_m,
                  m.refined_ate_yaw_rad * 180.0 / M_PI, 100.0 * m.refined_fraction, lost_events,
                  r.mean_step_ms);
      std::fflush(stdout);
      if (!out_dir.empty()) {
        const std::string base = out_dir + "/trial_" + std::to_string(seed);
        writeTum(r, false, base + "_estimate.tum");
        writeTum(r, true, base + "_truth.tum");
        writeFrameCsv(r, base + ".csv");
        std::ofstream(base + "_metrics.csv") << kMetricsHeader << metricsRow(r);
      }
    }

    // Summary: per trial and overall (ATE pooled over the converged frames of all trials).
    int successes = 0, converged = 0, within5 = 0;
    double sum_sq_t = 0.0, sum_sq_y = 0.0, sum_sq_rt = 0.0, sum_sq_ry = 0.0, sum_conv = 0.0;
    long long pooled = 0;
    std::string md =
        "| seed | converged at (s) | ATE (cm) | yaw ATE (deg) | refined ATE (cm) | refined yaw "
        "(deg) | refined frames | lost events | success |\n|---|---|---|---|---|---|---|---|---|\n";
    std::string csv = kMetricsHeader;
    for (const TrialResult& r : results) {
      const TrialMetrics& m = r.metrics;
      int lost_events = 0;
      for (const ReplayFrame& rf : r.frames) lost_events += rf.step.lost ? 1 : 0;
      char row[320];
      std::snprintf(row, sizeof(row), "| %llu | %s | %.2f | %.2f | %.2f | %.2f | %.0f%% | %d | %s |\n",
                    static_cast<unsigned long long>(r.seed),
                    m.converged ? std::to_string(m.converge_time_s).substr(0, 5).c_str() : "never",
                    100.0 * m.ate_translation_m, m.ate_yaw_rad * 180.0 / M_PI,
                    100.0 * m.refined_ate_translation_m, m.refined_ate_yaw_rad * 180.0 / M_PI,
                    100.0 * m.refined_fraction, lost_events, m.success ? "yes" : "no");
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
                  converged ? sum_conv / converged : NAN, within5,
                  static_cast<int>(results.size()),
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
      std::printf("wrote %s/{summary.md,summary.csv,trial_*_estimate.tum,trial_*_truth.tum,trial_*.csv}\n",
                  out_dir.c_str());
    }
    return successes == static_cast<int>(results.size()) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gmm_mcl_replay: %s\n", e.what());
    return 1;
  }
}
