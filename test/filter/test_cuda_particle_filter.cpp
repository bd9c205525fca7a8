// The device particle filter (CudaParticleFilter) against the host one (ParticleFilter, the
// reference), operation by operation. Deterministic operations (weights from given
// log-likelihoods, resampling indices for given weights, order and offsets, the KLD bin count,
// the estimate, the redraw's selection, the likelihood of device-resident poses) to stated
// tolerances; stochastic ones (prediction noise, uniform and Gaussian draws) statistically, with
// fixed seeds. Exits 77 with the reason when no CUDA device is present.
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

#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/backend/cuda_backend.h"
#include "gmm_mcl/filter/cuda_particle_filter.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/internal/particle_math.h"
#include "gmm_mcl/sim/box_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

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

std::unique_ptr<CudaBackend> makeCuda() { return std::unique_ptr<CudaBackend>(new CudaBackend(0)); }

ParticleFilterParams filterParams(int n, uint64_t seed = 7) {
  ParticleFilterParams p;
  p.num_particles = n;
  p.seed = seed;
  return p;
}

std::vector<Particle> randomParticles(int n, uint64_t seed, double spread_m = 1.0) {
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

std::vector<double> randomWeights(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.1, 1.0);
  std::vector<double> w(n);
  for (double& x : w) x = u(rng);
  return w;
}

double relDiff(double a, double b, double scale) { return std::abs(a - b) / scale; }

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

// ---- selection (screening and lost redraws) -------------------------------------------------

std::vector<Particle> sortedByX(std::vector<Particle> v) {
  std::sort(v.begin(), v.end(), [](const Particle& a, const Particle& b) { return a.x_m < b.x_m; });
  return v;
}

TEST(CudaParticleFilterTest, RedrawSelectionMatchesTheHost) {
  const int n = 4000, pool = 20000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  ParticleFilter host(filterParams(n));
  CudaParticleFilter device(filterParams(n), backend.get());
  // Distinct x everywhere, so that sets compare by x.
  std::vector<Particle> particles = randomParticles(n, 51);
  for (int i = 0; i < n; ++i) particles[i].x_m = i;
  const std::vector<double> w = randomWeights(n, 52);
  std::vector<double> ll(n);
  std::mt19937_64 rng(53);
  std::uniform_real_distribution<double> u(-5000.0, -1000.0);
  for (double& x : ll) x = u(rng);
  ll[17] = -std::numeric_limits<double>::infinity();  // non-finite: never kept
  ll[18] = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::pair<double, Particle>> candidates(pool);
  std::vector<Particle> cp = randomParticles(pool, 54);
  for (int i = 0; i < pool; ++i) {
    cp[i].x_m = 1e6 + i;
    candidates[i] = std::make_pair(u(rng), cp[i]);
  }
  const int keep = 400, count = 3600;
  for (int pass = 0; pass < 2; ++pass) {
    SCOPED_TRACE(pass == 0 ? "replaceWorstByBestCandidates" : "replaceAllByBestCandidates");
    host.setParticles(particles, w);
    device.setParticles(particles, w);
    host.setFrameLogLikelihoods(ll, std::vector<int>(n, 0));
    device.setFrameLogLikelihoods(ll, std::vector<int>(n, 0));
    host.setCandidatePool(candidates);
    device.setCandidatePool(candidates);
    if (pass == 0) {
      host.replaceWorstByBestCandidates(keep, count);
      device.replaceWorstByBestCandidates(keep, count);
    } else {
      host.replaceAllByBestCandidates();
      device.replaceAllByBestCandidates();
    }
    ASSERT_EQ(device.size(), host.size());
    // The same particles (any order) with the same weights.
    std::vector<std::pair<double, double>> hx, dx;  // (x, weight)
    for (int i = 0; i < host.size(); ++i)
      hx.emplace_back(host.particles()[i].x_m, host.weights()[i]);
    for (int i = 0; i < device.size(); ++i) {
      dx.emplace_back(device.particles()[i].x_m, device.weights()[i]);
    }
    std::sort(hx.begin(), hx.end());
    std::sort(dx.begin(), dx.end());
    for (size_t i = 0; i < hx.size(); ++i) {
      ASSERT_EQ(dx[i].first, hx[i].first) << i;
      ASSERT_NEAR(dx[i].second, hx[i].second, 1e-12 * hx[i].second) << i;
    }
  }
  // The centres of local draws: the best `elites` of the pool.
  host.setCandidatePool(candidates);
  device.setCandidatePool(candidates);
  host.selectCandidateCentres(200, false);
  device.selectCandidateCentres(200, true);
  EXPECT_EQ(device.scoredCandidates(), 0);  // the pool was cleared
  std::vector<std::pair<double, Particle>> sorted = candidates;
  std::sort(sorted.begin(), sorted.end(),
            [](const std::pair<double, Particle>& a, const std::pair<double, Particle>& b) {
              return a.first > b.first;
            });
  std::vector<Particle> best(200);
  for (int i = 0; i < 200; ++i) best[i] = sorted[i].second;
  const std::vector<Particle> centres = sortedByX(device.candidateCentres());
  best = sortedByX(best);
  ASSERT_EQ(centres.size(), best.size());
  for (size_t i = 0; i < best.size(); ++i) EXPECT_EQ(centres[i].x_m, best[i].x_m);
}

