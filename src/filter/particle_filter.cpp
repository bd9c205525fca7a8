#include "gmm_mcl/filter/particle_filter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "gmm_mcl/internal/particle_math.h"

namespace gmm_mcl {

ParticleFilter::ParticleFilter(const ParticleFilterParams& params)
    : params_(params),
      rng_(params.seed),
      augmented_(params.alpha_slow, params.alpha_fast, params.recovery_threshold) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument("particle filter parameters: " + err);
  particles_.resize(params.num_particles);
  weights_.assign(params.num_particles, 1.0 / params.num_particles);
}

void ParticleFilter::setParams(const ParticleFilterParams& params) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument("particle filter parameters: " + err);
  const uint64_t seed = params_.seed;
  params_ = params;
  params_.seed = seed;
  augmented_.setRates(params.alpha_slow, params.alpha_fast, params.recovery_threshold);
  const int n = params_.adaptive()
                    ? std::max(params_.min_particles, std::min(params_.num_particles, size()))
                    : params_.num_particles;
  if (n == size()) return;
  stratifiedLowVarianceResample(weights_, std::min(params_.resample_groups, n), n, &rng_,
                                &indices_);
  swap_.resize(n);
  for (int i = 0; i < n; ++i) swap_[i] = particles_[indices_[i]];
  particles_.swap(swap_);
  weights_.assign(n, 1.0 / n);
}

Particle ParticleFilter::sampleUniform(const InitRegion& r) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Particle p;
  p.x_m = r.centre_m.x() + r.half_extent_m.x() * u(rng_);
  p.y_m = r.centre_m.y() + r.half_extent_m.y() * u(rng_);
  p.z_m = r.centre_m.z() + r.half_extent_m.z() * u(rng_);
  p.yaw_rad = wrapAngle(r.yaw_centre_rad + r.yaw_half_range_rad * u(rng_));
  return p;
}

void ParticleFilter::initialiseUniform(const InitRegion& region) {
  particles_.resize(params_.num_particles);
  weights_.resize(params_.num_particles);
  for (Particle& p : particles_) p = sampleUniform(region);
  std::fill(weights_.begin(), weights_.end(), 1.0 / particles_.size());
  augmented_.reset();
}

void ParticleFilter::initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) {
  particles_.resize(params_.num_particles);
  weights_.resize(params_.num_particles);
  std::normal_distribution<double> g(0.0, 1.0);
  for (Particle& p : particles_) {
    p.x_m = mean.x_m + sigma[0] * g(rng_);
    p.y_m = mean.y_m + sigma[1] * g(rng_);
    p.z_m = mean.z_m + sigma[2] * g(rng_);
    p.yaw_rad = wrapAngle(mean.yaw_rad + sigma[3] * g(rng_));
  }
  std::fill(weights_.begin(), weights_.end(), 1.0 / particles_.size());
  augmented_.reset();
}

void ParticleFilter::predict(const PlanarDelta& delta) {
  std::normal_distribution<double> g(0.0, 1.0);
  const double st =
      delta.sigma_translation_m >= 0.0 ? delta.sigma_translation_m : params_.sigma_translation_m;
  const double sy = delta.sigma_yaw_rad >= 0.0 ? delta.sigma_yaw_rad : params_.sigma_yaw_rad;
  for (Particle& p : particles_) {
    const double c = std::cos(p.yaw_rad), s = std::sin(p.yaw_rad);
    p.x_m += c * delta.translation_m.x() - s * delta.translation_m.y() + st * g(rng_);
    p.y_m += s * delta.translation_m.x() + c * delta.translation_m.y() + st * g(rng_);
    p.z_m += delta.translation_m.z() + st * g(rng_);
    p.yaw_rad = wrapAngle(p.yaw_rad + delta.yaw_rad + sy * g(rng_));
  }
}

