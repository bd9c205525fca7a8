// gmm_mcl_kidnap: kidnapped-robot trials on the synthetic scene or a data set. Each seeded
// trial tracks from the true start, teleports the sensor inside the recovery region (odometry
// misses the jump) and measures the time until the estimate is back
// under 10 cm for 30 frames. Prints a markdown table; exit status 0 always when trials ran.
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/experiments/reliability/kidnap.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace reliability {

namespace {

const char* kUsage =
    "usage: gmm_mcl_kidnap [--scene synthetic|box|7scenes|tum|stanford] [--map MAP.gmm]\n"
    "                      [--dataset DIR]\n"
    "                      [--trials N] [--first-seed S] [--pixel-stride PX (8)]\n"
    "                      [--num-particles MAX]\n"
    "                      [--width PX] [--track-frames N] [--after-frames N] [--start-frame F]\n"
    "                      [--backend cpu|cuda]\n"
    "                      [--weighting paper|tempered] [--temperature T]\n"
    "                      [--sigma-translation-m M] [--sigma-yaw-rad RAD]\n"
    "                      [--attitude-noise DEG] [--no-lost-detector]\n"
    "                      [--lost-candidates-per-particle K] [--lost-reinit-fraction F]\n"
    "                      [--lost-margin-nats NATS] [--lost-grace-frames FRAMES]\n"
    "                      [--lost-frames FRAMES] [--min-particles MIN]\n"
    "                      [--depth-noise A,B,Z0] [--out DIR] [--init region|map]\n"
    "                      [--odometry truth|none] [--imu truth|attitude]\n"
    "Particles: MIN..MAX by KLD-sampling (default 1068..3000 on the CPU, 1068..100000 with\n"
    "CUDA; MIN = MAX: fixed).\n"
    "--track-frames 0: global localisation trials (uniform start, no kidnap): over the recovery\n"
    "region around the start, or with --init map over the whole map (its bounds, full yaw).\n"
    "--width: the synthetic scenes' camera width (f = 585 px at 640, scaled; default 640).\n"
    "7scenes needs --map (scripts/build_map_7scenes.sh); DIR defaults to\n"
    "$GMM_MCL_DATASETS/7scenes_redkitchen/data, else ../shared/datasets/...\n"
    "Filter parameters: every one as --name-with-dashes (the list under --help).\n";

}  // namespace

int run(int argc, char** argv) {
  std::string scene = "synthetic", map_path, backend = "cpu";
  const char* env = std::getenv("GMM_MCL_DATASETS");
  std::string dataset =
      std::string(env && *env ? env : "../shared/datasets") + "/7scenes_redkitchen/data";
  int trials = 10, width = 640;
  uint64_t first_seed = 1;
  KidnapParams kp;
  bool lost_detector = true;
  std::string out_dir, init = "region", odometry = "truth", imu = "truth";
  double attitude_noise_deg = kp.attitude_sigma_rad * 180.0 / M_PI;
  cli::CommandLine cl("gmm_mcl_kidnap", kUsage);
  // clang-format off
  cl.flags({{"scene", &scene}, {"map", &map_path}, {"dataset", &dataset}, {"trials", &trials},
           {"first-seed", &first_seed}, {"width", &width}, {"track-frames", &kp.track_frames}, {"after-frames", &kp.after_frames},
           {"start-frame", &kp.start_frame}, {"backend", &backend},
           {"attitude-noise", &attitude_noise_deg},
           {"no-lost-detector", cli::Clear{&lost_detector}}, {"out", &out_dir}, {"init", &init},
           {"odometry", &odometry}, {"imu", &imu}});
  // clang-format on
  kp.localizer.frame.pixel_stride = 8;
  cl.addLocalizerParams(&kp.localizer,
                        {"backend", "device_filter", "seed", "init_centre", "init_half_extent",
                         "init_yaw_centre", "init_yaw_half_range"});
  cl.particleRangeByBackend(&backend);
  cl.addDepthNoise(&kp.localizer.measurement.depth_noise);
  cl.alias("stride", "pixel-stride");
  cl.alias("particles", "num-particles");
  cl.parse(argc, argv);
  if (cl.given("attitude-noise")) kp.attitude_sigma_rad = attitude_noise_deg * M_PI / 180.0;
  if (init != "region" && init != "map") cl.fail("--init: region or map (got '" + init + "')");
  kp.whole_map_start = init == "map";
  if (odometry != "truth" && odometry != "none") cl.fail("--odometry: truth or none");
  kp.odometry = odometry == "truth";
  // --imu truth: attitude and (without odometry) the gyro's heading; attitude: attitude only.
  if (imu != "truth" && imu != "attitude") cl.fail("--imu: truth or attitude");
  kp.gyro = imu == "truth";
  return cli::reportErrors("gmm_mcl_kidnap", [&] {
    std::unique_ptr<FrameSource> src;
    if (scene == "synthetic" || scene == "box") {
      const Intrinsics K = sim::defaultCamera(width);  // f = 585 px at 640 px, scaled
      src = scene == "box" ? makeBoxSceneSource(K, 1500) : makeSyntheticSource(K, 1500);
      if (!cl.given("max-range-m")) kp.localizer.frame.max_range_m = 8.f;
    } else if (scene == "7scenes" || scene == "tum" || scene == "stanford") {
      if (map_path.empty() || (scene != "7scenes" && dataset.empty())) {
        cl.fail("--scene " + scene + " needs --map" + (scene == "7scenes" ? "" : " and --dataset"));
      }
      src = makeSequenceSource(scene, dataset, map_path);
    } else {
      cl.fail("--scene: unknown scene '" + scene + "'");
    }
    if (kp.whole_map_start && kp.track_frames != 0) {
      std::fprintf(stderr, "--init map is for global localisation trials (--track-frames 0)\n");
      return 2;
    }
    kp.localizer.backend = backend;
    if (!lost_detector) kp.localizer.lost.margin_nats = 0.0;
    std::printf(
        "gmm_mcl kidnap: %s, %d..%d particles, stride %d, %s weighting, lost detector %s, "
        "%d tracked + %d frames after the kidnap; %d candidates per redrawn particle, "
        "redraw fraction %.2f, margin %.1f nats/px\n\n",
        src->name().c_str(), kp.localizer.filter.min_particles, kp.localizer.filter.num_particles,
        kp.localizer.frame.pixel_stride, weightingModeName(kp.localizer.filter.weighting),
        lost_detector ? "on" : "off", kp.track_frames, kp.after_frames,
        kp.localizer.lost.candidates_per_particle, kp.localizer.lost.reinit_fraction,
        kp.localizer.lost.margin_nats);
    std::printf(
        "| seed | frames | jump (m) | yaw jump (deg) | error before (cm) | recovered in (s) "
        "| final error (cm) | ATE after (cm) | lost events | final best / reference (nats/px) "
        "| success |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n");
    int ok = 0;
    double sum_s = 0.0, worst_s = 0.0, step_ms = 0.0;
    for (int t = 0; t < trials; ++t) {
      const KidnapResult r = runKidnapTrial(*src, kp, first_seed + t);
      std::printf(
          "| %llu | %d..%d -> %d | %.2f | %.0f | %.1f | %s | %.1f | %.1f | %d "
          "| %.2f / %.2f | %s |\n",
          static_cast<unsigned long long>(r.seed), r.start_frame, r.from_frame - 1, r.to_frame,
          r.jump_m, r.jump_yaw_rad * 180.0 / M_PI, 100.0 * r.error_before_m,
          r.recovery_s >= 0.0 ? std::to_string(r.recovery_s).substr(0, 5).c_str() : "never",
          100.0 * r.final_error_m, 100.0 * r.ate_after_m, r.lost_events, r.final_best_loglik_px,
          r.final_reference_px, r.recovered ? "yes" : "no");
      std::fflush(stdout);
      if (r.recovered) {
        ++ok;
        sum_s += r.recovery_s;
        worst_s = std::max(worst_s, r.recovery_s);
      }
      step_ms += r.mean_step_ms;
      if (!out_dir.empty()) {  // one file per trial (trials of one folder may run in parallel)
        mkdir(out_dir.c_str(), 0755);
        std::ofstream f(out_dir + "/kidnap_" + std::to_string(r.seed) + ".csv");
        f << "seed,start_frame,kidnap_frame,to_frame,jump_m,recovered,recovery_s,final_error_m,"
             "ate_after_m,lost_events,mean_step_ms\n"
          << r.seed << ',' << r.start_frame << ',' << r.from_frame << ',' << r.to_frame << ','
          << r.jump_m << ',' << (r.recovered ? 1 : 0) << ',' << r.recovery_s << ','
          << r.final_error_m << ',' << r.ate_after_m << ',' << r.lost_events << ','
          << r.mean_step_ms << '\n';
        std::ofstream ff(out_dir + "/kidnap_" + std::to_string(r.seed) + "_frames.csv");
        ff << "frame,source_frame,after_kidnap,error_m,refined_error_m,best_loglik_px,"
              "reference_px,particles,lost_redrawn,position_sigma_m,neff\n";
        for (size_t k = 0; k < r.frames.size(); ++k) {
          const reliability::KidnapFrame& fr = r.frames[k];
          ff << k << ',' << fr.source_frame << ','
             << (static_cast<int>(k) >= kp.track_frames ? 1 : 0) << ',' << fr.error_m << ','
             << fr.refined_error_m << ',' << fr.best_loglik_px << ',' << fr.reference_px << ','
             << fr.particles << ',' << fr.lost_redrawn << ',' << fr.position_sigma_m << ','
             << fr.neff << '\n';
        }
      }
    }
    std::printf(
        "\n%d/%d recovered within %.0f s; mean recovery %.2f s, worst %.2f s; "
        "mean step %.1f ms\n",
        ok, trials, kp.max_recovery_s, ok > 0 ? sum_s / ok : 0.0, worst_s, step_ms / trials);
    return 0;
  });
}

}  // namespace reliability
}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::reliability::run(argc, argv); }