TEST(CudaParticleFilterTest, AfterResamplingEachParticleCarriesItsSourcesLikelihood) {
  const int n = 2000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  CudaParticleFilter device(filterParams(n), backend.get());
  std::vector<Particle> particles = randomParticles(n, 61);
  for (int i = 0; i < n; ++i) particles[i].x_m = i;
  device.setParticles(particles, randomWeights(n, 62));
  std::vector<double> ll(n);
  for (int i = 0; i < n; ++i) ll[i] = -1000.0 - i;  // particle i's likelihood falls with i
  device.setFrameLogLikelihoods(ll, std::vector<int>(n, 0));
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(63);
  std::shuffle(order.begin(), order.end(), rng);
  const std::vector<int> src = device.resampleWith(order, {0.3, 0.6, 0.1, 0.9}, n);
  const int keep = 100;
  device.replaceWorstByBestCandidates(keep, 0);
  ASSERT_EQ(device.size(), keep);
  // The kept ones are the resampled particles of the best sources.
  std::vector<int> sources(src);
  std::sort(sources.begin(), sources.end());
  std::vector<double> expected(sources.begin(), sources.begin() + keep);
  std::vector<double> got;
  for (const Particle& q : device.particles()) got.push_back(q.x_m);
  std::sort(got.begin(), got.end());
  ASSERT_EQ(got.size(), expected.size());
  for (int i = 0; i < keep; ++i) EXPECT_EQ(got[i], expected[i]);
}

// ---- sampling (statistical) -----------------------------------------------------------------

struct Moments {
  double mean[4] = {0, 0, 0, 0};
  double var[4] = {0, 0, 0, 0};
  double cov_xy = 0;
};

Moments moments(const std::vector<Particle>& v, const Particle& centre) {
  Moments m;
  const double n = static_cast<double>(v.size());
  for (const Particle& p : v) {
    const double d[4] = {p.x_m - centre.x_m, p.y_m - centre.y_m, p.z_m - centre.z_m,
                         wrapAngle(p.yaw_rad - centre.yaw_rad)};
    for (int k = 0; k < 4; ++k) m.mean[k] += d[k] / n;
  }
  for (const Particle& p : v) {
    const double d[4] = {p.x_m - centre.x_m, p.y_m - centre.y_m, p.z_m - centre.z_m,
                         wrapAngle(p.yaw_rad - centre.yaw_rad)};
    for (int k = 0; k < 4; ++k) m.var[k] += (d[k] - m.mean[k]) * (d[k] - m.mean[k]) / (n - 1);
    m.cov_xy += (d[0] - m.mean[0]) * (d[1] - m.mean[1]) / (n - 1);
  }
  return m;
}