bool ParticleFilter::updateWeights(const std::vector<double>& ll, int pixels) {
  const int n = size();
  if (static_cast<int>(ll.size()) != n || pixels <= 0) return false;
  double best = -std::numeric_limits<double>::infinity();
  for (double l : ll) {
    if (std::isfinite(l)) best = std::max(best, l);
  }
  if (!std::isfinite(best)) return false;
  std::vector<double> w(n, 0.0);
  if (params_.weighting == WeightingMode::kTempered) {
    auto weigh = [&](double beta) {
      for (int i = 0; i < n; ++i) {
        w[i] = std::isfinite(ll[i]) ? weights_[i] * std::exp((ll[i] - best) * beta) : 0.0;
      }
      double sum = 0.0, sum_sq = 0.0;
      for (double v : w) {
        sum += v;
        sum_sq += v * v;
      }
      return sum_sq > 0.0 ? sum * sum / sum_sq : 0.0;  // effective sample size
    };
    const double beta_max = 1.0 / (params_.temperature * pixels);
    const double neff_floor = params_.neff_floor_fraction * n;
    last_beta_fraction_ = 1.0;
    if (weigh(beta_max) < neff_floor && weigh(0.0) > neff_floor) {
      // Largest beta whose update keeps Neff at the floor (Neff falls as beta grows).
      double lo = 0.0, hi = beta_max;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        (weigh(mid) >= neff_floor ? lo : hi) = mid;
      }
      weigh(lo);
      last_beta_fraction_ = lo / beta_max;
    }
  } else {
    // NLL_i = -L_i; guard keeps the best NLL at least the margin (see WeightingMode::kPaper).
    const double margin = params_.paper_min_nll_per_pixel * pixels;
    const double shift = std::max(0.0, margin - (-best));
    const double floor_nll = std::max(margin, std::numeric_limits<double>::min());
    for (int i = 0; i < n; ++i) {
      if (std::isfinite(ll[i])) w[i] = weights_[i] / std::max(-ll[i] + shift, floor_nll);
    }
  }
  double total = 0.0;
  for (double v : w) total += v;
  if (!(total > 0.0) || !std::isfinite(total)) return false;
  for (int i = 0; i < n; ++i) weights_[i] = w[i] / total;
  return true;
}

int ParticleFilter::occupiedBins(const std::vector<int>& indices) const {
  // Bin keys of the given particles (16 bits per dimension; the key only has to tell bins apart
  // within a map of +-6.5 km at 0.2 m), counted by sort and unique.
  keys_.resize(indices.size());
  const double ib = 1.0 / params_.kld_bin_m, ia = 1.0 / params_.kld_bin_rad;
  for (size_t k = 0; k < indices.size(); ++k) {
    const Particle& p = particles_[indices[k]];
    keys_[k] = kldBinKey(ParticleState{p.x_m, p.y_m, p.z_m, p.yaw_rad}, ib, ia);
  }
  std::sort(keys_.begin(), keys_.end());
  return static_cast<int>(std::unique(keys_.begin(), keys_.end()) - keys_.begin());
}

void ParticleFilter::resample() {
  int n_out = size();
  if (params_.adaptive()) {
    // KLD-sampling: the bins that a resampling at the current count occupies set the count.
    stratifiedLowVarianceResample(weights_, params_.resample_groups, size(), &rng_, &indices_);
    const int bound = kldParticleBound(occupiedBins(indices_), params_.kld_epsilon, params_.kld_z);
    n_out = std::max(params_.min_particles, std::min(params_.num_particles, bound));
  }
  stratifiedLowVarianceResample(weights_, params_.resample_groups, n_out, &rng_, &indices_);
  swap_.resize(n_out);
  for (size_t i = 0; i < indices_.size(); ++i) swap_[i] = particles_[indices_[i]];
  particles_.swap(swap_);
  weights_.assign(n_out, 1.0 / n_out);
  resampled_since_evaluation_ = true;
}

bool ParticleFilter::resampleIfNeeded() {
  if (effectiveSampleSize() >= params_.resample_neff_fraction * size()) return false;
  resample();
  return true;
}

