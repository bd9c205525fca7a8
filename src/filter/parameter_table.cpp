#include "gmm_mcl/filter/parameter_table.h"

#include <cstdio>
#include <cstdlib>

#include "gmm_mcl/common/enum_names.h"
#include "gmm_mcl/measurement/depth_noise_preset.h"

namespace gmm_mcl {

namespace {

const EnumName<ParamType> kParamTypeNames[] = {{"bool", ParamType::kBool},
                                               {"int", ParamType::kInt},
                                               {"double", ParamType::kDouble},
                                               {"string", ParamType::kString},
                                               {"vector3", ParamType::kVector3}};

}  // namespace

const char* paramTypeName(ParamType type) { return enumNameOf(type, kParamTypeNames); }

namespace {

// Shortest text that reads back as the same number ("0.02", "1e-05", "3.14159"); a value that
// a float holds exactly (a float field's) as the same float: 0.1f is "0.1".
std::string number(double x) {
  if (std::isnan(x)) return "unset";
  const bool is_float = static_cast<double>(static_cast<float>(x)) == x;
  char buf[32];
  if (x == std::floor(x) && std::abs(x) < 1e15) {  // 10, not 1e+01
    std::snprintf(buf, sizeof(buf), "%.0f", x);
    return buf;
  }
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, x);
    const double back = std::strtod(buf, nullptr);
    if (back == x || (is_float && static_cast<float>(back) == static_cast<float>(x))) break;
  }
  return buf;
}

}  // namespace

std::string ParamValue::toString() const {
  switch (type) {
    case ParamType::kBool:
      return b ? "true" : "false";
    case ParamType::kInt:
      return std::to_string(i);
    case ParamType::kDouble:
      return number(d);
    case ParamType::kString:
      return s;
    case ParamType::kVector3:
      return "[" + number(v.x()) + ", " + number(v.y()) + ", " + number(v.z()) + "]";
  }
  return "";
}

bool ParamValue::operator==(const ParamValue& o) const {
  if (type != o.type) return false;
  switch (type) {
    case ParamType::kBool:
      return b == o.b;
    case ParamType::kInt:
      return i == o.i;
    case ParamType::kDouble:
      return d == o.d || (std::isnan(d) && std::isnan(o.d));
    case ParamType::kString:
      return s == o.s;
    case ParamType::kVector3:
      return v == o.v;
  }
  return false;
}

