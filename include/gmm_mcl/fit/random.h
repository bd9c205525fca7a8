// Small portable random source for the map builder: the same numbers on every platform and
// standard library for a seed (std::uniform_*_distribution is implementation-defined).
#pragma once

#include <cstdint>

namespace gmm_mcl {

// SplitMix64 seeding into xoshiro256**.
class FitRandom {
 public:
  explicit FitRandom(uint64_t seed) {
    uint64_t z = seed;
    for (int i = 0; i < 4; ++i) s_[i] = splitmix(&z);
  }
  uint64_t next() {
    const uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  // Uniform in [0, 1), 53 bits.
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
  // Uniform integer in [0, n), n > 0 (negligible modulo bias for the sizes used here).
  uint64_t below(uint64_t n) { return next() % n; }

 private:
  static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  static uint64_t splitmix(uint64_t* z) {
    uint64_t r = (*z += 0x9E3779B97F4A7C15ull);
    r = (r ^ (r >> 30)) * 0xBF58476D1CE4E5B9ull;
    r = (r ^ (r >> 27)) * 0x94D049BB133111EBull;
    return r ^ (r >> 31);
  }
  uint64_t s_[4];
};

}  // namespace gmm_mcl
