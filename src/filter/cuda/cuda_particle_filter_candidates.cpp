// The device particle filter's candidate pool (screening and lost-state redraws): draws,
// scoring on the backend's device frame, selection by score and replacement of the set.
#include <cuda_runtime_api.h>

#include <algorithm>
#include <stdexcept>

#include "cuda/cuda_particle_filter_impl.h"

namespace gmm_mcl {

void CudaParticleFilter::clearCandidates() { impl_->cand_count = impl_->cand_scored = 0; }

void CudaParticleFilter::drawUniformCandidates(const InitRegion& region, int n) {
  Impl& d = *impl_;
  if (n <= 0) return;
  const cuda::DeviceScope scope(d.device);
  d.growCandidates(d.cand_count + n);
  GMM_MCL_CUDA_CHECK(cuda::launchUniform(n, d.nextCall(), cuda::toBox(region),
                                         d.cand.data() + d.cand_count, nullptr, 0.0, d.stream));
  d.cand_count += n;
}

void CudaParticleFilter::scoreCandidates(const MeasurementContext& ctx) {
  Impl& d = *impl_;
  const int m = d.cand_count - d.cand_scored;
  if (m <= 0) return;
  const cuda::DeviceScope scope(d.device);
  d.growCandidates(d.cand_count);
  cuda::reserveAll(m, d.stream, d.cand_T_map_cam, d.cand_T_cam_map, d.cand_hits, d.cand_evals,
                   d.cand_pairs);
  d.scorePoses(ctx, d.cand.data() + d.cand_scored, m, d.cand_T_map_cam.data(),
               d.cand_T_cam_map.data(), d.cand_ll.data() + d.cand_scored, d.cand_hits.data(),
               d.cand_evals.data(), d.cand_pairs.data());
  d.cand_scored = d.cand_count;
}

int CudaParticleFilter::scoredCandidates() const { return impl_->cand_scored; }

void CudaParticleFilter::selectCandidateCentres(int elites, bool clear_pool) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  elites = std::max(0, std::min(elites, d.cand_scored));
  d.num_centres = elites;
  if (elites > 0) {
    d.orderCandidates();
    d.centres.reserve(elites, d.stream);
    GMM_MCL_CUDA_CHECK(cuda::launchGather(elites, d.values_sorted.data(), d.cand.data(), nullptr,
                                          d.centres.data(), nullptr, d.stream));
  }
  if (clear_pool) d.cand_count = d.cand_scored = 0;
}

void CudaParticleFilter::drawCandidatesAroundCentres(double sigma_m, double sigma_rad, int n) {
  Impl& d = *impl_;
  if (n <= 0 || d.num_centres == 0) return;
  const cuda::DeviceScope scope(d.device);
  d.growCandidates(d.cand_count + n);
  GMM_MCL_CUDA_CHECK(cuda::launchAround(n, d.nextCall(), d.centres.data(), d.num_centres, sigma_m,
                                        sigma_rad, d.cand.data() + d.cand_count, d.stream));
  d.cand_count += n;
}

void CudaParticleFilter::replaceAllByBestCandidates() {
  Impl& d = *impl_;
  if (d.cand_scored < d.n) {
    throw std::invalid_argument("replaceAll: the particle count must not change");
  }
  const cuda::DeviceScope scope(d.device);
  d.orderCandidates();
  GMM_MCL_CUDA_CHECK(cuda::launchGather(d.n, d.values_sorted.data(), d.cand.data(), nullptr,
                                        d.particles_swap.data(), nullptr, d.stream));
  std::swap(d.particles, d.particles_swap);
  GMM_MCL_CUDA_CHECK(cuda::launchFill(d.n, 1.0 / d.n, d.weights.data(), d.stream));
  d.ll_count = 0;
  d.setReplaced();
}

void CudaParticleFilter::replaceWorstByBestCandidates(int keep, int count) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  const int n = d.n;
  count = std::max(0, std::min(count, d.cand_scored));
  if (!d.frame_ll_valid) {
    throw std::invalid_argument("replaceWorst: one log-likelihood per particle expected");
  }
  keep = keep < 0 ? std::max(0, n - count) : std::min(keep, n);
  if (keep + count == 0 || (keep == n && count == 0)) return;
  const int m = keep + count;
  d.reserveParticles(m);  // keeps the set and its likelihoods
  if (keep > 0) {
    // Each particle's likelihood on this frame (its source's after a resampling).
    const double* ll = d.resampled_since_evaluation ? d.ll_follow.data() : d.ll.data();
    d.orderByScore(ll, n);
    GMM_MCL_CUDA_CHECK(cuda::launchGather(keep, d.values_sorted.data(), d.particles.data(), nullptr,
                                          d.particles_swap.data(), nullptr, d.stream));
    GMM_MCL_CUDA_CHECK(cuda::launchGatherValues(keep, d.values_sorted.data(), d.weights.data(),
                                                d.weights_swap.data(), d.stream));
  }
  if (count > 0) {
    d.orderCandidates();
    GMM_MCL_CUDA_CHECK(cuda::launchGather(count, d.values_sorted.data(), d.cand.data(), nullptr,
                                          d.particles_swap.data() + keep, nullptr, d.stream));
    GMM_MCL_CUDA_CHECK(cuda::launchFill(count, 1.0 / n, d.weights_swap.data() + keep, d.stream));
  }
  std::swap(d.particles, d.particles_swap);
  std::swap(d.weights, d.weights_swap);
  d.n = m;
  d.ll_count = 0;  // the frame's likelihoods no longer match the set
  d.normaliseWeights();
  d.setReplaced();
}

std::vector<Particle> CudaParticleFilter::candidateParticles() const {
  return impl_->download<Particle>(impl_->cand, impl_->cand_count);
}

std::vector<std::pair<double, Particle>> CudaParticleFilter::candidatePool() const {
  const Impl& d = *impl_;
  const std::vector<Particle> p = candidateParticles();
  const std::vector<double> ll = d.download<double>(d.cand_ll, d.cand_scored);
  std::vector<std::pair<double, Particle>> out(d.cand_scored);
  for (int i = 0; i < d.cand_scored; ++i) out[i] = std::make_pair(ll[i], p[i]);
  return out;
}

void CudaParticleFilter::setCandidatePool(const std::vector<std::pair<double, Particle>>& scored) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  const int m = static_cast<int>(scored.size());
  std::vector<Particle> p(m);
  std::vector<double> ll(m);
  for (int i = 0; i < m; ++i) {
    ll[i] = scored[i].first;
    p[i] = scored[i].second;
  }
  d.cand_count = d.cand_scored = 0;
  d.growCandidates(std::max(m, 1));
  cuda::copyToDeviceAsync(d.cand.data(), p.data(), m, d.stream);
  cuda::copyToDeviceAsync(d.cand_ll.data(), ll.data(), m, d.stream);
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  d.cand_count = d.cand_scored = m;
}

std::vector<Particle> CudaParticleFilter::candidateCentres() const {
  return impl_->download<Particle>(impl_->centres, impl_->num_centres);
}

}  // namespace gmm_mcl
