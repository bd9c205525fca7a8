#include "gmm_mcl/replay/replay.h"

#include <cmath>
#include <fstream>
#include <random>
#include <stdexcept>

namespace gmm_mcl {

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

TrialResult runSevenScenesTrial(const SevenScenesSequence& seq, const DepthProvider& depth,
                                const GmmMap& map_aligned, const ReplayParams& params,
                                uint64_t seed, const ProgressCallback& progress) {
  const int n = params.max_frames > 0 ? std::min(params.max_frames, seq.size()) : seq.size();
  const Eigen::Isometry3d T_base_cam = opticalToBase();
  Eigen::Isometry3d T_aligned_world = Eigen::Isometry3d::Identity();
  T_aligned_world.linear() = seq.R_aligned_world();
  std::vector<Eigen::Isometry3d> truth(n);
  for (int f = 0; f < n; ++f) truth[f] = T_aligned_world * seq.T_world_cam(f) * T_base_cam.inverse();

  LocalizerParams lp = params.localizer;
  lp.T_base_cam = T_base_cam;
  lp.filter.seed = seed;
  const Particle start = poseToParticle(truth[0]);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.half_extent_m.setConstant(params.init_half_extent_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  lp.init.yaw_half_range_rad = params.init_yaw_half_range_rad;
  Localizer loc(lp, map_aligned);

  std::mt19937_64 rng(seed * 7919 + 17);  // odometry and attitude noise, apart from the filter's
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Isometry3d odom = truth[0];
  TrialResult out;
  out.seed = seed;
  out.frames.reserve(n);
  double total_ms = 0.0;
  for (int f = 0; f < n; ++f) {
    if (f > 0) {
      Eigen::Isometry3d delta = truth[f - 1].inverse() * truth[f];
      delta.translation() += params.odom_sigma_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
      delta.linear() = delta.linear() * Eigen::AngleAxisd(params.odom_sigma_yaw_rad * g(rng),
                                                          Eigen::Vector3d::UnitZ())
                                            .toRotationMatrix();
      odom = odom * delta;
    }
    double roll, pitch, yaw;
    rpyFromRotation(truth[f].linear(), &roll, &pitch, &yaw);
    StepInput in;
    in.stamp_s = f / seq.frameRateHz();
    in.has_odometry = true;
    in.T_odom_base = odom;
    in.has_attitude = true;
    in.roll_rad = roll + params.attitude_sigma_rad * g(rng);
    in.pitch_rad = pitch + params.attitude_sigma_rad * g(rng);
    in.depth = &depth(f);
    in.intrinsics = seq.intrinsics();
    ReplayFrame rf;
    rf.stamp_s = in.stamp_s;
    rf.step = loc.step(in);
    rf.estimate = rf.step.estimate.mean;
    rf.truth = poseToParticle(truth[f]);
    rf.error.stamp_s = in.stamp_s;
    rf.error.translation_m = std::sqrt(std::pow(rf.estimate.x_m - rf.truth.x_m, 2) +
                                       std::pow(rf.estimate.y_m - rf.truth.y_m, 2) +
                                       std::pow(rf.estimate.z_m - rf.truth.z_m, 2));
    rf.error.yaw_rad = std::abs(wrapAngle(rf.estimate.yaw_rad - rf.truth.yaw_rad));
    total_ms += rf.step.timings.total_ms;
    out.frames.push_back(rf);
    if (progress) progress(f, n, out.frames.back());
  }
  std::vector<FrameError> errors;
  for (const ReplayFrame& rf : out.frames) errors.push_back(rf.error);
  out.metrics = evaluateTrial(errors, params.evaluation);
  out.mean_step_ms = n > 0 ? total_ms / n : 0.0;
  return out;
}

void writeTum(const TrialResult& r, bool truth, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out.precision(9);
  for (const ReplayFrame& f : r.frames) {
    const Particle& p = truth ? f.truth : f.estimate;
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(p.yaw_rad, Eigen::Vector3d::UnitZ()));  // yaw of the 4-DoF state
    out << f.stamp_s << ' ' << p.x_m << ' ' << p.y_m << ' ' << p.z_m << ' ' << q.x() << ' '
        << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
}

void writeFrameCsv(const TrialResult& r, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << "stamp_s,error_m,error_yaw_deg,est_x,est_y,est_z,est_yaw,true_x,true_y,true_z,true_yaw,"
         "neff,loglik_best_per_px,loglik_mean_per_px,floor_hit_fraction,relevant_per_patch,"
         "beta_fraction,reinitialised,status,pixels,frame_prep_ms,membership_ms,likelihood_ms,"
         "resample_ms,total_ms\n";
  out.precision(7);
  for (const ReplayFrame& f : r.frames) {
    const StepResult& s = f.step;
    out << f.stamp_s << ',' << f.error.translation_m << ',' << f.error.yaw_rad * 180.0 / M_PI
        << ',' << f.estimate.x_m << ',' << f.estimate.y_m << ',' << f.estimate.z_m << ','
        << f.estimate.yaw_rad << ',' << f.truth.x_m << ',' << f.truth.y_m << ',' << f.truth.z_m
        << ',' << f.truth.yaw_rad << ',' << s.neff << ',' << s.best_loglik_per_pixel << ','
        << s.mean_loglik_per_pixel << ',' << s.floor_hit_fraction << ',' << s.relevant_per_patch
        << ',' << s.beta_fraction << ',' << s.reinitialised << ',' << stepStatusName(s.status)
        << ',' << s.pixels << ',' << s.timings.frame_prep_ms << ','
        << s.timings.projection_membership_ms << ',' << s.timings.likelihood_ms << ','
        << s.timings.resample_ms << ',' << s.timings.total_ms << '\n';
  }
}

}  // namespace gmm_mcl
