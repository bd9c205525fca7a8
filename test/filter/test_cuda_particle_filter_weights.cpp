// The device particle filter (CudaParticleFilter) against the host one (ParticleFilter, the
// reference): weights from given log-likelihoods, resampling indices for given weights, order and
// offsets, the KLD bin count and the estimate, to stated tolerances. Exits 77 with the reason when
// no CUDA device is present.
#include "cuda_particle_filter_test_utils.h"

namespace gmm_mcl {
namespace {

// ---- weights --------------------------------------------------------------------------------

struct WeightCase {
  const char* name;
  WeightingMode mode;
  double ll_spread;   // nats, the spread of the log-likelihoods
  bool peaked_prior;  // prior weights concentrated on a few particles
  bool non_finite;    // some -inf and NaN entries
};

TEST(CudaParticleFilterTest, WeightsMatchTheHostForTheSameLogLikelihoods) {
  const WeightCase cases[] = {
      {"tempered, floor free", WeightingMode::kTempered, 30.0, false, false},
      {"tempered, floor binds (bisection)", WeightingMode::kTempered, 30000.0, false, false},
      {"tempered, prior below the floor", WeightingMode::kTempered, 30000.0, true, false},
      {"tempered, non-finite entries", WeightingMode::kTempered, 3000.0, false, true},
      {"paper", WeightingMode::kPaper, 3000.0, false, true},
  };
  const int n = 5000, pixels = 1200;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  for (const WeightCase& c : cases) {
    SCOPED_TRACE(c.name);
    ParticleFilterParams p = filterParams(n);
    p.weighting = c.mode;
    ParticleFilter host(p);
    CudaParticleFilter device(p, backend.get());
    const std::vector<Particle> particles = randomParticles(n, 3);
    std::vector<double> prior = randomWeights(n, 4);
    if (c.peaked_prior) {
      for (int i = 10; i < n; ++i) prior[i] *= 1e-6;
    }
    host.setParticles(particles, prior);
    device.setParticles(particles, prior);
    std::mt19937_64 rng(5);
    std::normal_distribution<double> g(-2.0 * pixels, c.ll_spread / 3.0);
    std::vector<double> ll(n);
    std::vector<int> hits(n);
    for (int i = 0; i < n; ++i) {
      ll[i] = g(rng);
      hits[i] = i % 97;
    }
    if (c.non_finite) {
      for (int i = 0; i < n; i += 50) ll[i] = -std::numeric_limits<double>::infinity();
      for (int i = 25; i < n; i += 100) ll[i] = std::numeric_limits<double>::quiet_NaN();
    }
    host.setFrameLogLikelihoods(ll, hits);
    device.setFrameLogLikelihoods(ll, hits);
    FrameScores hs, ds;
    const bool hok = host.weighFrame(pixels, &hs);
    const bool dok = device.weighFrame(pixels, &ds);
    ASSERT_EQ(hok, dok);
    ASSERT_TRUE(hok);
    const std::vector<double>& hw = host.weights();
    const std::vector<double>& dw = device.weights();
    ASSERT_EQ(hw.size(), dw.size());
    const double wmax = *std::max_element(hw.begin(), hw.end());
    double worst = 0.0;
    for (int i = 0; i < n; ++i) worst = std::max(worst, relDiff(dw[i], hw[i], wmax));
    std::printf(
        "[ measured ] %s: weights max |dw| / max w = %.2e, beta fraction %.6f vs %.6f, "
        "Neff %.1f vs %.1f\n",
        c.name, worst, ds.beta_fraction, hs.beta_fraction, device.effectiveSampleSize(),
        host.effectiveSampleSize());
    EXPECT_LT(worst, kWeightRelTol);
    EXPECT_NEAR(ds.beta_fraction, hs.beta_fraction, kBetaTol);
    EXPECT_EQ(ds.best_loglik, hs.best_loglik);
    EXPECT_EQ(ds.best_floor_hits, hs.best_floor_hits);
    EXPECT_LT(relDiff(ds.mean_loglik, hs.mean_loglik, std::abs(hs.mean_loglik)), 1e-12);
    EXPECT_LT(relDiff(device.effectiveSampleSize(), host.effectiveSampleSize(),
                      host.effectiveSampleSize()),
              1e-9);
    if (std::string(c.name).find("bisection") != std::string::npos) {
      EXPECT_LT(hs.beta_fraction, 1.0);  // the case does exercise the bisection
    }
  }
}

TEST(CudaParticleFilterTest, DegenerateLikelihoodsKeepTheWeights) {
  const int n = 300;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  CudaParticleFilter device(filterParams(n), backend.get());
  const std::vector<double> prior = randomWeights(n, 9);
  device.setParticles(randomParticles(n, 8), prior);
  const std::vector<double> before = device.weights();
  device.setFrameLogLikelihoods(std::vector<double>(n, -std::numeric_limits<double>::infinity()),
                                std::vector<int>(n, 0));
  FrameScores s;
  EXPECT_FALSE(device.weighFrame(100, &s));
  EXPECT_EQ(device.weights(), before);
}

// ---- resampling -----------------------------------------------------------------------------

TEST(CudaParticleFilterTest, ResamplingIndicesMatchTheHostForTheSameOrderAndOffsets) {
  const int n = 20000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  for (int n_out : {n, 1068, 3001}) {
    SCOPED_TRACE(n_out);
    CudaParticleFilter device(filterParams(n), backend.get());
    std::vector<double> w = randomWeights(n, 11);
    for (int i = 0; i < n; i += 7) w[i] = 0.0;        // particles that cannot be drawn
    for (int i = 3; i < n; i += 1000) w[i] *= 300.0;  // and some that are drawn often
    const double total = std::accumulate(w.begin(), w.end(), 0.0);
    for (double& x : w) x /= total;
    device.setParticles(randomParticles(n, 12), w);
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::mt19937_64 rng(13);
    std::shuffle(order.begin(), order.end(), rng);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<double> offsets(4);
    for (double& o : offsets) o = u(rng);
    std::vector<int> expected;
    stratifiedLowVarianceIndices(w, order, offsets, n_out, &expected);
    const std::vector<int> got = device.resampleWith(order, offsets, n_out);
    ASSERT_EQ(got.size(), expected.size());
    // An index may differ only where the draw lies on a boundary of the cumulative mass to
    // within the rounding of the two summation orders.
    std::vector<double> cumulative(n);
    double c = 0.0;
    for (int j = 0; j < n; ++j) cumulative[j] = (c += w[order[j]] * n_out);
    int differ = 0;
    const int groups = static_cast<int>(offsets.size());
    for (int k = 0, out = 0; k < groups; ++k) {
      const int count = n_out / groups + (k < n_out % groups ? 1 : 0);
      for (int m = 0; m < count; ++m, ++out) {
        if (got[out] == expected[out]) continue;
        ++differ;
        const double draw = out + offsets[k];
        double nearest = 1e300;
        for (double b : cumulative) nearest = std::min(nearest, std::abs(b - draw));
        EXPECT_LT(nearest, 1e-9 * n_out) << "output " << out;
      }
    }
    std::printf("[ measured ] n_out %d: %d of %d indices differ (boundary draws)\n", n_out, differ,
                n_out);
    // The set became the drawn particles with equal weights.
    ASSERT_EQ(device.size(), n_out);
    const std::vector<double>& dw = device.weights();
    for (double x : dw) ASSERT_NEAR(x, 1.0 / n_out, 1e-15);
  }
}

TEST(CudaParticleFilterTest, KldBinCountAndAdaptiveCountMatchTheHost) {
  std::unique_ptr<CudaBackend> backend = makeCuda();
  // Bins of a spread set: the device count against the host's keys.
  {
    const int n = 30000;
    CudaParticleFilter device(filterParams(n), backend.get());
    const std::vector<Particle> particles = randomParticles(n, 21, 2.0);
    device.setParticles(particles, std::vector<double>(n, 1.0));
    std::set<uint64_t> keys;
    const ParticleFilterParams p = filterParams(n);
    for (const Particle& q : particles) {
      keys.insert(kldBinKey(ParticleState{q.x_m, q.y_m, q.z_m, q.yaw_rad}, 1.0 / p.kld_bin_m,
                            1.0 / p.kld_bin_rad));
    }
    std::printf("[ measured ] occupied bins: device %d, host %zu\n", device.occupiedBins(),
                keys.size());
    EXPECT_EQ(device.occupiedBins(), static_cast<int>(keys.size()));
  }
  // The adaptive count: 50 well-filled bins (200 particles each, equal weights) are all drawn
  // by any resampling, so both filters set the count to the bound of 50 bins.
  const int bins = 50, per_bin = 200, n = bins * per_bin;
  ParticleFilterParams p = filterParams(n);
  p.min_particles = 300;
  std::vector<Particle> particles(n);
  std::mt19937_64 rng(22);
  std::uniform_real_distribution<double> inside(0.02, 0.18);
  for (int b = 0; b < bins; ++b) {
    for (int k = 0; k < per_bin; ++k) {
      Particle& q = particles[b * per_bin + k];
      q.x_m = 0.2 * (b % 10) + inside(rng);
      q.y_m = 0.2 * (b / 10) + inside(rng);
      q.z_m = 0.5 + inside(rng) * 0.1;
      q.yaw_rad = 0.1;
    }
  }
  ParticleFilter host(p);
  CudaParticleFilter device(p, backend.get());
  host.setParticles(particles, std::vector<double>(n, 1.0));
  device.setParticles(particles, std::vector<double>(n, 1.0));
  host.resample();
  device.resample();
  const int expected = std::max(
      p.min_particles, std::min(p.num_particles, kldParticleBound(bins, p.kld_epsilon, p.kld_z)));
  std::printf("[ measured ] adaptive count: device %d, host %d, bound of %d bins %d\n",
              device.size(), host.size(), bins, expected);
  EXPECT_EQ(host.size(), expected);
  EXPECT_EQ(device.size(), expected);
}

TEST(CudaParticleFilterTest, ResamplingDrawsInProportionToTheWeights) {
  // Stochastic check of the whole device resampling (random order and offsets): particle i is
  // drawn N w_i times in expectation and never more than groups + 1 away from it.
  const int n = 1000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  ParticleFilterParams p = filterParams(n);
  CudaParticleFilter device(p, backend.get());
  std::vector<double> w = randomWeights(n, 31);
  const double total = std::accumulate(w.begin(), w.end(), 0.0);
  std::vector<Particle> particles(n);
  for (int i = 0; i < n; ++i) particles[i].x_m = i;  // the index, to count copies
  device.setParticles(particles, w);
  device.resample();
  const std::vector<Particle>& out = device.particles();
  std::vector<int> copies(n, 0);
  for (const Particle& q : out) ++copies[static_cast<int>(q.x_m)];
  for (int i = 0; i < n; ++i) {
    EXPECT_LE(std::abs(copies[i] - n * w[i] / total), p.resample_groups + 1.0) << i;
  }
}

// ---- estimate -------------------------------------------------------------------------------

TEST(CudaParticleFilterTest, EstimateMatchesTheHost) {
  const int n = 25000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  ParticleFilter host(filterParams(n));
  CudaParticleFilter device(filterParams(n), backend.get());
  std::vector<Particle> particles = randomParticles(n, 41, 0.5);
  // Yaw around +-pi: the mean and the wrapped differences.
  std::mt19937_64 rng(42);
  std::normal_distribution<double> g(0.0, 0.2);
  for (Particle& q : particles) q.yaw_rad = wrapAngle(M_PI + g(rng));
  const std::vector<double> w = randomWeights(n, 43);
  host.setParticles(particles, w);
  device.setParticles(particles, w);
  const PoseEstimate he = host.estimate(), de = device.estimate();
  double worst = 0.0;
  worst = std::max(worst, std::abs(he.mean.x_m - de.mean.x_m));
  worst = std::max(worst, std::abs(he.mean.y_m - de.mean.y_m));
  worst = std::max(worst, std::abs(he.mean.z_m - de.mean.z_m));
  worst = std::max(worst, std::abs(wrapAngle(he.mean.yaw_rad - de.mean.yaw_rad)));
  const double cov_diff = (he.covariance - de.covariance).cwiseAbs().maxCoeff();
  std::printf("[ measured ] estimate: mean %.2e, covariance %.2e, Neff %.6f vs %.6f\n", worst,
              cov_diff, device.effectiveSampleSize(), host.effectiveSampleSize());
  EXPECT_LT(worst, kEstimateTol);
  EXPECT_LT(cov_diff, kEstimateTol);
  EXPECT_LT(
      relDiff(device.effectiveSampleSize(), host.effectiveSampleSize(), host.effectiveSampleSize()),
      1e-9);
}

}  // namespace
}  // namespace gmm_mcl
