// Localizer::stepOnce and its stages: one frame through predict, frame preparation,
// likelihood, weights, estimate and refinement, resampling and recovery.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {
namespace {

// A refined frame informs the depth-scale estimate only when its per-pixel log-likelihood is
// within this of the lost detector's reference (a right pose scores about the reference; a
// wrong place in the Replica office scored 2.7 nats below, a pose 10-20 cm off 1.5).
constexpr double kDepthScaleFitNats = 1.0;

}  // namespace

void Localizer::beliefSpread(const Eigen::Matrix<double, 6, 6>& C, double* position_sigma,
                             double* yaw_sigma) {
  *position_sigma = std::sqrt(std::max({C(0, 0), C(1, 1), C(2, 2)}));
  *yaw_sigma = std::sqrt(C(5, 5));
}

void Localizer::stepOnce(const StepInput& in, StepResult* res_out) {
  StepResult& res = *res_out;
  const Clock::time_point t_start = Clock::now();
  host_frame_ready_ = false;
  takeStepInputs(in, &res);
  predictStep(in, &res);
  const bool any_frame =
      in.depth != nullptr || std::any_of(in.more_cameras.begin(), in.more_cameras.end(),
                                         [](const CameraInput& c) { return c.depth != nullptr; });
  if (!any_frame) return finishStep(StepStatus::kPredictOnly, "", t_start, &res);
  std::string why;
  long long patches_with_pixels = -1;  // from the device frame
  StepStatus status = selectStepCamera(in, &patches_with_pixels, &res, &why);
  if (status != StepStatus::kOk) return finishStep(status, why, t_start, &res);
  MeasurementContext ctx;
  ctx.backend = backend_.get();
  ctx.frame = host_frame_ready_ ? &host_frame_ : nullptr;
  ctx.roll_rad = roll_rad_;
  ctx.pitch_rad = pitch_rad_;
  ctx.T_base_cam = cam_.T_base_cam;
  ctx.params = cam_.measurement;
  if (start_places_.active()) followStartPlaces(&res);
  status = evaluateStep(ctx, patches_with_pixels, &res, &why);
  if (status != StepStatus::kOk) return finishStep(status, why, t_start, &res);
  status = evaluateMoreCameras(in, ctx, &res, &why);
  if (status != StepStatus::kOk) return finishStep(status, why, t_start, &res);
  status = weighStep(&res, &why);
  if (status != StepStatus::kOk) return finishStep(status, why, t_start, &res);
  if (seed_start_places_) seedStartPlaces();
  res.start_places = static_cast<int>(start_places_.places().size());
  estimateAndRefine(in, &res);
  status = resampleAndRecover(ctx, &res, &why);
  if (status != StepStatus::kOk) return finishStep(status, why, t_start, &res);
  // Last: its scoring replaces the backend's frame of this step.
  if (params_.lost.rival_check_frames > 0) checkRivals(&res);
  res.timings.total_ms = msSince(t_start);
}

