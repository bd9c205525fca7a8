// Refinement of the converged estimate below the particle spacing: a continuous local
// maximisation of the same GMM likelihood as the particle weights (with the patch membership,
// the depth-noise model and the floor) over the 6-DoF pose (x, y, z, yaw, and roll and pitch
// with a Gaussian prior at the attitude input: an IMU's 0.5 deg of roll noise moves a wall 2 m
// away by 2 cm, more than the particle spacing), by expectation-maximisation: each iteration weighs
// every (pixel, relevant component) pair by its responsibility at the current pose (the floor takes
// the pixels no component explains), then takes one damped Gauss-Newton step on the weighted
// Mahalanobis residuals; a step is kept only when the likelihood rises. The particle set is not
// changed: the refined pose is reported beside the particle mean (docs/unseen_scenes.md).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/measurement_params.h"
#include "gmm_mcl/measurement/normal_equations.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {

struct RefinementParams {
  bool enabled = true;
  int max_iterations = 15;
  // Only a converged filter is refined: the particles' position and yaw spread (one standard
  // deviation) must be below these.
  double max_position_sigma_m = 0.10;
  double max_yaw_sigma_rad = 0.10;
  // While the previous frame was refined, refinement goes on up to these spreads (the larger of
  // them and the two above; at their defaults, the two above alone): a tracked set widens where
  // the prediction is wide (no odometry, a slow camera) or a view leaves a direction open, and its
  // mean then drifts while the refined track would hold. The correction limits below still apply;
  // the constant-velocity model does not learn from such a frame's refined pose. Measured in
  // docs/no_odometry.md (0.3 and 0.3: better at 10 Hz, and at 30 Hz two drifts in 24 trials).
  double track_max_position_sigma_m = 0.10;
  double track_max_yaw_sigma_rad = 0.10;
  // The same on a step predicted without odometry (the constant-velocity model, or no motion),
  // where the prediction is wider than odometry's and the set widens with it while the refined
  // track holds (docs/no_odometry.md: every rate better on both backends).
  double cv_track_max_position_sigma_m = 0.30;
  double cv_track_max_yaw_sigma_rad = 0.30;
  // A refined pose farther than this from the particle mean is rejected (a local optimum of the
  // likelihood that the particles do not support).
  double max_correction_m = 0.15;
  double max_correction_rad = 0.10;
  // Standard deviation of the prior on roll and pitch around the attitude input (the IMU's
  // noise); 0 keeps them fixed (a 4-DoF refinement).
  double attitude_prior_sigma_rad = 0.0087;
  // Iterations stop when a step moves less than both of these.
  double tolerance_m = 5e-4;
  double tolerance_rad = 5e-4;
  // Depth-scale self-calibration (docs/measurement_model.md, "Depth scale"): the refinement also
  // estimates the factor f by which the camera's depths (and so its points, along their rays)
  // are to be multiplied, each camera of a rig its own. The pose is refined with the frames'
  // current estimates (RefinementFrame::depth_scale); then the f take a Newton and a secant step
  // from them with the pose marginalised and a Gaussian prior of this standard deviation,
  // corrected for the depth noise's bias, kept within 1 +- depth_scale_max_error. An evaluator
  // without supportsDepthScale() is not used then (the sums run on the host); the noise correction
  // needs the frame's points on the host (RefinementFrame::points).
  bool estimate_depth_scale = false;
  // Take the depth noise's bias out of the estimate (simulation-extrapolation with the
  // measurement model's depth noise); off for a camera without noise (a simulator).
  bool depth_scale_noise_correction = true;
  double depth_scale_prior_sigma = 0.005;
  double depth_scale_max_error = 0.05;
  // The localizer's estimate: the refined frames' estimates averaged with their information as
  // weights, the past frames' weight shrinking by this fraction per frame (about 1 / rate
  // frames remembered).
  double depth_scale_rate = 0.02;
  // Its value at start (the nodelet saves the estimate here with the pose, ~save_pose_rate).
  double depth_scale_initial = 1.0;

  std::string validate() const;
};

