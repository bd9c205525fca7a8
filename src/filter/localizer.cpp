#include "gmm_mcl/filter/localizer.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <utility>
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
      region_(params.init) {
  if (map_.empty()) throw std::invalid_argument("localizer: the map is empty");
  if (!backend_) backend_ = makeBackend(params_.backend, &backend_warning_);
  prepareMap();
  std::string why;
  filter_ = makeParticleFilter(params_.filter, backend_.get(), params_.device_filter, &why);
  if (!why.empty()) backend_warning_ += (backend_warning_.empty() ? "" : "; ") + why;
  filter_->initialiseUniform(region_);
  lost_ = LostDetector(params_.lost, map_self_ll_);
}

void Localizer::prepareMap() {
  backend_->setMap(map_);
  blurred_map_ = GmmMap();
  if (params_.lost.redraw_blur_m > 0.0 && params_.lost.local_candidate_fraction > 0.0) {
    std::vector<GaussianComponent> blurred = map_.components();
    const double b2 = params_.lost.redraw_blur_m * params_.lost.redraw_blur_m;
    for (GaussianComponent& c : blurred) c.cov_m2 += b2 * Eigen::Matrix3d::Identity();
    blurred_map_ = GmmMap(std::move(blurred), "blurred map");
  }
  map_self_ll_ = gmm_mcl::mapSelfLogDensity(map_, params_.measurement.floor_log_density,
                                            params_.measurement.depth_noise);
}

void Localizer::setParams(const LocalizerParams& params) {
  validated(params);
  if (params.backend != params_.backend || params.filter.seed != params_.filter.seed ||
      params.device_filter != params_.device_filter) {
    throw std::invalid_argument(
        "localizer parameters: backend, device_filter and seed are fixed at construction");
  }
  const MeasurementParams& m = params.measurement;
  const MeasurementParams& m0 = params_.measurement;
  const bool map_terms = m.floor_log_density != m0.floor_log_density ||
                         m.depth_noise.a_m != m0.depth_noise.a_m ||
                         m.depth_noise.b_per_m != m0.depth_noise.b_per_m ||
                         m.depth_noise.z0_m != m0.depth_noise.z0_m ||
                         params.lost.redraw_blur_m != params_.lost.redraw_blur_m ||
                         params.lost.local_candidate_fraction != params_.lost.local_candidate_fraction;
  filter_->setParams(params.filter);
  params_ = params;
  if (map_terms) prepareMap();
  lost_.setParams(params_.lost, map_self_ll_);
}

void Localizer::setMap(GmmMap map) {
  if (map.empty()) throw std::invalid_argument("localizer: the map is empty");
  map_ = std::move(map);
  prepareMap();
  lost_ = LostDetector(params_.lost, map_self_ll_);
  have_refined_ = false;
}

void Localizer::reset(const InitRegion& region) {
  const std::string err = region.validate();
  if (!err.empty()) throw std::invalid_argument("reset region: " + err);
  region_ = region;
  filter_->initialiseUniform(region_);
  lost_.restart();
  screen_pending_ = true;
  have_refined_ = false;
}

void Localizer::resetToPose(const Particle& pose, const Eigen::Vector4d& sigma) {
  filter_->initialiseGaussian(pose, sigma);
  lost_.restart();
  screen_pending_ = false;
  have_refined_ = false;
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
  return particleToPose(filter_->estimate().mean, roll_rad_, pitch_rad_);
}

void Localizer::screenCandidates(const MeasurementContext& ctx, int count, bool local_stage) {
  filter_->clearCandidates();
  const int per = params_.lost.candidates_per_particle;
  if (count <= 0) return;
  const int total = count * per;
  // With the local stage, part of the candidates are drawn around the best uniform ones
  // (Gaussian, local_sigma_m / local_sigma_rad): a uniform candidate rarely lands inside the
  // likelihood's basin (a few decimetres), one of the best few often lands beside it.
  const int local =
      local_stage && per > 1 ? static_cast<int>(params_.lost.local_candidate_fraction * total) : 0;
  const int batch = filter_->size();  // the backend's usual batch size
  // The uniform stage of a redraw against the blurred map (a wider basin), then the map again.
  const bool blur = local_stage && !blurred_map_.empty();
  if (blur) backend_->setMap(blurred_map_);
  try {
    for (int done = 0; done < total - local; done += batch) {
      filter_->drawUniformCandidates(region_, std::min(batch, total - local - done));
      filter_->scoreCandidates(ctx);
    }
  } catch (...) {
    if (blur) backend_->setMap(map_);
    throw;
  }
  if (blur) backend_->setMap(map_);
  if (local > 0) {
    const int elites =
        std::max(1, static_cast<int>(params_.lost.elite_fraction * filter_->scoredCandidates()));
    // Blurred scores only chose the centres; the redraw is chosen by the map's own scores.
    filter_->selectCandidateCentres(elites, blur);
    for (int done = 0; done < local; done += batch) {
      filter_->drawCandidatesAroundCentres(params_.lost.local_sigma_m,
                                           params_.lost.local_sigma_rad,
                                           std::min(batch, local - done));
      filter_->scoreCandidates(ctx);
    }
  }
}

