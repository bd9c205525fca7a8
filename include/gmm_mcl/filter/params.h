// Parameters of the particle filter and the localizer, defaults from the paper (N = 1068,
// Table 1 desktop values). Every struct has validate(): empty when valid, else every fault.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "gmm_mcl/backend/backend_params.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/filter/motion_model.h"
#include "gmm_mcl/filter/pose_refinement.h"
#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {

constexpr int kDefaultParticleCount = 1068;

enum class WeightingMode {
  // Paper Eq. weight: w ~ 1 / NLL. Guard: when the best particle's NLL is below
  // paper_min_nll_per_pixel * pixels (NLL can be negative), every NLL is shifted up by the same
  // amount so that the best one equals that margin; otherwise the paper's formula is unchanged.
  kPaper,
  // w ~ exp(beta * (L - L_max)) with beta = 1 / (temperature * pixels) (the mean per-pixel
  // log-likelihood, tempered), lowered for this frame where needed so that the effective sample
  // size after the update stays >= neff_floor_fraction * N: one frame can never collapse the
  // particle set (adaptive tempering, as in SMC samplers). Steady tracking never hits the floor.
  kTempered,
};
bool parseWeightingMode(const std::string& name, WeightingMode* out);
const char* weightingModeName(WeightingMode mode);

// Uniform initial distribution: a box in the map frame and a yaw range.
struct InitRegion {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extent_m = Eigen::Vector3d(2.0, 2.0, 2.0);  // the paper's 4 m cube
  double yaw_centre_rad = 0.0;
  double yaw_half_range_rad = 0.5 * M_PI;  // a yaw range of pi

  std::string validate() const;
};

struct ParticleFilterParams {
  // The particle count at every uniform or Gaussian (re)initialisation, and the largest count.
  int num_particles = kDefaultParticleCount;
  // Adaptive particle count (KLD-sampling, Fox 2003): at each resampling the count becomes the
  // number of samples that bounds the Kullback-Leibler error of the resampled set by
  // kld_epsilon with probability kld_quantile's (z = kld_z) for the number of occupied state bins
  // (kld_bin_m x kld_bin_m x kld_bin_m x kld_bin_rad), within [min_particles, num_particles]: a
  // spread or lost belief keeps num_particles, a converged one shrinks to min_particles.
  // min_particles 0 (or num_particles): a fixed count, the paper's.
  int min_particles = 0;
  double kld_epsilon = 0.05;
  double kld_z = 2.326;  // upper 0.99 quantile of the standard normal
  double kld_bin_m = 0.2;
  double kld_bin_rad = 0.2;
  // Process noise per update (paper Table 1, desktop).
  double sigma_translation_m = 0.02;
  double sigma_yaw_rad = 0.01;
  // Augmented MCL rates (Thrun's convention: the slow average has the smaller rate). Table 1
  // lists the pair 0.01 / 0.001; assigned to the roles by magnitude, since alpha_slow >
  // alpha_fast would reinitialise while the likelihood improves and never when it drops.
  double alpha_slow = 0.001;
  double alpha_fast = 0.01;
  // Dead band of the recovery rule (AugmentedMcl): reinitialise only once w_fast < threshold *
  // w_slow. 1 = Thrun's rule.
  double recovery_threshold = 0.9;
  WeightingMode weighting = WeightingMode::kTempered;
  double temperature = 1.0;              // kTempered
  double neff_floor_fraction = 0.2;      // kTempered: adaptive tempering floor (0 = off)
  double paper_min_nll_per_pixel = 1.0;  // kPaper guard, nats per pixel
  int resample_groups = 4;               // stratified groups, low-variance sampling inside each
  double resample_neff_fraction = 0.5;   // resample when Neff < fraction * N
  double attitude_sigma_rad = 0.0087;    // roll/pitch standard deviation for the covariance
  uint64_t seed = 1;

  bool adaptive() const { return min_particles > 0 && min_particles < num_particles; }
  std::string validate() const;
};

// The KLD-sampling bound: particles needed for k occupied bins (Fox 2003, Eq. 8), at least 1.
int kldParticleBound(int occupied_bins, double epsilon, double z);

// The particle-count range the tools use when none is given, by backend: "cuda" 100,000 while
// the belief is spread or lost, down to 1068 (the paper's N) while tracking; "cpu" (and a TX2's
// budget) 3000 down to 1068. Measured on the unseen-scene protocol (docs/unseen_scenes.md).
void defaultParticleRange(const std::string& backend, int* min_particles, int* max_particles);