// Gaussian draws around `centre` with these sigmas: means, variances, independence.
void expectGaussian(const std::vector<Particle>& v, const Particle& centre, const double sigma[4],
                    const char* what) {
  SCOPED_TRACE(what);
  const double n = static_cast<double>(v.size());
  const Moments m = moments(v, centre);
  for (int k = 0; k < 4; ++k) {
    const double se_mean = sigma[k] / std::sqrt(n);
    const double se_var = sigma[k] * sigma[k] * std::sqrt(2.0 / (n - 1));
    EXPECT_LT(std::abs(m.mean[k]), kSigmas * se_mean) << "axis " << k;
    EXPECT_LT(std::abs(m.var[k] - sigma[k] * sigma[k]), kSigmas * se_var) << "axis " << k;
  }
  EXPECT_LT(std::abs(m.cov_xy) / (sigma[0] * sigma[1]), kSigmas / std::sqrt(n));
  std::printf("[ measured ] %s: mean/se %.2f %.2f %.2f %.2f, var/sigma^2 %.4f %.4f %.4f %.4f\n",
              what, m.mean[0] / (sigma[0] / std::sqrt(n)), m.mean[1] / (sigma[1] / std::sqrt(n)),
              m.mean[2] / (sigma[2] / std::sqrt(n)), m.mean[3] / (sigma[3] / std::sqrt(n)),
              m.var[0] / (sigma[0] * sigma[0]), m.var[1] / (sigma[1] * sigma[1]),
              m.var[2] / (sigma[2] * sigma[2]), m.var[3] / (sigma[3] * sigma[3]));
}

TEST(CudaParticleFilterTest, PredictionMovesInTheYawFrameWithTheConfiguredNoise) {
  const int n = 200000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  ParticleFilterParams p = filterParams(n);
  p.sigma_translation_m = 0.02;
  p.sigma_yaw_rad = 0.01;
  const Particle start{1.0, 2.0, 0.5, 3.1};  // near +pi: the yaw wraps
  PlanarDelta delta;
  delta.translation_m = Eigen::Vector3d(0.1, -0.05, 0.02);
  delta.yaw_rad = 0.1;
  Particle expected = start;
  const double c = std::cos(start.yaw_rad), s = std::sin(start.yaw_rad);
  expected.x_m += c * 0.1 - s * -0.05;
  expected.y_m += s * 0.1 + c * -0.05;
  expected.z_m += 0.02;
  expected.yaw_rad = wrapAngle(start.yaw_rad + 0.1);
  const double sigma[4] = {0.02, 0.02, 0.02, 0.01};
  for (int pass = 0; pass < 2; ++pass) {
    std::unique_ptr<ParticleFilterBase> f;
    if (pass == 0) {
      f.reset(new ParticleFilter(p));
    } else {
      f.reset(new CudaParticleFilter(p, backend.get()));
    }
    f->setParticles(std::vector<Particle>(n, start), std::vector<double>(n, 1.0));
    f->predict(delta);
    const std::vector<Particle>& out = f->particles();
    for (const Particle& q : out) {
      ASSERT_GE(q.yaw_rad, -M_PI);
      ASSERT_LT(q.yaw_rad, M_PI);
    }
    expectGaussian(out, expected, sigma, pass == 0 ? "host prediction" : "device prediction");
  }
}