const DepthFrame& Localizer::hostFrame(const StepInput& in) {
  if (!host_frame_ready_) {
    host_frame_ = prepareFrame(*in.depth, in.intrinsics, params_.frame);
    host_frame_ready_ = true;
  }
  return host_frame_;
}

void Localizer::backendFailed(const std::string& what, StepResult* res) {
  res->status = StepStatus::kBackendError;
  res->message += (res->message.empty() ? "" : "; ") + std::string("likelihood backend: ") + what;
  backend_fault_ = what;
  const bool accelerated = backend_->name() != "cpu" || filter_->name() != "host";
  if (params_.cpu_fallback && accelerated) {
    // Keep the belief: the particles copied down (from a failed device this may fail too; then
    // a Gaussian around the last estimate, else the initial region).
    std::string kept = "particles kept";
    if (filter_->name() != "host") {
      std::vector<Particle> particles;
      std::vector<double> weights;
      try {
        particles = filter_->particles();
        weights = filter_->weights();
      } catch (const std::exception&) {
        particles.clear();
      }
      std::unique_ptr<ParticleFilterBase> host(new ParticleFilter(params_.filter));
      double total = 0.0;
      for (double w : weights) total += w;
      if (!particles.empty() && particles.size() == weights.size() && total > 0.0 &&
          std::isfinite(total)) {
        host->setParticles(particles, weights);
      } else if (have_estimate_) {
        const Eigen::Matrix<double, 6, 6>& C = last_estimate_.covariance;
        const Eigen::Vector4d sigma(std::sqrt(C(0, 0)), std::sqrt(C(1, 1)), std::sqrt(C(2, 2)),
                                    std::sqrt(C(5, 5)));
        host->initialiseGaussian(last_estimate_.mean, sigma.cwiseMax(1e-3));
        kept = "particles lost with the device: redrawn around the last estimate";
      } else {
        host->initialiseUniform(region_);
        kept = "particles lost with the device: redrawn from the initial region";
      }
      filter_.reset();  // the device filter works on the backend's stream: gone first
      filter_ = std::move(host);
    }
    const std::string failed = backend_->name();
    backend_ = makeBackend("cpu", nullptr);
    backend_->setMap(map_);
    backend_warning_ = "the " + failed + " backend failed (" + what +
                       "): fell back to the CPU backend, " + kept;
    res->backend_fallback = true;
    res->message += "; fell back to the CPU backend (" + kept + ")";
  }
  try {
    res->estimate = filter_->estimate();
    res->refinement.pose = res->estimate.mean;
    res->neff = filter_->effectiveSampleSize();
    res->particles = filter_->size();
  } catch (const std::exception&) {
    // The device failed again: the result carries no estimate.
  }
}

StepResult Localizer::step(const StepInput& in) {
  const Clock::time_point t_start = Clock::now();
  StepResult res;
  try {
    stepOnce(in, &res);
  } catch (const BackendError& e) {
    backendFailed(e.what(), &res);
    res.timings.total_ms = msSince(t_start);
  }
  if (res.status != StepStatus::kBackendError || res.backend_fallback) {
    last_estimate_ = res.estimate;
    have_estimate_ = true;
  }
  return res;
}