void Localizer::takeStepInputs(const StepInput& in, StepResult* res) {
  step_dt_s_ = have_stamp_ ? in.stamp_s - last_stamp_s_ : 0.0;
  // Time going backwards (a looped bag): start over from the initial region.
  if (have_stamp_ && in.stamp_s < last_stamp_s_) {
    std::ostringstream msg;
    msg << "time jumped back from " << last_stamp_s_ << " s to " << in.stamp_s
        << " s: filter re-initialised";
    filter_->initialiseUniform(region_);
    lost_.restart();
    start_places_.stop();
    screen_pending_ = true;
    have_refined_ = false;
    have_odometry_ = false;
    have_gyro_yaw_ = false;
    have_stamp_ = false;
    motion_model_.reset();
    step_dt_s_ = 0.0;
    res->status = StepStatus::kTimeJumpBack;
    res->message = msg.str();
  }
  have_stamp_ = true;
  last_stamp_s_ = in.stamp_s;
  syncDepthScales(in);  // a scale for each camera the input names
  if (in.has_T_base_cam) {
    if (in.T_base_cam.matrix().allFinite()) {
      params_.T_base_cam = in.T_base_cam;
    } else {
      res->message += std::string(res->message.empty() ? "" : "; ") +
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
}

void Localizer::predictStep(const StepInput& in, StepResult* res) {
  const Clock::time_point t0 = Clock::now();
  PlanarDelta delta;
  if (in.has_odometry && have_odometry_) {
    delta = odometryDelta(last_odom_, in.T_odom_base);
    if (!(delta.translation_m.norm() <= params_.max_odometry_step_m) ||
        !std::isfinite(delta.yaw_rad)) {
      std::ostringstream msg;
      msg << "odometry step of " << delta.translation_m.norm() << " m exceeds "
          << params_.max_odometry_step_m << " m: ignored";
      res->odometry_jump = true;
      res->message += (res->message.empty() ? "" : "; ") + msg.str();
      delta = PlanarDelta();
    }
  }
  if (in.has_odometry && have_odometry_) {
    res->motion = MotionSource::kOdometry;
  } else if (params_.constant_velocity.enabled) {
    // No odometry (or its first message: no delta yet): the filter's own recent motion, its
    // yaw change from the gyro where the input has one.
    const bool gyro = in.has_gyro_yaw && have_gyro_yaw_ && in.gyro_segment == last_gyro_segment_;
    const double gyro_delta = gyro ? in.gyro_yaw_rad - last_gyro_yaw_rad_ : 0.0;
    delta = motion_model_.predict(step_dt_s_, params_.filter.sigma_translation_m,
                                  params_.filter.sigma_yaw_rad, gyro ? &gyro_delta : nullptr,
                                  &res->gyro_yaw);
    res->motion = MotionSource::kConstantVelocity;
  } else {
    res->motion = MotionSource::kStatic;
  }
  if (in.has_odometry) {
    last_odom_ = in.T_odom_base;
    have_odometry_ = true;
  }
  have_gyro_yaw_ = in.has_gyro_yaw && std::isfinite(in.gyro_yaw_rad);
  last_gyro_yaw_rad_ = in.gyro_yaw_rad;
  last_gyro_segment_ = in.gyro_segment;
  filter_->predict(delta);
  last_delta_ = delta;
  // The last refined pose moves like a particle, without noise.
  if (have_refined_) applyDelta(delta, &last_refined_);
  if (rival_pending_) applyDelta(delta, &rival_);  // a rival awaiting its next check
  res->timings.predict_ms = msSince(t0);
}

void Localizer::finishStep(StepStatus status, const std::string& why, Clock::time_point t_start,
                           StepResult* res) {
  if (res->status == StepStatus::kOk) res->status = status;
  if (!why.empty()) res->message += (res->message.empty() ? "" : "; ") + why;
  const Clock::time_point t0 = Clock::now();
  res->estimate = filter_->estimate();
  res->refinement.pose = res->estimate.mean;
  res->neff = filter_->effectiveSampleSize();
  res->particles = filter_->size();
  res->timings.estimate_ms = msSince(t0);
  res->timings.total_ms = msSince(t_start);
}

StepStatus Localizer::selectStepCamera(const StepInput& in, long long* patches_with_pixels,
                                       StepResult* res, std::string* why) {
  // StepInput's own camera, else the first of the others with a usable frame (a rig whose
  // first camera dropped out goes on with the rest).
  const int cameras = 1 + static_cast<int>(in.more_cameras.size());
  if (!in.more_cameras.empty()) {
    res->cameras.resize(cameras);
    for (int c = 1; c < cameras; ++c) res->cameras[c].name = in.more_cameras[c - 1].name;
  }
  StepStatus first_status = StepStatus::kOk;
  std::string first_why;
  for (int c = 0; c < cameras; ++c) {
    cam_ = StepCamera();
    if (c == 0) {
      cam_.depth = in.depth;
      cam_.intrinsics = in.intrinsics;
      cam_.T_base_cam = params_.T_base_cam;
      cam_.frame = &params_.frame;
      cam_.measurement = &params_.measurement;
    } else {
      const CameraInput& m = in.more_cameras[c - 1];
      cam_.depth = m.depth;
      cam_.intrinsics = m.intrinsics;
      cam_.T_base_cam = m.T_base_cam;
      cam_.frame = &m.frame;
      cam_.measurement = &m.measurement;
    }
    if (cam_.depth == nullptr) {
      if (!res->cameras.empty()) res->cameras[c].problem = "no frame";
      continue;
    }
    host_frame_ready_ = false;
    std::string camera_why;
    const StepStatus status = prepareStepFrame(patches_with_pixels, res, &camera_why);
    if (status == StepStatus::kOk) {
      first_camera_ = c;
      cam_.pixels = res->pixels;
      cameras_used_ = 1;
      if (!res->cameras.empty()) {
        res->cameras[c].used = true;
        res->cameras[c].pixels = res->pixels;
      }
      return status;
    }
    if (res->cameras.empty()) {
      *why = camera_why;
      return status;
    }
    res->cameras[c].problem = camera_why;
    if (first_status == StepStatus::kOk) first_status = status;
    first_why += std::string(first_why.empty() ? "" : "; ") + "camera " +
                 (c == 0 ? std::string("1") : "'" + res->cameras[c].name + "'") + ": " + camera_why;
  }
  *why = first_why;
  return first_status;
}

StepStatus Localizer::evaluateMoreCameras(const StepInput& in, const MeasurementContext& ctx,
                                          StepResult* res, std::string* why) {
  // Each further camera's frame prepared with its own parameters and scored with its own
  // measurement model; its log-likelihood added to every particle's (docs/multi_camera.md).
  bool on_device = false;
  std::string skipped;
  more_frames_.assign(in.more_cameras.size() + 1, DepthFrame());
  for (int c = first_camera_ + 1; c <= static_cast<int>(in.more_cameras.size()); ++c) {
    const CameraInput& m = in.more_cameras[c - 1];
    CameraStepResult& out = res->cameras[c];
    if (m.depth == nullptr) {
      out.problem = "no frame";
      continue;
    }
    const Clock::time_point t0 = Clock::now();
    MeasurementContext more = ctx;
    more.T_base_cam = m.T_base_cam;
    more.params = &m.measurement;
    int pixels = 0;
    try {
      DeviceFrameSummary summary;
      if (filter_->prepareDeviceFrame(*m.depth, m.intrinsics, m.frame, &summary)) {
        on_device = true;
        pixels = summary.pixels;
        more.frame = nullptr;
      } else {
        more_frames_[c] = prepareFrame(*m.depth, m.intrinsics, m.frame);
        pixels = static_cast<int>(more_frames_[c].size());
        more.frame = &more_frames_[c];
      }
    } catch (const BackendError&) {
      throw;
    } catch (const std::exception& e) {
      out.problem = e.what();
    }
    res->timings.frame_prep_ms += msSince(t0);
    if (out.problem.empty() && pixels == 0) out.problem = "no valid depth pixel";
    if (!out.problem.empty()) {
      skipped += std::string(skipped.empty() ? "" : "; ") + "camera '" + out.name +
                 "' not used: " + out.problem;
      continue;
    }
    // Scaled to the first camera's pixel count: each camera's frame is one frame's evidence,
    // whatever its stride and resolution (docs/multi_camera.md).
    const double scale = static_cast<double>(cam_.pixels) / pixels;
    EvaluationStats stats;
    try {
      filter_->accumulateFrame(more, scale, &stats);
    } catch (const BackendError&) {
      throw;
    } catch (const std::exception& e) {
      *why = std::string("likelihood backend: ") + e.what();
      return StepStatus::kBackendError;
    }
    out.used = true;
    out.pixels = pixels;
    res->pixels += pixels;
    ++cameras_used_;
    res->evaluations += stats.evaluations;
    res->timings.projection_membership_ms += stats.projection_membership_ms;
    res->timings.likelihood_ms += stats.likelihood_ms;
  }
  if (first_camera_ > 0 || !skipped.empty()) {
    std::string note = skipped;
    if (first_camera_ > 0) {
      note = "camera '" + res->cameras[first_camera_].name + "' measured first (" +
             res->cameras[0].problem + " from camera 1)" + (note.empty() ? "" : "; ") + note;
    }
    res->message += (res->message.empty() ? "" : "; ") + note;
  }
  // The device holds the last camera's frame now: the first camera's again for the refinement
  // and any redraw of this step.
  if (on_device) {
    DeviceFrameSummary summary;
    filter_->prepareDeviceFrame(*cam_.depth, cam_.intrinsics, *cam_.frame, &summary);
  }
  return StepStatus::kOk;
}

StepStatus Localizer::prepareStepFrame(long long* patches_with_pixels, StepResult* res,
                                       std::string* why) {
  // With the device filter the raw image is uploaded once and prepared on the GPU; on the host
  // otherwise (and wherever the host needs the points: refinement).
  const Clock::time_point t0 = Clock::now();
  try {
    DeviceFrameSummary summary;
    if (filter_->prepareDeviceFrame(*cam_.depth, cam_.intrinsics, *cam_.frame, &summary)) {
      res->pixels = summary.pixels;
      *patches_with_pixels = summary.patches_with_pixels;
    } else {
      res->pixels = static_cast<int>(hostFrame().size());
    }
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {
    *why = e.what();
    return StepStatus::kBadFrame;
  }
  res->timings.frame_prep_ms = msSince(t0);
  if (res->pixels == 0) {
    const DepthFrame& frame = hostFrame();
    std::ostringstream msg;
    msg << "no valid depth pixel (" << frame.invalid_pixels << " invalid, "
        << frame.out_of_range_pixels << " out of range of " << frame.total_pixels_sampled << ")";
    *why = msg.str();
    return StepStatus::kNoValidPixels;
  }
  return StepStatus::kOk;
}

StepStatus Localizer::evaluateStep(const MeasurementContext& ctx, long long patches_with_pixels,
                                   StepResult* res, std::string* why) {
  // Likelihood of every particle; after a uniform (re)initialisation the set is first replaced
  // by the best of candidates_per_particle times as many uniform draws.
  EvaluationStats stats;
  try {
    if (screen_pending_ && params_.lost.candidates_per_particle > 1) {
      const double area_m2 = 4.0 * region_.half_extent_m.x() * region_.half_extent_m.y();
      const bool wide = area_m2 >= params_.lost.start_local_stage_min_area_m2;
      const Clock::time_point t0 = Clock::now();
      screenCandidates(ctx, filter_->size(), wide);
      filter_->replaceAllByBestCandidates();
      res->timings.screen_ms = msSince(t0);
      seed_start_places_ = wide && params_.lost.start_places > 0;
      res->screened_candidates = filter_->size() * params_.lost.candidates_per_particle;
    }
    screen_pending_ = false;
    filter_->evaluateFrame(ctx, &stats);
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {
    *why = std::string("likelihood backend: ") + e.what();
    return StepStatus::kBackendError;
  }
  if (patches_with_pixels >= 0) stats.patches_with_pixels = patches_with_pixels;
  res->timings.projection_membership_ms += stats.projection_membership_ms;
  res->timings.likelihood_ms += stats.likelihood_ms;
  res->evaluations += stats.evaluations;
  if (stats.patches_with_pixels > 0) {
    res->relevant_per_patch = static_cast<double>(stats.relevant_pairs) /
                              (stats.patches_with_pixels * static_cast<double>(filter_->size()));
  }
  return StepStatus::kOk;
}

StepStatus Localizer::weighStep(StepResult* res, std::string* why) {
  const Clock::time_point t0 = Clock::now();
  FrameScores scores;
  // A rig's log-likelihoods are scaled to the first camera's pixel count (evaluateMoreCameras):
  // the tempered exponent takes that count, so that each camera's frame is one frame's
  // evidence, and the per-pixel levels are the cameras' mean (one camera: its pixels).
  const int per_pixel = cameras_used_ * cam_.pixels;
  const int weigh_pixels =
      params_.filter.weighting == WeightingMode::kTempered ? cam_.pixels : per_pixel;
  if (!filter_->weighFrame(weigh_pixels, &scores)) {
    *why = "no particle has a usable likelihood: weights kept";
    return StepStatus::kDegenerateWeights;
  }
  res->beta_fraction = scores.beta_fraction;
  res->best_loglik_per_pixel = scores.best_loglik / per_pixel;
  res->mean_loglik_per_pixel = scores.mean_loglik / per_pixel;
  res->floor_hit_fraction = static_cast<double>(scores.best_floor_hits) / res->pixels;
  if (scores.best_floor_hits >= res->pixels) {
    res->message += std::string(res->message.empty() ? "" : "; ") +
                    "every used pixel is at the likelihood floor for every particle: no particle "
                    "sees the mapped surfaces";
  }
  res->timings.weights_ms = msSince(t0);
  return StepStatus::kOk;
}

void Localizer::estimateAndRefine(const StepInput& in, StepResult* res) {
  // Estimate from the updated weights, refined when the filter has converged.
  const Clock::time_point t0 = Clock::now();
  res->estimate = filter_->estimate();
  res->neff = filter_->effectiveSampleSize();
  res->particles = filter_->size();
  res->timings.estimate_ms = msSince(t0);
  res->refinement.pose = res->estimate.mean;
  if (params_.refinement.enabled) {
    // A converged set, or one that widened while the previous frame was refined (its track; a
    // step predicted without odometry has tracking limits of its own).
    const RefinementParams& rp = params_.refinement;
    double position_sigma, yaw_sigma;
    beliefSpread(res->estimate.covariance, &position_sigma, &yaw_sigma);
    const bool odometry = res->motion == MotionSource::kOdometry;
    const double track_position_m =
        odometry ? rp.track_max_position_sigma_m : rp.cv_track_max_position_sigma_m;
    const double track_yaw_rad =
        odometry ? rp.track_max_yaw_sigma_rad : rp.cv_track_max_yaw_sigma_rad;
    const double max_position_sigma_m = have_refined_
                                            ? std::max(rp.max_position_sigma_m, track_position_m)
                                            : rp.max_position_sigma_m;
    const double max_yaw_sigma_rad =
        have_refined_ ? std::max(rp.max_yaw_sigma_rad, track_yaw_rad) : rp.max_yaw_sigma_rad;
    if (position_sigma <= max_position_sigma_m && yaw_sigma <= max_yaw_sigma_rad) {
      refineEstimate(in, res);
    } else {
      res->refinement.why = "not converged";
    }
  }
  have_refined_ = res->refinement.refined;
  if (have_refined_) last_refined_ = res->refinement.pose;
  reportDepthScales(res);
  observeMotion(in, *res);
}

void Localizer::syncDepthScales(const StepInput& in) {
  for (size_t c = depth_scales_.size(); c <= in.more_cameras.size(); ++c) {
    depth_scales_.push_back(in.more_cameras[c - 1].depth_scale_initial);
    depth_scale_information_.push_back(0.0);
  }
}

void Localizer::reportDepthScales(StepResult* res) const {
  const RefinementParams& rp = params_.refinement;
  auto report = [&](int c, double* scale, bool* at_bound) {
    const double f = c < static_cast<int>(depth_scales_.size()) ? depth_scales_[c] : 1.0;
    *scale = rp.estimate_depth_scale ? f : 1.0;
    *at_bound = rp.estimate_depth_scale && std::abs(f - 1.0) >= 0.99 * rp.depth_scale_max_error;
  };
  report(0, &res->depth_scale, &res->depth_scale_at_bound);
  for (int c = 0; c < static_cast<int>(res->cameras.size()); ++c) {
    report(c, &res->cameras[c].depth_scale, &res->cameras[c].depth_scale_at_bound);
  }
}

void Localizer::observeMotion(const StepInput& in, const StepResult& res) {
  // The constant-velocity model learns from the refined pose of a set within refinement's
  // convergence limits, else from the particle mean up to twice as spread, trusted by (limit /
  // spread)^2: the velocity builds up while the filter converges, which in turn narrows the
  // prediction. A more spread belief restarts it from zero. A pose refined on a set beyond the
  // limits (refinement's tracking limits) is reported but not learned from: where a view leaves
  // a direction open the refined pose can slide along it, and a velocity learned from the slide
  // would move the particles after it.
  double position_sigma, yaw_sigma;
  beliefSpread(res.estimate.covariance, &position_sigma, &yaw_sigma);
  const double limit_m = params_.refinement.max_position_sigma_m;
  const double limit_rad = params_.refinement.max_yaw_sigma_rad;
  if (res.refinement.refined && position_sigma <= limit_m && yaw_sigma <= limit_rad) {
    motion_model_.observe(in.stamp_s, res.refinement.pose);
  } else if (position_sigma <= 2.0 * limit_m && yaw_sigma <= 2.0 * limit_rad) {
    const double confidence = std::min({1.0, std::pow(limit_m / std::max(position_sigma, 1e-9), 2),
                                        std::pow(limit_rad / std::max(yaw_sigma, 1e-9), 2)});
    motion_model_.observe(in.stamp_s, res.estimate.mean, confidence);
  } else {
    motion_model_.reset();
  }
  // No attitude input at all (no IMU, no odometry orientation): roll and pitch held from the
  // last refined estimate, which the refinement moves towards the frame's likelihood within its
  // attitude prior (docs/no_odometry.md).
  if (!in.has_attitude && !in.has_odometry && res.refinement.refined &&
      params_.refinement.attitude_prior_sigma_rad > 0.0 && std::isfinite(res.refinement.roll_rad) &&
      std::isfinite(res.refinement.pitch_rad)) {
    roll_rad_ = res.refinement.roll_rad;
    pitch_rad_ = res.refinement.pitch_rad;
  }
}

void Localizer::refineComponents(const Particle& mean, const RefinementFrame& rf,
                                 const Eigen::Isometry3d& T_base_cam, const FrameParams& frame,
                                 const MeasurementParams& mp, std::vector<ComponentF>* out) {
  // The components a camera can meet: the map grid's near its view from the particle mean,
  // grown by the largest correction the refinement may make (and some attitude), so that its
  // cost follows the view and not the map (docs/building_scale.md).
  const ViewReach reach = viewReach(rf.intrinsics, rf.grid.patch_size_px, rf.grid.cols,
                                    rf.grid.rows, patchInflation(rf.grid.patch_size_px),
                                    frame.max_range_m, mp.sigma_bound, mp.depth_noise);
  const Eigen::Isometry3d T_map_cam = particleToPose(mean, roll_rad_, pitch_rad_) * T_base_cam;
  viewComponents(map_, toRigidF(T_map_cam), rf.intrinsics, reach,
                 refinementReach(params_.refinement, reach), &refine_index_, out);
}

void Localizer::refineEstimate(const StepInput& in, StepResult* res) {
  // Warm start from the last refined pose moved by this frame's odometry, while it stays near
  // the particle mean (a few iterations instead of a dozen when tracking).
  Particle start = res->estimate.mean;
  if (have_refined_ &&
      std::hypot(std::hypot(last_refined_.x_m - start.x_m, last_refined_.y_m - start.y_m),
                 last_refined_.z_m - start.z_m) < 0.5 * params_.refinement.max_correction_m &&
      std::abs(wrapAngle(last_refined_.yaw_rad - start.yaw_rad)) <
          0.5 * params_.refinement.max_correction_rad) {
    start = last_refined_;
  }
  // The pixel sums run on the backend (on the GPU with the CUDA backend, reading the frame it
  // prepared there), else on the host with the points prepared there now.
  NormalEquationsEvaluator* sums = backend_->normalEquations();
  RefinementFrame rf;
  // The depth scales: each camera's own. Their noise correction draws noise on the frame's points
  // on the host (the sums still run on the backend's evaluator).
  const bool with_scale = params_.refinement.estimate_depth_scale;
  if (!host_frame_ready_ && sums != nullptr && sums->hasBackendFrame() &&
      (!with_scale ||
       (sums->supportsDepthScale() && !params_.refinement.depth_scale_noise_correction))) {
    rf.intrinsics = cam_.intrinsics;
    rf.grid =
        PatchGrid::forImage(cam_.depth->width_px, cam_.depth->height_px, cam_.frame->patch_size_px);
    rf.pixels = cam_.pixels;
  } else {
    const Clock::time_point tp = Clock::now();
    rf = RefinementFrame::of(hostFrame());
    res->timings.frame_prep_ms += msSince(tp);
  }
  const MeasurementParams& mp = *cam_.measurement;
  refineComponents(res->estimate.mean, rf, cam_.T_base_cam, *cam_.frame, mp, &refine_components_);
  // The rig's other cameras used in this update: their frames on the host.
  std::vector<RefinementView> more;
  std::vector<int> more_camera;  // the camera of each view
  more_components_.resize(res->cameras.size());
  for (int c = first_camera_ + 1; c < static_cast<int>(res->cameras.size()); ++c) {
    if (!res->cameras[c].used) continue;
    const CameraInput& m = in.more_cameras[c - 1];
    if (more_frames_[c].intrinsics.width_px == 0) {  // prepared on the device only
      const Clock::time_point tp = Clock::now();
      more_frames_[c] = prepareFrame(*m.depth, m.intrinsics, m.frame);
      res->timings.frame_prep_ms += msSince(tp);
    }
    RefinementView v;
    v.frame = RefinementFrame::of(more_frames_[c]);
    v.weight = static_cast<double>(cam_.pixels) / std::max<size_t>(1, more_frames_[c].size());
    v.T_base_cam = m.T_base_cam;
    v.params = &m.measurement;
    v.frame.depth_scale = with_scale ? depth_scales_[c] : 1.0;
    refineComponents(res->estimate.mean, v.frame, m.T_base_cam, m.frame, m.measurement,
                     &more_components_[c]);
    v.components = &more_components_[c];
    // The backend's evaluator for this camera (its pixel sums on the GPU with CUDA), else host.
    if (more_sums_.size() < res->cameras.size()) more_sums_.resize(res->cameras.size());
    if (!more_sums_[c]) more_sums_[c] = backend_->makeNormalEquations();
    v.sums = more_sums_[c].get();
    more.push_back(v);
    more_camera.push_back(c);
  }
  rf.depth_scale = with_scale ? depth_scales_[first_camera_] : 1.0;
  res->refinement = refinePose(refine_components_, rf, start, roll_rad_, pitch_rad_,
                               cam_.T_base_cam, mp, params_.refinement, sums, more);
  // Judged against the particle mean, whatever the start.
  const Particle& r = res->refinement.pose;
  const Particle& mean = res->estimate.mean;
  if (res->refinement.refined &&
      (std::hypot(std::hypot(r.x_m - mean.x_m, r.y_m - mean.y_m), r.z_m - mean.z_m) >
           params_.refinement.max_correction_m ||
       std::abs(wrapAngle(r.yaw_rad - mean.yaw_rad)) > params_.refinement.max_correction_rad)) {
    res->refinement.refined = false;
    res->refinement.why = "refined pose too far from the particle mean: rejected";
    res->refinement.pose = res->estimate.mean;
  }
  if (with_scale) {
    learnDepthScale(first_camera_, res->refinement.depth_scale,
                    res->refinement.depth_scale_information, *res);
    for (size_t k = 0; k < more_camera.size() && k < res->refinement.more_depth_scale.size(); ++k) {
      learnDepthScale(more_camera[k], res->refinement.more_depth_scale[k],
                      res->refinement.more_depth_scale_information[k], *res);
    }
  }
  res->timings.refine_ms = res->refinement.ms;
}

void Localizer::learnDepthScale(int c, double estimate, double info, const StepResult& res) {
  // The depth scale: the mean of the refined frames' estimates weighted by their information (a
  // frame whose scale trades against a translation, a frontal wall, counts little), the past
  // frames' weight shrinking by depth_scale_rate per frame (it remembers about 1 / rate
  // frames: one frame's estimate is tied to its pose, and a stretch of poorly refined frames
  // must not carry it away). Only frames that fit the map about as well as the lost detector's
  // reference says a right pose does: a filter settled in a wrong place (scoring nats per pixel
  // lower) would teach the scale that place's misfit.
  if (!res.refinement.refined || !(info > 0.0) ||
      res.refinement.loglik_refined < lost_.reference() - kDepthScaleFitNats) {
    return;
  }
  const RefinementParams& rp = params_.refinement;
  double& f = depth_scales_[c];
  double& information = depth_scale_information_[c];
  information = (1.0 - rp.depth_scale_rate) * information + info;
  f += info / information * (estimate - f);
  f = std::min(1.0 + rp.depth_scale_max_error, std::max(1.0 - rp.depth_scale_max_error, f));
}

void Localizer::seedStartPlaces() {
  seed_start_places_ = false;
  StartHypothesesParams p;
  p.places = params_.lost.start_places;
  p.frames = params_.lost.start_place_frames;
  start_places_ = StartHypotheses(p, params_.filter.seed ^ 0x5bd1e995u);
  // The set's weights after the first update rank its particles by their frame's likelihood
  // (equal weights before it).
  start_places_.seed(filter_->particles(), filter_->weights());
}

void Localizer::followStartPlaces(StepResult* res) {
  const Clock::time_point t0 = Clock::now();
  start_places_.predict(last_delta_);
  const std::vector<Particle>& proposals = start_places_.proposals();
  std::vector<RigidTransformF> poses(proposals.size());
  for (size_t i = 0; i < proposals.size(); ++i) {
    poses[i] = toRigidF(particleToPose(proposals[i], roll_rad_, pitch_rad_) * cam_.T_base_cam);
  }
  const DepthFrame& frame = hostFrame();
  BackendOutput out;
  try {
    backend_->evaluate(frame, poses, *cam_.measurement, &out);
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {  // the stage ends; the particle set goes on
    start_places_.stop();
    res->message += std::string(res->message.empty() ? "" : "; ") + "start places not scored (" +
                    e.what() + "): their stage ended";
    return;
  }
  start_places_.update(out.log_likelihood, static_cast<int>(frame.size()));
  res->evaluations += out.evaluations;
  if (start_places_.finished()) {
    // The best place seeds the particle set unless the set has already settled there.
    const StartHypotheses::Place best = start_places_.best();
    const int followed = static_cast<int>(start_places_.places().size());
    start_places_.stop();
    const PoseEstimate e = filter_->estimate();
    double position_sigma, yaw_sigma;
    beliefSpread(e.covariance, &position_sigma, &yaw_sigma);
    const bool settled_there =
        position_sigma <= params_.refinement.max_position_sigma_m &&
        yaw_sigma <= params_.refinement.max_yaw_sigma_rad &&
        std::hypot(std::hypot(e.mean.x_m - best.pose.x_m, e.mean.y_m - best.pose.y_m),
                   e.mean.z_m - best.pose.z_m) < params_.refinement.max_correction_m &&
        std::abs(wrapAngle(e.mean.yaw_rad - best.pose.yaw_rad)) <
            params_.refinement.max_correction_rad;
    if (!settled_there) {
      filter_->initialiseGaussian(best.pose, placeSigma());
      lost_.restart();
      have_refined_ = false;
      motion_model_.reset();
      res->start_place_chosen = true;
      std::ostringstream msg;
      msg << "start: the best of " << followed << " places followed over "
          << params_.lost.start_place_frames << " frames (" << best.last_loglik
          << " nats/px on this frame) seeds the particles at (" << best.pose.x_m << ", "
          << best.pose.y_m << ", " << best.pose.z_m << ") m, yaw " << best.pose.yaw_rad << " rad";
      res->message += (res->message.empty() ? "" : "; ") + msg.str();
    }
  }
  res->timings.likelihood_ms += msSince(t0);
}

StepStatus Localizer::resampleAndRecover(const MeasurementContext& ctx, StepResult* res,
                                         std::string* why) {
  const Clock::time_point t0 = Clock::now();
  res->resampled = filter_->resampleIfNeeded();
  res->reinitialised = filter_->recoverFrame(cameras_used_ * cam_.pixels, region_);
  // A rig whose set of cameras changed (one dropped out, came back) scores another per-pixel
  // level: the lost detector's reference restarts from the map's rather than call that lost.
  uint64_t camera_set = 1;
  if (!res->cameras.empty()) {
    camera_set = 0;
    for (size_t c = 0; c < res->cameras.size() && c < 64; ++c) {
      if (res->cameras[c].used) camera_set |= uint64_t{1} << c;
    }
  }
  if (camera_set_ != 0 && camera_set != camera_set_) lost_.rebase();
  camera_set_ = camera_set;
  // Absolute-quality recovery: the worst particles by this frame's likelihood (after any
  // resampling, each particle carries its source's likelihood) are redrawn.
  if (lost_.update(res->best_loglik_per_pixel)) {
    res->lost = true;
    have_refined_ = false;
    rival_pending_ = false;
    motion_model_.reset();
    // The worst fraction is redrawn; with an adaptive count the set grows back to its largest.
    const int n = filter_->size();
    const int keep = n - static_cast<int>(std::floor(params_.lost.reinit_fraction * n));
    const int count = params_.filter.adaptive() ? params_.filter.num_particles - keep : n - keep;
    try {
      screenCandidates(ctx, count, true, true);
      filter_->replaceWorstByBestCandidates(keep, count);
      res->lost_reinitialised = count;
      res->screened_candidates += count * params_.lost.candidates_per_particle;
    } catch (const BackendError&) {
      throw;
    } catch (const std::exception& e) {
      *why = std::string("likelihood backend: ") + e.what();
      return StepStatus::kBackendError;
    }
    std::ostringstream msg;
    msg << "lost: best log-likelihood " << res->best_loglik_per_pixel
        << " nats/px stayed more than " << params_.lost.margin_nats << " below the reference "
        << lost_.reference() << " for " << params_.lost.frames
        << " frames: " << res->lost_reinitialised
        << " particles redrawn from the recovery region (best of "
        << params_.lost.candidates_per_particle << " candidates each)";
    res->message += (res->message.empty() ? "" : "; ") + msg.str();
  }
  res->reference_loglik_per_pixel = lost_.reference();
  res->timings.resample_ms = msSince(t0);
  return StepStatus::kOk;
}

}  // namespace gmm_mcl
