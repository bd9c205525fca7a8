#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {
namespace {

TEST(ResamplingTest, ExpectedCopiesEqualNTimesWeightWithLowVariance) {
  const int n = 200, trials = 4000, groups = 4;
  std::mt19937_64 rng(7);
  std::gamma_distribution<double> gamma(0.5, 1.0);
  std::vector<double> w(n);
  double total = 0.0;
  for (double& v : w) total += (v = gamma(rng));
  for (double& v : w) v /= total;

  std::vector<double> sum(n, 0.0), sum_sq(n, 0.0);
  std::vector<int> idx, copies(n);
  int worst_deviation_excess = 0;
  for (int t = 0; t < trials; ++t) {
    stratifiedLowVarianceResample(w, groups, n, &rng, &idx);
    ASSERT_EQ(static_cast<int>(idx.size()), n);
    std::fill(copies.begin(), copies.end(), 0);
    for (int i : idx) ++copies[i];
    for (int i = 0; i < n; ++i) {
      sum[i] += copies[i];
      sum_sq[i] += copies[i] * copies[i];
      if (std::abs(copies[i] - n * w[i]) > groups + 1) ++worst_deviation_excess;
    }
  }
  double var_total = 0.0, multinomial_total = 0.0, worst_z = 0.0;
  for (int i = 0; i < n; ++i) {
    const double mean = sum[i] / trials;
    const double var = sum_sq[i] / trials - mean * mean;
    var_total += var;
    multinomial_total += n * w[i] * (1.0 - w[i]);
    // Unbiased: the mean count is within 5 standard errors of N w_i.
    const double se = std::sqrt(std::max(var, 1e-4) / trials);
    worst_z = std::max(worst_z, std::abs(mean - n * w[i]) / se);
  }
  std::printf("[ measured ] worst z %.2f; total variance %.2f vs multinomial %.2f\n", worst_z,
              var_total, multinomial_total);
  EXPECT_LT(worst_z, 5.0);
  EXPECT_EQ(worst_deviation_excess, 0);
  EXPECT_LT(var_total, 0.25 * multinomial_total);
}

TEST(ResamplingTest, DegenerateWeightCopiesOneParticle) {
  std::vector<double> w(50, 0.0);
  w[17] = 1.0;
  std::mt19937_64 rng(1);
  std::vector<int> idx;
  stratifiedLowVarianceResample(w, 4, 50, &rng, &idx);
  for (int i : idx) EXPECT_EQ(i, 17);
}

TEST(ResamplingTest, EffectiveSampleSize) {
  EXPECT_DOUBLE_EQ(effectiveSampleSize(std::vector<double>(10, 0.1)), 10.0);
  EXPECT_DOUBLE_EQ(effectiveSampleSize({1.0, 0.0, 0.0}), 1.0);
}

}  // namespace
}  // namespace gmm_mcl
