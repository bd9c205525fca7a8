// The localizer: owns the predict / update / resample / recover / reset policy. Inputs are
// plain values (no ROS); the nodelet, replay and demo all drive it through step().
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/motion_model.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/filter/particle_filter_base.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/filter/start_hypotheses.h"

namespace gmm_mcl {

enum class StepStatus {
  kOk,                 // predicted and updated
  kPredictOnly,        // no depth frame given: predicted only
  kNoValidPixels,      // frame had no usable pixel: predicted only, weights kept
  kBadFrame,           // frame could not be used (size mismatch, layout): predicted only
  kDegenerateWeights,  // every likelihood non-finite or every weight zero: weights kept
  kBackendError,       // the backend failed (message names the fault): weights kept; with
                       // LocalizerParams::cpu_fallback the CPU backend takes over from here
  kTimeJumpBack,       // stamp went backwards: filter re-initialised from the initial region
};
const char* stepStatusName(StepStatus status);

// Another depth camera of the same update (a rig: forward + down; docs/multi_camera.md). Its
// log-likelihood is added to the other cameras' for every particle: one update per frame set.
// Its frame is prepared with its own parameters (stride, range) and scored with its own
// measurement parameters (depth noise); copy the localizer's (params().frame, .measurement)
// for the defaults.
struct CameraInput {
  std::string name;                   // in messages and StepResult::cameras
  const DepthImage* depth = nullptr;  // nullptr: no frame of this camera in this set
  Intrinsics intrinsics;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();  // its optical frame in base
  FrameParams frame;
  MeasurementParams measurement;
  // Its depth-scale estimate at start (refine_depth_scale; read when the camera first appears).
  double depth_scale_initial = 1.0;
};

struct StepInput {
  double stamp_s = 0.0;
  bool has_odometry = false;
  Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();
  // Roll/pitch from the IMU; else from odometry orientation; with neither, held from the last
  // refined estimate (the refinement estimates them, refine_attitude_prior_sigma_rad > 0).
  bool has_attitude = false;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  // The IMU gyro's heading at the stamp: its turn rate about the vertical integrated over time,
  // from any origin (only differences between steps are used). A step without odometry takes its
  // yaw change from the difference to the previous step's (cv_gyro), where the
  // constant-velocity model's yaw rate lags a fast turn. gyro_segment: the run of gap-free
  // samples the heading belongs to; headings of different runs are not compared (a gap or a time
  // jump starts a new run: GyroHeading). A caller with one continuous source leaves it 0.
  bool has_gyro_yaw = false;
  double gyro_yaw_rad = 0.0;
  long long gyro_segment = 0;
  const DepthImage* depth = nullptr;  // nullptr: predict only
  Intrinsics intrinsics;
  // The camera optical frame in the base frame at this frame's stamp (a gimbal, a moving
  // joint); false: params().T_base_cam. Kept for the following frames; the belief is untouched.
  bool has_T_base_cam = false;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  // The rig's other cameras at this stamp. When the first camera (depth) has no frame or no
  // usable pixel, the first usable of these takes its place for the step: screening, redraws
  // and the refinement use that one camera; the update sums over all usable ones.
  std::vector<CameraInput> more_cameras;
};

// One camera of a step (the first camera, then more_cameras in order).
struct CameraStepResult {
  std::string name;     // "" for the first camera
  bool used = false;    // its likelihood is in this update
  int pixels = 0;       // its used pixels
  std::string problem;  // why not used (no frame, no valid pixel, a bad frame)
  // Its depth-scale estimate after this step and whether it sits at its bound (as
  // StepResult::depth_scale for the first camera).
  double depth_scale = 1.0;
  bool depth_scale_at_bound = false;
};

struct StepTimings {
  double predict_ms = 0, frame_prep_ms = 0, projection_membership_ms = 0, likelihood_ms = 0,
         weights_ms = 0, resample_ms = 0, estimate_ms = 0, refine_ms = 0, rival_ms = 0,
         total_ms = 0;
  // Part of total_ms and of no other stage: the start's screening (after a uniform
  // (re)initialisation, its candidates drawn and scored and the best kept; 0 on other steps).
  double screen_ms = 0;
};

struct StepResult {
  StepStatus status = StepStatus::kOk;
  std::string message;         // why, for any status but kOk
  bool odometry_jump = false;  // an odometry step over max_odometry_step_m was ignored
  // How this step predicted: odometry, the constant-velocity model (no odometry, or the first
  // step of an odometry that appeared) or no motion (motion_model.h).
  MotionSource motion = MotionSource::kOdometry;
  // A constant-velocity step whose yaw change came from the IMU gyro's heading (cv_gyro).
  bool gyro_yaw = false;
  // The backend failed on this frame and the localizer switched to the CPU backend (the
  // particles kept); Localizer::backendWarning() says why from now on.
  bool backend_fallback = false;
  bool resampled = false;
  int reinitialised = 0;        // augmented-MCL reinitialised particles
  bool lost = false;            // the LostDetector fired on this frame (see message)
  int lost_reinitialised = 0;   // particles redrawn because of it
  int screened_candidates = 0;  // uniform candidates scored on this frame (redraws, start)
  // A wide start's places still followed after this step (start_hypotheses.h; 0: none), and
  // whether this step's best of them seeded the particle set.
  int start_places = 0;
  bool start_place_chosen = false;
  // The estimate was checked against rival places on this step (lost.rival_*): the best rival's
  // refined per-pixel log-likelihood minus the estimate's, both on the check's coarse frame (NaN:
  // no rival apart from the estimate's own place), and whether a rival won its last check in a
  // row (lost.rival_frames) and seeded the particle set.
  bool rival_checked = false;
  double rival_gain_per_pixel = std::numeric_limits<double>::quiet_NaN();
  bool rival_chosen = false;
  double reference_loglik_per_pixel = 0.0;  // the LostDetector's reference level
  PoseEstimate estimate;
  // The estimate refined by local maximisation of the likelihood (pose_refinement.h), when the
  // filter has converged and refinement is on; refinement.refined says whether it is usable.
  RefinementResult refinement;
  // The (first) camera's depth-scale estimate after this step (refine_depth_scale; 1 when off),
  // and whether it sits at its bound, 1 +- refine_depth_scale_max_error (within 1% of that
  // range): the camera's depths are further off than the bound allows, or the map does not fit.
  // A rig's other cameras: `cameras`.
  double depth_scale = 1.0;
  bool depth_scale_at_bound = false;
  double neff = 0.0;  // effective sample size after the update (before resampling)
  int particles = 0;  // particle count of this step
  int pixels = 0;     // used pixels (over all cameras used)
  // Per camera when more_cameras is not empty (the first camera first); empty otherwise.
  std::vector<CameraStepResult> cameras;
  double best_loglik_per_pixel = 0.0;
  double mean_loglik_per_pixel = 0.0;  // weighted mean over particles
  double floor_hit_fraction = 0.0;     // of used pixels, at the best particle
  double relevant_per_patch = 0.0;     // average members per patch with pixels
  double beta_fraction = 1.0;          // tempered: exponent used / 1 / (T * pixels)
  long long evaluations = 0;
  StepTimings timings;
};

class Localizer {
 public:
  // Validates params (throws std::invalid_argument naming every fault), initialises uniformly
  // over params.init. backend == nullptr: made from params.backend (CPU fallback).
  Localizer(const LocalizerParams& params, GmmMap map,
            std::unique_ptr<LikelihoodBackend> backend = nullptr);

