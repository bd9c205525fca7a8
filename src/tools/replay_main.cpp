// gmm_mcl_replay: the DESIGN.md accuracy protocol on a 7-Scenes sequence, offline and seeded.
// Writes per trial a TUM trajectory (estimate and ground truth) and a per-frame CSV, and a
// summary table (markdown and CSV) over all trials.
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"

using namespace gmm_mcl;

namespace {

void usage() {
  std::printf(
      "usage: gmm_mcl_replay --map MAP.gmm [--dataset DIR] [--trials N] [--first-seed S]\n"
      "                      [--frames N] [--stride PX] [--particles N]\n"
      "                      [--weighting paper|tempered] [--temperature T] [--neff-floor F]\n"
      "                      [--out DIR] [--quiet]\n"
      "DIR defaults to $GMM_MCL_DATASETS/7scenes_redkitchen/data, else\n"
      "../shared/datasets/7scenes_redkitchen/data. Runs trials with seeds S..S+N-1 (1..10).\n");
}

std::string defaultDataset() {
  const char* env = std::getenv("GMM_MCL_DATASETS");
  const std::string root = env && *env ? env : "../shared/datasets";
  return root + "/7scenes_redkitchen/data";
}

}  // namespace

int main(int argc, char** argv) {
  std::string dataset = defaultDataset(), map_path, out_dir, weighting = "tempered";
  int trials = 10, frames = -1, stride = 4, particles = kDefaultParticleCount;
  uint64_t first_seed = 1;
  double temperature = -1.0, neff_floor = -1.0;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "missing value after %s\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--map") map_path = next();
    else if (a == "--dataset") dataset = next();
    else if (a == "--trials") trials = std::atoi(next());
    else if (a == "--first-seed") first_seed = std::strtoull(next(), nullptr, 10);
    else if (a == "--frames") frames = std::atoi(next());
    else if (a == "--stride") stride = std::atoi(next());
    else if (a == "--particles") particles = std::atoi(next());
    else if (a == "--weighting") weighting = next();
    else if (a == "--temperature") temperature = std::atof(next());
    else if (a == "--neff-floor") neff_floor = std::atof(next());
    else if (a == "--out") out_dir = next();
    else if (a == "--quiet") quiet = true;
    else {
      usage();
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (map_path.empty()) {
    usage();
    return 2;
  }
  try {
    const SevenScenesSequence seq(dataset, frames);
    const GmmMap map_world = loadMap(map_path);
    const GmmMap map = rotateMap(map_world, seq.R_aligned_world(), map_path + " (gravity-aligned)");
    ReplayParams rp;
    rp.max_frames = frames;
    rp.localizer.filter.num_particles = particles;
    rp.localizer.frame.pixel_stride = stride;
    if (!parseWeightingMode(weighting, &rp.localizer.filter.weighting)) {
      std::fprintf(stderr, "unknown weighting '%s' (paper, tempered)\n", weighting.c_str());
      return 2;
    }
    if (temperature > 0.0) rp.localizer.filter.temperature = temperature;
    if (neff_floor >= 0.0) rp.localizer.filter.neff_floor_fraction = neff_floor;
    if (!out_dir.empty()) mkdir(out_dir.c_str(), 0755);

    std::printf("gmm_mcl replay: %s, %d frames, map %s (%zu components%s), %d particles, "
                "stride %d, %s weighting (T %.3g, Neff floor %.2f), %d trials from seed %llu\n",
                dataset.c_str(), seq.size(), map_path.c_str(), map.size(),
                seq.hasGravity() ? ", gravity-aligned" : "", particles, stride,
                weighting.c_str(), rp.localizer.filter.temperature,
                rp.localizer.filter.neff_floor_fraction, trials,
                static_cast<unsigned long long>(first_seed));
    std::fflush(stdout);
    std::vector<DepthImage> depth(seq.size());
    for (int f = 0; f < seq.size(); ++f) depth[f] = seq.loadDepth(f);
    const DepthProvider provider = [&depth](int f) -> const DepthImage& { return depth[f]; };

    std::vector<TrialResult> results;
    for (int t = 0; t < trials; ++t) {
      const uint64_t seed = first_seed + t;
      const ProgressCallback progress = [&](int f, int total, const ReplayFrame& rf) {
        if (quiet) return;
        if (f % 25 == 0 || f == total - 1) {
          const int width = 30, done = (f + 1) * width / total;
          std::fprintf(stderr, "\r  seed %2llu [%.*s%*s] %4d/%d  error %6.3f m  %5.0f ms  ",
                       static_cast<unsigned long long>(seed), done,
                       "==============================", width - done, "", f + 1, total,
                       rf.error.translation_m, rf.step.timings.total_ms);
          if (f == total - 1) std::fprintf(stderr, "\n");
        }
      };
      results.push_back(runSevenScenesTrial(seq, provider, map, rp, seed, progress));
      const TrialResult& r = results.back();
      const TrialMetrics& m = r.metrics;
      std::printf("trial seed %2llu: %s, converged at %.2f s, ATE %.2f cm / %.2f deg, "
                  "mean step %.0f ms\n",
                  static_cast<unsigned long long>(seed), m.success ? "success" : "FAILURE",
                  m.converged ? m.converge_time_s : NAN, 100.0 * m.ate_translation_m,
                  m.ate_yaw_rad * 180.0 / M_PI, r.mean_step_ms);
      std::fflush(stdout);
      if (!out_dir.empty()) {
        const std::string base = out_dir + "/trial_" + std::to_string(seed);
        writeTum(r, false, base + "_estimate.tum");
        writeTum(r, true, base + "_truth.tum");
        writeFrameCsv(r, base + ".csv");
      }
    }

    // Summary: per trial and overall (ATE pooled over the converged frames of all trials).
    int successes = 0, converged = 0;
    double sum_sq_t = 0.0, sum_sq_y = 0.0, sum_conv = 0.0;
    long long pooled = 0;
    std::string md = "| seed | converged at (s) | ATE (cm) | yaw ATE (deg) | success |\n|---|---|---|---|---|\n";
    std::string csv = "seed,converged,converge_time_s,ate_cm,ate_yaw_deg,success\n";
    for (const TrialResult& r : results) {
      const TrialMetrics& m = r.metrics;
      char row[256];
      std::snprintf(row, sizeof(row), "| %llu | %s | %.2f | %.2f | %s |\n",
                    static_cast<unsigned long long>(r.seed),
                    m.converged ? std::to_string(m.converge_time_s).substr(0, 5).c_str() : "never",
                    100.0 * m.ate_translation_m, m.ate_yaw_rad * 180.0 / M_PI,
                    m.success ? "yes" : "no");
      md += row;
      std::snprintf(row, sizeof(row), "%llu,%d,%.3f,%.3f,%.3f,%d\n",
                    static_cast<unsigned long long>(r.seed), m.converged ? 1 : 0,
                    m.converge_time_s, 100.0 * m.ate_translation_m, m.ate_yaw_rad * 180 / M_PI,
                    m.success ? 1 : 0);
      csv += row;
      successes += m.success ? 1 : 0;
      if (m.converged) {
        ++converged;
        sum_conv += m.converge_time_s;
        const int count = m.frames - m.converge_frame;
        sum_sq_t += m.ate_translation_m * m.ate_translation_m * count;
        sum_sq_y += m.ate_yaw_rad * m.ate_yaw_rad * count;
        pooled += count;
      }
    }
    char overall[256];
    std::snprintf(overall, sizeof(overall),
                  "| all | mean %.2f | %.2f | %.2f | %d/%d |\n",
                  converged ? sum_conv / converged : NAN,
                  pooled ? 100.0 * std::sqrt(sum_sq_t / pooled) : NAN,
                  pooled ? std::sqrt(sum_sq_y / pooled) * 180.0 / M_PI : NAN, successes,
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