struct RefinementResult {
  bool refined = false;   // false: not converged, no pixels, or no improving step (see why)
  std::string why;        // set when not refined
  Particle pose;          // the refined pose (the start when not refined)
  double roll_rad = 0.0;  // and its roll and pitch (the attitude input when not refined)
  double pitch_rad = 0.0;
  // The frame's depth-scale estimate (a Newton and a secant step from
  // RefinementFrame::depth_scale toward the frame's own; the frame's when not estimated or not
  // refined). The pose is refined with RefinementFrame::depth_scale.
  double depth_scale = 1.0;
  // What the frame's pixels tell of the depth scale with the pose free (the inverse variance of
  // f after the pose is marginalised out of the normal equations, without f's prior): small for
  // a frame whose scale trades against a translation (a frontal wall). 0 when not estimated.
  double depth_scale_information = 0.0;
  // The same for each RefinementView of the rig (in their order): each camera's depth scale is
  // its own (RefinementView::frame.depth_scale at the start).
  std::vector<double> more_depth_scale;
  std::vector<double> more_depth_scale_information;
  // Whether the pixel sums ran on the evaluator given (a backend's: the GPU with CUDA) rather
  // than on the host.
  bool sums_on_backend = false;
  int iterations = 0;
  double loglik_start = 0.0;  // nats per pixel at the start and the refined pose
  double loglik_refined = 0.0;
  double ms = 0.0;
};

// The frame a refinement maximises over: its intrinsics, patch grid and pixel count, with the
// points on the host (`points`) or, with points == nullptr, on the evaluator's device
// (NormalEquationsEvaluator::setPointsFromBackendFrame: the backend's current frame).
struct RefinementFrame {
  Intrinsics intrinsics;
  PatchGrid grid;
  int pixels = 0;
  const DepthFrame* points = nullptr;
  // The factor applied to the points' depths along their rays (the current depth-scale estimate;
  // 1: the camera's depths as they are).
  double depth_scale = 1.0;

  static RefinementFrame of(const DepthFrame& frame) {
    RefinementFrame f;
    f.intrinsics = frame.intrinsics;
    f.grid = frame.grid;
    f.pixels = static_cast<int>(frame.size());
    f.points = &frame;
    return f;
  }
};

// Another camera of a rig in the same refinement (docs/multi_camera.md): its frame (points on the
// host; its depth scale in frame.depth_scale), its components (packed map components near its
// view), extrinsics and measurement parameters. Its pixel sums run in `sums` (a backend's,
// LikelihoodBackend::makeNormalEquations; nullptr: on the host). With the depth scale estimated,
// each camera's is estimated (RefinementResult::more_depth_scale).
struct RefinementView {
  const std::vector<ComponentF>* components = nullptr;
  RefinementFrame frame;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  const MeasurementParams* params = nullptr;
  NormalEquationsEvaluator* sums = nullptr;
  // Its log-likelihood's weight in the sum (the localizer's: the first frame's pixel count over
  // this one's, so that each camera weighs as one frame).
  double weight = 1.0;
};

// Maximises the frame's log-likelihood (with `more`, the sum over the rig's frames) around `start`
// (a base pose; roll and pitch shared as in the filter). `components`: the map's packed components.
// `sums`: where the pixel sums run (a backend's evaluator, LikelihoodBackend::normalEquations());
// nullptr: on the host.
RefinementResult refinePose(const std::vector<ComponentF>& components, const RefinementFrame& frame,
                            const Particle& start, double roll_rad, double pitch_rad,
                            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params,
                            const RefinementParams& refinement,
                            NormalEquationsEvaluator* sums = nullptr,
                            const std::vector<RefinementView>& more = {});
inline RefinementResult refinePose(const std::vector<ComponentF>& components,
                                   const DepthFrame& frame, const Particle& start, double roll_rad,
                                   double pitch_rad, const Eigen::Isometry3d& T_base_cam,
                                   const MeasurementParams& params,
                                   const RefinementParams& refinement,
                                   NormalEquationsEvaluator* sums = nullptr) {
  return refinePose(components, RefinementFrame::of(frame), start, roll_rad, pitch_rad, T_base_cam,
                    params, refinement, sums);
}

// How far the components a refinement may need lie beyond the view of its start (view volume
// `reach`): its largest correction, and the far end of the view swept by its largest turn with
// some attitude slack. viewComponents grown by this gives a refinement its components.
double refinementReach(const RefinementParams& refinement, const ViewReach& reach);

}  // namespace gmm_mcl