TEST(CudaParticleFilterTest, UniformAndGaussianDrawsHaveTheirDistributions) {
  const int n = 200000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  CudaParticleFilter device(filterParams(n), backend.get());
  InitRegion r;
  r.centre_m = Eigen::Vector3d(1.0, -2.0, 1.5);
  r.half_extent_m = Eigen::Vector3d(2.0, 1.0, 0.5);
  r.yaw_centre_rad = 0.4;
  r.yaw_half_range_rad = 1.0;
  const double h[4] = {2.0, 1.0, 0.5, 1.0};
  const Particle centre{1.0, -2.0, 1.5, 0.4};
  auto expectUniform = [&](const std::vector<Particle>& v, const char* what) {
    SCOPED_TRACE(what);
    const Moments m = moments(v, centre);
    for (const Particle& q : v) {
      ASSERT_LE(std::abs(q.x_m - 1.0), 2.0);
      ASSERT_LE(std::abs(q.y_m + 2.0), 1.0);
      ASSERT_LE(std::abs(q.z_m - 1.5), 0.5);
      ASSERT_LE(std::abs(wrapAngle(q.yaw_rad - 0.4)), 1.0 + 1e-12);
    }
    for (int k = 0; k < 4; ++k) {
      // U(-h, h): mean 0, variance h^2 / 3, Var[(x - c)^2] = 4 h^4 / 45.
      const double se_mean = h[k] / std::sqrt(3.0 * n);
      const double se_var = std::sqrt(4.0 * std::pow(h[k], 4) / 45.0 / n);
      EXPECT_LT(std::abs(m.mean[k]), kSigmas * se_mean) << what << " axis " << k;
      EXPECT_LT(std::abs(m.var[k] - h[k] * h[k] / 3.0), kSigmas * se_var) << what << " axis " << k;
    }
  };
  device.initialiseUniform(r);
  expectUniform(device.particles(), "initialiseUniform");
  for (double w : device.weights()) ASSERT_EQ(w, 1.0 / n);
  device.clearCandidates();
  device.drawUniformCandidates(r, n / 2);
  device.drawUniformCandidates(r, n / 2);  // appended, with other draws
  const std::vector<Particle> candidates = device.candidateParticles();
  ASSERT_EQ(static_cast<int>(candidates.size()), n);
  EXPECT_NE(candidates[0].x_m, candidates[n / 2].x_m);
  expectUniform(candidates, "drawUniformCandidates");

  const double sigma[4] = {0.3, 0.2, 0.1, 0.05};
  device.initialiseGaussian(centre, Eigen::Vector4d(sigma[0], sigma[1], sigma[2], sigma[3]));
  expectGaussian(device.particles(), centre, sigma, "initialiseGaussian");

  // Local draws around the best candidates, in turn.
  std::vector<std::pair<double, Particle>> pool;
  for (int i = 0; i < 4; ++i) {
    pool.emplace_back(-double(i), Particle{double(10 * i), 0.0, 0.0, 0.0});
  }
  device.setCandidatePool(pool);
  device.selectCandidateCentres(2, true);
  device.drawCandidatesAroundCentres(0.25, 0.2, n);
  const std::vector<Particle> local = device.candidateParticles();
  std::vector<Particle> around0, around1;
  for (int i = 0; i < n; ++i) (i % 2 == 0 ? around0 : around1).push_back(local[i]);
  // Centres in score order are x = 0 and x = 10, one of them every other draw.
  const bool zero_first = std::abs(local[0].x_m) < std::abs(local[0].x_m - 10.0);
  const double s_local[4] = {0.25, 0.25, 0.25, 0.2};
  expectGaussian(zero_first ? around0 : around1, Particle{0, 0, 0, 0}, s_local, "around centre 0");
  expectGaussian(zero_first ? around1 : around0, Particle{10, 0, 0, 0}, s_local, "around centre 1");
}

TEST(CudaParticleFilterTest, SameSeedSameDrawsOtherSeedOtherDraws) {
  const int n = 1000;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  InitRegion r;
  CudaParticleFilter a(filterParams(n, 5), backend.get()), b(filterParams(n, 5), backend.get()),
      c(filterParams(n, 6), backend.get());
  for (CudaParticleFilter* f : {&a, &b, &c}) {
    f->initialiseUniform(r);
    f->predict(PlanarDelta());
  }
  EXPECT_EQ(a.particles()[123].x_m, b.particles()[123].x_m);
  EXPECT_EQ(a.particles()[999].yaw_rad, b.particles()[999].yaw_rad);
  EXPECT_NE(a.particles()[123].x_m, c.particles()[123].x_m);
}

// ---- likelihood of device-resident particles ------------------------------------------------

// The reference base pose seen by the small camera: its depth image (to 9 m) and its frame at
// `stride`.
struct ReferenceView {
  explicit ReferenceView(int stride)
      : fp(test::frameParams(stride)),
        image(test::renderImage(T_map_base, K, fp.max_range_m + 1.0)),
        frame(prepareFrame(image, K, fp)) {}
  const Intrinsics K = test::smallCamera();
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const FrameParams fp;
  const DepthImage image;
  const DepthFrame frame;
};

