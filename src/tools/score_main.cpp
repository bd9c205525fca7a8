// gmm_mcl_score: the log-likelihood of one frame of a data set at one pose, as the filter
// computes it (patch membership, float kernel) and exactly (every component, double), with the
// floor hits, the relevant components per patch and the level the map and the depth-noise model
// predict for a correct pose (the lost detector's starting reference); per pixel on request.
// The answer to "does the true pose score near the map's own level with these settings?".
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/replay/replay.h"

using namespace gmm_mcl;

namespace {

void usage() {
  std::printf(
      "usage: gmm_mcl_score --map MAP.gmm [--format 7scenes|tum|stanford] [--dataset DIR]\n"
      "                     [--frame I] [--pose X,Y,Z,YAW] [--stride PX] [--depth-noise A,B,Z0]\n"
      "                     [--floor NATS] [--min-range M] [--max-range M] [--gravity G]\n"
      "                     [--per-pixel OUT.csv]\n"
      "The pose is the base in the gravity-aligned map frame (as gmm_mcl_replay's estimates),\n"
      "with the frame's true roll and pitch; default: the frame's ground truth. MAP is in the "
      "data\n"
      "set's world frame. --per-pixel writes u, v, depth and the exact log-likelihood of every\n"
      "used pixel. DIR defaults to the 7-Scenes folder under $GMM_MCL_DATASETS.\n");
}

bool parseNumbers(const char* text, int n, double* out) {
  std::string s(text);
  for (int k = 0; k < n; ++k) {
    char* end = nullptr;
    out[k] = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || !std::isfinite(out[k])) return false;
    s = end;
    if (k + 1 < n) {
      if (s.empty() || s[0] != ',') return false;
      s = s.substr(1);
    }
  }
  return s.empty();
}

}  // namespace