  StepResult step(const StepInput& input);

  // New parameters for the same belief: the particles, their weights and the recovery region
  // stay (a particle count outside the new range is resampled to it). Throws
  // std::invalid_argument naming every fault, or when backend or seed differ (fixed at
  // construction); params.init is used only by the constructor.
  void setParams(const LocalizerParams& params);
  // Another map in the same frame (e.g. an updated one): the particles stay, the lost detector's
  // reference restarts from the new map's level. Throws std::invalid_argument when empty.
  void setMap(GmmMap map);

  // Uniform over a region (e.g. global localisation over mapBounds()); becomes the region that
  // recovery draws from.
  void reset(const InitRegion& region);
  // Gaussian around a pose (e.g. /initialpose), sigmas for x, y, z, yaw.
  void resetToPose(const Particle& pose, const Eigen::Vector4d& sigma);
  // The map's bounding box (means, padded by 3 sigma) with the full yaw range.
  InitRegion mapBounds() const;

  // The particle set (with the device filter, particles() and weights() copy it down from the
  // GPU when called).
  const ParticleFilterBase& filter() const { return *filter_; }
  const GmmMap& map() const { return map_; }
  const LocalizerParams& params() const { return params_; }
  LikelihoodBackend& backend() { return *backend_; }
  // Why the backend or the particle filter is not the one asked for (no device, a fallback after
  // a failure); empty when it is.
  const std::string& backendWarning() const { return backend_warning_; }
  // The last backend failure at run time (empty when none).
  const std::string& backendFault() const { return backend_fault_; }
  // Where the particle set lives: "host" or "cuda".
  std::string filterName() const { return filter_->name(); }
  Eigen::Isometry3d meanPose() const;
  double rollRad() const { return roll_rad_; }
  // The map's own expected per-point log-density (the LostDetector's starting reference).
  double mapSelfLogDensity() const { return map_self_ll_; }
  double pitchRad() const { return pitch_rad_; }
  // The constant-velocity model of steps without odometry (its velocity: velocity()).
  const ConstantVelocityModel& motionModel() const { return motion_model_; }
  // A wide start's places while they are followed (start_hypotheses.h; inactive otherwise).
  const StartHypotheses& startPlaces() const { return start_places_; }
  // The belief's spread: the largest position standard deviation and the yaw's (what the
  // refinement's limits compare, PoseEstimate::covariance).
  static void beliefSpread(const Eigen::Matrix<double, 6, 6>& covariance, double* position_sigma,
                           double* yaw_sigma);

