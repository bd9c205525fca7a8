// Kidnapped-robot trials: the filter tracks a sequence from its true start, then the sensor is
// teleported to another part of the sequence while odometry misses the jump (it reports the old
// motion across it, then the new motion with the body's true tilt, as a gravity-aware odometry);
// the trial measures whether and when the estimate comes back (DESIGN.md's convergence rule:
// error below 10 cm for 30 frames). Sources: the built-in synthetic scene and 7-Scenes.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gmm_mcl/filter/localizer.h"

namespace gmm_mcl {
namespace reliability {

// A sequence of true base poses with depth frames (rendered or read on demand).
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual int size() const = 0;
  virtual const Eigen::Isometry3d& truthBase(int i) const = 0;  // base in the map frame
  virtual DepthImage depth(int i, std::mt19937_64* rng) const = 0;
  virtual const Intrinsics& intrinsics() const = 0;
  virtual const Eigen::Isometry3d& baseToCamera() const = 0;
  virtual const GmmMap& map() const = 0;
  virtual double frameRateHz() const { return 30.0; }
  virtual std::string name() const = 0;
};

// The built-in synthetic scene (the mesh scene: room, boxes, cylinders; tiled GMM, 0.4 m,
// 1.5 cm) along its 6-DoF trajectory, rendered through the structured-light sensor model.
std::unique_ptr<FrameSource> makeSyntheticSource(const Intrinsics& K, int frames);
// The older box scene (room and blocks only) with axial noise and 2% dropout.
std::unique_ptr<FrameSource> makeBoxSceneSource(const Intrinsics& K, int frames);
// 7-Scenes redkitchen (gravity-aligned, like gmm_mcl_replay) against a map file.
std::unique_ptr<FrameSource> makeSevenScenesSource(const std::string& data_dir,
                                                   const std::string& map_path);
// Any data-set folder that gmm_mcl_replay reads ("7scenes", "tum", "stanford"), gravity-aligned
// as there, against a map file in the data set's world frame.
std::unique_ptr<FrameSource> makeSequenceSource(const std::string& format,
                                                const std::string& data_dir,
                                                const std::string& map_path);

struct KidnapParams {
  LocalizerParams localizer;  // T_base_cam and init are set per trial
  // Tracked frames before the kidnap (the filter starts at the truth). 0: a global
  // localisation trial instead: the filter starts uniform over the recovery region around a
  // random start frame and the recovery time is the convergence time.
  int track_frames = 45;
  // With track_frames 0: start uniform over the whole map's bounds and the full yaw circle
  // (Localizer::mapBounds()) instead of the recovery region around the start.
  bool whole_map_start = false;
  // false: the odometry is withheld (the localizer's constant-velocity model predicts; the
  // kidnap is then a jump of the frames alone): docs/no_odometry.md.
  bool odometry = true;
  // Without odometry, the IMU gyro's heading as well (StepInput::gyro_yaw_rad; as gmm_mcl_replay
  // --imu truth): the turn the odometry would report (across the kidnap the old trajectory's),
  // with the protocol's gyro bias and noise (ProtocolNoise).
  bool gyro = true;
  int after_frames = 180;                         // frames after it
  int start_frame = -1;                           // -1: drawn per seed
  double region_half_extent_m = 2.0;              // recovery region: the protocol's 4 m cube ...
  double region_yaw_half_range_rad = 0.5 * M_PI;  // ... and yaw range pi around the true start
  double min_jump_m = 1.0;                        // the teleport moves at least this far
  double odom_sigma_m = 0.005;                    // per frame (DESIGN.md protocol)
  double odom_sigma_yaw_rad = 0.002;
  double attitude_sigma_rad = 0.5 * M_PI / 180.0;
  double recovered_below_m = 0.10;
  int hold_frames = 30;
  double max_recovery_s = 5.0;
};

// One frame of a trial, for the per-frame CSV (gmm_mcl_kidnap --out).
struct KidnapFrame {
  int source_frame = 0;
  double error_m = 0.0;           // particle mean vs truth
  double refined_error_m = -1.0;  // refined pose vs truth; -1: not refined
  double best_loglik_px = 0.0;
  double reference_px = 0.0;
  int particles = 0;
  int lost_redrawn = 0;
  double position_sigma_m = 0.0;  // largest standard deviation of x, y, z
  double neff = 0.0;
};

struct KidnapResult {
  uint64_t seed = 0;
  int start_frame = 0, from_frame = 0, to_frame = 0;  // source indices
  double jump_m = 0.0, jump_yaw_rad = 0.0;
  double error_before_m = 0.0;  // at the last frame before the kidnap
  bool recovered = false;       // back within max_recovery_s and under the threshold at the end
  double recovery_s = -1.0;     // from the kidnap to the first frame of the holding window
  double final_error_m = 0.0;
  double ate_after_m = 0.0;  // RMSE from the recovery on
  int lost_events = 0;       // LostDetector firings
  int augmented_reinitialised = 0;
  bool any_non_finite = false;  // a NaN/inf in any estimate or covariance
  double mean_step_ms = 0.0;
  // At the last frame: the best particle's per-pixel log-likelihood and the LostDetector's
  // reference (a settled wrong mode shows as a best score within the margin of the reference).
  double final_best_loglik_px = 0.0;
  double final_reference_px = 0.0;
  std::vector<KidnapFrame> frames;  // every frame of the trial, the kidnap at track_frames
};

// Picks, for `seed`, a start frame, the kidnap frame (start + track_frames) and a destination
// that lies in the recovery region around the start, at least min_jump_m away, with room for
// after_frames. Throws std::runtime_error when the source has no such destination.
KidnapResult planKidnap(const FrameSource& src, const KidnapParams& params, uint64_t seed);

KidnapResult runKidnapTrial(const FrameSource& src, const KidnapParams& params, uint64_t seed);

}  // namespace reliability
}  // namespace gmm_mcl
