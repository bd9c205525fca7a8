#include "gmm_mcl/replay/replay.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace gmm_mcl {
namespace {

// Stamps with microseconds whatever their magnitude (TUM stamps are about 1.3e9 s).
std::string stampText(double t_s) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%.6f", t_s);
  return buf;
}

// The distance between a pose and the truth; NaN when their yaws differ by more than the bound.
double distanceWithinYawM(const Particle& p, const Particle& truth, double max_yaw_error_rad) {
  if (std::abs(wrapAngle(p.yaw_rad - truth.yaw_rad)) > max_yaw_error_rad) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return std::sqrt(std::pow(p.x_m - truth.x_m, 2) + std::pow(p.y_m - truth.y_m, 2) +
                   std::pow(p.z_m - truth.z_m, 2));
}

}  // namespace

Eigen::Isometry3d opticalToBase() {
  // Columns: optical x, y, z expressed in the base frame.
  Eigen::Matrix3d R_base_optical;
  R_base_optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R_base_optical;
  return T;
}

GmmMap rotateMap(const GmmMap& map, const Eigen::Matrix3d& R, const std::string& source) {
  std::vector<GaussianComponent> comps = map.components();
  for (GaussianComponent& c : comps) {
    c.mean_m = R * c.mean_m;
    const Eigen::Matrix3d S = R * c.cov_m2 * R.transpose();
    c.cov_m2 = 0.5 * (S + S.transpose());
  }
  return GmmMap(std::move(comps), source);
}

std::vector<Eigen::Isometry3d> alignedBaseTrajectory(const Sequence& seq, int n) {
  const Eigen::Isometry3d T_cam_base = opticalToBase().inverse();
  Eigen::Isometry3d T_aligned_world = Eigen::Isometry3d::Identity();
  T_aligned_world.linear() = seq.R_aligned_world();
  std::vector<Eigen::Isometry3d> truth(n);
  for (int f = 0; f < n; ++f) truth[f] = T_aligned_world * seq.T_world_cam(f) * T_cam_base;
  return truth;
}

ReplayFrame makeReplayFrame(double stamp_s, const StepResult& step, const Particle* truth) {
  ReplayFrame rf;
  rf.stamp_s = stamp_s;
  rf.step = step;
  rf.estimate = step.estimate.mean;
  rf.error.stamp_s = stamp_s;
  rf.has_truth = truth != nullptr;
  rf.refined = step.refinement.refined ? step.refinement.pose : rf.estimate;
  if (truth) {
    rf.truth = *truth;
    auto distance = [truth](const Particle& p) {
      return std::sqrt(std::pow(p.x_m - truth->x_m, 2) + std::pow(p.y_m - truth->y_m, 2) +
                       std::pow(p.z_m - truth->z_m, 2));
    };
    rf.error.translation_m = distance(rf.estimate);
    rf.error.yaw_rad = std::abs(wrapAngle(rf.estimate.yaw_rad - truth->yaw_rad));
    rf.error.refined_translation_m = distance(rf.refined);
    rf.error.refined_yaw_rad = std::abs(wrapAngle(rf.refined.yaw_rad - truth->yaw_rad));
    rf.error.refined = step.refinement.refined;
  }
  return rf;
}

double nearestParticleM(const std::vector<Particle>& particles, const Particle& truth,
                        double max_yaw_error_rad) {
  double best = std::numeric_limits<double>::quiet_NaN();
  for (const Particle& p : particles) {
    const double d = distanceWithinYawM(p, truth, max_yaw_error_rad);
    if (std::isfinite(d) && !(d >= best)) best = d;
  }
  return best;
}

void finishTrial(const EvaluationParams& params, TrialResult* result) {
  std::vector<FrameError> errors;
  double total_ms = 0.0;
  for (const ReplayFrame& rf : result->frames) {
    if (rf.has_truth) errors.push_back(rf.error);
    total_ms += rf.step.timings.total_ms;
  }
  result->metrics = evaluateTrial(errors, params);
  result->mean_step_ms = result->frames.empty() ? 0.0 : total_ms / result->frames.size();
}

