#include "gmm_mcl/filter/start_hypotheses.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace gmm_mcl {

StartHypotheses::StartHypotheses(const StartHypothesesParams& params, uint64_t seed)
    : params_(params), rng_(seed) {}

bool StartHypotheses::samePlace(const Particle& a, const Particle& b) const {
  const double d = std::hypot(std::hypot(a.x_m - b.x_m, a.y_m - b.y_m), a.z_m - b.z_m);
  return d < params_.separation_m &&
         std::abs(wrapAngle(a.yaw_rad - b.yaw_rad)) < params_.separation_rad;
}

void StartHypotheses::seed(const std::vector<Particle>& poses, const std::vector<double>& scores) {
  places_.clear();
  frames_ = 0;
  if (params_.places <= 0 || poses.size() != scores.size()) return;
  std::vector<size_t> order(poses.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&scores](size_t a, size_t b) { return scores[a] > scores[b]; });
  for (size_t i : order) {
    if (static_cast<int>(places_.size()) >= params_.places) break;
    if (!std::isfinite(scores[i])) break;
    const bool taken = std::any_of(places_.begin(), places_.end(),
                                   [&](const Place& p) { return samePlace(p.pose, poses[i]); });
    if (!taken) places_.push_back(Place{poses[i], 0.0, 0.0});
  }
}

void StartHypotheses::predict(const PlanarDelta& delta) {
  for (Place& place : places_) applyDelta(delta, &place.pose);
}

const std::vector<Particle>& StartHypotheses::proposals() {
  const int draws = std::max(1, params_.draws);
  proposals_.resize(places_.size() * draws);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t h = 0; h < places_.size(); ++h) {
    const Particle& c = places_[h].pose;
    proposals_[h * draws] = c;
    for (int k = 1; k < draws; ++k) {
      Particle& p = proposals_[h * draws + k];
      p.x_m = c.x_m + params_.sigma_m * g(rng_);
      p.y_m = c.y_m + params_.sigma_m * g(rng_);
      p.z_m = c.z_m + 0.2 * params_.sigma_m * g(rng_);
      p.yaw_rad = wrapAngle(c.yaw_rad + params_.sigma_rad * g(rng_));
    }
  }
  return proposals_;
}

void StartHypotheses::update(const std::vector<double>& log_likelihood, int pixels) {
  const int draws = std::max(1, params_.draws);
  if (log_likelihood.size() != proposals_.size() || pixels <= 0) return;
  const double memory = params_.memory_frames > 0.0 ? params_.memory_frames : params_.frames / 3.0;
  const double keep = 1.0 - 1.0 / std::max(1.0, memory);
  for (size_t h = 0; h < places_.size(); ++h) {
    int best = -1;
    double best_ll = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < draws; ++k) {
      const double ll = log_likelihood[h * draws + k];
      if (std::isfinite(ll) && ll > best_ll) {
        best_ll = ll;
        best = k;
      }
    }
    Place& place = places_[h];
    // A place no draw of which scores (it left the map) keeps its pose and its lowest score.
    if (best < 0) {
      place.score = -std::numeric_limits<double>::infinity();
      continue;
    }
    // The place scores the mean of its draws' per-pixel likelihoods (log of the mean of their
    // exponentials: the evidence of the place's neighbourhood, as the particle filter's tempered
    // weights would sum it), not the best draw's: the best of a few draws lets a wrong place
    // re-fit every frame and score as well as the truth. It moves to its best draw (the climb).
    double sum = 0.0;
    for (int k = 0; k < draws; ++k) {
      const double ll = log_likelihood[h * draws + k];
      if (std::isfinite(ll)) sum += std::exp((ll - best_ll) / pixels);
    }
    place.pose = proposals_[h * draws + best];
    place.last_loglik = best_ll / pixels + std::log(sum / draws);
    place.score = keep * place.score + place.last_loglik;
  }
  ++frames_;
  merge();
}

void StartHypotheses::merge() {
  std::stable_sort(places_.begin(), places_.end(),
                   [](const Place& a, const Place& b) { return a.score > b.score; });
  std::vector<Place> kept;
  kept.reserve(places_.size());
  for (const Place& p : places_) {
    if (!std::isfinite(p.score)) continue;
    const bool taken = std::any_of(kept.begin(), kept.end(),
                                   [&](const Place& q) { return samePlace(q.pose, p.pose); });
    if (!taken) kept.push_back(p);
  }
  places_.swap(kept);
}

const StartHypotheses::Place& StartHypotheses::best() const {
  return *std::max_element(places_.begin(), places_.end(),
                           [](const Place& a, const Place& b) { return a.score < b.score; });
}

}  // namespace gmm_mcl
