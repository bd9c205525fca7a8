// The device particle filter's operations on the set: buffers, launches on the CUDA backend's
// stream and the few read-backs per frame (the frame's pixel count, the weight update's scalars,
// the estimate, the KLD bin count when the count adapts). The candidate pool is in
// cuda_particle_filter_candidates.cpp, the shared steps in cuda_particle_filter_impl.cpp.
#include <cuda_runtime_api.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cuda/cuda_factory.h"
#include "cuda/cuda_particle_filter_impl.h"
#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {

namespace {

// ParticleFilter::updateWeights's bisection steps.
constexpr int kBisectionIterations = 40;

}  // namespace

CudaParticleFilter::CudaParticleFilter(const ParticleFilterParams& params, CudaBackend* backend) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument("particle filter parameters: " + err);
  if (backend == nullptr) throw std::invalid_argument("device particle filter: no CUDA backend");
  impl_.reset(new Impl(params, backend));
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.reserveParticles(params.num_particles);
  d.n = params.num_particles;
  const double w = 1.0 / d.n;
  // ParticleFilter's starting set: every particle at the origin, equal weights.
  GMM_MCL_CUDA_CHECK(cudaMemsetAsync(d.particles.data(), 0, d.n * sizeof(ParticleState), d.stream));
  GMM_MCL_CUDA_CHECK(cuda::launchFill(d.n, w, d.weights.data(), d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
}

CudaParticleFilter::~CudaParticleFilter() {
  if (!impl_) return;
  // Nothing queued may outlive the buffers; errors of a failed device are not actionable here.
  if (cudaSetDevice(impl_->device) == cudaSuccess) cudaStreamSynchronize(impl_->stream);
  impl_.reset();
  cudaGetLastError();
}

const ParticleFilterParams& CudaParticleFilter::params() const { return impl_->params; }

void CudaParticleFilter::setParams(const ParticleFilterParams& params) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument("particle filter parameters: " + err);
  Impl& d = *impl_;
  const uint64_t seed = d.params.seed;  // the generator's counter stream stays
  d.params = params;
  d.params.seed = seed;
  d.augmented.setRates(params.alpha_slow, params.alpha_fast, params.recovery_threshold);
  const int n_out = d.params.adaptive()
                        ? std::max(d.params.min_particles, std::min(d.params.num_particles, d.n))
                        : d.params.num_particles;
  if (n_out == d.n) return;
  // ParticleFilter::setParams's resampling to the allowed count, on the device.
  const cuda::DeviceScope scope(d.device);
  d.drawStratifiedIndices(n_out);
  d.gatherResampled(n_out);
}
int CudaParticleFilter::size() const { return impl_->n; }

const std::vector<Particle>& CudaParticleFilter::particles() const {
  const Impl& d = *impl_;
  return d.cachedDownload(d.particles, d.n, &d.h_particles, &d.particles_cached);
}

const std::vector<double>& CudaParticleFilter::weights() const {
  const Impl& d = *impl_;
  return d.cachedDownload(d.weights, d.n, &d.h_weights, &d.weights_cached);
}

void CudaParticleFilter::setParticles(const std::vector<Particle>& particles,
                                      const std::vector<double>& weights) {
  if (particles.size() != weights.size() || particles.empty()) {
    throw std::invalid_argument("setParticles: sizes differ or empty");
  }
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  double total = 0.0;
  for (double w : weights) total += w;
  std::vector<double> w(weights.size());
  for (size_t i = 0; i < weights.size(); ++i) w[i] = weights[i] / total;
  const int m = static_cast<int>(particles.size());
  d.clearForNewSet(m);
  cuda::copyToDeviceAsync(d.particles.data(), particles.data(), m, d.stream);
  cuda::copyToDeviceAsync(d.weights.data(), w.data(), m, d.stream);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));  // the host vectors go away
  d.n = m;
  d.setReplaced();
}