TrialResult runTrial(const Sequence& seq, const DepthProvider& depth, const GmmMap& map_aligned,
                     const ReplayParams& params, uint64_t seed, const ProgressCallback& progress) {
  const int n = params.max_frames > 0 ? std::min(params.max_frames, seq.size()) : seq.size();
  const std::vector<Eigen::Isometry3d> truth = alignedBaseTrajectory(seq, n);
  if (params.frame_step < 1) throw std::invalid_argument("replay: frame_step must be >= 1");
  const int step = params.frame_step;
  const int steps = (n + step - 1) / step;

  LocalizerParams lp = params.localizer;
  lp.T_base_cam = opticalToBase();
  lp.filter.seed = seed;
  const Particle start = poseToParticle(truth[0]);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.half_extent_m.setConstant(params.init_half_extent_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  lp.init.yaw_half_range_rad = params.init_yaw_half_range_rad;
  Localizer loc(lp, map_aligned);
  if (params.whole_map_start) loc.reset(loc.mapBounds());

  OdometrySynthesizer odometry(params.noise, seed);  // apart from the filter's generator
  TrialResult out;
  out.seed = seed;
  out.frames.reserve(steps);
  for (int k = 0; k < steps; ++k) {
    const int f = k * step;
    StepInput in;
    in.stamp_s = seq.stampS(f);
    // Drawn even when withheld: the same seed gives the same attitude noise either way.
    const Eigen::Isometry3d T_odom_base = odometry.next(truth[f], k > 0 ? step : 1.0);
    in.has_odometry = params.odometry;
    if (params.odometry) in.T_odom_base = T_odom_base;
    double roll = 0.0, pitch = 0.0;
    odometry.attitude(truth[f], &roll, &pitch);
    in.has_attitude = params.attitude;
    if (params.attitude) in.roll_rad = roll, in.pitch_rad = pitch;
    const double gyro_yaw =
        odometry.gyroYaw(truth[f], k > 0 ? in.stamp_s - seq.stampS(f - step) : 0.0);
    in.has_gyro_yaw = params.gyro;
    if (params.gyro) in.gyro_yaw_rad = gyro_yaw;
    in.depth = &depth(f);
    in.intrinsics = seq.intrinsics();
    const Particle true_pose = poseToParticle(truth[f]);
    out.frames.push_back(makeReplayFrame(in.stamp_s, loc.step(in), &true_pose));
    if (params.nearest_particle) {
      ReplayFrame& rf = out.frames.back();
      rf.nearest_particle_m =
          nearestParticleM(loc.filter().particles(), true_pose, params.nearest_particle_yaw_rad);
      // The places are in order of their scores: the index is the rank.
      const std::vector<StartHypotheses::Place>& places = loc.startPlaces().places();
      for (size_t i = 0; i < places.size(); ++i) {
        const double d =
            distanceWithinYawM(places[i].pose, true_pose, params.nearest_particle_yaw_rad);
        if (d < rf.nearest_place_m || (std::isfinite(d) && rf.nearest_place_rank < 0)) {
          rf.nearest_place_m = d;
          rf.nearest_place_rank = static_cast<int>(i);
        }
      }
    }
    if (progress) progress(k, steps, out.frames.back());
  }
  finishTrial(params.evaluation, &out);
  return out;
}

void writeTum(const TrialResult& r, bool truth, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out.precision(9);
  for (const ReplayFrame& f : r.frames) {
    if (truth && !f.has_truth) continue;
    const Particle& p = truth ? f.truth : f.estimate;
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(p.yaw_rad, Eigen::Vector3d::UnitZ()));  // yaw of the 4-DoF state
    out << stampText(f.stamp_s) << ' ' << p.x_m << ' ' << p.y_m << ' ' << p.z_m << ' ' << q.x()
        << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
}

void writeFrameCsv(const TrialResult& r, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << "stamp_s,error_m,error_yaw_deg,est_x,est_y,est_z,est_yaw,true_x,true_y,true_z,true_yaw,"
         "neff,loglik_best_per_px,loglik_mean_per_px,floor_hit_fraction,relevant_per_patch,"
         "beta_fraction,reinitialised,lost_redrawn,status,pixels,frame_prep_ms,membership_ms,"
         "likelihood_ms,resample_ms,refined,refined_error_m,refined_error_yaw_deg,refine_ms,"
         "particles,total_ms,depth_scale,nearest_particle_m,loglik_refined_per_px,"
         "reference_loglik_per_px,start_places,nearest_place_m,nearest_place_rank,"
         "rival_gain_per_px,rival_chosen,rival_ms,position_sigma_m,yaw_sigma_rad\n";
  out.precision(7);
  for (const ReplayFrame& f : r.frames) {
    const StepResult& s = f.step;
    out << stampText(f.stamp_s) << ',';
    if (f.has_truth)
      out << f.error.translation_m << ',' << f.error.yaw_rad * 180.0 / M_PI;
    else
      out << ',';
    out << ',' << f.estimate.x_m << ',' << f.estimate.y_m << ',' << f.estimate.z_m << ','
        << f.estimate.yaw_rad << ',';
    if (f.has_truth) {
      out << f.truth.x_m << ',' << f.truth.y_m << ',' << f.truth.z_m << ',' << f.truth.yaw_rad;
    } else {
      out << ",,,";
    }
    out << ',' << s.neff << ',' << s.best_loglik_per_pixel << ',' << s.mean_loglik_per_pixel << ','
        << s.floor_hit_fraction << ',' << s.relevant_per_patch << ',' << s.beta_fraction << ','
        << s.reinitialised << ',' << s.lost_reinitialised << ',' << stepStatusName(s.status) << ','
        << s.pixels << ',' << s.timings.frame_prep_ms << ',' << s.timings.projection_membership_ms
        << ',' << s.timings.likelihood_ms << ',' << s.timings.resample_ms << ','
        << (s.refinement.refined ? 1 : 0) << ',';
    if (f.has_truth) {
      out << f.error.refined_translation_m << ',' << f.error.refined_yaw_rad * 180.0 / M_PI;
    } else {
      out << ',';
    }
    out << ',' << s.timings.refine_ms << ',' << s.particles << ',' << s.timings.total_ms << ','
        << s.depth_scale << ',';
    if (std::isfinite(f.nearest_particle_m)) out << f.nearest_particle_m;
    out << ',';
    if (s.refinement.refined) out << s.refinement.loglik_refined;
    out << ',' << s.reference_loglik_per_pixel << ',' << s.start_places << ',';
    if (std::isfinite(f.nearest_place_m)) out << f.nearest_place_m;
    out << ',' << f.nearest_place_rank << ',';
    if (std::isfinite(s.rival_gain_per_pixel)) out << s.rival_gain_per_pixel;
    double position_sigma, yaw_sigma;
    Localizer::beliefSpread(s.estimate.covariance, &position_sigma, &yaw_sigma);
    out << ',' << (s.rival_chosen ? 1 : 0) << ',' << s.timings.rival_ms << ',' << position_sigma
        << ',' << yaw_sigma << '\n';
  }
}

}  // namespace gmm_mcl