void Localizer::stepOnce(const StepInput& in, StepResult* res_out) {
  StepResult& res = *res_out;
  const Clock::time_point t_start = Clock::now();
  host_frame_ready_ = false;
  // Time going backwards (a looped bag): start over from the initial region.
  if (have_stamp_ && in.stamp_s < last_stamp_s_) {
    std::ostringstream msg;
    msg << "time jumped back from " << last_stamp_s_ << " s to " << in.stamp_s
        << " s: filter re-initialised";
    filter_->initialiseUniform(region_);
    lost_.restart();
    screen_pending_ = true;
    have_refined_ = false;
    have_odometry_ = false;
    have_stamp_ = false;
    res.status = StepStatus::kTimeJumpBack;
    res.message = msg.str();
  }
  have_stamp_ = true;
  last_stamp_s_ = in.stamp_s;
  if (in.has_T_base_cam) {
    if (in.T_base_cam.matrix().allFinite()) {
      params_.T_base_cam = in.T_base_cam;
    } else {
      res.message += std::string(res.message.empty() ? "" : "; ") +
                     "base -> camera transform not finite: the previous one used";
    }
  }

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
  filter_->predict(delta);
  if (have_refined_) {  // the last refined pose moved like a particle, without noise
    const double c = std::cos(last_refined_.yaw_rad), sn = std::sin(last_refined_.yaw_rad);
    last_refined_.x_m += c * delta.translation_m.x() - sn * delta.translation_m.y();
    last_refined_.y_m += sn * delta.translation_m.x() + c * delta.translation_m.y();
    last_refined_.z_m += delta.translation_m.z();
    last_refined_.yaw_rad = wrapAngle(last_refined_.yaw_rad + delta.yaw_rad);
  }
  res.timings.predict_ms = msSince(t0);

  auto finish = [&](StepStatus status, const std::string& why) {
    if (res.status == StepStatus::kOk) res.status = status;
    if (!why.empty()) res.message += (res.message.empty() ? "" : "; ") + why;
    t0 = Clock::now();
    res.estimate = filter_->estimate();
    res.refinement.pose = res.estimate.mean;
    res.neff = filter_->effectiveSampleSize();
    res.particles = filter_->size();
    res.timings.estimate_ms = msSince(t0);
    res.timings.total_ms = msSince(t_start);
  };

  if (in.depth == nullptr) return finish(StepStatus::kPredictOnly, "");

  // Frame preparation: with the device filter the raw image is uploaded once and prepared on
  // the GPU; on the host otherwise (and wherever the host needs the points: refinement).
  t0 = Clock::now();
  long long patches_with_pixels = -1;  // from the device frame
  try {
    DeviceFrameSummary summary;
    if (filter_->prepareDeviceFrame(*in.depth, in.intrinsics, params_.frame, &summary)) {
      res.pixels = summary.pixels;
      patches_with_pixels = summary.patches_with_pixels;
    } else {
      res.pixels = static_cast<int>(hostFrame(in).size());
    }
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {
    return finish(StepStatus::kBadFrame, e.what());
  }
  res.timings.frame_prep_ms = msSince(t0);
  if (res.pixels == 0) {
    const DepthFrame& frame = hostFrame(in);
    std::ostringstream msg;
    msg << "no valid depth pixel (" << frame.invalid_pixels << " invalid, "
        << frame.out_of_range_pixels << " out of range of " << frame.total_pixels_sampled << ")";
    return finish(StepStatus::kNoValidPixels, msg.str());
  }
  MeasurementContext ctx;
  ctx.backend = backend_.get();
  ctx.frame = host_frame_ready_ ? &host_frame_ : nullptr;
  ctx.roll_rad = roll_rad_;
  ctx.pitch_rad = pitch_rad_;
  ctx.T_base_cam = params_.T_base_cam;
  ctx.params = &params_.measurement;

  // Likelihood of every particle; after a uniform (re)initialisation the set is first replaced
  // by the best of candidates_per_particle times as many uniform draws.
  EvaluationStats stats;
  try {
    if (screen_pending_ && params_.lost.candidates_per_particle > 1) {
      screenCandidates(ctx, filter_->size());
      filter_->replaceAllByBestCandidates();
      res.screened_candidates = filter_->size() * params_.lost.candidates_per_particle;
    }
    screen_pending_ = false;
    filter_->evaluateFrame(ctx, &stats);
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {
    return finish(StepStatus::kBackendError, std::string("likelihood backend: ") + e.what());
  }
  if (patches_with_pixels >= 0) stats.patches_with_pixels = patches_with_pixels;
  res.timings.projection_membership_ms = stats.projection_membership_ms;
  res.timings.likelihood_ms = stats.likelihood_ms;
  res.evaluations = stats.evaluations;
  if (stats.patches_with_pixels > 0) {
    res.relevant_per_patch = static_cast<double>(stats.relevant_pairs) /
                             (stats.patches_with_pixels * static_cast<double>(filter_->size()));
  }

  // Weights.
  t0 = Clock::now();
  FrameScores scores;
  if (!filter_->weighFrame(res.pixels, &scores)) {
    return finish(StepStatus::kDegenerateWeights,
                  "no particle has a usable likelihood: weights kept");
  }
  res.beta_fraction = scores.beta_fraction;
  res.best_loglik_per_pixel = scores.best_loglik / res.pixels;
  res.mean_loglik_per_pixel = scores.mean_loglik / res.pixels;
  res.floor_hit_fraction = static_cast<double>(scores.best_floor_hits) / res.pixels;
  if (scores.best_floor_hits >= res.pixels) {
    res.message += std::string(res.message.empty() ? "" : "; ") +
                   "every used pixel is at the likelihood floor for every particle: no particle "
                   "sees the mapped surfaces";
  }
  res.timings.weights_ms = msSince(t0);

  // Estimate from the updated weights (refined when the filter has converged), then resample
  // and recover.
  t0 = Clock::now();
  res.estimate = filter_->estimate();
  res.neff = filter_->effectiveSampleSize();
  res.particles = filter_->size();
  res.timings.estimate_ms = msSince(t0);
  res.refinement.pose = res.estimate.mean;
  if (params_.refinement.enabled) {
    const Eigen::Matrix<double, 6, 6>& C = res.estimate.covariance;
    const double position_sigma = std::sqrt(std::max({C(0, 0), C(1, 1), C(2, 2)}));
    const double yaw_sigma = std::sqrt(C(5, 5));
    if (position_sigma <= params_.refinement.max_position_sigma_m &&
        yaw_sigma <= params_.refinement.max_yaw_sigma_rad) {
      // Warm start from the last refined pose moved by this frame's odometry, while it stays
      // near the particle mean (a few iterations instead of a dozen when tracking).
      Particle start = res.estimate.mean;
      if (have_refined_ && std::hypot(std::hypot(last_refined_.x_m - start.x_m,
                                                 last_refined_.y_m - start.y_m),
                                      last_refined_.z_m - start.z_m) <
                               0.5 * params_.refinement.max_correction_m &&
          std::abs(wrapAngle(last_refined_.yaw_rad - start.yaw_rad)) <
              0.5 * params_.refinement.max_correction_rad) {
        start = last_refined_;
      }
      // The pixel sums run on the backend (on the GPU with the CUDA backend, reading the frame it
      // prepared there), else on the host with the points prepared there now.
      NormalEquationsEvaluator* sums = backend_->normalEquations();
      RefinementFrame rf;
      if (!host_frame_ready_ && sums != nullptr && sums->hasBackendFrame()) {
        rf.intrinsics = in.intrinsics;
        rf.grid = PatchGrid::forImage(in.depth->width_px, in.depth->height_px,
                                      params_.frame.patch_size_px);
        rf.pixels = res.pixels;
      } else {
        const Clock::time_point tp = Clock::now();
        rf = RefinementFrame::of(hostFrame(in));
        res.timings.frame_prep_ms += msSince(tp);
      }
      res.refinement = refinePose(map_.packed(), rf, start, roll_rad_, pitch_rad_,
                                  params_.T_base_cam, params_.measurement, params_.refinement,
                                  sums);
      // Judged against the particle mean, whatever the start.
      const Particle& r = res.refinement.pose;
      if (res.refinement.refined &&
          (std::hypot(std::hypot(r.x_m - res.estimate.mean.x_m, r.y_m - res.estimate.mean.y_m),
                      r.z_m - res.estimate.mean.z_m) > params_.refinement.max_correction_m ||
           std::abs(wrapAngle(r.yaw_rad - res.estimate.mean.yaw_rad)) >
               params_.refinement.max_correction_rad)) {
        res.refinement.refined = false;
        res.refinement.why = "refined pose too far from the particle mean: rejected";
        res.refinement.pose = res.estimate.mean;
      }
      res.timings.refine_ms = res.refinement.ms;
    } else {
      res.refinement.why = "not converged";
    }
  }
  have_refined_ = res.refinement.refined;
  if (have_refined_) last_refined_ = res.refinement.pose;
  t0 = Clock::now();
  res.resampled = filter_->resampleIfNeeded();
  res.reinitialised = filter_->recoverFrame(res.pixels, region_);
  // Absolute-quality recovery: the worst particles by this frame's likelihood (after any
  // resampling, each particle carries its source's likelihood) are redrawn.
  if (lost_.update(res.best_loglik_per_pixel)) {
    res.lost = true;
    have_refined_ = false;
    // The worst fraction is redrawn; with an adaptive count the set grows back to its largest.
    const int n = filter_->size();
    const int keep = n - static_cast<int>(std::floor(params_.lost.reinit_fraction * n));
    const int count = params_.filter.adaptive() ? params_.filter.num_particles - keep : n - keep;
    try {
      screenCandidates(ctx, count, true);
      filter_->replaceWorstByBestCandidates(keep, count);
      res.lost_reinitialised = count;
      res.screened_candidates += count * params_.lost.candidates_per_particle;
    } catch (const BackendError&) {
      throw;
    } catch (const std::exception& e) {
      return finish(StepStatus::kBackendError, std::string("likelihood backend: ") + e.what());
    }
    std::ostringstream msg;
    msg << "lost: best log-likelihood " << res.best_loglik_per_pixel << " nats/px stayed more than "
        << params_.lost.margin_nats << " below the reference " << lost_.reference() << " for "
        << params_.lost.frames << " frames: " << res.lost_reinitialised
        << " particles redrawn from the recovery region (best of "
        << params_.lost.candidates_per_particle << " candidates each)";
    res.message += (res.message.empty() ? "" : "; ") + msg.str();
  }
  res.reference_loglik_per_pixel = lost_.reference();
  res.timings.resample_ms = msSince(t0);
  res.timings.total_ms = msSince(t_start);
}

}  // namespace gmm_mcl
