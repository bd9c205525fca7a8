// The device particle filter (CudaParticleFilter) against the host one (ParticleFilter, the
// reference): the redraw's selection and the likelihood each resampled particle carries, to stated
// tolerances; prediction noise and uniform and Gaussian draws statistically, with fixed seeds.
// Exits 77 with the reason when no CUDA device is present.
#include "cuda_particle_filter_test_utils.h"

namespace gmm_mcl {
namespace {

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

}  // namespace
}  // namespace gmm_mcl
