#include "gmm_mcl/filter/start_hypotheses.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace gmm_mcl {
namespace {

// The places kept so far by the cell (edge: the separation) of their position, so that a
// candidate is compared with the places of its own and the 26 neighbouring cells only: two
// poses closer than the separation lie in neighbouring cells. Cells are hashed (a collision
// only adds places to compare).
class PlaceCells {
 public:
  explicit PlaceCells(double cell_m) : inv_(cell_m > 0.0 ? 1.0 / cell_m : 0.0) {}
  // Whether same(place) holds for a place added before.
  template <class Same>
  bool any(const Particle& p, const std::vector<StartHypotheses::Place>& places, Same same) const {
    if (inv_ <= 0.0) return false;  // no separation: every place is distinct
    const long long cx = cell(p.x_m), cy = cell(p.y_m), cz = cell(p.z_m);
    for (long long dx = -1; dx <= 1; ++dx) {
      for (long long dy = -1; dy <= 1; ++dy) {
        for (long long dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(key(cx + dx, cy + dy, cz + dz));
          if (it == cells_.end()) continue;
          for (int k : it->second) {
            if (same(places[k].pose)) return true;
          }
        }
      }
    }
    return false;
  }
  void add(const Particle& p, int index) {
    if (inv_ > 0.0) cells_[key(cell(p.x_m), cell(p.y_m), cell(p.z_m))].push_back(index);
  }

 private:
  long long cell(double v) const {  // bounded first: no float outside long long's range
    return static_cast<long long>(std::floor(std::max(-1e15, std::min(1e15, v * inv_))));
  }
  static unsigned long long key(long long x, long long y, long long z) {
    return static_cast<unsigned long long>(x) * 73856093ULL ^
           static_cast<unsigned long long>(y) * 19349663ULL ^
           static_cast<unsigned long long>(z) * 83492791ULL;
  }
  double inv_;
  std::unordered_map<unsigned long long, std::vector<int>> cells_;
};

}  // namespace

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
  PlaceCells cells(params_.separation_m);
  for (size_t i : order) {
    if (static_cast<int>(places_.size()) >= params_.places) break;
    if (!std::isfinite(scores[i])) break;
    if (cells.any(poses[i], places_, [&](const Particle& q) { return samePlace(q, poses[i]); })) {
      continue;
    }
    cells.add(poses[i], static_cast<int>(places_.size()));
    places_.push_back(Place{poses[i], 0.0, 0.0});
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
  PlaceCells cells(params_.separation_m);
  for (const Place& p : places_) {
    if (!std::isfinite(p.score)) continue;
    if (cells.any(p.pose, kept, [&](const Particle& q) { return samePlace(q, p.pose); })) continue;
    cells.add(p.pose, static_cast<int>(kept.size()));
    kept.push_back(p);
  }
  places_.swap(kept);
}

const StartHypotheses::Place& StartHypotheses::best() const {
  return *std::max_element(places_.begin(), places_.end(),
                           [](const Place& a, const Place& b) { return a.score < b.score; });
}

}  // namespace gmm_mcl
