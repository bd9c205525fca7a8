// The simulator's seeded random draws where a seed must give the same result with any standard
// library: std::mt19937_64 (whose output sequence the standard fixes) and uniform numbers made
// from its bits here, not by the implementation-defined std:: distributions.
#pragma once

#include <algorithm>
#include <cstdint>
#include <random>

namespace gmm_mcl {
namespace sim {

class UniformRng {
 public:
  explicit UniformRng(uint64_t seed) : gen_(seed) {}
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(gen_() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  // Uniform integer in [0, n) (n > 0) and in [a, b] (inclusive).
  int below(int n) { return std::min(n - 1, static_cast<int>(uniform() * n)); }
  int between(int a, int b) { return a + below(b - a + 1); }
  bool chance(double p) { return uniform() < p; }

 private:
  std::mt19937_64 gen_;
};

}  // namespace sim
}  // namespace gmm_mcl