// Absolute-quality recovery (LostDetector): when the best particle's per-pixel log-likelihood
// stays more than margin_nats below a reference level for `frames` frames, the worst
// reinit_fraction of the particles (by that frame's likelihood) are drawn afresh from the
// recovery region. The reference starts at the map's own expected per-point log-density and
// follows the best score (rate up, rate down per frame).
struct LostDetectionParams {
  double margin_nats = 3.0;  // per pixel; 0 = off
  int frames = 10;           // consecutive frames below (1/3 s at 30 Hz)
  int grace_frames = 30;     // after any (re)initialisation, before judging
  double reference_rate_up = 0.05;
  double reference_rate_down = 0.005;
  // The reference never follows the best score further down than this below the level the map
  // and the depth-noise model predict for a correct pose (mapSelfLogDensity with the noise): a
  // filter settled in a wrong mode from its first frames, or after a kidnap, is flagged however
  // long it stays there, while a scene whose true pose scores somewhat below the map's own level
  // (clutter, an older map) still lowers the reference that far.
  double reference_max_drop_nats = 0.5;
  double reinit_fraction = 0.9;  // the best (1 - fraction) particles are kept
  // Redrawn particles (here and at a uniform (re)initialisation) are the best-scoring of this
  // many uniform candidates per particle, scored on the current frame: a denser search of the
  // region for the same particle count (1 = plain uniform draws).
  int candidates_per_particle = 16;
  // A lost redraw draws this fraction of its candidates around the best elite_fraction of the
  // uniform ones (Gaussian, local_sigma_m per axis, local_sigma_rad in yaw): the search narrows
  // onto the promising places within one frame.
  double local_candidate_fraction = 0.5;
  double elite_fraction = 0.01;
  double local_sigma_m = 0.25;
  double local_sigma_rad = 0.2;
  // Levels of local candidates, each around the best of those before it and a third as wide
  // (the local candidates shared equally among them).
  int local_levels = 1;
  // A lost redraw scores its uniform candidates against the map blurred by this much (every
  // covariance plus blur^2 I): the likelihood's basin widens from a few decimetres to about a
  // metre, so that far more of the uniform candidates land in the true pose's basin; the local
  // candidates around the best of them are scored against the map itself. 0: no blur.
  double redraw_blur_m = 0.15;
  // The blurred map of a lost redraw merges the components whose means share a cube of this edge
  // (moment matching: weight, mean and covariance of the cube's mixture) before the blur: a
  // coarser map for a coarse stage, fewer components to project per candidate. 0: no merge.
  double redraw_merge_m = 0.3;
  // A lost redraw's candidates are scored on a coarse frame of about this many pixels (a
  // stride of sqrt(width * height / coarse_pixels), rounded down to a multiple of the frame's,
  // in patches of 4 x 4 of its pixels: 300 is stride 32 and 128 px patches at 640 x 480). They
  // only choose which poses enter the set; the next frame weighs those on the full frame. Host
  // particle filter only (the GPU filter scores on its device frame). 0: the frame itself.
  // A wide start keeps the frame and the unmerged blurred map (docs/building_scale.md).
  int coarse_pixels = 300;
  // A uniform start over a region of at least this horizontal area (a whole building,
  // ~global_localization) searches as a lost redraw does: the blurred map's uniform stage, then
  // the local candidates. Uniform draws alone rarely land in the true pose's basin there. Smaller
  // regions (the 4 m cube, one room) keep the plain uniform candidates. 0: every start.
  double start_local_stage_min_area_m2 = 400.0;
  // Such a start can also follow this many of the first update's best distinct places over
  // its next start_place_frames frames, each by a hill climb on every frame
  // (start_hypotheses.h); then the best of them seeds the particle set unless the set already
  // sits there. 0: off (the default: in the building world it found the truth in 1 of 4 walks,
  // docs/building_scale.md).
  int start_places = 0;
  int start_place_frames = 90;
  // Rival places: every rival_check_frames frames the estimate is checked against the places
  // around it (within rival_radius_m, yaw within rival_yaw_rad) while the set is no wider than
  // that, on a coarse frame (about 1200 pixels): rival_candidates poses scored against the merged
  // blurred map, the best rival_places distinct ones moved to the best of local draws on the
  // blurred map, then each and the estimate refined on the map (pose_refinement.h). A rival that
  // beats the estimate by rival_margin_nats per pixel on rival_frames frames in a row (refined
  // again on each, moved by the steps' motion) seeds the particle set. A set that settles beside
  // the truth, sliding along a wall that leaves a direction open, scores at the map's level and
  // never trips the lost detector; the truth's basin, a decimetre wide, holds no particle any
  // more (docs/building_scale.md). 0: off (the default: it helped the 2-core CPU backend in some
  // walks of the building world and one Replica start, changed nothing on an H200 with 100,000
  // particles, and a check costs about 0.1 s on the CPU; 15 is the setting measured).
  int rival_check_frames = 0;
  double rival_radius_m = 2.0;
  double rival_yaw_rad = 0.15;
  int rival_candidates = 256;
  int rival_places = 8;
  double rival_margin_nats = 0.2;
  int rival_frames = 2;

  std::string validate() const;
};

struct LocalizerParams {
  ParticleFilterParams filter;
  LostDetectionParams lost;
  FrameParams frame;
  MeasurementParams measurement;
  RefinementParams refinement;
  InitRegion init;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();  // camera optical frame in base
  // An odometry step longer than this (per update) is treated as a jump: not applied, reported.
  double max_odometry_step_m = 1.0;
  // Steps without odometry: the constant-velocity model (docs/no_odometry.md).
  ConstantVelocityParams constant_velocity;
  std::string backend = "cpu";
  // With the CUDA backend the particle set lives on the GPU and the whole filter step runs
  // there (CudaParticleFilter); false keeps it on the host (ParticleFilter, the reference), the
  // backend scoring uploaded poses. No effect with the CPU backend.
  bool device_filter = true;
  // When the backend fails at run time (a CUDA error, the GPU out of memory), switch to the CPU
  // backend keeping the particles (copied down from the GPU) instead of failing every frame.
  bool cpu_fallback = true;
  // The CUDA backend's kernel tuning (start-up; no effect with the CPU backend).
  CudaTuningParams cuda;

  std::string validate() const;
};

}  // namespace gmm_mcl