int main(int argc, char** argv) {
  std::string map_path, format = "7scenes", dataset, per_pixel_path;
  int frame_index = 0;
  bool have_pose = false;
  double pose[4] = {0, 0, 0, 0};
  MeasurementParams measurement;
  FrameParams fp;
  fp.pixel_stride = 8;
  SequenceOptions so;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "gmm_mcl_score: %s needs a value\n", a.c_str());
      return 2;
    }
    const char* v = argv[++i];
    double num[3];
    auto number = [&](double* out) {
      if (!parseNumbers(v, 1, out)) {
        std::fprintf(stderr, "gmm_mcl_score: %s: '%s' is not a number\n", a.c_str(), v);
        std::exit(2);
      }
    };
    if (a == "--map")
      map_path = v;
    else if (a == "--format")
      format = v;
    else if (a == "--dataset")
      dataset = v;
    else if (a == "--gravity")
      so.gravity = v;
    else if (a == "--per-pixel")
      per_pixel_path = v;
    else if (a == "--frame") {
      number(num);
      frame_index = static_cast<int>(num[0]);
    } else if (a == "--stride") {
      number(num);
      fp.pixel_stride = static_cast<int>(num[0]);
    } else if (a == "--floor") {
      number(num);
      measurement.floor_log_density = static_cast<float>(num[0]);
    } else if (a == "--min-range") {
      number(num);
      fp.min_range_m = static_cast<float>(num[0]);
    } else if (a == "--max-range") {
      number(num);
      fp.max_range_m = static_cast<float>(num[0]);
    } else if (a == "--pose") {
      if (!parseNumbers(v, 4, pose)) {
        std::fprintf(stderr, "gmm_mcl_score: --pose: expected X,Y,Z,YAW (got '%s')\n", v);
        return 2;
      }
      have_pose = true;
    } else if (a == "--depth-noise") {
      if (!parseNumbers(v, 3, num)) {
        std::fprintf(stderr, "gmm_mcl_score: --depth-noise: expected A,B,Z0 (got '%s')\n", v);
        return 2;
      }
      measurement.depth_noise.a_m = static_cast<float>(num[0]);
      measurement.depth_noise.b_per_m = static_cast<float>(num[1]);
      measurement.depth_noise.z0_m = static_cast<float>(num[2]);
    } else {
      usage();
      return 2;
    }
  }
  if (map_path.empty()) {
    usage();
    return 2;
  }
  try {
    const std::string err = measurement.validate() + fp.validate();
    if (!err.empty()) throw std::invalid_argument(err);
    if (dataset.empty()) {
      const char* env = std::getenv("GMM_MCL_DATASETS");
      dataset = std::string(env && *env ? env : "../shared/datasets") + "/7scenes_redkitchen/data";
    }
    so.max_frames = frame_index + 1;
    const std::unique_ptr<Sequence> seq = openSequence(format, dataset, so);
    if (frame_index < 0 || frame_index >= seq->size()) {
      throw std::invalid_argument("--frame " + std::to_string(frame_index) + ": the sequence has " +
                                  std::to_string(seq->size()) + " frames");
    }
    const GmmMap map =
        rotateMap(loadMap(map_path), seq->R_aligned_world(), map_path + " (gravity-aligned)");
    const Eigen::Isometry3d T_base_cam = opticalToBase();
    const Eigen::Isometry3d truth = alignedBaseTrajectory(*seq, frame_index + 1)[frame_index];
    double roll, pitch, yaw;
    rpyFromRotation(truth.linear(), &roll, &pitch, &yaw);
    Particle p = poseToParticle(truth);
    if (have_pose) p = Particle{pose[0], pose[1], pose[2], pose[3]};
    const Eigen::Isometry3d T_map_cam = particleToPose(p, roll, pitch) * T_base_cam;
    const DepthFrame frame = prepareFrame(seq->loadDepth(frame_index), seq->intrinsics(), fp);
    if (frame.empty())
      throw std::runtime_error("frame " + std::to_string(frame_index) + " has no usable pixel");
    LikelihoodScratch scratch;
    const FrameLikelihood approx =
        poseLogLikelihood(map.packed(), frame, toRigidF(T_map_cam), measurement, &scratch);
    std::vector<double> per_pixel;
    const FrameLikelihood exact = exactFrameLogLikelihood(
        map, frame, T_map_cam, measurement, per_pixel_path.empty() ? nullptr : &per_pixel);
    long long pairs = 0, patches = 0;
    for (int q = 0; q < frame.grid.count(); ++q) {
      if (frame.patch_begin[q + 1] == frame.patch_begin[q]) continue;
      pairs += scratch.membership.countFor(q);
      ++patches;
    }
    const double px = frame.size();
    std::printf("%s frame %d, pose x %.3f y %.3f z %.3f yaw %.4f (%s), roll %.4f pitch %.4f\n",
                dataset.c_str(), frame_index, p.x_m, p.y_m, p.z_m, p.yaw_rad,
                have_pose ? "given" : "ground truth", roll, pitch);
    std::printf("pixels %d (stride %d; %d invalid, %d out of range)\n", static_cast<int>(px),
                fp.pixel_stride, frame.invalid_pixels, frame.out_of_range_pixels);
    std::printf(
        "log-likelihood per pixel: %.4f as the filter computes it (%.1f relevant "
        "components per patch), %.4f exactly (all %zu components)\n",
        approx.log_likelihood / px, patches ? static_cast<double>(pairs) / patches : 0.0,
        exact.log_likelihood / px, map.size());
    std::printf("floor hits: %.1f%% (floor %.1f nats)\n", 100.0 * exact.floor_hits / px,
                measurement.floor_log_density);
    std::printf(
        "the map's predicted level: %.4f nats/px with depth noise %.4g + %.4g (z - %.2g)^2 "
        "m (%.4f without the noise)\n",
        mapSelfLogDensity(map, measurement.floor_log_density, measurement.depth_noise),
        measurement.depth_noise.a_m, measurement.depth_noise.b_per_m, measurement.depth_noise.z0_m,
        mapSelfLogDensity(map, measurement.floor_log_density));
    if (!per_pixel_path.empty()) {
      std::ofstream out(per_pixel_path);
      if (!out) throw std::runtime_error(per_pixel_path + ": cannot open for writing");
      out << "u,v,depth_m,loglik\n";
      const Intrinsics& K = frame.intrinsics;
      for (size_t i = 0; i < frame.size(); ++i) {
        out << std::lround(K.cx_px + K.fx_px * frame.x_m[i] / frame.z_m[i]) << ','
            << std::lround(K.cy_px + K.fy_px * frame.y_m[i] / frame.z_m[i]) << ',' << frame.z_m[i]
            << ',' << per_pixel[i] << '\n';
      }
      std::printf("wrote %s\n", per_pixel_path.c_str());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gmm_mcl_score: %s\n", e.what());
    return 1;
  }
  return 0;
}
