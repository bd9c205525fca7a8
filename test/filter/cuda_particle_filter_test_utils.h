// Shared by the test_cuda_particle_filter_* suites: the device particle filter
// (CudaParticleFilter) against the host one (ParticleFilter, the reference), tolerances and
// random inputs.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cuda/cuda_backend.h"
#include "cuda/cuda_particle_filter.h"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/internal/particle_math.h"
#include "gmm_mcl/sim/box_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {

// Weights from the same log-likelihoods: both evaluate exp in double; the sums differ in order
// (the device's tree against the host's loop), ~1e-16 relative, and the bisection's decisions
// could differ only where Neff(mid) is within that of the floor.
constexpr double kWeightRelTol = 1e-9;
constexpr double kBetaTol = 1e-9;
// Estimate: double sums in another order.
constexpr double kEstimateTol = 1e-9;
// Per-particle log-likelihood, as test_cuda_backend (the kernels' float arithmetic).
constexpr double kLikelihoodRelTol = 1e-5;
// A statistic agrees with its expectation within this many standard errors.
constexpr double kSigmas = 4.5;

inline std::unique_ptr<CudaBackend> makeCuda() {
  return std::unique_ptr<CudaBackend>(new CudaBackend(0));
}

inline ParticleFilterParams filterParams(int n, uint64_t seed = 7) {
  ParticleFilterParams p;
  p.num_particles = n;
  p.seed = seed;
  return p;
}

inline std::vector<Particle> randomParticles(int n, uint64_t seed, double spread_m = 1.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-spread_m, spread_m), a(-M_PI, M_PI);
  std::vector<Particle> out(n);
  for (Particle& p : out) {
    p.x_m = 1.0 + u(rng);
    p.y_m = -2.0 + u(rng);
    p.z_m = 0.5 + 0.2 * u(rng);
    p.yaw_rad = a(rng);
  }
  return out;
}

inline std::vector<double> randomWeights(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.1, 1.0);
  std::vector<double> w(n);
  for (double& x : w) x = u(rng);
  return w;
}

inline double relDiff(double a, double b, double scale) { return std::abs(a - b) / scale; }

}  // namespace gmm_mcl
