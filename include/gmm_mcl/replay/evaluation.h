// The accuracy protocol of DESIGN.md: convergence, ATE after convergence, success.
#pragma once

#include <string>
#include <vector>

namespace gmm_mcl {

struct FrameError {
  double stamp_s = 0.0;
  double translation_m = 0.0;  // |estimated - true| base position
  double yaw_rad = 0.0;        // |wrapped yaw difference|
  // The same for the refined pose (the particle mean where the frame was not refined).
  double refined_translation_m = 0.0;
  double refined_yaw_rad = 0.0;
  bool refined = false;
};

struct EvaluationParams {
  double converged_below_m = 0.10;  // error threshold of convergence and success
  int hold_frames = 30;             // converged: the error stays below it this many frames
  int tail_frames = 100;            // success: converged and the last frames all below it
};

struct TrialMetrics {
  int frames = 0;
  bool converged = false;
  int converge_frame = -1;         // first frame after which the error stays below for hold_frames
  double converge_time_s = 0.0;    // its stamp minus the first stamp
  double ate_translation_m = 0.0;  // RMSE over frames from converge_frame on
  double ate_yaw_rad = 0.0;
  bool success = false;
  // ATE of the refined pose over the same frames, and the fraction of them that were refined.
  double refined_ate_translation_m = 0.0;
  double refined_ate_yaw_rad = 0.0;
  double refined_fraction = 0.0;
};

TrialMetrics evaluateTrial(const std::vector<FrameError>& errors, const EvaluationParams& params);

}  // namespace gmm_mcl