int ParticleFilter::recover(const std::vector<double>& ll, int pixels, const InitRegion& region) {
  if (params_.alpha_slow <= 0.0 || pixels <= 0) return 0;
  // Average per-pixel likelihood exp(L_i / pixels) over the particles, in log space.
  double mx = -std::numeric_limits<double>::infinity();
  int finite = 0;
  for (double l : ll) {
    if (std::isfinite(l)) {
      mx = std::max(mx, l / pixels);
      ++finite;
    }
  }
  if (finite == 0) return 0;
  double sum = 0.0;
  for (double l : ll) {
    if (std::isfinite(l)) sum += std::exp(l / pixels - mx);
  }
  const double average = std::exp(mx) * sum / static_cast<double>(ll.size());
  const int count = augmented_.update(average, size());
  if (count == 0) return 0;
  // Reinitialise `count` distinct, randomly chosen particles.
  std::vector<int> order(size());
  std::iota(order.begin(), order.end(), 0);
  for (int k = 0; k < count; ++k) {
    std::uniform_int_distribution<int> pick(k, size() - 1);
    std::swap(order[k], order[pick(rng_)]);
    particles_[order[k]] = sampleUniform(region);
    weights_[order[k]] = 1.0 / size();  // a fresh particle carries the average weight
  }
  const double total = std::accumulate(weights_.begin(), weights_.end(), 0.0);
  for (double& w : weights_) w /= total;
  return count;
}

void ParticleFilter::replaceWorst(const std::vector<double>& ll,
                                  const std::vector<Particle>& replacements, int keep) {
  if (static_cast<int>(ll.size()) != size()) {
    throw std::invalid_argument("replaceWorst: one log-likelihood per particle expected");
  }
  const int n = size();
  keep = keep < 0 ? std::max(0, n - static_cast<int>(replacements.size())) : std::min(keep, n);
  const int added = static_cast<int>(replacements.size());
  if (keep + added == 0 || (keep == n && added == 0)) return;
  auto key = [&ll](int i) {
    return std::isfinite(ll[i]) ? ll[i] : -std::numeric_limits<double>::infinity();
  };
  // The `keep` best first (any order), then the replacements, each with the old average weight.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  if (keep > 0 && keep < n) {
    std::nth_element(order.begin(), order.begin() + (keep - 1), order.end(),
                     [&key](int a, int b) { return key(a) > key(b); });
  }
  swap_.resize(keep + added);
  std::vector<double> w(keep + added);
  for (int k = 0; k < keep; ++k) {
    swap_[k] = particles_[order[k]];
    w[k] = weights_[order[k]];
  }
  for (int k = 0; k < added; ++k) {
    swap_[keep + k] = replacements[k];
    w[keep + k] = 1.0 / n;
  }
  particles_.swap(swap_);
  const double total = std::accumulate(w.begin(), w.end(), 0.0);
  for (double& v : w) v /= total;
  weights_.swap(w);
}

void ParticleFilter::replaceAll(const std::vector<Particle>& particles) {
  if (static_cast<int>(particles.size()) != size()) {
    throw std::invalid_argument("replaceAll: the particle count must not change");
  }
  particles_ = particles;
  std::fill(weights_.begin(), weights_.end(), 1.0 / size());
}

void ParticleFilter::sampleAround(const std::vector<Particle>& centres, double sigma_m,
                                  double sigma_rad, int n, std::vector<Particle>* out) {
  out->resize(centres.empty() ? 0 : std::max(0, n));
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t k = 0; k < out->size(); ++k) {
    const Particle& c = centres[k % centres.size()];
    Particle& p = (*out)[k];
    p.x_m = c.x_m + sigma_m * g(rng_);
    p.y_m = c.y_m + sigma_m * g(rng_);
    p.z_m = c.z_m + sigma_m * g(rng_);
    p.yaw_rad = wrapAngle(c.yaw_rad + sigma_rad * g(rng_));
  }
}

void ParticleFilter::sampleRegion(const InitRegion& region, int n, std::vector<Particle>* out) {
  out->resize(std::max(0, n));
  for (Particle& p : *out) p = sampleUniform(region);
}

namespace {
constexpr double kMinVariance = 1e-8;  // (0.1 mm)^2, (1e-4 rad)^2
}  // namespace

PoseEstimate ParticleFilter::estimate() const {
  PoseEstimate e;
  double sx = 0, sy = 0, sz = 0, sc = 0, ss = 0;
  for (int i = 0; i < size(); ++i) {
    const double w = weights_[i];
    sx += w * particles_[i].x_m;
    sy += w * particles_[i].y_m;
    sz += w * particles_[i].z_m;
    sc += w * std::cos(particles_[i].yaw_rad);
    ss += w * std::sin(particles_[i].yaw_rad);
  }
  e.mean.x_m = sx;
  e.mean.y_m = sy;
  e.mean.z_m = sz;
  e.mean.yaw_rad = std::atan2(ss, sc);
  // 4x4 covariance of (x, y, z, yaw) with yaw differences wrapped, placed in ROS order.
  Eigen::Matrix4d c = Eigen::Matrix4d::Zero();
  for (int i = 0; i < size(); ++i) {
    const Eigen::Vector4d d(particles_[i].x_m - sx, particles_[i].y_m - sy, particles_[i].z_m - sz,
                            wrapAngle(particles_[i].yaw_rad - e.mean.yaw_rad));
    c += weights_[i] * d * d.transpose();
  }
  return poseEstimateFromMoments(e.mean, c, params_);
}

