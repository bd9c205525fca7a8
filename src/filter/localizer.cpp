#include "gmm_mcl/filter/localizer.h"

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace gmm_mcl {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

const LocalizerParams& validated(const LocalizerParams& p) {
  const std::string err = p.validate();
  if (!err.empty()) throw std::invalid_argument("localizer parameters: " + err);
  return p;
}

}  // namespace

const char* stepStatusName(StepStatus status) {
  switch (status) {
    case StepStatus::kOk: return "ok";
    case StepStatus::kPredictOnly: return "predict_only";
    case StepStatus::kNoValidPixels: return "no_valid_pixels";
    case StepStatus::kBadFrame: return "bad_frame";
    case StepStatus::kDegenerateWeights: return "degenerate_weights";
    case StepStatus::kBackendError: return "backend_error";
    case StepStatus::kTimeJumpBack: return "time_jump_back";
  }
  return "unknown";
}

Localizer::Localizer(const LocalizerParams& params, GmmMap map,
                     std::unique_ptr<LikelihoodBackend> backend)
    : params_(validated(params)),
      map_(std::move(map)),
      backend_(std::move(backend)),
      filter_(params.filter),
      region_(params.init) {
  if (map_.empty()) throw std::invalid_argument("localizer: the map is empty");
  if (!backend_) backend_ = makeBackend(params_.backend, &backend_warning_);
  backend_->setMap(map_);
  filter_.initialiseUniform(region_);
}

void Localizer::reset(const InitRegion& region) {
  const std::string err = region.validate();
  if (!err.empty()) throw std::invalid_argument("reset region: " + err);
  region_ = region;
  filter_.initialiseUniform(region_);
}

void Localizer::resetToPose(const Particle& pose, const Eigen::Vector4d& sigma) {
  filter_.initialiseGaussian(pose, sigma);
}

InitRegion Localizer::mapBounds() const {
  Eigen::Vector3d lo = map_.minBound(), hi = map_.maxBound();
  for (size_t i = 0; i < map_.size(); ++i) {
    lo = lo.cwiseMin(map_.components()[i].mean_m - map_.threeSigmaHalfExtent(i));
    hi = hi.cwiseMax(map_.components()[i].mean_m + map_.threeSigmaHalfExtent(i));
  }
  InitRegion r;
  r.centre_m = 0.5 * (lo + hi);
  r.half_extent_m = 0.5 * (hi - lo);
  r.yaw_centre_rad = 0.0;
  r.yaw_half_range_rad = M_PI;
  return r;
}

Eigen::Isometry3d Localizer::meanPose() const {
  return particleToPose(filter_.estimate().mean, roll_rad_, pitch_rad_);
}