void CudaParticleFilter::initialiseUniform(const InitRegion& region) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.clearForNewSet(d.params.num_particles);
  d.n = d.params.num_particles;
  GMM_MCL_CUDA_CHECK(cuda::launchUniform(d.n, d.nextCall(), cuda::toBox(region), d.particles.data(),
                                         d.weights.data(), 1.0 / d.n, d.stream));
  d.augmented.reset();
  d.setReplaced();
}

void CudaParticleFilter::initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.clearForNewSet(d.params.num_particles);
  d.n = d.params.num_particles;
  const ParticleState m{mean.x_m, mean.y_m, mean.z_m, mean.yaw_rad};
  const double s[4] = {sigma[0], sigma[1], sigma[2], sigma[3]};
  GMM_MCL_CUDA_CHECK(cuda::launchGaussian(d.n, d.nextCall(), m, s, d.particles.data(),
                                          d.weights.data(), 1.0 / d.n, d.stream));
  d.augmented.reset();
  d.setReplaced();
}

void CudaParticleFilter::predict(const PlanarDelta& delta) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  cuda::PredictConfig cfg;
  cfg.delta[0] = delta.translation_m.x();
  cfg.delta[1] = delta.translation_m.y();
  cfg.delta[2] = delta.translation_m.z();
  cfg.delta[3] = delta.yaw_rad;
  cfg.sigma_m =
      delta.sigma_translation_m >= 0.0 ? delta.sigma_translation_m : d.params.sigma_translation_m;
  cfg.sigma_rad = delta.sigma_yaw_rad >= 0.0 ? delta.sigma_yaw_rad : d.params.sigma_yaw_rad;
  GMM_MCL_CUDA_CHECK(cuda::launchPredict(d.n, d.nextCall(), cfg, d.particles.data(), d.stream));
  d.particles_cached = d.estimate_cached = false;
}

bool CudaParticleFilter::prepareDeviceFrame(const DepthImage& image, const Intrinsics& K,
                                            const FrameParams& frame_params,
                                            DeviceFrameSummary* summary) {
  const CudaBackend::DeviceFrameInfo info =
      impl_->backend->prepareDeviceFrame(image, K, frame_params);
  summary->pixels = info.pixels;
  summary->patches_with_pixels = info.patches_with_pixels;
  return true;
}

void CudaParticleFilter::evaluateFrame(const MeasurementContext& ctx, EvaluationStats* stats) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.scorePoses(ctx, d.particles.data(), d.n, d.T_map_cam.data(), d.T_cam_map.data(), d.ll.data(),
               d.hits.data(), d.evals.data(), d.pairs.data());
  d.ll_count = d.n;
  d.resampled_since_evaluation = false;
  d.frame_ll_valid = true;
  d.have_ws = false;
  GMM_MCL_CUDA_CHECK(
      cuda::launchSumCounts(d.n, d.evals.data(), d.pairs.data(), d.count_sums.data(), d.stream));
  cuda::copyToHost(d.h_count_sums.data(), d.count_sums.data(), 2, d.stream);
  if (stats) {
    stats->evaluations = static_cast<long long>(d.h_count_sums[0]);
    stats->relevant_pairs = static_cast<long long>(d.h_count_sums[1]);
    d.backend->deviceStageMs(&stats->projection_membership_ms, &stats->likelihood_ms);
  }
}

void CudaParticleFilter::accumulateFrame(const MeasurementContext& ctx, double scale,
                                         EvaluationStats* stats) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.ll_count != d.n || d.resampled_since_evaluation || !d.frame_ll_valid) {
    throw std::logic_error("accumulateFrame: the set has no frame likelihoods to add to");
  }
  d.ll_more.reserve(d.capacity, d.stream);
  d.hits_more.reserve(d.capacity, d.stream);
  d.scorePoses(ctx, d.particles.data(), d.n, d.T_map_cam.data(), d.T_cam_map.data(),
               d.ll_more.data(), d.hits_more.data(), d.evals.data(), d.pairs.data());
  GMM_MCL_CUDA_CHECK(cuda::launchAddFrame(d.n, scale, d.ll_more.data(), d.hits_more.data(),
                                          d.ll.data(), d.hits.data(), d.stream));
  d.have_ws = false;
  GMM_MCL_CUDA_CHECK(
      cuda::launchSumCounts(d.n, d.evals.data(), d.pairs.data(), d.count_sums.data(), d.stream));
  cuda::copyToHost(d.h_count_sums.data(), d.count_sums.data(), 2, d.stream);
  if (stats) {
    stats->evaluations = static_cast<long long>(d.h_count_sums[0]);
    stats->relevant_pairs = static_cast<long long>(d.h_count_sums[1]);
    d.backend->deviceStageMs(&stats->projection_membership_ms, &stats->likelihood_ms);
  }
}