 private:
  // The particle set a chosen place seeds (a wide start's best place, a winning rival): x, y, z,
  // yaw sigmas.
  static Eigen::Vector4d placeSigma() { return Eigen::Vector4d(0.05, 0.05, 0.01, 0.03); }
  // Fills the filter's candidate pool with count * lost.candidates_per_particle draws scored on
  // the frame in batches of the particle count: uniform from the recovery region, and with
  // local_stage a fraction (lost.local_candidate_fraction) around the best uniform ones instead.
  // A lost redraw's (redraw) are scored on the coarse frame (coarseContext) and its uniform
  // stage against redraw_map_; a wide start's keep the frame and blurred_map_.
  void screenCandidates(const MeasurementContext& context, int count, bool local_stage = false,
                        bool redraw = false);
  void stepOnce(const StepInput& input, StepResult* res);
  // The stages of stepOnce in order; those returning a status other than kOk end the step
  // (finishStep) with *why.
  void takeStepInputs(const StepInput& input, StepResult* res);  // stamp, mount, attitude
  void predictStep(const StepInput& input, StepResult* res);
  // The camera that measures first this step (StepInput's own, or the first usable of
  // more_cameras): prepared (cam_), else the status of the first camera tried with *why.
  StepStatus selectStepCamera(const StepInput& input, long long* patches_with_pixels,
                              StepResult* res, std::string* why);
  StepStatus prepareStepFrame(long long* patches_with_pixels, StepResult* res, std::string* why);
  // The rig's other cameras after first_camera_: prepared and their likelihoods added.
  StepStatus evaluateMoreCameras(const StepInput& input, const MeasurementContext& context,
                                 StepResult* res, std::string* why);
  StepStatus evaluateStep(const MeasurementContext& context, long long patches_with_pixels,
                          StepResult* res, std::string* why);
  StepStatus weighStep(StepResult* res, std::string* why);
  void estimateAndRefine(const StepInput& input, StepResult* res);
  void refineEstimate(const StepInput& input, StepResult* res);  // the converged estimate
  // The estimate against rival places around it, every lost.rival_check_frames frames while the
  // set is no wider than lost.rival_radius_m (rival_check.cpp). At the end of a step: it scores
  // on the step camera's host frame, which replaces the backend's.
  void checkRivals(StepResult* res);
  // Poses around `centre` scored on the rival frame against the blurred map: the best distinct
  // ones, at most lost.rival_places, best first.
  std::vector<Particle> proposeRivals(const Particle& centre);
  // Each place moved to the best of its draws around it on the rival frame against the blurred
  // map.
  void climbRivals(std::vector<Particle>* places);
  // A place's local maximum of the likelihood on the rival frame (the pose refinement).
  RefinementResult refineRival(const Particle& start);
  // The poses' per-pixel log-likelihoods on rival_frame_ against `map` (the localizer's map, or
  // a blurred one set on the backend for the call; an empty one: the localizer's).
  std::vector<double> scoreRivalPoses(const std::vector<Particle>& poses, const GmmMap& map);
  // depth_scales_ for the cameras of `input` (a camera seen first starts at its initial value).
  void syncDepthScales(const StepInput& input);
  // A refined frame's depth-scale estimate (and its information) into camera c's estimate.
  void learnDepthScale(int c, double estimate, double information, const StepResult& res);
  // The estimates into res (StepResult::depth_scale, cameras[].depth_scale).
  void reportDepthScales(StepResult* res) const;
  // The packed components a camera (its frame rf, extrinsics, parameters) can meet while the
  // refinement moves the pose from `mean`.
  void refineComponents(const Particle& mean, const RefinementFrame& rf,
                        const Eigen::Isometry3d& T_base_cam, const FrameParams& frame,
                        const MeasurementParams& mp, std::vector<ComponentF>* out);
  // The motion model's velocity sample and the held attitude (no attitude input) of a step.
  void observeMotion(const StepInput& input, const StepResult& res);
  StepStatus resampleAndRecover(const MeasurementContext& context, StepResult* res,
                                std::string* why);
  // A wide start's places (start_places_): followed on this frame, and at the stage's end the
  // best seeds the particle set (before the set is scored on the frame).
  void followStartPlaces(StepResult* res);
  // After a wide start's first update: its best distinct places, from the scored particle set.
  void seedStartPlaces();
  // An early end: the status (unless one is set), the message, the estimate and the timings.
  void finishStep(StepStatus status, const std::string& why,
                  std::chrono::steady_clock::time_point t_start, StepResult* res);
  // The host frame of this step's first camera (prepared here when the filter prepared it on
  // the device).
  const DepthFrame& hostFrame();
  // ctx with the step camera's frame at lost.coarse_stride_px / coarse_patch_px (coarse_frame_),
  // or ctx itself (no host frame, the frame's own stride, or nothing left at the coarse stride).
  const MeasurementContext& coarseContext(const MeasurementContext& ctx);
  // A backend failure: the status, and with cpu_fallback the switch to the CPU backend.
  void backendFailed(const std::string& what, StepResult* res);
  // What the map and the measurement parameters determine: the backend's map, the blurred map
  // of lost redraws and the map's expected per-point log-density (the lost detector's start).
  void prepareMap();

