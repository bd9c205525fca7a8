// The device particle filter (CudaParticleFilter) against the host one (ParticleFilter, the
// reference): the likelihood of device-resident poses, screening and the recovery counts, to stated
// tolerances. Exits 77 with the reason when no CUDA device is present.
#include <tuple>

#include "cuda_particle_filter_test_utils.h"

namespace gmm_mcl {
namespace {

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

// The CPU and the CUDA backend, both with the map.
struct BothBackends {
  explicit BothBackends(const GmmMap& map) : gpu(makeCuda()) {
    cpu.setMap(map);
    gpu->setMap(map);
  }
  CpuBackend cpu;
  std::unique_ptr<CudaBackend> gpu;
};

TEST(CudaParticleFilterTest, LikelihoodOfDeviceParticlesMatchesTheHostPath) {
  const auto& w = test::world();
  const ReferenceView view(4);
  const int n = 3000;
  const ParticleFilterParams p = filterParams(n);
  BothBackends backends(w.map);
  CpuBackend& cpu = backends.cpu;
  CudaBackend* gpu = backends.gpu.get();
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
    CudaParticleFilter device(p, gpu);
    device.setParticles(particles, std::vector<double>(n, 1.0));
    if (source == 0) {
      DeviceFrameSummary summary;
      ASSERT_TRUE(device.prepareDeviceFrame(view.image, view.K, view.fp, &summary));
      EXPECT_EQ(summary.pixels, static_cast<int>(view.frame.size()));
    } else {
      gpu->uploadDeviceFrame(view.frame);
    }
    ctx.backend = gpu;
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
    // The host (CPU backend) drops the pairs the frame's depths rule out (MemberDepthPrune),
    // which the CUDA kernels keep.
    EXPECT_LE(hs.evaluations, ds.evaluations);
    EXPECT_GT(hs.evaluations, ds.evaluations / 10);
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

TEST(CudaParticleFilterTest, ASecondCamerasFrameAddsUpLikeTheHosts) {
  // A rig: the reference camera and a second one looking back and down from the same base;
  // each frame prepared on the GPU in turn, the second's likelihoods added (accumulateFrame).
  const auto& w = test::world();
  const ReferenceView view(4);
  Eigen::Isometry3d T_base_cam2 = w.T_base_cam;
  T_base_cam2.linear() = Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                         Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                         w.T_base_cam.linear();
  const FrameParams fp2 = test::frameParams(8);
  // renderImage renders from T_map_base * T_base_cam.
  const DepthImage image2 = test::renderImage(
      view.T_map_base * T_base_cam2 * w.T_base_cam.inverse(), view.K, fp2.max_range_m + 1.0);
  const DepthFrame frame2 = prepareFrame(image2, view.K, fp2);
  ASSERT_GT(frame2.size(), 0u);
  const MeasurementParams mp;
  MeasurementContext a, b;  // the reference camera's frame and the second one's
  std::tie(a.frame, a.T_base_cam, a.params) = std::make_tuple(&view.frame, w.T_base_cam, &mp);
  std::tie(b.frame, b.T_base_cam, b.params) = std::make_tuple(&frame2, T_base_cam2, &mp);
  const int n = 2000;
  const ParticleFilterParams p = filterParams(n);
  BothBackends backends(w.map);
  CpuBackend& cpu = backends.cpu;
  CudaBackend* gpu = backends.gpu.get();
  const Particle ref = poseToParticle(view.T_map_base);
  std::vector<Particle> particles(n, ref);
  std::mt19937_64 rng(72);
  std::uniform_real_distribution<double> um(-0.4, 0.4), ua(-0.3, 0.3);
  for (int i = 1; i < n; ++i) {
    particles[i].x_m += um(rng);
    particles[i].y_m += um(rng);
    particles[i].yaw_rad = wrapAngle(particles[i].yaw_rad + ua(rng));
  }
  ParticleFilter host(p);
  host.setParticles(particles, std::vector<double>(n, 1.0));
  a.backend = b.backend = &cpu;
  host.evaluateFrame(a, nullptr);
  host.accumulateFrame(b, 0.25, nullptr);
  const std::vector<double> expected = host.frameLogLikelihoods();
  CudaParticleFilter device(p, gpu);
  device.setParticles(particles, std::vector<double>(n, 1.0));
  a.backend = b.backend = gpu;
  a.frame = b.frame = nullptr;
  DeviceFrameSummary summary;
  ASSERT_TRUE(device.prepareDeviceFrame(view.image, view.K, view.fp, &summary));
  device.evaluateFrame(a, nullptr);
  ASSERT_TRUE(device.prepareDeviceFrame(image2, view.K, fp2, &summary));
  EXPECT_EQ(summary.pixels, static_cast<int>(frame2.size()));
  EvaluationStats stats;
  device.accumulateFrame(b, 0.25, &stats);
  EXPECT_GT(stats.evaluations, 0);
  const std::vector<double> got = device.frameLogLikelihoods();
  ASSERT_EQ(got.size(), expected.size());
  const double floor_scale = static_cast<double>(view.frame.size() + 0.25 * frame2.size());
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    worst =
        std::max(worst, relDiff(got[i], expected[i], std::max(std::abs(expected[i]), floor_scale)));
  }
  std::printf("[ measured ] two cameras: max relative log-likelihood difference %.2e\n", worst);
  EXPECT_LT(worst, kLikelihoodRelTol);
  device.resample();
  EXPECT_THROW(device.accumulateFrame(b, 1.0, nullptr), std::logic_error);
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