StepResult Localizer::step(const StepInput& in) {
  const Clock::time_point t_start = Clock::now();
  StepResult res;
  // Time going backwards (a looped bag): start over from the initial region.
  if (have_stamp_ && in.stamp_s < last_stamp_s_) {
    std::ostringstream msg;
    msg << "time jumped back from " << last_stamp_s_ << " s to " << in.stamp_s
        << " s: filter re-initialised";
    filter_.initialiseUniform(region_);
    have_odometry_ = false;
    have_stamp_ = false;
    res.status = StepStatus::kTimeJumpBack;
    res.message = msg.str();
  }
  have_stamp_ = true;
  last_stamp_s_ = in.stamp_s;

  // Attitude shared by all particles.
  if (in.has_attitude) {
    roll_rad_ = in.roll_rad;
    pitch_rad_ = in.pitch_rad;
  } else if (in.has_odometry) {
    double yaw;
    rpyFromRotation(in.T_odom_base.linear(), &roll_rad_, &pitch_rad_, &yaw);
  }

  // Predict.
  Clock::time_point t0 = Clock::now();
  PlanarDelta delta;
  if (in.has_odometry && have_odometry_) {
    delta = odometryDelta(last_odom_, in.T_odom_base);
    if (!(delta.translation_m.norm() <= params_.max_odometry_step_m) ||
        !std::isfinite(delta.yaw_rad)) {
      std::ostringstream msg;
      msg << "odometry step of " << delta.translation_m.norm() << " m exceeds "
          << params_.max_odometry_step_m << " m: ignored";
      res.odometry_jump = true;
      res.message += (res.message.empty() ? "" : "; ") + msg.str();
      delta = PlanarDelta();
    }
  }
  if (in.has_odometry) {
    last_odom_ = in.T_odom_base;
    have_odometry_ = true;
  }
  filter_.predict(delta);
  res.timings.predict_ms = msSince(t0);

  auto finish = [&](StepStatus status, const std::string& why) {
    if (res.status == StepStatus::kOk) res.status = status;
    if (!why.empty()) res.message += (res.message.empty() ? "" : "; ") + why;
    t0 = Clock::now();
    res.estimate = filter_.estimate();
    res.neff = filter_.effectiveSampleSize();
    res.timings.estimate_ms = msSince(t0);
    res.timings.total_ms = msSince(t_start);
    return res;
  };

  if (in.depth == nullptr) return finish(StepStatus::kPredictOnly, "");

  // Frame preparation.
  t0 = Clock::now();
  DepthFrame frame;
  try {
    frame = prepareFrame(*in.depth, in.intrinsics, params_.frame);
  } catch (const std::exception& e) {
    return finish(StepStatus::kBadFrame, e.what());
  }
  res.timings.frame_prep_ms = msSince(t0);
  res.pixels = static_cast<int>(frame.size());
  if (frame.empty()) {
    std::ostringstream msg;
    msg << "no valid depth pixel (" << frame.invalid_pixels << " invalid, "
        << frame.out_of_range_pixels << " out of range of " << frame.total_pixels_sampled << ")";
    return finish(StepStatus::kNoValidPixels, msg.str());
  }

  // Likelihood of every particle.
  const std::vector<Particle>& particles = filter_.particles();
  poses_.resize(particles.size());
  for (size_t i = 0; i < particles.size(); ++i) {
    poses_[i] = toRigidF(particleToPose(particles[i], roll_rad_, pitch_rad_) * params_.T_base_cam);
  }
  try {
    backend_->evaluate(frame, poses_, params_.measurement, &output_);
  } catch (const std::exception& e) {
    return finish(StepStatus::kBackendError, std::string("likelihood backend: ") + e.what());
  }
  res.timings.projection_membership_ms = output_.projection_membership_ms;
  res.timings.likelihood_ms = output_.likelihood_ms;
  res.evaluations = output_.evaluations;
  if (output_.patches_with_pixels > 0) {
    res.relevant_per_patch = static_cast<double>(output_.relevant_pairs) /
                             (output_.patches_with_pixels * static_cast<double>(particles.size()));
  }

  // Weights.
  t0 = Clock::now();
  if (!filter_.updateWeights(output_.log_likelihood, res.pixels)) {
    return finish(StepStatus::kDegenerateWeights,
                  "no particle has a usable likelihood: weights kept");
  }
  res.beta_fraction = filter_.lastBetaFraction();
  const std::vector<double>& w = filter_.weights();
  size_t best = 0;
  double mean_ll = 0.0;
  for (size_t i = 0; i < w.size(); ++i) {
    if (output_.log_likelihood[i] > output_.log_likelihood[best]) best = i;
    if (w[i] > 0.0) mean_ll += w[i] * output_.log_likelihood[i];
  }
  res.best_loglik_per_pixel = output_.log_likelihood[best] / res.pixels;
  res.mean_loglik_per_pixel = mean_ll / res.pixels;
  res.floor_hit_fraction = static_cast<double>(output_.floor_hits[best]) / res.pixels;
  res.timings.weights_ms = msSince(t0);

  // Estimate from the updated weights, then resample and recover.
  t0 = Clock::now();
  res.estimate = filter_.estimate();
  res.neff = filter_.effectiveSampleSize();
  res.timings.estimate_ms = msSince(t0);
  t0 = Clock::now();
  res.resampled = filter_.resampleIfNeeded();
  res.reinitialised = filter_.recover(output_.log_likelihood, res.pixels, region_);
  res.timings.resample_ms = msSince(t0);
  res.timings.total_ms = msSince(t_start);
  return res;
}

}  // namespace gmm_mcl