namespace {

using P = LocalizerParams;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr bool kRuntime = true, kStartup = false;

// choices: the accepted values of a string parameter (none: any, or those p already has).
void add(ParamTable<P>* t, ParamSpec<P> p, std::vector<std::string> choices = {}) {
  if (!choices.empty()) p.choices = std::move(choices);
  t->push_back(std::move(p));
}

// Particles.
void addParticlesParams(ParamTable<P>* t) {
  const char* g = "particles";
  add(t, paramSpec<P>("num_particles", GMM_MCL_PARAM_FIELD(P, filter.num_particles), "", g,
                      {1, 1e7}, kRuntime,
                      "Particle count at every (re)initialisation and the largest count (paper: "
                      "1068); a change resamples the current set to the new count"));
  add(t,
      paramSpec<P>(
          "min_particles", GMM_MCL_PARAM_FIELD(P, filter.min_particles), "", g, {0, 1e7}, kRuntime,
          "Smallest count of the adaptive (KLD-sampling) particle count, which moves within "
          "[min_particles, num_particles] at each resampling; 0 = a fixed count"));
  add(t, paramSpec<P>("kld_epsilon", GMM_MCL_PARAM_FIELD(P, filter.kld_epsilon), "", g, {1e-4, 1},
                      kRuntime,
                      "KLD-sampling: bound on the Kullback-Leibler error of the resampled set"));
  add(t, paramSpec<P>(
             "kld_z", GMM_MCL_PARAM_FIELD(P, filter.kld_z), "", g, {0.1, 10}, kRuntime,
             "KLD-sampling: standard normal quantile of the bound's probability (2.326: 0.99)"));
  add(t, paramSpec<P>("kld_bin_m", GMM_MCL_PARAM_FIELD(P, filter.kld_bin_m), "m", g, {1e-3, 10},
                      kRuntime, "KLD-sampling: bin size along x, y and z"));
  add(t, paramSpec<P>("kld_bin_rad", GMM_MCL_PARAM_FIELD(P, filter.kld_bin_rad), "rad", g,
                      {1e-3, 3.15}, kRuntime, "KLD-sampling: bin size in yaw"));
  add(t, paramSpec<P>(
             "resample_neff_fraction", GMM_MCL_PARAM_FIELD(P, filter.resample_neff_fraction), "", g,
             {0, 1}, kRuntime,
             "Resample when the effective sample size falls below this fraction of the count"));
  add(t, paramSpec<P>("resample_groups", GMM_MCL_PARAM_FIELD(P, filter.resample_groups), "", g,
                      {1, 1e7}, kRuntime,
                      "Stratified resampling groups (low-variance sampling inside each); at most "
                      "the smallest count"));
  add(t, paramSpec<P>("seed", GMM_MCL_PARAM_FIELD(P, filter.seed), "", g, {0, 2147483647}, kStartup,
                      "Seed of the filter's random generator: equal inputs give equal outputs"));
}

// Motion model.
void addMotionParams(ParamTable<P>* t) {
  const char* g = "motion";
  add(t, paramSpec<P>(
             "sigma_translation_m", GMM_MCL_PARAM_FIELD(P, filter.sigma_translation_m), "m", g,
             {0, 1}, kRuntime,
             "Process noise per update along x, y and z (paper Table 1: 0.02 desktop, 0.025 TX2)"));
  add(t, paramSpec<P>("sigma_yaw_rad", GMM_MCL_PARAM_FIELD(P, filter.sigma_yaw_rad), "rad", g,
                      {0, 1}, kRuntime,
                      "Process noise per update in yaw (paper Table 1: 0.01 desktop, 0.1 TX2)"));
  add(t, paramSpec<P>("max_odometry_step_m", GMM_MCL_PARAM_FIELD(P, max_odometry_step_m), "m", g,
                      {1e-3, 1000}, kRuntime,
                      "An odometry step longer than this between two updates is a jump: not "
                      "applied, reported in the status"));
  add(t, paramSpec<P>(
             "attitude_sigma_rad", GMM_MCL_PARAM_FIELD(P, filter.attitude_sigma_rad), "rad", g,
             {0, 1}, kRuntime,
             "Roll and pitch standard deviation reported in the pose covariance (the IMU's)"));
  add(t, paramSpec<P>("cv_model", GMM_MCL_PARAM_FIELD(P, constant_velocity.enabled), "", g, {},
                      kRuntime,
                      "Steps without odometry predict with a constant velocity estimated from the "
                      "filter's own converged estimates (false: no motion, the per-update noise)"));
  add(t, paramSpec<P>("cv_velocity_smoothing",
                      GMM_MCL_PARAM_FIELD(P, constant_velocity.velocity_smoothing), "", g,
                      {1e-3, 1}, kRuntime,
                      "Constant-velocity model: weight of the newest velocity sample (exponential "
                      "smoothing; 1 = the last sample alone)"));
  add(t, paramSpec<P>("cv_vertical_time_constant_s",
                      GMM_MCL_PARAM_FIELD(P, constant_velocity.vertical_time_constant_s), "s", g,
                      {0, 100}, kRuntime,
                      "Constant-velocity model: the vertical speed learns over this time (each "
                      "sample by 1 - exp(-dt / this); 0: as the other axes)"));
  add(t,
      paramSpec<P>("cv_sigma_speed_m_s", GMM_MCL_PARAM_FIELD(P, constant_velocity.sigma_speed_m_s),
                   "m/s", g, {0, 10}, kRuntime,
                   "Constant-velocity model: translation noise sigma_translation_m + this x the "
                   "time since the last step (twice while no velocity is known)"));
  add(t, paramSpec<P>("cv_sigma_yaw_rate_rad_s",
                      GMM_MCL_PARAM_FIELD(P, constant_velocity.sigma_yaw_rate_rad_s), "rad/s", g,
                      {0, 10}, kRuntime,
                      "Constant-velocity model: yaw noise sigma_yaw_rad + this x the time since "
                      "the last step (twice while no velocity is known)"));
  add(t, paramSpec<P>("cv_max_gap_s", GMM_MCL_PARAM_FIELD(P, constant_velocity.max_gap_s), "s", g,
                      {1e-3, 100}, kRuntime,
                      "Constant-velocity model: a longer gap between steps or estimates forgets "
                      "the velocity"));
  add(t, paramSpec<P>("cv_max_speed_m_s", GMM_MCL_PARAM_FIELD(P, constant_velocity.max_speed_m_s),
                      "m/s", g, {1e-3, 100}, kRuntime,
                      "Constant-velocity model: a faster velocity sample is a jump of the estimate "
                      "and restarts the velocity from zero"));
  add(t, paramSpec<P>("cv_gyro", GMM_MCL_PARAM_FIELD(P, constant_velocity.use_gyro), "", g, {},
                      kRuntime,
                      "Steps without odometry take their yaw change from the IMU gyro's heading "
                      "where the input has one (the nodelet: imu angular_velocity) instead of the "
                      "constant-velocity yaw rate"));
  add(t, paramSpec<P>("cv_world_velocity", GMM_MCL_PARAM_FIELD(P, constant_velocity.world_velocity),
                      "", g, {}, kRuntime,
                      "Constant-velocity model, a step turned by the gyro: the translation "
                      "velocity held in the map frame (a drone, a hand-held camera) instead of "
                      "the body frame (a car)"));
  add(t, paramSpec<P>("cv_gyro_sigma_yaw_rate_rad_s",
                      GMM_MCL_PARAM_FIELD(P, constant_velocity.gyro_sigma_yaw_rate_rad_s), "rad/s",
                      g, {0, 10}, kRuntime,
                      "Yaw noise of a gyro-predicted step: sigma_yaw_rad + this x the time since "
                      "the last step"));
}

// Weighting.
void addWeightingParams(ParamTable<P>* t) {
  const char* g = "weighting";
  {
    ParamSpec<P> p;
    p.name = "weighting";
    p.field = "filter.weighting";
    p.type = ParamType::kString;
    p.group = g;
    p.runtime = kRuntime;
    p.choices = {"tempered", "paper"};
    p.help =
        "Particle weights: tempered = exp of the tempered mean log-likelihood with an Neff "
        "floor; paper = 1 / NLL with its guard";
    p.get = [](const P& s) {
      ParamValue v;
      v.type = ParamType::kString;
      v.s = weightingModeName(s.filter.weighting);
      return v;
    };
    p.set = [](P* s, const ParamValue& v) { parseWeightingMode(v.s, &s->filter.weighting); };
    add(t, p);
  }
  add(t, paramSpec<P>("temperature", GMM_MCL_PARAM_FIELD(P, filter.temperature), "", g, {0.01, 100},
                      kRuntime, "tempered: the temperature T (weights exp(L / (T pixels)))"));
  add(t, paramSpec<P>("neff_floor_fraction", GMM_MCL_PARAM_FIELD(P, filter.neff_floor_fraction), "",
                      g, {0, 0.99}, kRuntime,
                      "tempered: one update never leaves fewer effective particles than this "
                      "fraction of the count (0 = off)"));
  add(t, paramSpec<P>(
             "paper_min_nll_per_pixel", GMM_MCL_PARAM_FIELD(P, filter.paper_min_nll_per_pixel),
             "nats/px", g, {0, 100}, kRuntime,
             "paper: guard, the best particle's NLL is shifted up to at least this per pixel"));
}

// Recovery.
void addRecoveryParams(ParamTable<P>* t) {
  const char* g = "recovery";
  add(t,
      paramSpec<P>("alpha_slow", GMM_MCL_PARAM_FIELD(P, filter.alpha_slow), "", g, {0, 1}, kRuntime,
                   "Augmented MCL: rate of the slow likelihood average (the smaller of the pair; "
                   "0 = no recovery)"));
  add(t,
      paramSpec<P>("alpha_fast", GMM_MCL_PARAM_FIELD(P, filter.alpha_fast), "", g, {0, 1}, kRuntime,
                   "Augmented MCL: rate of the fast likelihood average (the larger of the pair)"));
  add(t,
      paramSpec<P>(
          "recovery_threshold", GMM_MCL_PARAM_FIELD(P, filter.recovery_threshold), "", g, {1e-3, 1},
          kRuntime,
          "Augmented MCL: reinitialise only once w_fast < threshold * w_slow (1 = Thrun's rule)"));
}

// Lost detector.
void addLostParams(ParamTable<P>* t) {
  const char* g = "lost";
  add(t, paramSpec<P>("lost_margin_nats", GMM_MCL_PARAM_FIELD(P, lost.margin_nats), "nats/px", g,
                      {0, 100}, kRuntime,
                      "Lost detector: the best particle's log-likelihood this far below the "
                      "reference counts as below (0 = detector off)"));
  add(t, paramSpec<P>("lost_frames", GMM_MCL_PARAM_FIELD(P, lost.frames), "", g, {1, 1e5}, kRuntime,
                      "Lost detector: consecutive frames below before the filter is judged lost"));
  add(t,
      paramSpec<P>("lost_grace_frames", GMM_MCL_PARAM_FIELD(P, lost.grace_frames), "", g, {0, 1e6},
                   kRuntime, "Lost detector: frames after any (re)initialisation before judging"));
  add(t, paramSpec<P>(
             "lost_reference_rate_up", GMM_MCL_PARAM_FIELD(P, lost.reference_rate_up), "", g,
             {1e-4, 1}, kRuntime,
             "Lost detector: per-frame rate at which the reference follows a better best score"));
  add(t, paramSpec<P>(
             "lost_reference_rate_down", GMM_MCL_PARAM_FIELD(P, lost.reference_rate_down), "", g,
             {1e-4, 1}, kRuntime,
             "Lost detector: per-frame rate at which the reference follows a worse best score"));
  add(t, paramSpec<P>("lost_reference_max_drop_nats",
                      GMM_MCL_PARAM_FIELD(P, lost.reference_max_drop_nats), "nats/px", g, {0, 100},
                      kRuntime,
                      "Lost detector: the reference never sinks further than this below the level "
                      "the map predicts for a correct pose"));
  add(t, paramSpec<P>("lost_reinit_fraction", GMM_MCL_PARAM_FIELD(P, lost.reinit_fraction), "", g,
                      {1e-3, 1}, kRuntime,
                      "Lost detector: fraction of the particles (the worst) redrawn when lost"));
  add(t,
      paramSpec<P>("lost_candidates_per_particle",
                   GMM_MCL_PARAM_FIELD(P, lost.candidates_per_particle), "", g, {1, 1000}, kRuntime,
                   "Redrawn particles (and a uniform start) are the best of this many scored "
                   "candidates each (1 = plain draws)"));
  add(t, paramSpec<P>(
             "lost_local_candidate_fraction", GMM_MCL_PARAM_FIELD(P, lost.local_candidate_fraction),
             "", g, {0, 0.99}, kRuntime,
             "Lost redraw: fraction of the candidates drawn around the best uniform ones"));
  add(t, paramSpec<P>(
             "lost_elite_fraction", GMM_MCL_PARAM_FIELD(P, lost.elite_fraction), "", g, {1e-4, 1},
             kRuntime,
             "Lost redraw: the local candidates surround this best fraction of the uniform ones"));
  add(t, paramSpec<P>("lost_local_sigma_m", GMM_MCL_PARAM_FIELD(P, lost.local_sigma_m), "m", g,
                      {1e-3, 10}, kRuntime,
                      "Lost redraw: spread of the local candidates along x, y and z"));
  add(t,
      paramSpec<P>("lost_local_sigma_rad", GMM_MCL_PARAM_FIELD(P, lost.local_sigma_rad), "rad", g,
                   {1e-3, 3.15}, kRuntime, "Lost redraw: spread of the local candidates in yaw"));
  add(t, paramSpec<P>("lost_local_levels", GMM_MCL_PARAM_FIELD(P, lost.local_levels), "", g, {1, 4},
                      kRuntime,
                      "Lost redraw: levels of local candidates, each around the best so far and a "
                      "third as wide"));
  add(t, paramSpec<P>("lost_redraw_blur_m", GMM_MCL_PARAM_FIELD(P, lost.redraw_blur_m), "m", g,
                      {0, 2}, kRuntime,
                      "Lost redraw: uniform candidates are scored against the map blurred by this "
                      "much (a wider basin; 0 = the map)"));
  add(t, paramSpec<P>("lost_redraw_merge_m", GMM_MCL_PARAM_FIELD(P, lost.redraw_merge_m), "m", g,
                      {0, 5}, kRuntime,
                      "Lost redraw: the blurred map merges the components within cubes of this "
                      "edge (fewer components to score; 0 = no merge)"));
  add(t, paramSpec<P>("lost_coarse_pixels", GMM_MCL_PARAM_FIELD(P, lost.coarse_pixels), "", g,
                      {0, 1e7}, kRuntime,
                      "Lost redraw: candidates are scored on a coarse frame of "
                      "about this many pixels (host particle filter; 0 = the full frame)"));
  add(t, paramSpec<P>("lost_start_local_stage_min_area_m2",
                      GMM_MCL_PARAM_FIELD(P, lost.start_local_stage_min_area_m2), "m^2", g,
                      {0, 1e12}, kRuntime,
                      "A uniform start over at least this horizontal area (a whole building) "
                      "searches as a lost redraw does: blurred uniform stage, then local "
                      "candidates"));
  add(t, paramSpec<P>("lost_start_places", GMM_MCL_PARAM_FIELD(P, lost.start_places), "", g,
                      {0, 100000}, kRuntime,
                      "Such a wide start follows this many of its first update's best distinct "
                      "places over its next frames, each by its own hill climb; the best then "
                      "seeds the particles (0 = off)"));
  add(t,
      paramSpec<P>("lost_start_place_frames", GMM_MCL_PARAM_FIELD(P, lost.start_place_frames),
                   "frames", g, {1, 100000}, kRuntime,
                   "Frames a wide start follows its places before the best seeds the particles"));
  add(t, paramSpec<P>("lost_rival_check_frames", GMM_MCL_PARAM_FIELD(P, lost.rival_check_frames),
                      "frames", g, {0, 100000}, kRuntime,
                      "Every this many frames the estimate is checked against rival places "
                      "around it; one that scores better on several frames in a row seeds the "
                      "particles (0 = off)"));
  add(t, paramSpec<P>("lost_rival_radius_m", GMM_MCL_PARAM_FIELD(P, lost.rival_radius_m), "m", g,
                      {1e-3, 100}, kRuntime,
                      "Rival places: searched within this distance of the estimate"));
  add(t, paramSpec<P>("lost_rival_yaw_rad", GMM_MCL_PARAM_FIELD(P, lost.rival_yaw_rad), "rad", g,
                      {0, 3.15}, kRuntime,
                      "Rival places: searched within this yaw of the estimate's"));
  add(t, paramSpec<P>("lost_rival_candidates", GMM_MCL_PARAM_FIELD(P, lost.rival_candidates), "", g,
                      {1, 1e6}, kRuntime,
                      "Rival places: poses scored on a coarse frame against the blurred map"));
  add(t,
      paramSpec<P>("lost_rival_places", GMM_MCL_PARAM_FIELD(P, lost.rival_places), "", g, {1, 1000},
                   kRuntime,
                   "Rival places: the best this many distinct candidates are refined on the map"));
  add(t, paramSpec<P>("lost_rival_margin_nats", GMM_MCL_PARAM_FIELD(P, lost.rival_margin_nats),
                      "nats/px", g, {0, 100}, kRuntime,
                      "Rival places: a rival's refined log-likelihood must beat the estimate's "
                      "by this much"));
  add(t, paramSpec<P>("lost_rival_frames", GMM_MCL_PARAM_FIELD(P, lost.rival_frames), "frames", g,
                      {1, 1000}, kRuntime,
                      "Rival places: a rival must win on this many frames in a row"));
}

// Depth frame.
void addFrameParams(ParamTable<P>* t) {
  const char* g = "frame";
  add(t, paramSpec<P>("pixel_stride", GMM_MCL_PARAM_FIELD(P, frame.pixel_stride), "px", g, {1, 64},
                      kRuntime, "Use every n-th pixel along rows and columns"));
  add(t,
      paramSpec<P>(
          "patch_size_px", GMM_MCL_PARAM_FIELD(P, frame.patch_size_px), "px", g, {4, 256}, kStartup,
          "Side of the square patches for which relevant components are selected (paper: 32)"));
  add(t, paramSpec<P>("min_range_m", GMM_MCL_PARAM_FIELD(P, frame.min_range_m), "m", g, {1e-3, 100},
                      kRuntime, "Depths nearer than this are not used"));
  add(t, paramSpec<P>("max_range_m", GMM_MCL_PARAM_FIELD(P, frame.max_range_m), "m", g, {1e-2, 100},
                      kRuntime, "Depths farther than this are not used"));
}

// Measurement model.
void addMeasurementParams(ParamTable<P>* t) {
  const char* g = "measurement";
  add(t, paramSpec<P>("min_component_depth_m",
                      GMM_MCL_PARAM_FIELD(P, measurement.min_component_depth_m), "m", g, {1e-3, 10},
                      kRuntime,
                      "Components whose mean is nearer to the camera (or behind it) are left out"));
  add(t, paramSpec<P>("sigma_bound", GMM_MCL_PARAM_FIELD(P, measurement.sigma_bound), "sigma", g,
                      {0.5, 10}, kRuntime,
                      "A component is relevant to a patch when its ellipse of this many standard "
                      "deviations overlaps it"));
  add(t, paramSpec<P>(
             "floor_log_density", GMM_MCL_PARAM_FIELD(P, measurement.floor_log_density),
             "ln(1/m^3)", g, {-80, 20}, kRuntime,
             "Outlier floor: each pixel's log-likelihood is ln(exp(floor) + mixture density)"));
  {
    // Before depth_noise_a_m, _b_per_m and _z0_m: the loaders apply the table in order, so that
    // those given beside a preset override its numbers.
    ParamSpec<P> p =
        paramSpec<P>("depth_noise_preset", GMM_MCL_PARAM_FIELD(P, measurement.depth_noise_preset),
                     "", g, {}, kStartup,
                     "Camera whose depth noise to use (docs/measurement_model.md, Sensor presets): "
                     "fills depth_noise_a_m, _b_per_m and _z0_m, which override it where also "
                     "given; custom = those three as given");
    p.choices = depthNoisePresetChoices();
    p.set = [](P* s, const ParamValue& v) {
      s->measurement.depth_noise_preset = v.s;
      applyDepthNoisePreset(v.s, &s->measurement.depth_noise);  // unknown: validate() says so
    };
    add(t, p);
  }
  add(t, paramSpec<P>("depth_noise_a_m", GMM_MCL_PARAM_FIELD(P, measurement.depth_noise.a_m), "m",
                      g, {0, 1}, kRuntime,
                      "Camera depth noise sigma(z) = a + b (z - z0)^2: the constant a (a = b = 0: "
                      "the map alone, the paper's model)"));
  add(t,
      paramSpec<P>("depth_noise_b_per_m", GMM_MCL_PARAM_FIELD(P, measurement.depth_noise.b_per_m),
                   "1/m", g, {0, 1}, kRuntime, "Camera depth noise: the quadratic coefficient b"));
  add(t,
      paramSpec<P>("depth_noise_z0_m", GMM_MCL_PARAM_FIELD(P, measurement.depth_noise.z0_m), "m", g,
                   {0, 10}, kRuntime, "Camera depth noise: the depth z0 of the smallest noise"));
}

// Refinement.
void addRefinementParams(ParamTable<P>* t) {
  const char* g = "refinement";
  add(t, paramSpec<P>(
             "refine", GMM_MCL_PARAM_FIELD(P, refinement.enabled), "", g, {}, kRuntime,
             "Refine the converged estimate below the particle spacing (reported in the status)"));
  add(t, paramSpec<P>("refine_max_iterations", GMM_MCL_PARAM_FIELD(P, refinement.max_iterations),
                      "", g, {1, 100}, kRuntime, "Refinement: iterations at most"));
  add(t, paramSpec<P>("refine_max_position_sigma_m",
                      GMM_MCL_PARAM_FIELD(P, refinement.max_position_sigma_m), "m", g, {1e-3, 10},
                      kRuntime,
                      "Refinement runs only while the particles' position spread is below this"));
  add(t,
      paramSpec<P>("refine_max_yaw_sigma_rad", GMM_MCL_PARAM_FIELD(P, refinement.max_yaw_sigma_rad),
                   "rad", g, {1e-3, 3.15}, kRuntime,
                   "Refinement runs only while the particles' yaw spread is below this"));
  add(t, paramSpec<P>("refine_track_max_position_sigma_m",
                      GMM_MCL_PARAM_FIELD(P, refinement.track_max_position_sigma_m), "m", g,
                      {1e-3, 10}, kRuntime,
                      "While the previous frame was refined, refinement runs while the position "
                      "spread is below this (or refine_max_position_sigma_m if larger)"));
  add(t, paramSpec<P>("refine_track_max_yaw_sigma_rad",
                      GMM_MCL_PARAM_FIELD(P, refinement.track_max_yaw_sigma_rad), "rad", g,
                      {1e-3, 3.15}, kRuntime,
                      "While the previous frame was refined, refinement runs while the yaw spread "
                      "is below this (or refine_max_yaw_sigma_rad if larger)"));
  add(t, paramSpec<P>("refine_cv_track_max_position_sigma_m",
                      GMM_MCL_PARAM_FIELD(P, refinement.cv_track_max_position_sigma_m), "m", g,
                      {1e-3, 10}, kRuntime,
                      "refine_track_max_position_sigma_m on a step predicted without odometry"));
  add(t, paramSpec<P>("refine_cv_track_max_yaw_sigma_rad",
                      GMM_MCL_PARAM_FIELD(P, refinement.cv_track_max_yaw_sigma_rad), "rad", g,
                      {1e-3, 3.15}, kRuntime,
                      "refine_track_max_yaw_sigma_rad on a step predicted without odometry"));
  add(t,
      paramSpec<P>("refine_max_correction_m", GMM_MCL_PARAM_FIELD(P, refinement.max_correction_m),
                   "m", g, {1e-3, 10}, kRuntime,
                   "A refined pose farther than this from the particle mean is rejected"));
  add(t,
      paramSpec<P>("refine_max_correction_rad",
                   GMM_MCL_PARAM_FIELD(P, refinement.max_correction_rad), "rad", g, {1e-3, 3.15},
                   kRuntime, "A refined yaw farther than this from the particle mean is rejected"));
  add(t,
      paramSpec<P>(
          "refine_attitude_prior_sigma_rad",
          GMM_MCL_PARAM_FIELD(P, refinement.attitude_prior_sigma_rad), "rad", g, {0, 1}, kRuntime,
          "Refinement: prior on roll and pitch around the attitude input (0 = held fixed)"));
  add(t,
      paramSpec<P>("refine_tolerance_m", GMM_MCL_PARAM_FIELD(P, refinement.tolerance_m), "m", g,
                   {1e-6, 1}, kRuntime,
                   "Refinement stops when a step moves less than this and refine_tolerance_rad"));
  add(t, paramSpec<P>("refine_tolerance_rad", GMM_MCL_PARAM_FIELD(P, refinement.tolerance_rad),
                      "rad", g, {1e-6, 1}, kRuntime,
                      "Refinement stops when a step turns less than this and moves less than "
                      "refine_tolerance_m"));
  add(t, paramSpec<P>("refine_depth_scale", GMM_MCL_PARAM_FIELD(P, refinement.estimate_depth_scale),
                      "", g, {}, kRuntime,
                      "Refinement also estimates each camera's depth scale (a factor on its "
                      "depths, filtered over frames, applied to the refined frames' points)"));
  add(t, paramSpec<P>("refine_depth_scale_noise_correction",
                      GMM_MCL_PARAM_FIELD(P, refinement.depth_scale_noise_correction), "", g, {},
                      kRuntime,
                      "Depth scale: take the depth noise's bias out of the estimate (off for a "
                      "camera without noise, a simulator)"));
  add(t, paramSpec<P>(
             "refine_depth_scale_prior_sigma",
             GMM_MCL_PARAM_FIELD(P, refinement.depth_scale_prior_sigma), "", g, {1e-5, 1}, kRuntime,
             "Depth scale: prior standard deviation per frame around the current estimate"));
  add(t, paramSpec<P>("refine_depth_scale_max_error",
                      GMM_MCL_PARAM_FIELD(P, refinement.depth_scale_max_error), "", g, {1e-4, 0.49},
                      kRuntime, "Depth scale: kept within 1 +- this"));
  add(t,
      paramSpec<P>("refine_depth_scale_rate", GMM_MCL_PARAM_FIELD(P, refinement.depth_scale_rate),
                   "", g, {1e-4, 1}, kRuntime,
                   "Depth scale: the estimate is the refined frames' information-weighted mean, "
                   "the past frames' weight shrinking by this fraction per frame"));
  add(t, paramSpec<P>("refine_depth_scale_initial",
                      GMM_MCL_PARAM_FIELD(P, refinement.depth_scale_initial), "", g, {0.5, 1.5},
                      kStartup,
                      "Depth scale: the (first) camera's estimate at start (saved here with the "
                      "pose by save_pose_rate; a rig camera's under ~NAME/)"));
}

// Initial region.
void addInitParams(ParamTable<P>* t) {
  const char* g = "init";
  add(t, paramSpec<P>("init_centre", GMM_MCL_PARAM_FIELD(P, init.centre_m), "m", g, {}, kStartup,
                      "Centre of the uniform initial region in the map frame [x, y, z] (also where "
                      "recovery draws from)"));
  add(t,
      paramSpec<P>("init_half_extent", GMM_MCL_PARAM_FIELD(P, init.half_extent_m), "m", g, {},
                   kStartup, "Half extents of the initial region [x, y, z] (paper: a 4 m cube)"));
  add(t, paramSpec<P>("init_yaw_centre", GMM_MCL_PARAM_FIELD(P, init.yaw_centre_rad), "rad", g,
                      {-kInf, kInf}, kStartup, "Centre of the initial yaw range"));
  add(t, paramSpec<P>("init_yaw_half_range", GMM_MCL_PARAM_FIELD(P, init.yaw_half_range_rad), "rad",
                      g, {0, M_PI}, kStartup,
                      "Half of the initial yaw range (paper: pi / 2, a range of pi)"));
}

// Backend.
void addBackendParams(ParamTable<P>* t) {
  const char* g = "backend";
  add(t,
      paramSpec<P>("backend", GMM_MCL_PARAM_FIELD(P, backend), "", g, {}, kStartup,
                   "Likelihood backend: cpu (OpenMP) or cuda (falls back to the CPU with a "
                   "warning where CUDA is not built or no device is usable)"),
      {"cpu", "cuda"});
  add(t, paramSpec<P>("device_filter", GMM_MCL_PARAM_FIELD(P, device_filter), "", g, {}, kStartup,
                      "With the cuda backend the whole filter step runs on the GPU (the particle "
                      "set lives there); false: the set stays on the host and only the likelihood "
                      "runs on the GPU. No effect with the cpu backend"));
  add(t, paramSpec<P>("cpu_fallback", GMM_MCL_PARAM_FIELD(P, cpu_fallback), "", g, {}, kRuntime,
                      "When the cuda backend fails at run time (a CUDA error, the GPU out of "
                      "memory), switch to the cpu backend keeping the particles instead of failing "
                      "every frame (reported in /diagnostics)"));
}

// The CUDA backend's kernel tuning (docs/cuda_backend.md): the measured choices unless set.
void addCudaParams(ParamTable<P>* t) {
  const char* g = "cuda";
  add(t,
      paramSpec<P>(
          "cuda_likelihood_shape", GMM_MCL_PARAM_FIELD(P, cuda.likelihood_shape), "", g, {},
          kStartup,
          "The cuda backend's likelihood kernel shape, pixel groups x pixels per group; auto: by "
          "the largest patch (8x2 up to 16 px, 32x2 up to 64 px, else 32x4)"),
      {"auto", "32x4", "32x2", "32x1", "16x4", "16x2", "16x1", "8x4", "8x2", "8x1", "4x4", "4x2"});
  add(t,
      paramSpec<P>("cuda_stage_members", GMM_MCL_PARAM_FIELD(P, cuda.stage_members), "", g, {},
                   kStartup,
                   "The cuda backend stages the members' records in shared memory once per patch "
                   "(32x4 only); auto: for patches of more than 128 px"),
      {"auto", "on", "off"});
  add(t, paramSpec<P>("cuda_band_patches", GMM_MCL_PARAM_FIELD(P, cuda.band_patches), "", g,
                      {0, 1e6}, kStartup,
                      "Patches per work item of the cuda backend's likelihood kernel (0: 10)"));
  add(t, paramSpec<P>("cuda_view_cull_min_pairs", GMM_MCL_PARAM_FIELD(P, cuda.view_cull_min_pairs),
                      "", g, {0, 1e15}, kStartup,
                      "The cuda backend culls the map to the particles' views from this many "
                      "(particle, component) pairs per update on (0: always)"));
  add(t, paramSpec<P>("cuda_membership_pass_words",
                      GMM_MCL_PARAM_FIELD(P, cuda.membership_pass_words), "", g, {0, 1e6}, kStartup,
                      "About this many bitmask words per pass of the cuda backend's membership "
                      "kernel where the visible components need more: the nearest number of "
                      "passes, all of one size (0: always one pass)"));
  add(t, paramSpec<P>("cuda_place_groups", GMM_MCL_PARAM_FIELD(P, cuda.place_groups), "", g, {},
                      kStartup,
                      "The cuda backend evaluates a cloud spread over a large map (20,000 "
                      "components or more) group by group of places, each over its own view "
                      "(measured slower on an H100: docs/building_scale.md)"));
  add(t, paramSpec<P>("cuda_local_lists_min_components",
                      GMM_MCL_PARAM_FIELD(P, cuda.local_lists_min_components), "", g, {0, 1e9},
                      kStartup,
                      "From this many components visible to an update's poses together (after the "
                      "view cull) on, the cuda backend's bitmasks and forms of each pose cover "
                      "only what that pose can see, and each pose skips the chunks of them "
                      "outside its view (0: always)"));
  add(t,
      paramSpec<P>("cuda_z_order_min_components",
                   GMM_MCL_PARAM_FIELD(P, cuda.z_order_min_components), "", g, {0, 1e9}, kStartup,
                   "From this many map components on, the cuda backend holds them in the Z "
                   "order of their means, so that each pose skips the chunks of them outside "
                   "its view"));
}

}  // namespace

const ParamTable<LocalizerParams>& localizerParamTable() {
  static const ParamTable<P> table =
      makeParamTable<P>({addParticlesParams, addMotionParams, addWeightingParams, addRecoveryParams,
                         addLostParams, addFrameParams, addMeasurementParams, addRefinementParams,
                         addInitParams, addBackendParams, addCudaParams});
  return table;
}

}  // namespace gmm_mcl
