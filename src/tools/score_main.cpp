// gmm_mcl_score: the log-likelihood of one frame of a data set at one pose, as the filter
// computes it (patch membership, float kernel) and exactly (every component, double), with the
// floor hits, the relevant components per patch and the level the map and the depth-noise model
// predict for a correct pose (the lost detector's starting reference); per pixel on request.
// The answer to "does the true pose score near the map's own level with these settings?".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/replay/replay.h"

namespace gmm_mcl {
namespace {

const char* kUsage =
    "usage: gmm_mcl_score --map MAP.gmm [--format 7scenes|tum|stanford] [--dataset DIR]\n"
    "                     [--frame I] [--pose X,Y,Z,YAW] [--pixel-stride PX (8)]\n"
    "                     [--depth-noise A,B,Z0]\n"
    "                     [--floor-log-density NATS] [--min-range-m M] [--max-range-m M]\n"
    "                     [--gravity G]\n"
    "                     [--per-pixel OUT.csv] [--refine] [--frames FIRST:LAST:STEP]\n"
    "                     [--attitude-noise DEG]\n"
    "The pose is the base in the gravity-aligned map frame (as gmm_mcl_replay's estimates),\n"
    "with the frame's true roll and pitch; default: the frame's ground truth. MAP is in the "
    "data\n"
    "set's world frame. --per-pixel writes u, v, depth and the exact log-likelihood of every\n"
    "used pixel. DIR defaults to the 7-Scenes folder under $GMM_MCL_DATASETS.\n"
    "--refine also maximises the likelihood from the pose (the filter's refinement, 6-DoF with\n"
    "the prior on roll and pitch at the true attitude) and prints how far the maximum lies from\n"
    "the ground truth. --frames scores every STEP-th frame of FIRST..LAST at its ground truth\n"
    "(with --refine: where the likelihood's own maximum lies, per frame as CSV on stdout and\n"
    "summarised on stderr): the accuracy that the map and the ground truth allow together.\n"
    "--attitude-noise: with --frames --refine, the refinement's attitude prior at the true roll\n"
    "and pitch plus this much Gaussian noise (the DESIGN.md protocol's IMU: 0.5).\n"
    "--refine-depth-scale true: the refinement also estimates the camera's depth scale, the\n"
    "pose refined with --refine-depth-scale-initial (default 1); per frame and summarised.\n"
    "Frame, measurement and refinement parameters: every one as --name-with-dashes (list under\n"
    "--help).\n";

// The frame as the refinement takes it: its depths times the depth scale that
// --refine-depth-scale-initial gives (the estimate a running filter would hold).
RefinementFrame scaledFrame(const DepthFrame& frame, const RefinementParams& rp) {
  RefinementFrame f = RefinementFrame::of(frame);
  f.depth_scale = rp.depth_scale_initial;
  return f;
}

// The components a pose's view can meet (grown by the refinement's reach when it refines): the
// pose's sums over them equal those over the whole map, at a cost that follows the view.
std::vector<ComponentF> componentsNear(const GmmMap& map, const DepthFrame& frame,
                                       const Eigen::Isometry3d& T_map_cam,
                                       const MeasurementParams& measurement,
                                       const RefinementParams* rp) {
  const ViewReach reach = viewReach(frame, measurement);
  std::vector<int> index;
  std::vector<ComponentF> out;
  viewComponents(map, toRigidF(T_map_cam), frame.intrinsics, reach,
                 rp ? refinementReach(*rp, reach) : 0.0, &index, &out);
  return out;
}

// Every step-th frame of first..last at its ground truth: the frame's log-likelihood there and,
// with refine, where the likelihood's maximum near it lies. CSV on stdout, summary on stderr.
int scoreRange(const Sequence& seq, const GmmMap& map, const Eigen::Isometry3d& T_base_cam,
               const FrameParams& fp, const MeasurementParams& measurement,
               const RefinementParams& rp, int first, int last, int step, bool refine,
               double attitude_noise_rad) {
  const std::vector<Eigen::Isometry3d> truth = alignedBaseTrajectory(seq, last + 1);
  std::printf("frame,pixels,loglik_per_px_truth,floor_hit_fraction%s\n",
              refine ? ",refined,loglik_per_px_refined,offset_m,offset_x_m,offset_y_m,offset_z_m,"
                       "offset_yaw_deg,offset_roll_deg,offset_pitch_deg,iterations,depth_scale,"
                       "depth_scale_information"
                     : "");
  std::vector<double> lls, offsets, scales;
  double scale_info = 0.0, scale_weighted = 0.0;
  double sum_sq = 0.0, sum_sq_yaw = 0.0;
  Eigen::Vector3d mean_offset = Eigen::Vector3d::Zero();
  int refined = 0;
  LikelihoodScratch scratch;
  for (int i = first; i <= last; i += step) {
    const DepthFrame frame = prepareFrame(seq.loadDepth(i), seq.intrinsics(), fp);
    if (frame.empty()) {
      std::fprintf(stderr, "frame %d: no usable pixel, skipped\n", i);
      continue;
    }
    double roll, pitch, yaw;
    rpyFromRotation(truth[i].linear(), &roll, &pitch, &yaw);
    const Particle p = poseToParticle(truth[i]);
    const Eigen::Isometry3d T_map_cam = particleToPose(p, roll, pitch) * T_base_cam;
    const std::vector<ComponentF> near =
        componentsNear(map, frame, T_map_cam, measurement, refine ? &rp : nullptr);
    const FrameLikelihood l =
        poseLogLikelihood(near, frame, toRigidF(T_map_cam), measurement, &scratch);
    const double px = frame.size();
    lls.push_back(l.log_likelihood / px);
    std::printf("%d,%d,%.5f,%.4f", i, static_cast<int>(px), l.log_likelihood / px,
                l.floor_hits / px);
    if (refine) {
      // The refinement's attitude prior at the IMU's roll and pitch: the truth, or the truth
      // with the protocol's attitude noise (seeded per frame).
      double roll_in = roll, pitch_in = pitch;
      if (attitude_noise_rad > 0.0) {
        std::mt19937_64 rng(1000003ULL * (i + 1));
        std::normal_distribution<double> g(0.0, attitude_noise_rad);
        roll_in += g(rng);
        pitch_in += g(rng);
      }
      const RefinementResult r = refinePose(near, scaledFrame(frame, rp), p, roll_in, pitch_in,
                                            T_base_cam, measurement, rp);
      const Eigen::Vector3d d(r.pose.x_m - p.x_m, r.pose.y_m - p.y_m, r.pose.z_m - p.z_m);
      const double dyaw = wrapAngle(r.pose.yaw_rad - p.yaw_rad);
      std::printf(",%d,%.5f,%.5f,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%d,%.5f,%.4g", r.refined ? 1 : 0,
                  r.loglik_refined, d.norm(), d.x(), d.y(), d.z(), dyaw * 180.0 / M_PI,
                  (r.roll_rad - roll) * 180.0 / M_PI, (r.pitch_rad - pitch) * 180.0 / M_PI,
                  r.iterations, r.depth_scale, r.depth_scale_information);
      if (r.refined) {
        ++refined;
        scales.push_back(r.depth_scale);
        scale_info += r.depth_scale_information;
        scale_weighted += r.depth_scale_information * r.depth_scale;
        offsets.push_back(d.norm());
        sum_sq += d.squaredNorm();
        sum_sq_yaw += dyaw * dyaw;
        mean_offset += d;
      }
    }
    std::printf("\n");
  }
  if (lls.empty()) {
    std::fprintf(stderr, "gmm_mcl_score: no frame with usable pixels in %d..%d\n", first, last);
    return 1;
  }
  std::fprintf(stderr, "%zu frames: median log-likelihood at the ground truth %.4f nats/px\n",
               lls.size(), upperMedian(lls));
  if (refine && refined > 0) {
    mean_offset /= refined;
    std::fprintf(stderr,
                 "likelihood maximum vs ground truth over %d refined frames: RMSE %.2f cm, median "
                 "%.2f cm, yaw RMSE %.3f deg; mean offset (%.2f, %.2f, %.2f) cm\n",
                 refined, 100.0 * std::sqrt(sum_sq / refined), 100.0 * upperMedian(offsets),
                 std::sqrt(sum_sq_yaw / refined) * 180.0 / M_PI, 100.0 * mean_offset.x(),
                 100.0 * mean_offset.y(), 100.0 * mean_offset.z());
    if (rp.estimate_depth_scale) {
      double mean = 0.0;
      for (double f : scales) mean += f;
      mean /= scales.size();
      std::fprintf(stderr,
                   "depth scale at the maximum: mean %.5f, median %.5f, weighted by each frame's "
                   "information %.5f (+- %.5f)\n",
                   mean, upperMedian(scales), scale_info > 0 ? scale_weighted / scale_info : 0.0,
                   scale_info > 0 ? 1.0 / std::sqrt(scale_info) : 0.0);
    }
  }
  return 0;
}

struct Options {
  std::string map_path, format = "7scenes", dataset, per_pixel_path;
  int frame_index = 0;
  int range_first = -1, range_last = -1, range_step = 1;
  bool refine = false;
  double attitude_noise_rad = 0.0;
  bool have_pose = false;
  double pose[4] = {0, 0, 0, 0};
  LocalizerParams lp;  // its frame and measurement parameters
  SequenceOptions so;
};

// The command line, checked (a usage error exits with status 2).
Options parseOptions(int argc, char** argv) {
  Options o;
  o.lp.frame.pixel_stride = 8;
  std::string frames_text, pose_text;
  double attitude_noise_deg = 0.0;
  cli::CommandLine cl("gmm_mcl_score", kUsage);
  // clang-format off
  cl.flags({{"map", &o.map_path}, {"format", &o.format}, {"dataset", &o.dataset},
            {"gravity", &o.so.gravity}, {"per-pixel", &o.per_pixel_path}, {"frame", &o.frame_index},
            {"attitude-noise", &attitude_noise_deg}, {"frames", &frames_text},
            {"pose", &pose_text}, {"refine", &o.refine}});
  // clang-format on
  cl.addLocalizerParams(&o.lp, {"refine"}, {"frame", "measurement", "refinement"});
  cl.alias("stride", "pixel-stride");
  cl.addDepthNoise(&o.lp.measurement.depth_noise);
  cl.parse(argc, argv);
  o.attitude_noise_rad = attitude_noise_deg * M_PI / 180.0;
  if (!frames_text.empty()) {
    const std::string& r = frames_text;
    const size_t c1 = r.find(':'), c2 = r.find(':', c1 == std::string::npos ? c1 : c1 + 1);
    double a3[3];
    if (c1 == std::string::npos || c2 == std::string::npos ||
        !cli::parseNumberList(r.substr(0, c1), 1, &a3[0]) ||
        !cli::parseNumberList(r.substr(c1 + 1, c2 - c1 - 1), 1, &a3[1]) ||
        !cli::parseNumberList(r.substr(c2 + 1), 1, &a3[2]) || a3[0] < 0 || a3[1] < a3[0] ||
        a3[2] < 1) {
      cl.fail("--frames: expected FIRST:LAST:STEP (got '" + r + "')");
    }
    o.range_first = static_cast<int>(a3[0]);
    o.range_last = static_cast<int>(a3[1]);
    o.range_step = static_cast<int>(a3[2]);
  }
  if (!pose_text.empty()) {
    if (!cli::parseNumberList(pose_text, 4, o.pose))
      cl.fail("--pose: expected X,Y,Z,YAW (got '" + pose_text + "')");
    o.have_pose = true;
  }
  if (o.map_path.empty()) cl.fail("--map is needed");
  return o;
}

// --refine: where the likelihood's maximum near the pose lies, against the ground truth.
void printRefinement(const GmmMap& map, const DepthFrame& frame, const Particle& p, double roll,
                     double pitch, const Eigen::Isometry3d& T_base_cam,
                     const MeasurementParams& measurement, const RefinementParams& rp,
                     const Eigen::Isometry3d& truth) {
  const std::vector<ComponentF> near =
      componentsNear(map, frame, particleToPose(p, roll, pitch) * T_base_cam, measurement, &rp);
  const RefinementResult r =
      refinePose(near, scaledFrame(frame, rp), p, roll, pitch, T_base_cam, measurement, rp);
  const Particle truth_p = poseToParticle(truth);
  std::printf(
      "refined: %s, x %.4f y %.4f z %.4f yaw %.5f roll %.5f pitch %.5f, %.4f nats/px "
      "(from %.4f), %d iterations, depth scale %.5f; %.2f mm and %.3f deg from the ground "
      "truth\n",
      r.refined ? "yes" : r.why.c_str(), r.pose.x_m, r.pose.y_m, r.pose.z_m, r.pose.yaw_rad,
      r.roll_rad, r.pitch_rad, r.loglik_refined, r.loglik_start, r.iterations, r.depth_scale,
      1000.0 *
          std::sqrt(std::pow(r.pose.x_m - truth_p.x_m, 2) + std::pow(r.pose.y_m - truth_p.y_m, 2) +
                    std::pow(r.pose.z_m - truth_p.z_m, 2)),
      std::abs(wrapAngle(r.pose.yaw_rad - truth_p.yaw_rad)) * 180.0 / M_PI);
}

// --per-pixel: u, v, depth and the exact log-likelihood of every used pixel.
void writePerPixel(const DepthFrame& frame, const std::vector<double>& per_pixel,
                   const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << "u,v,depth_m,loglik\n";
  const Intrinsics& K = frame.intrinsics;
  for (size_t i = 0; i < frame.size(); ++i) {
    out << std::lround(K.cx_px + K.fx_px * frame.x_m[i] / frame.z_m[i]) << ','
        << std::lround(K.cy_px + K.fy_px * frame.y_m[i] / frame.z_m[i]) << ',' << frame.z_m[i]
        << ',' << per_pixel[i] << '\n';
  }
  std::printf("wrote %s\n", path.c_str());
}

// One frame at one pose (the ground truth unless --pose): both likelihoods and what explains
// them.
void scoreFrame(const Sequence& seq, const GmmMap& map, const Eigen::Isometry3d& T_base_cam,
                const Options& o) {
  const MeasurementParams& measurement = o.lp.measurement;
  const FrameParams& fp = o.lp.frame;
  const int frame_index = o.frame_index;
  const Eigen::Isometry3d truth = alignedBaseTrajectory(seq, frame_index + 1)[frame_index];
  double roll, pitch, yaw;
  rpyFromRotation(truth.linear(), &roll, &pitch, &yaw);
  Particle p = poseToParticle(truth);
  if (o.have_pose) p = Particle{o.pose[0], o.pose[1], o.pose[2], o.pose[3]};
  const Eigen::Isometry3d T_map_cam = particleToPose(p, roll, pitch) * T_base_cam;
  const DepthFrame frame = prepareFrame(seq.loadDepth(frame_index), seq.intrinsics(), fp);
  if (frame.empty())
    throw std::runtime_error("frame " + std::to_string(frame_index) + " has no usable pixel");
  LikelihoodScratch scratch;
  const FrameLikelihood approx =
      poseLogLikelihood(componentsNear(map, frame, T_map_cam, measurement, nullptr), frame,
                        toRigidF(T_map_cam), measurement, &scratch);
  std::vector<double> per_pixel;
  const FrameLikelihood exact = exactFrameLogLikelihood(
      map, frame, T_map_cam, measurement, o.per_pixel_path.empty() ? nullptr : &per_pixel);
  long long pairs = 0, patches = 0;
  for (int q = 0; q < frame.grid.count(); ++q) {
    if (frame.patch_begin[q + 1] == frame.patch_begin[q]) continue;
    pairs += scratch.membership.countFor(q);
    ++patches;
  }
  const double px = frame.size();
  std::printf("%s frame %d, pose x %.3f y %.3f z %.3f yaw %.4f (%s), roll %.4f pitch %.4f\n",
              o.dataset.c_str(), frame_index, p.x_m, p.y_m, p.z_m, p.yaw_rad,
              o.have_pose ? "given" : "ground truth", roll, pitch);
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
  if (o.refine) {
    printRefinement(map, frame, p, roll, pitch, T_base_cam, measurement, o.lp.refinement, truth);
  }
  if (!o.per_pixel_path.empty()) writePerPixel(frame, per_pixel, o.per_pixel_path);
}

int run(int argc, char** argv) {
  Options o = parseOptions(argc, argv);
  const MeasurementParams& measurement = o.lp.measurement;
  const FrameParams& fp = o.lp.frame;
  return cli::reportErrors("gmm_mcl_score", [&] {
    const std::string err = measurement.validate() + fp.validate() + o.lp.refinement.validate();
    if (!err.empty()) throw std::invalid_argument(err);
    if (o.dataset.empty()) {
      const char* env = std::getenv("GMM_MCL_DATASETS");
      o.dataset =
          std::string(env && *env ? env : "../shared/datasets") + "/7scenes_redkitchen/data";
    }
    o.so.max_frames = (o.range_first >= 0 ? o.range_last : o.frame_index) + 1;
    const std::unique_ptr<Sequence> seq = openSequence(o.format, o.dataset, o.so);
    const int last_needed = o.range_first >= 0 ? o.range_last : o.frame_index;
    if (o.frame_index < 0 || last_needed >= seq->size()) {
      throw std::invalid_argument("frame " + std::to_string(last_needed) + ": the sequence has " +
                                  std::to_string(seq->size()) + " frames");
    }
    const GmmMap map =
        rotateMap(loadMap(o.map_path), seq->R_aligned_world(), o.map_path + " (gravity-aligned)");
    const Eigen::Isometry3d T_base_cam = opticalToBase();
    if (o.range_first >= 0) {
      return scoreRange(*seq, map, T_base_cam, fp, measurement, o.lp.refinement, o.range_first,
                        o.range_last, o.range_step, o.refine, o.attitude_noise_rad);
    }
    scoreFrame(*seq, map, T_base_cam, o);
    return 0;
  });
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
