#include "gmm_mcl/filter/resampling.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace gmm_mcl {

void stratifiedLowVarianceResample(const std::vector<double>& weights, int groups, int n_out,
                                   std::mt19937_64* rng, std::vector<int>* indices) {
  const int n = static_cast<int>(weights.size());
  indices->resize(n_out);
  if (n == 0 || n_out == 0) return;
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), *rng);
  groups = std::max(1, std::min(groups, n_out));
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<double> offsets(groups);
  for (double& o : offsets) o = uniform(*rng);
  stratifiedLowVarianceIndices(weights, order, offsets, n_out, indices);
}

void stratifiedLowVarianceIndices(const std::vector<double>& weights, const std::vector<int>& order,
                                  const std::vector<double>& offsets, int n_out,
                                  std::vector<int>* indices) {
  const int n = static_cast<int>(weights.size());
  indices->resize(n_out);
  if (n == 0 || n_out == 0) return;
  const int groups = static_cast<int>(offsets.size());
  // Cumulative mass in the shuffled order, scaled to [0, n_out).
  double total = 0.0;
  for (double w : weights) total += w;
  const double scale = n_out / total;
  int src = 0;
  double cumulative = weights[order[0]] * scale;
  int out = 0;
  for (int g = 0; g < groups; ++g) {
    const int count = n_out / groups + (g < n_out % groups ? 1 : 0);
    const double offset = offsets[g];
    for (int k = 0; k < count; ++k, ++out) {
      const double u = out + offset;  // in [out, out + 1): this draw's own slice
      while (cumulative <= u && src < n - 1) cumulative += weights[order[++src]] * scale;
      (*indices)[out] = order[src];
    }
  }
}

int AugmentedMcl::update(double average_likelihood, int n) {
  if (!(average_likelihood > 0.0) || !std::isfinite(average_likelihood)) return 0;
  if (!initialised_) {
    w_slow_ = w_fast_ = average_likelihood;
    initialised_ = true;
    return 0;
  }
  w_slow_ += alpha_slow_ * (average_likelihood - w_slow_);
  w_fast_ += alpha_fast_ * (average_likelihood - w_fast_);
  if (!(w_slow_ > 0.0)) return 0;
  const double fraction = std::max(0.0, 1.0 - w_fast_ / (threshold_ * w_slow_));
  return std::min(n, static_cast<int>(std::floor(n * fraction)));
}

double effectiveSampleSize(const std::vector<double>& weights) {
  double sum_sq = 0.0;
  for (double w : weights) sum_sq += w * w;
  return sum_sq > 0.0 ? 1.0 / sum_sq : 0.0;
}

}  // namespace gmm_mcl
