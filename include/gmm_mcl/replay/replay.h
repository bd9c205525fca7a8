// Offline replay of a recorded sequence (any Sequence format) through the Localizer (no ROS
// master, as fast as the CPU allows, seeded): odometry and attitude synthesised from ground
// truth per DESIGN.md (OdometrySynthesizer).
#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/replay/evaluation.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"

namespace gmm_mcl {

struct ReplayParams {
  LocalizerParams localizer;        // init region is set per trial around the true start
  int max_frames = -1;              // all
  ProtocolNoise noise;              // odometry and attitude noise (DESIGN.md protocol)
  double init_half_extent_m = 2.0;  // 4 m cube
  double init_yaw_half_range_rad = 0.5 * M_PI;  // yaw range pi
  // Global localisation: start uniform over the whole map's bounds (Localizer::mapBounds(), the
  // full yaw circle) instead of the cube around the true start.
  bool whole_map_start = false;
  // Inputs withheld (docs/no_odometry.md): no odometry (the localizer's constant-velocity model
  // predicts), no attitude (roll and pitch held from the refined estimates), no gyro heading
  // (a step without odometry turns at the constant-velocity model's yaw rate).
  bool odometry = true;
  bool attitude = true;
  bool gyro = true;
  // Every frame_step-th frame of the sequence (2: 15 Hz from 30 Hz); the synthesised odometry's
  // noise grows with the interval (variance x frame_step).
  int frame_step = 1;
  // Per frame, the distance from the truth to the nearest particle whose yaw is within
  // nearest_particle_yaw_rad of the truth's (NaN: none): whether the set still holds the truth
  // (global localisation). Copies the particle set down from the device each frame.
  bool nearest_particle = false;
  double nearest_particle_yaw_rad = 0.2;
  EvaluationParams evaluation;
};

struct ReplayFrame {
  double stamp_s = 0.0;
  Particle estimate;
  Particle refined;       // the refined pose, or the estimate where the frame was not refined
  bool has_truth = true;  // false: truth and error are unknown (a bag without ground truth)
  Particle truth;
  FrameError error;
  StepResult step;
  double nearest_particle_m = std::numeric_limits<double>::quiet_NaN();  // see ReplayParams
  // With nearest_particle, while a wide start follows its places: the nearest place's distance
  // (yaw within the same bound; NaN: none) and its rank by score (0: the best; -1: none).
  double nearest_place_m = std::numeric_limits<double>::quiet_NaN();
  int nearest_place_rank = -1;
};

struct TrialResult {
  uint64_t seed = 0;
  std::vector<ReplayFrame> frames;
  TrialMetrics metrics;
  double mean_step_ms = 0.0;
};

// Base frame of a handheld depth camera: x forward (optical z), y left, z up (optical -y).
Eigen::Isometry3d opticalToBase();
// The map rotated by R (means and covariances).
GmmMap rotateMap(const GmmMap& map, const Eigen::Matrix3d& R, const std::string& source);

using DepthProvider = std::function<const DepthImage&(int frame)>;
using ProgressCallback = std::function<void(int frame, int total, const ReplayFrame&)>;

// True base poses of the first n frames in the gravity-aligned frame (base = opticalToBase()).
std::vector<Eigen::Isometry3d> alignedBaseTrajectory(const Sequence& seq, int n);

// Fills the estimate, truth and error of a frame from a step result.
ReplayFrame makeReplayFrame(double stamp_s, const StepResult& step, const Particle* truth);

// One seeded trial over a sequence. `map_aligned` must already be in the gravity-aligned frame
// (rotateMap with seq.R_aligned_world()). Stamps are the sequence's own.
TrialResult runTrial(const Sequence& seq, const DepthProvider& depth, const GmmMap& map_aligned,
                     const ReplayParams& params, uint64_t seed,
                     const ProgressCallback& progress = nullptr);
inline TrialResult runSevenScenesTrial(const SevenScenesSequence& seq, const DepthProvider& depth,
                                       const GmmMap& map_aligned, const ReplayParams& params,
                                       uint64_t seed, const ProgressCallback& progress = nullptr) {
  return runTrial(seq, depth, map_aligned, params, seed, progress);
}
// Metrics of a trial's frames with truth (evaluateTrial) and the mean step time.
void finishTrial(const EvaluationParams& params, TrialResult* result);
// The distance from truth to the nearest particle within max_yaw_error_rad of its yaw (NaN: none).
double nearestParticleM(const std::vector<Particle>& particles, const Particle& truth,
                        double max_yaw_error_rad);

// Writers: TUM trajectory (t tx ty tz qx qy qz qw, readable by evo) of the estimate or the
// truth (frames with truth only), and the per-frame CSV (errors, empty where the truth is
// unknown, Neff, log-likelihood, stage timings).
void writeTum(const TrialResult& r, bool truth, const std::string& path);
void writeFrameCsv(const TrialResult& r, const std::string& path);

}  // namespace gmm_mcl