TEST(CudaParticleFilterTest, LikelihoodOfDeviceParticlesMatchesTheHostPath) {
  const auto& w = test::world();
  const ReferenceView view(4);
  const int n = 3000;
  const ParticleFilterParams p = filterParams(n);
  CpuBackend cpu;
  std::unique_ptr<CudaBackend> gpu = makeCuda();
  cpu.setMap(w.map);
  gpu->setMap(w.map);
  MeasurementParams mp;
  MeasurementContext ctx;
  ctx.frame = &view.frame;
  ctx.roll_rad = 0.02;
  ctx.pitch_rad = -0.03;
  ctx.T_base_cam = w.T_base_cam;
  ctx.params = &mp;
  // Particles around the reference pose.
  const Particle ref = poseToParticle(view.T_map_base);
  std::vector<Particle> particles(n);
  std::mt19937_64 rng(71);
  std::uniform_real_distribution<double> um(-0.5, 0.5), ua(-0.3, 0.3);
  for (Particle& q : particles) {
    q = ref;
    q.x_m += um(rng);
    q.y_m += um(rng);
    q.z_m += 0.2 * um(rng);
    q.yaw_rad = wrapAngle(q.yaw_rad + ua(rng));
  }
  particles[0] = ref;
  ParticleFilter host(p);
  host.setParticles(particles, std::vector<double>(n, 1.0));
  ctx.backend = &cpu;
  EvaluationStats hs;
  host.evaluateFrame(ctx, &hs);
  const std::vector<double> expected = host.frameLogLikelihoods();
  const double floor_scale = static_cast<double>(view.frame.size());
  for (int source = 0; source < 2; ++source) {
    SCOPED_TRACE(source == 0 ? "frame prepared on the GPU" : "host frame uploaded");
    CudaParticleFilter device(p, gpu.get());
    device.setParticles(particles, std::vector<double>(n, 1.0));
    if (source == 0) {
      DeviceFrameSummary summary;
      ASSERT_TRUE(device.prepareDeviceFrame(view.image, view.K, view.fp, &summary));
      EXPECT_EQ(summary.pixels, static_cast<int>(view.frame.size()));
    } else {
      gpu->uploadDeviceFrame(view.frame);
    }
    ctx.backend = gpu.get();
    EvaluationStats ds;
    device.evaluateFrame(ctx, &ds);
    const std::vector<double> got = device.frameLogLikelihoods();
    ASSERT_EQ(got.size(), expected.size());
    double worst = 0.0;
    for (int i = 0; i < n; ++i) {
      worst = std::max(worst,
                       relDiff(got[i], expected[i], std::max(std::abs(expected[i]), floor_scale)));
    }
    std::printf(
        "[ measured ] device-resident poses: max relative log-likelihood difference "
        "%.2e (%d particles, %zu pixels), evaluations %lld vs %lld\n",
        worst, n, view.frame.size(), ds.evaluations, hs.evaluations);
    EXPECT_LT(worst, kLikelihoodRelTol);
    EXPECT_NEAR(static_cast<double>(ds.evaluations), static_cast<double>(hs.evaluations),
                1e-3 * hs.evaluations);
    // And the scores of the weight update on them.
    ParticleFilter host_w(p);
    host_w.setParticles(particles, std::vector<double>(n, 1.0));
    host_w.setFrameLogLikelihoods(got, std::vector<int>(n, 0));
    FrameScores a, b;
    ASSERT_TRUE(device.weighFrame(static_cast<int>(view.frame.size()), &a));
    ASSERT_TRUE(host_w.weighFrame(static_cast<int>(view.frame.size()), &b));
    EXPECT_EQ(a.best_loglik, b.best_loglik);
    EXPECT_NEAR(a.beta_fraction, b.beta_fraction, kBetaTol);
  }
}