bool CudaParticleFilter::weighFrame(int pixels, FrameScores* scores) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (d.ll_count != d.n || d.resampled_since_evaluation || pixels <= 0 || d.n == 0) return false;
  const ParticleFilterParams& p = d.params;
  cuda::WeightConfig cfg;
  cfg.tempered = p.weighting == WeightingMode::kTempered ? 1 : 0;
  cfg.pixels = pixels;
  cfg.beta_max = 1.0 / (p.temperature * pixels);
  cfg.neff_floor = p.neff_floor_fraction * d.n;
  cfg.paper_margin = p.paper_min_nll_per_pixel * pixels;
  d.w_new.reserve(d.capacity, d.stream);
  GMM_MCL_CUDA_CHECK(cuda::launchWeightStart(d.n, cfg, d.ll.data(), d.weights.data(),
                                             d.wstate.data(), d.scratch(), d.stream));
  // Steady tracking rarely hits the Neff floor: read the decision back (a few microseconds)
  // rather than queue the bisection's launches every frame.
  cuda::copyToHost(d.h_wstate.data(), d.wstate.data(), 1, d.stream);
  if (d.h_wstate[0].bisect == cuda::kExponentBisected) {
    GMM_MCL_CUDA_CHECK(cuda::launchWeightBisection(d.n, cfg, kBisectionIterations, d.ll.data(),
                                                   d.weights.data(), d.wstate.data(), d.scratch(),
                                                   d.stream));
  }
  GMM_MCL_CUDA_CHECK(cuda::launchWeightFinish(d.n, cfg, d.ll.data(), d.hits.data(),
                                              d.weights.data(), d.w_new.data(), d.wstate.data(),
                                              d.scratch(), d.stream));
  cuda::copyToHost(d.h_wstate.data(), d.wstate.data(), 1, d.stream);
  d.ws = d.h_wstate[0];
  d.have_ws = d.ws.finite > 0;
  d.ws_pixels = pixels;
  if (d.ws.finite == 0 || !d.ws.ok) return false;
  d.weightsChanged();
  d.neff_value = d.ws.neff;
  d.neff_cached = true;
  scores->best_loglik = d.ws.argmax_ll;
  scores->mean_loglik = d.ws.mean_ll;
  scores->best_floor_hits = d.ws.best_hits;
  scores->beta_fraction = d.ws.beta_fraction;
  return true;
}

PoseEstimate CudaParticleFilter::estimate() const {
  impl_->computeEstimateUnless(impl_->estimate_cached);
  return impl_->estimate_value;
}

double CudaParticleFilter::effectiveSampleSize() const {
  impl_->computeEstimateUnless(impl_->neff_cached);
  return impl_->neff_value;
}

bool CudaParticleFilter::resampleIfNeeded() {
  if (effectiveSampleSize() >= impl_->params.resample_neff_fraction * size()) return false;
  resample();
  return true;
}

void CudaParticleFilter::resample() {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  const ParticleFilterParams& p = d.params;
  int n_out = d.n;
  if (p.adaptive()) {
    // KLD-sampling: the bins that a resampling at the current count occupies set the count.
    d.drawStratifiedIndices(d.n);
    const int bound = kldParticleBound(d.countBins(d.n), p.kld_epsilon, p.kld_z);
    n_out = std::max(p.min_particles, std::min(p.num_particles, bound));
  }
  d.drawStratifiedIndices(n_out);
  d.gatherResampled(n_out);
}

