// Absolute-quality "lost" detection. Augmented MCL (paper) compares a fast and a slow average
// of the likelihood, so it only sees a drop: a filter that settles in a wrong mode from its
// first frames (or whose likelihood stays poor after a kidnap longer than the averages remember)
// is never flagged. This detector compares the best particle's per-pixel log-likelihood with a
// reference level and flags the filter as lost when it stays more than a margin below for a
// number of frames; the Localizer then reinitialises the worst particles. The reference starts
// at what the map and the depth-noise model predict for a correct pose, rises with the best
// score and sinks with it only a bounded amount (LostDetectionParams::reference_max_drop_nats).
#pragma once

#include "gmm_mcl/filter/params.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

// Mean of ln(exp(floor) + sum_j lambda_j N(x; mu_j, Sigma_j)) over `samples` points drawn from
// the map itself (seeded, deterministic): what a perfect sensor at the true pose would score
// per pixel. The starting reference of the detector.
double mapSelfLogDensity(const GmmMap& map, float floor_log_density, int samples = 2048,
                         uint64_t seed = 12345);
// The same for a depth camera with `noise` (measurement_params.h): every component convolved
// with the noise at nominal_range_m along its normal (its smallest-variance direction, a surface
// seen head-on), points drawn from the convolved map. A sharp map seen by a noisy camera scores
// the true pose about ln(sigma' / sigma) per pixel below its noise-free level; this predicts it.
double mapSelfLogDensity(const GmmMap& map, float floor_log_density, const DepthNoiseModel& noise,
                         int samples = 2048, uint64_t seed = 12345, double nominal_range_m = 2.0);

class LostDetector {
 public:
  LostDetector() = default;
  LostDetector(const LostDetectionParams& params, double initial_reference);

  // New parameters and starting reference (e.g. another map or measurement model); the current
  // reference is kept, raised to the new lowest level where below it.
  void setParams(const LostDetectionParams& params, double initial_reference);
  // Restarts the grace period (after any re-initialisation of the particle set).
  void restart();
  // The reference back to its starting level, and the grace period restarted: the scores'
  // level changed for another reason than the pose (a rig's camera dropped out or came back).
  void rebase();
  // Feeds one frame's best per-pixel log-likelihood; returns true when the filter is judged
  // lost on this frame (then the grace period restarts).
  bool update(double best_loglik_per_pixel);

  double reference() const { return reference_; }
  int framesBelow() const { return frames_below_; }
  bool enabled() const { return params_.margin_nats > 0.0; }

 private:
  LostDetectionParams params_;
  double reference_ = 0.0;
  double floor_ = 0.0;  // the reference's lowest value
  int frames_below_ = 0;
  int frames_since_restart_ = 0;
};

}  // namespace gmm_mcl