TEST(CudaParticleFilterTest, ScreeningScoresTheDrawsAndKeepsTheBest) {
  const auto& w = test::world();
  const ReferenceView view(8);
  const int n = 500, per = 8;
  std::unique_ptr<CudaBackend> gpu = makeCuda();
  gpu->setMap(w.map);
  CpuBackend cpu;
  cpu.setMap(w.map);
  CudaParticleFilter device(filterParams(n), gpu.get());
  DeviceFrameSummary summary;
  ASSERT_TRUE(device.prepareDeviceFrame(view.image, view.K, view.fp, &summary));
  MeasurementParams mp;
  MeasurementContext ctx;
  ctx.backend = gpu.get();
  ctx.T_base_cam = w.T_base_cam;
  ctx.params = &mp;
  InitRegion r;
  const Particle ref = poseToParticle(view.T_map_base);
  r.centre_m = Eigen::Vector3d(ref.x_m, ref.y_m, ref.z_m);
  r.half_extent_m = Eigen::Vector3d(1.0, 1.0, 0.3);
  r.yaw_centre_rad = ref.yaw_rad;
  r.yaw_half_range_rad = 0.8;
  device.clearCandidates();
  for (int b = 0; b < per; ++b) {
    device.drawUniformCandidates(r, n);
    device.scoreCandidates(ctx);
  }
  const std::vector<std::pair<double, Particle>> pool = device.candidatePool();
  ASSERT_EQ(static_cast<int>(pool.size()), n * per);
  // The device's scores against the CPU backend on the same candidates.
  std::vector<RigidTransformF> poses(pool.size());
  for (size_t i = 0; i < pool.size(); ++i) {
    poses[i] = toRigidF(particleToPose(pool[i].second, 0.0, 0.0) * w.T_base_cam);
  }
  BackendOutput out;
  cpu.evaluate(view.frame, poses, mp, &out);
  double worst = 0.0;
  for (size_t i = 0; i < pool.size(); ++i) {
    worst = std::max(worst,
                     relDiff(pool[i].first, out.log_likelihood[i],
                             std::max(std::abs(out.log_likelihood[i]), double(view.frame.size()))));
  }
  std::printf("[ measured ] screening: %zu candidates, max relative score difference %.2e\n",
              pool.size(), worst);
  EXPECT_LT(worst, kLikelihoodRelTol);
  // The set becomes the n best by the device's scores.
  std::vector<std::pair<double, Particle>> sorted = pool;
  std::sort(sorted.begin(), sorted.end(),
            [](const std::pair<double, Particle>& a, const std::pair<double, Particle>& b) {
              return a.first > b.first;
            });
  device.replaceAllByBestCandidates();
  ASSERT_EQ(device.size(), n);
  std::map<double, double> score_of;  // by x (distinct)
  for (const auto& c : pool) score_of[c.second.x_m] = c.first;
  std::set<double> distinct;
  for (const Particle& q : device.particles()) {
    ASSERT_EQ(score_of.count(q.x_m), 1u);
    EXPECT_GE(score_of[q.x_m], sorted[n - 1].first);  // among the n best scores
    distinct.insert(q.x_m);
  }
  EXPECT_EQ(static_cast<int>(distinct.size()), n);
}

TEST(CudaParticleFilterTest, RecoveryCountsMatchTheHost) {
  // The same likelihoods frame after frame: the augmented-MCL averages, hence the counts, agree;
  // on the device exactly that many particles are redrawn.
  const int n = 2000, pixels = 500;
  std::unique_ptr<CudaBackend> backend = makeCuda();
  ParticleFilterParams p = filterParams(n);
  ParticleFilter host(p);
  CudaParticleFilter device(p, backend.get());
  InitRegion far;
  far.centre_m = Eigen::Vector3d(100.0, 100.0, 100.0);
  far.half_extent_m = Eigen::Vector3d(1.0, 1.0, 1.0);
  const std::vector<Particle> particles = randomParticles(n, 81);
  std::mt19937_64 rng(82);
  int total = 0;
  for (int frame = 0; frame < 40; ++frame) {
    host.setParticles(particles, std::vector<double>(n, 1.0));
    device.setParticles(particles, std::vector<double>(n, 1.0));
    // Likelihood falling after frame 10: the fast average drops below the slow one.
    std::normal_distribution<double> g(frame < 10 ? -0.5 * pixels : -5.0 * pixels, 20.0);
    std::vector<double> ll(n);
    for (double& x : ll) x = g(rng);
    host.setFrameLogLikelihoods(ll, std::vector<int>(n, 0));
    device.setFrameLogLikelihoods(ll, std::vector<int>(n, 0));
    FrameScores s;
    ASSERT_TRUE(host.weighFrame(pixels, &s));
    ASSERT_TRUE(device.weighFrame(pixels, &s));
    const int hc = host.recoverFrame(pixels, far);
    const int dc = device.recoverFrame(pixels, far);
    ASSERT_EQ(dc, hc) << "frame " << frame;
    int moved = 0;
    for (const Particle& q : device.particles()) moved += q.x_m > 50.0 ? 1 : 0;
    EXPECT_EQ(moved, dc) << "frame " << frame;
    double wsum = 0.0;
    for (double x : device.weights()) wsum += x;
    EXPECT_NEAR(wsum, 1.0, 1e-12);
    total += dc;
  }
  std::printf("[ measured ] recovery: %d particles reinitialised over 40 frames\n", total);
  EXPECT_GT(total, 0);  // the case does exercise the recovery
}

}  // namespace
}  // namespace gmm_mcl
