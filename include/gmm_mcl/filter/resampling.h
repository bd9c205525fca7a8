// Resampling and particle-deprivation handling (paper Sec. Sampling Strategy, Handling
// Particle Deprivation).
#pragma once

#include <random>
#include <vector>

namespace gmm_mcl {

// Stratified groups with low-variance sampling inside each: particles are put in a random order,
// the cumulative weight is cut into `groups` strata of n_g / N mass each (n_g outputs per group),
// and each stratum is sampled systematically with its own random offset. Every output draw is
// uniform on its own 1/N slice, so particle i gets N * w_i copies in expectation, and never more
// than `groups` + 1 away from it. `weights` must be normalised. Fills `indices` (size n_out).
void stratifiedLowVarianceResample(const std::vector<double>& weights, int groups, int n_out,
                                   std::mt19937_64* rng, std::vector<int>* indices);
// The same with the random order and the groups' offsets given: order is a permutation of the
// particles, offsets[g] in [0, 1) for each of max(1, min(groups, n_out)) groups. The arithmetic
// that the device filter reproduces (and is tested against).
void stratifiedLowVarianceIndices(const std::vector<double>& weights, const std::vector<int>& order,
                                  const std::vector<double>& offsets, int n_out,
                                  std::vector<int>* indices);

// Augmented MCL (Thrun et al., Probabilistic Robotics, Table 8.3) on the average per-pixel
// likelihood of a frame. Reinitialisation fraction: max(0, 1 - w_fast / (threshold * w_slow)),
// count floor(N * fraction). threshold = 1 is Thrun's rule; below 1 it is a dead band: the fast
// average must fall that far below the slow one before anything is reinitialised, so the
// frame-to-frame jitter of steady tracking reinitialises nothing. Both averages start at the
// first frame's value.
class AugmentedMcl {
 public:
  AugmentedMcl(double alpha_slow, double alpha_fast, double threshold)
      : alpha_slow_(alpha_slow), alpha_fast_(alpha_fast), threshold_(threshold) {}
  // Feeds one frame's average likelihood (> 0); returns how many of n particles to reinitialise.
  int update(double average_likelihood, int n);
  void reset() { initialised_ = false; }
  // New rates and threshold; the averages are kept.
  void setRates(double alpha_slow, double alpha_fast, double threshold) {
    alpha_slow_ = alpha_slow;
    alpha_fast_ = alpha_fast;
    threshold_ = threshold;
  }
  double wSlow() const { return w_slow_; }
  double wFast() const { return w_fast_; }

 private:
  double alpha_slow_;
  double alpha_fast_;
  double threshold_;
  double w_slow_ = 0.0;
  double w_fast_ = 0.0;
  bool initialised_ = false;
};

// Effective sample size 1 / sum(w^2) of normalised weights.
double effectiveSampleSize(const std::vector<double>& weights);

}  // namespace gmm_mcl