PoseEstimate poseEstimateFromMoments(const Particle& mean, const Eigen::Matrix4d& c,
                                     const ParticleFilterParams& params) {
  PoseEstimate e;
  e.mean = mean;
  const int idx[4] = {0, 1, 2, 5};
  for (int r = 0; r < 4; ++r) {
    for (int k = 0; k < 4; ++k) e.covariance(idx[r], idx[k]) = c(r, k);
  }
  // Floor: one step of process noise, so that a collapsed set (every particle a copy of one)
  // still reports a positive-definite covariance instead of a singular one.
  const double var_t = params.sigma_translation_m * params.sigma_translation_m;
  const double var_yaw = params.sigma_yaw_rad * params.sigma_yaw_rad;
  for (int r = 0; r < 3; ++r) e.covariance(r, r) += std::max(var_t, kMinVariance);
  e.covariance(5, 5) += std::max(var_yaw, kMinVariance);
  const double att = params.attitude_sigma_rad * params.attitude_sigma_rad;
  e.covariance(3, 3) = att;
  e.covariance(4, 4) = att;
  return e;
}

void ParticleFilter::setParticles(const std::vector<Particle>& particles,
                                  const std::vector<double>& weights) {
  if (particles.size() != weights.size() || particles.empty()) {
    throw std::invalid_argument("setParticles: sizes differ or empty");
  }
  particles_ = particles;
  const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
  weights_.resize(weights.size());
  for (size_t i = 0; i < weights.size(); ++i) weights_[i] = weights[i] / total;
}

// ---- ParticleFilterBase: frame likelihoods and the candidate pool ---------------------------

void ParticleFilter::evaluatePoses(const MeasurementContext& ctx,
                                   const std::vector<Particle>& particles, BackendOutput* out) {
  if (ctx.backend == nullptr || ctx.frame == nullptr || ctx.params == nullptr) {
    throw std::invalid_argument(
        "host particle filter: a backend, a host frame and parameters "
        "are needed to score particles");
  }
  poses_.resize(particles.size());
  for (size_t i = 0; i < particles.size(); ++i) {
    poses_[i] =
        toRigidF(particleToPose(particles[i], ctx.roll_rad, ctx.pitch_rad) * ctx.T_base_cam);
  }
  ctx.backend->evaluate(*ctx.frame, poses_, *ctx.params, out);
}

namespace {

// One backend evaluation's counts and stage times (stats may be null).
void reportEvaluation(const BackendOutput& out, EvaluationStats* stats) {
  if (!stats) return;
  stats->evaluations = out.evaluations;
  stats->relevant_pairs = out.relevant_pairs;
  stats->patches_with_pixels = out.patches_with_pixels;
  stats->projection_membership_ms = out.projection_membership_ms;
  stats->likelihood_ms = out.likelihood_ms;
}

}  // namespace

void ParticleFilter::evaluateFrame(const MeasurementContext& ctx, EvaluationStats* stats) {
  evaluatePoses(ctx, particles_, &output_);
  resampled_since_evaluation_ = false;
  reportEvaluation(output_, stats);
}

void ParticleFilter::accumulateFrame(const MeasurementContext& ctx, double scale,
                                     EvaluationStats* stats) {
  if (output_.log_likelihood.size() != particles_.size() || resampled_since_evaluation_) {
    throw std::logic_error("accumulateFrame: the set has no frame likelihoods to add to");
  }
  evaluatePoses(ctx, particles_, &more_output_);
  for (size_t i = 0; i < particles_.size(); ++i) {
    output_.log_likelihood[i] += scale * more_output_.log_likelihood[i];
    output_.floor_hits[i] += more_output_.floor_hits[i];
  }
  output_.evaluations += more_output_.evaluations;
  output_.relevant_pairs += more_output_.relevant_pairs;
  reportEvaluation(more_output_, stats);
}