std::vector<int> CudaParticleFilter::resampleWith(const std::vector<int>& order,
                                                  const std::vector<double>& offsets, int n_out) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  if (static_cast<int>(order.size()) != d.n || offsets.empty() || n_out <= 0) {
    throw std::invalid_argument("resampleWith: one order entry per particle, offsets, n_out > 0");
  }
  d.reserveSort(d.n);
  d.offsets.reserve(offsets.size(), d.stream);
  cuda::copyToDeviceAsync(d.values_sorted.data(), order.data(), d.n, d.stream);
  cuda::copyToDeviceAsync(d.offsets.data(), offsets.data(), offsets.size(), d.stream);
  d.stratifiedIndices(n_out, static_cast<int>(offsets.size()));
  std::vector<int> indices = lastResampleIndices();
  d.gatherResampled(n_out);
  return indices;
}

std::vector<int> CudaParticleFilter::lastResampleIndices() const {
  return impl_->download<int>(impl_->indices, impl_->last_indices);
}

int CudaParticleFilter::occupiedBins() const {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  // The identity as indices.
  std::vector<int> iota(d.n);
  for (int i = 0; i < d.n; ++i) iota[i] = i;
  d.indices.reserve(std::max(d.n, 1), d.stream);
  cuda::copyToDeviceAsync(d.indices.data(), iota.data(), d.n, d.stream);
  d.last_indices = 0;
  return d.countBins(d.n);
}

int CudaParticleFilter::recoverFrame(int pixels, const InitRegion& region) {
  Impl& d = *impl_;
  const ParticleFilterParams& p = d.params;
  if (p.alpha_slow <= 0.0 || pixels <= 0 || !d.have_ws || d.ws.finite == 0) return 0;
  // The frame's average per-pixel likelihood over the particles as evaluated (before any
  // resampling), in log space: exp(max) * sum exp(L_i / pixels - max) / count.
  const double average = std::exp(d.ws.best / pixels) * d.ws.recover_sum / d.ll_count;
  const int count = d.augmented.update(average, d.n);
  if (count == 0) return 0;
  const cuda::DeviceScope scope(d.device);
  d.randomOrder(d.n);  // `count` distinct particles: the first of a random order
  GMM_MCL_CUDA_CHECK(cuda::launchReinitialise(count, d.values_sorted.data(), d.nextCall(),
                                              cuda::toBox(region), d.particles.data(),
                                              d.weights.data(), 1.0 / d.n, d.stream));
  d.normaliseWeights();
  d.changed();
  return count;
}

void CudaParticleFilter::synchronize() {
  const cuda::DeviceScope scope(impl_->device);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(impl_->stream));
}

void CudaParticleFilter::setFrameLogLikelihoods(const std::vector<double>& log_likelihood,
                                                const std::vector<int>& floor_hits) {
  Impl& d = *impl_;
  if (static_cast<int>(log_likelihood.size()) != d.n ||
      log_likelihood.size() != floor_hits.size()) {
    throw std::invalid_argument("setFrameLogLikelihoods: one entry per particle");
  }
  const cuda::DeviceScope scope(d.device);
  cuda::copyToDeviceAsync(d.ll.data(), log_likelihood.data(), d.n, d.stream);
  cuda::copyToDeviceAsync(d.hits.data(), floor_hits.data(), d.n, d.stream);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  d.ll_count = d.n;
  d.resampled_since_evaluation = false;
  d.frame_ll_valid = true;
  d.have_ws = false;
}

std::vector<double> CudaParticleFilter::frameLogLikelihoods() const {
  return impl_->download<double>(impl_->ll, impl_->ll_count);
}

// The factory's entry (cuda/cuda_factory.h): the device filter on the CUDA backend.
std::unique_ptr<ParticleFilterBase> makeCudaParticleFilter(const ParticleFilterParams& params,
                                                           LikelihoodBackend* backend) {
  CudaBackend* cuda_backend = dynamic_cast<CudaBackend*>(backend);
  if (cuda_backend == nullptr) return nullptr;
  return std::unique_ptr<ParticleFilterBase>(new CudaParticleFilter(params, cuda_backend));
}

}  // namespace gmm_mcl
