#include "gmm_mcl/filter/localizer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "gmm_mcl/common/enum_names.h"
#include "gmm_mcl/common/timing.h"

namespace gmm_mcl {
namespace {

const LocalizerParams& validated(const LocalizerParams& p) {
  const std::string err = p.validate();
  if (!err.empty()) throw std::invalid_argument("localizer parameters: " + err);
  return p;
}

}  // namespace

namespace {

const EnumName<StepStatus> kStepStatusNames[] = {
    {"ok", StepStatus::kOk},
    {"predict_only", StepStatus::kPredictOnly},
    {"no_valid_pixels", StepStatus::kNoValidPixels},
    {"bad_frame", StepStatus::kBadFrame},
    {"degenerate_weights", StepStatus::kDegenerateWeights},
    {"backend_error", StepStatus::kBackendError},
    {"time_jump_back", StepStatus::kTimeJumpBack}};

}  // namespace

const char* stepStatusName(StepStatus status) { return enumNameOf(status, kStepStatusNames); }

Localizer::Localizer(const LocalizerParams& params, GmmMap map,
                     std::unique_ptr<LikelihoodBackend> backend)
    : params_(validated(params)),
      map_(std::move(map)),
      backend_(std::move(backend)),
      region_(params.init),
      motion_model_(params.constant_velocity),
      rival_rng_(params.filter.seed ^ 0x2545f491u) {
  if (map_.empty()) throw std::invalid_argument("localizer: the map is empty");
  if (!backend_) {
    BackendOptions options;
    options.cuda = params_.cuda;
    backend_ = makeBackend(params_.backend, &backend_warning_, options);
  }
  prepareMap();
  std::string why;
  filter_ = makeParticleFilter(params_.filter, backend_.get(), params_.device_filter, &why);
  if (!why.empty()) backend_warning_ += (backend_warning_.empty() ? "" : "; ") + why;
  filter_->initialiseUniform(region_);
  lost_ = LostDetector(params_.lost, map_self_ll_);
  depth_scales_.assign(1, params_.refinement.depth_scale_initial);
  depth_scale_information_.assign(1, 0.0);
}

void Localizer::prepareMap() {
  backend_->setMap(map_);
  blurred_map_ = redraw_map_ = GmmMap();
  if (params_.lost.redraw_blur_m > 0.0 && params_.lost.local_candidate_fraction > 0.0) {
    const double b2 = params_.lost.redraw_blur_m * params_.lost.redraw_blur_m;
    auto blurred = [&](std::vector<GaussianComponent> components, const char* name) {
      for (GaussianComponent& c : components) c.cov_m2 += b2 * Eigen::Matrix3d::Identity();
      // The same surface, blurred: the original's weights (its mapped surface), not the larger
      // surface the blurred covariances would suggest.
      return GmmMap(std::move(components), name, map_.surfaceArea());
    };
    blurred_map_ = blurred(map_.components(), "blurred map");
    // A redraw's: merged first (its coarse stage needs no finer map than its blur).
    if (params_.lost.redraw_merge_m > 0.0) {
      redraw_map_ = blurred(mergedByCell(map_.components(), params_.lost.redraw_merge_m),
                            "merged blurred map");
    }
  }
  map_self_ll_ = gmm_mcl::mapSelfLogDensity(map_, params_.measurement.floor_log_density,
                                            params_.measurement.depth_noise);
}

void Localizer::setParams(const LocalizerParams& params) {
  validated(params);
  const CudaTuningParams &c = params.cuda, &c0 = params_.cuda;
  if (params.backend != params_.backend || params.filter.seed != params_.filter.seed ||
      params.device_filter != params_.device_filter || c.likelihood_shape != c0.likelihood_shape ||
      c.stage_members != c0.stage_members || c.band_patches != c0.band_patches ||
      c.view_cull_min_pairs != c0.view_cull_min_pairs ||
      c.membership_pass_words != c0.membership_pass_words || c.place_groups != c0.place_groups ||
      c.local_lists_min_components != c0.local_lists_min_components ||
      c.z_order_min_components != c0.z_order_min_components) {
    throw std::invalid_argument(
        "localizer parameters: backend, device_filter, seed and the cuda_* tuning are fixed at "
        "construction");
  }
  const MeasurementParams& m = params.measurement;
  const MeasurementParams& m0 = params_.measurement;
  const bool map_terms =
      m.floor_log_density != m0.floor_log_density || m.depth_noise.a_m != m0.depth_noise.a_m ||
      m.depth_noise.b_per_m != m0.depth_noise.b_per_m ||
      m.depth_noise.z0_m != m0.depth_noise.z0_m ||
      params.lost.redraw_blur_m != params_.lost.redraw_blur_m ||
      params.lost.redraw_merge_m != params_.lost.redraw_merge_m ||
      params.lost.local_candidate_fraction != params_.lost.local_candidate_fraction;
  filter_->setParams(params.filter);
  motion_model_.setParams(params.constant_velocity);
  params_ = params;
  if (map_terms) prepareMap();
  lost_.setParams(params_.lost, map_self_ll_);
  if (params_.lost.start_places == 0) start_places_.stop();
}

void Localizer::setMap(GmmMap map) {
  if (map.empty()) throw std::invalid_argument("localizer: the map is empty");
  map_ = std::move(map);
  prepareMap();
  lost_ = LostDetector(params_.lost, map_self_ll_);
  have_refined_ = false;
  start_places_.stop();
  rival_pending_ = false;
}

void Localizer::reset(const InitRegion& region) {
  const std::string err = region.validate();
  if (!err.empty()) throw std::invalid_argument("reset region: " + err);
  region_ = region;
  filter_->initialiseUniform(region_);
  lost_.restart();
  screen_pending_ = true;
  have_refined_ = false;
  motion_model_.reset();
  start_places_.stop();
  rival_pending_ = false;
}

void Localizer::resetToPose(const Particle& pose, const Eigen::Vector4d& sigma) {
  filter_->initialiseGaussian(pose, sigma);
  lost_.restart();
  screen_pending_ = false;
  have_refined_ = false;
  motion_model_.reset();
  start_places_.stop();
  rival_pending_ = false;
}

InitRegion Localizer::mapBounds() const { return gmm_mcl::mapBounds(map_); }

InitRegion mapBounds(const GmmMap& map) {
  Eigen::Vector3d lo = map.minBound(), hi = map.maxBound();
  for (size_t i = 0; i < map.size(); ++i) {
    lo = lo.cwiseMin(map.components()[i].mean_m - map.threeSigmaHalfExtent(i));
    hi = hi.cwiseMax(map.components()[i].mean_m + map.threeSigmaHalfExtent(i));
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

void Localizer::screenCandidates(const MeasurementContext& ctx, int count, bool local_stage,
                                 bool redraw) {
  filter_->clearCandidates();
  const int per = params_.lost.candidates_per_particle;
  if (count <= 0) return;
  const int total = count * per;
  // With the local stage, part of the candidates are drawn around the best uniform ones
  // (Gaussian, local_sigma_m / local_sigma_rad): a uniform candidate rarely lands inside the
  // likelihood's basin (a few decimetres), one of the best few often lands beside it.
  const int local =
      local_stage && per > 1 ? static_cast<int>(params_.lost.local_candidate_fraction * total) : 0;
  // Drawn in batches of at least the largest particle count (the draws of the earlier version),
  // and each stage's draws scored in one call: the backend's per-call work (the poses' view
  // groups, the cull of a large map, its waits) is paid once per stage, not once per batch.
  // Measured on an H100: the first update from the 4 m cube in the map of 10 x 10 rooms took
  // 51 ms in 16 calls and 14-17 ms in one; the building world's whole-map start 10.7 and 4.3 s.
  const int batch = std::max(filter_->size(), params_.filter.num_particles);
  // The candidates only choose which poses enter the set, and the next frame weighs those on
  // the full frame: a redraw's are scored on a coarse frame (host filter; the GPU filter scores
  // on its device frame).
  const MeasurementContext& scoring = redraw ? coarseContext(ctx) : ctx;
  // The uniform stage of a redraw against the blurred map (a wider basin; a redraw's merged
  // too), then the map again.
  const bool blur = local_stage && !blurred_map_.empty();
  if (blur) backend_->setMap(redraw && !redraw_map_.empty() ? redraw_map_ : blurred_map_);
  try {
    for (int done = 0; done < total - local; done += batch) {
      filter_->drawUniformCandidates(region_, std::min(batch, total - local - done));
    }
    filter_->scoreCandidates(scoring);
  } catch (...) {
    if (blur) backend_->setMap(map_);
    throw;
  }
  if (blur) backend_->setMap(map_);
  // Each further level draws around the best of the candidates so far, a third as wide: the
  // search narrows from the blurred map's metre onto the map's own basin (about 0.1 m).
  const int levels = local > 0 ? params_.lost.local_levels : 0;
  double sigma_m = params_.lost.local_sigma_m, sigma_rad = params_.lost.local_sigma_rad;
  for (int level = 0; level < levels; ++level) {
    const int elites =
        std::max(1, static_cast<int>(params_.lost.elite_fraction * filter_->scoredCandidates()));
    // Blurred scores only chose the first centres; the redraw is chosen by the map's own scores.
    filter_->selectCandidateCentres(elites, blur && level == 0);
    const int n = level + 1 < levels ? local / levels : local - (levels - 1) * (local / levels);
    for (int done = 0; done < n; done += batch) {
      filter_->drawCandidatesAroundCentres(sigma_m, sigma_rad, std::min(batch, n - done));
    }
    filter_->scoreCandidates(scoring);
    sigma_m /= 3.0;
    sigma_rad /= 3.0;
  }
}

const MeasurementContext& Localizer::coarseContext(const MeasurementContext& ctx) {
  coarse_ctx_ = ctx;
  if (ctx.frame == nullptr || cam_.depth == nullptr || cam_.frame == nullptr) return ctx;
  const FrameParams& full = *cam_.frame;
  const int pixels = params_.lost.coarse_pixels;
  if (pixels <= 0) return ctx;
  const double area = static_cast<double>(cam_.depth->width_px) * cam_.depth->height_px;
  FrameParams coarse = full;
  // A multiple of the frame's stride: the coarse pixels are some of the frame's own (an image
  // reduced to the frame's stride still has them).
  coarse.pixel_stride =
      full.pixel_stride *
      std::max(1, static_cast<int>(std::floor(std::sqrt(area / pixels) / full.pixel_stride)));
  if (coarse.pixel_stride == full.pixel_stride) return ctx;
  coarse.patch_size_px = std::max(full.patch_size_px, 4 * coarse.pixel_stride);
  coarse_frame_ = prepareFrame(*cam_.depth, cam_.intrinsics, coarse);
  // A frame with nothing left at the coarse stride (a few valid pixels) is scored in full.
  if (coarse_frame_.empty()) return ctx;
  coarse_ctx_.frame = &coarse_frame_;
  return coarse_ctx_;
}

const DepthFrame& Localizer::hostFrame() {
  if (!host_frame_ready_) {
    host_frame_ = prepareFrame(*cam_.depth, cam_.intrinsics, *cam_.frame);
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
      std::unique_ptr<ParticleFilterBase> host = std::make_unique<ParticleFilter>(params_.filter);
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
    more_sums_.clear();  // the rig's evaluators work on the backend's stream: gone first
    backend_ = makeBackend("cpu", nullptr);
    backend_->setMap(map_);
    backend_warning_ =
        "the " + failed + " backend failed (" + what + "): fell back to the CPU backend, " + kept;
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

}  // namespace gmm_mcl