void ParticleFilter::setFrameLogLikelihoods(const std::vector<double>& log_likelihood,
                                            const std::vector<int>& floor_hits) {
  if (log_likelihood.size() != floor_hits.size()) {
    throw std::invalid_argument("setFrameLogLikelihoods: one floor-hit count per likelihood");
  }
  output_ = BackendOutput();
  output_.log_likelihood = log_likelihood;
  output_.floor_hits = floor_hits;
  resampled_since_evaluation_ = false;
}

bool ParticleFilter::weighFrame(int pixels, FrameScores* scores) {
  const std::vector<double>& ll = output_.log_likelihood;
  if (!updateWeights(ll, pixels)) return false;
  // The best particle (the first of the largest) and the weighted mean, over the new weights.
  size_t best = 0;
  double mean_ll = 0.0;
  for (size_t i = 0; i < weights_.size(); ++i) {
    if (ll[i] > ll[best]) best = i;
    if (weights_[i] > 0.0) mean_ll += weights_[i] * ll[i];
  }
  scores->best_loglik = ll[best];
  scores->mean_loglik = mean_ll;
  scores->best_floor_hits = output_.floor_hits[best];
  scores->beta_fraction = last_beta_fraction_;
  return true;
}

int ParticleFilter::recoverFrame(int pixels, const InitRegion& region) {
  return recover(output_.log_likelihood, pixels, region);
}

void ParticleFilter::clearCandidates() {
  scored_.clear();
  pending_.clear();
}

void ParticleFilter::drawUniformCandidates(const InitRegion& region, int n) {
  const size_t first = pending_.size();
  pending_.resize(first + std::max(0, n));
  for (size_t k = first; k < pending_.size(); ++k) pending_[k] = sampleUniform(region);
}

void ParticleFilter::scoreCandidates(const MeasurementContext& ctx) {
  if (pending_.empty()) return;
  evaluatePoses(ctx, pending_, &candidate_output_);
  for (size_t i = 0; i < pending_.size(); ++i) {
    const double ll = candidate_output_.log_likelihood[i];
    scored_.emplace_back(std::isfinite(ll) ? ll : -std::numeric_limits<double>::infinity(),
                         pending_[i]);
  }
  pending_.clear();
}

namespace {
bool byScore(const std::pair<double, Particle>& a, const std::pair<double, Particle>& b) {
  return a.first > b.first;
}
}  // namespace

void ParticleFilter::selectCandidateCentres(int elites, bool clear_pool) {
  elites = std::max(0, std::min(elites, static_cast<int>(scored_.size())));
  std::partial_sort(scored_.begin(), scored_.begin() + elites, scored_.end(), byScore);
  centres_.resize(elites);
  for (int e = 0; e < elites; ++e) centres_[e] = scored_[e].second;
  if (clear_pool) scored_.clear();
}

void ParticleFilter::drawCandidatesAroundCentres(double sigma_m, double sigma_rad, int n) {
  std::vector<Particle> drawn;
  sampleAround(centres_, sigma_m, sigma_rad, n, &drawn);
  pending_.insert(pending_.end(), drawn.begin(), drawn.end());
}

std::vector<Particle> ParticleFilter::bestCandidates(int count) {
  std::vector<Particle> best;
  count = std::min(count, static_cast<int>(scored_.size()));
  if (count <= 0) return best;
  std::nth_element(scored_.begin(), scored_.begin() + (count - 1), scored_.end(), byScore);
  best.reserve(count);
  for (int i = 0; i < count; ++i) best.push_back(scored_[i].second);
  return best;
}

void ParticleFilter::replaceAllByBestCandidates() { replaceAll(bestCandidates(size())); }

void ParticleFilter::replaceWorstByBestCandidates(int keep, int count) {
  // Each particle's likelihood on this frame: after a resampling, its source's.
  const std::vector<double>& ll = output_.log_likelihood;
  ll_scratch_ = ll;
  if (resampled_since_evaluation_) {
    ll_scratch_.resize(indices_.size());
    for (size_t i = 0; i < indices_.size(); ++i) ll_scratch_[i] = ll[indices_[i]];
  }
  replaceWorst(ll_scratch_, bestCandidates(count), keep);
}

}  // namespace gmm_mcl