  LocalizerParams params_;
  GmmMap map_;
  GmmMap blurred_map_;  // map_ with lost.redraw_blur_m^2 on every covariance (wide starts)
  GmmMap redraw_map_;   // the same of map_ merged by lost.redraw_merge_m (lost redraws)
  std::unique_ptr<LikelihoodBackend> backend_;
  std::string backend_warning_;
  std::string backend_fault_;
  std::unique_ptr<ParticleFilterBase> filter_;
  InitRegion region_;
  double map_self_ll_ = 0.0;
  LostDetector lost_;
  bool screen_pending_ = true;      // after a uniform (re)initialisation: screen the next frame
  bool seed_start_places_ = false;  // this step screened a wide start: seed start_places_
  StartHypotheses start_places_;
  PlanarDelta last_delta_;  // this step's motion (predictStep)
  // The camera measuring first this step: its frame, extrinsics and parameters.
  struct StepCamera {
    const DepthImage* depth = nullptr;
    Intrinsics intrinsics;
    Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
    const FrameParams* frame = nullptr;
    const MeasurementParams* measurement = nullptr;
    int pixels = 0;  // its used pixels
  };
  StepCamera cam_;
  DepthFrame host_frame_;
  DepthFrame coarse_frame_;  // a redraw's candidates' (LostDetectionParams::coarse_stride_px)
  MeasurementContext coarse_ctx_;
  // The rig's other cameras this step (indexed like StepResult::cameras): their host frames
  // (an unprepared frame has zero width), their refinement components.
  int first_camera_ = 0;  // the camera measuring first this step (0: StepInput's own)
  int cameras_used_ = 1;  // cameras in this step's update
  uint64_t camera_set_ =
      0;  // the last update's cameras (bit c: StepResult::cameras[c]; 0: none yet)
  std::vector<DepthFrame> more_frames_;
  std::vector<std::vector<ComponentF>> more_components_;
  // Their refinement's pixel sums on the backend (makeNormalEquations; null: on the host).
  std::vector<std::unique_ptr<NormalEquationsEvaluator>> more_sums_;
  bool host_frame_ready_ = false;
  bool have_estimate_ = false;  // last_estimate_: the last step's (a fallback's belief)
  PoseEstimate last_estimate_;
  bool have_odometry_ = false;
  Eigen::Isometry3d last_odom_ = Eigen::Isometry3d::Identity();
  bool have_gyro_yaw_ = false;  // the previous step's StepInput::gyro_yaw_rad
  double last_gyro_yaw_rad_ = 0.0;
  long long last_gyro_segment_ = 0;
  bool have_stamp_ = false;
  double last_stamp_s_ = 0.0;
  double step_dt_s_ = 0.0;  // time since the previous step (0 at the first, after a jump back)
  ConstantVelocityModel motion_model_;
  double roll_rad_ = 0.0;
  double pitch_rad_ = 0.0;
  bool have_refined_ = false;  // last_refined_: the last frame's refined pose, moved by odometry
  Particle last_refined_;
  // Each camera's depth-scale estimate (refine_depth_scale; the first camera, then
  // more_cameras) and its refined frames' information, summed with the estimate's forgetting
  // (0: none yet).
  std::vector<double> depth_scales_;
  std::vector<double> depth_scale_information_;
  // The components the refinement can meet this frame (map indices, packed copies).
  std::vector<int> refine_index_;
  std::vector<ComponentF> refine_components_;
  // Rival places (checkRivals): frames since the last check, and the rival that won the last
  // check (moved by each step's motion) until the next frame confirms or drops it.
  int frames_since_rival_check_ = 0;
  bool rival_pending_ = false;
  int rival_wins_ = 0;  // frames in a row the pending rival won
  Particle rival_;
  std::mt19937 rival_rng_;
  DepthFrame rival_frame_;  // the step camera's frame at the rivals' coarser stride
  std::vector<ComponentF> rival_components_;  // the map's near a place (its refinement)
};

// The map's 3-sigma bounding box with any yaw: the region of a whole-map (global) start. Needs
// no localizer (the nodelet reads it before making one).
InitRegion mapBounds(const GmmMap& map);

}  // namespace gmm_mcl
