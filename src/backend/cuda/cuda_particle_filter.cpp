// Host side of the device particle filter: buffers, launches on the CUDA backend's stream and
// the few read-backs per frame (the frame's pixel count, the weight update's scalars, the
// estimate, the KLD bin count when the count adapts).
#include "gmm_mcl/filter/cuda_particle_filter.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cuda/device_buffer.cuh"
#include "cuda/filter_kernels.cuh"
#include "gmm_mcl/backend/cuda_backend.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {

namespace {

// ParticleFilter::updateWeights's bisection steps.
constexpr int kBisectionIterations = 40;

static_assert(sizeof(Particle) == sizeof(ParticleState), "Particle and ParticleState differ");

RegionBox toBox(const InitRegion& r) {
  RegionBox b;
  for (int k = 0; k < 3; ++k) {
    b.centre_m[k] = r.centre_m[k];
    b.half_extent_m[k] = r.half_extent_m[k];
  }
  b.yaw_centre_rad = r.yaw_centre_rad;
  b.yaw_half_range_rad = r.yaw_half_range_rad;
  return b;
}

CameraMount toMount(const MeasurementContext& ctx) {
  CameraMount m;
  const Eigen::Matrix3d A = (Eigen::AngleAxisd(ctx.pitch_rad, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(ctx.roll_rad, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Matrix3d B = ctx.T_base_cam.linear();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      m.R_pitch_roll[r * 3 + c] = A(r, c);
      m.R_base_cam[r * 3 + c] = B(r, c);
    }
    m.t_base_cam[r] = ctx.T_base_cam.translation()[r];
  }
  return m;
}

// Grows a device array to at least n elements keeping its first `live` ones (geometric growth).
template <typename T>
void growKeeping(cuda::DeviceBuffer<T>* b, size_t n, size_t live, cudaStream_t s) {
  if (n <= b->capacity()) return;
  cuda::DeviceBuffer<T> bigger(std::max(n, b->capacity() + b->capacity() / 2));
  if (live > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(bigger.data(), b->data(), live * sizeof(T),
                                       cudaMemcpyDeviceToDevice, s));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  *b = std::move(bigger);
}

}  // namespace

struct CudaParticleFilter::Impl {
  ParticleFilterParams params;
  CudaBackend* backend = nullptr;
  int device = 0;
  cudaStream_t stream = nullptr;
  int n = 0;
  size_t capacity = 0;
  // The set and its frame.
  cuda::DeviceBuffer<ParticleState> particles, particles_swap;
  cuda::DeviceBuffer<double> weights, weights_swap, w_new;
  cuda::DeviceBuffer<double> ll, ll_follow, ll_follow_swap;  // as evaluated; following resampling
  cuda::DeviceBuffer<int> hits;
  cuda::DeviceBuffer<long long> evals, pairs;
  cuda::DeviceBuffer<RigidTransformF> T_map_cam, T_cam_map;
  int ll_count = 0;  // particles when evaluated
  bool resampled_since_evaluation = false;
  // Each particle of the set has its frame likelihood in ll (as evaluated) or, after a
  // resampling, in ll_follow (its source's).
  bool frame_ll_valid = false;
  // Sorting and resampling scratch.
  cuda::DeviceBuffer<uint32_t> keys32, keys32_sorted;
  cuda::DeviceBuffer<double> keysf, keysf_sorted, cumulative, offsets;
  cuda::DeviceBuffer<int> values, values_sorted, indices;
  cuda::DeviceBuffer<uint64_t> bins, bins_sorted;
  cuda::DeviceBuffer<unsigned char> temp;
  int last_indices = 0;
  // Reductions and what comes back.
  cuda::DeviceBuffer<double> partials;
  cuda::DeviceBuffer<unsigned> counter;
  cuda::DeviceBuffer<cuda::WeightState> wstate;
  cuda::DeviceBuffer<cuda::EstimateState> estate;
  cuda::DeviceBuffer<double> total;
  cuda::DeviceBuffer<int> count;
  cuda::DeviceBuffer<unsigned long long> count_sums;
  cuda::PinnedBuffer<cuda::WeightState> h_wstate;
  cuda::PinnedBuffer<cuda::EstimateState> h_estate;
  cuda::PinnedBuffer<int> h_count;
  cuda::PinnedBuffer<unsigned long long> h_count_sums;
  cuda::WeightState ws;
  bool have_ws = false;
  int ws_pixels = 0;
  // Candidate pool.
  cuda::DeviceBuffer<ParticleState> cand, centres;
  cuda::DeviceBuffer<double> cand_ll;
  cuda::DeviceBuffer<int> cand_hits;
  cuda::DeviceBuffer<long long> cand_evals, cand_pairs;
  cuda::DeviceBuffer<RigidTransformF> cand_T_map_cam, cand_T_cam_map;
  int cand_count = 0, cand_scored = 0, num_centres = 0;
  // Host state.
  AugmentedMcl augmented;
  unsigned long long calls = 0;
  mutable std::vector<Particle> h_particles;
  mutable std::vector<double> h_weights;
  mutable bool particles_cached = false, weights_cached = false;
  mutable bool estimate_cached = false, neff_cached = false;
  mutable PoseEstimate estimate_value;
  mutable double neff_value = 0.0;

  explicit Impl(const ParticleFilterParams& p)
      : params(p), augmented(p.alpha_slow, p.alpha_fast, p.recovery_threshold) {}

  cuda::ReduceScratch scratch() { return cuda::ReduceScratch{partials.data(), counter.data()}; }
  cuda::RandomCall nextCall() { return cuda::RandomCall{params.seed, calls++}; }
  void changed() {
    particles_cached = weights_cached = estimate_cached = neff_cached = false;
  }
  void weightsChanged() { weights_cached = estimate_cached = neff_cached = false; }

  // Every per-particle array holds at least m particles (contents kept only by the caller).
  void reserveParticles(size_t m) {
    if (m <= capacity) return;
    const size_t c = std::max(m, capacity + capacity / 2);
    // The live arrays keep their contents.
    growKeeping(&particles, c, n, stream);
    growKeeping(&weights, c, n, stream);
    growKeeping(&ll, c, ll_count, stream);
    growKeeping(&ll_follow, c, n, stream);
    growKeeping(&hits, c, ll_count, stream);
    particles_swap.reserve(c, stream);
    weights_swap.reserve(c, stream);
    ll_follow_swap.reserve(c, stream);
    w_new.reserve(c, stream);
    evals.reserve(c, stream);
    pairs.reserve(c, stream);
    T_map_cam.reserve(c, stream);
    T_cam_map.reserve(c, stream);
    capacity = c;
  }
  // Sort scratch for m elements.
  void reserveSort(size_t m) {
    keys32.reserve(m, stream);
    keys32_sorted.reserve(m, stream);
    keysf.reserve(m, stream);
    keysf_sorted.reserve(m, stream);
    values.reserve(m, stream);
    values_sorted.reserve(m, stream);
  }
  template <typename F>
  void runCub(F f) {
    size_t bytes = 0;
    GMM_MCL_CUDA_CHECK(f(nullptr, &bytes));
    temp.reserve(std::max<size_t>(bytes, 1), stream);
    GMM_MCL_CUDA_CHECK(f(temp.data(), &bytes));
  }
  // values_sorted[0..m) = 0..m-1 in a random order.
  void randomOrder(int m) {
    reserveSort(m);
    GMM_MCL_CUDA_CHECK(
        cuda::launchRandomKeys(m, nextCall(), keys32.data(), values.data(), stream));
    runCub([&](void* t, size_t* b) {
      return cuda::sortPairsU32(t, b, keys32.data(), keys32_sorted.data(), values.data(),
                                values_sorted.data(), m, stream);
    });
  }
  // values_sorted[0..m) = indices of scores[0..m) by descending score (non-finite last).
  void orderByScore(const double* scores, int m) {
    reserveSort(m);
    GMM_MCL_CUDA_CHECK(cuda::launchScoreKeys(m, scores, keysf.data(), values.data(), stream));
    runCub([&](void* t, size_t* b) {
      return cuda::sortPairsDescendingF64(t, b, keysf.data(), keysf_sorted.data(), values.data(),
                                          values_sorted.data(), m, stream);
    });
  }
  // indices[0..n_out) of the stratified scheme over the current weights, with the order in
  // values_sorted and the offsets in `offsets`.
  void stratifiedIndices(int n_out, int groups) {
    cumulative.reserve(n, stream);
    indices.reserve(std::max(n_out, 1), stream);
    GMM_MCL_CUDA_CHECK(cuda::launchSum(n, weights.data(), total.data(), scratch(), stream));
    GMM_MCL_CUDA_CHECK(cuda::launchPermuteScaled(n, values_sorted.data(), weights.data(),
                                                 total.data(), n_out, keysf.data(), stream));
    runCub([&](void* t, size_t* b) {
      return cuda::inclusiveSumF64(t, b, keysf.data(), cumulative.data(), n, stream);
    });
    GMM_MCL_CUDA_CHECK(cuda::launchStratifiedIndices(n, n_out, groups, cumulative.data(),
                                                     values_sorted.data(), offsets.data(),
                                                     indices.data(), stream));
    last_indices = n_out;
  }
  // The set becomes particles[indices[0..n_out)], equal weights; each particle's frame
  // likelihood follows its source.
  void gatherResampled(int n_out) {
    reserveParticles(n_out);
    const double* ll_src = resampled_since_evaluation ? ll_follow.data() : ll.data();
    const bool have_ll = frame_ll_valid;
    GMM_MCL_CUDA_CHECK(cuda::launchGather(n_out, indices.data(), particles.data(),
                                          have_ll ? ll_src : nullptr, particles_swap.data(),
                                          have_ll ? ll_follow_swap.data() : nullptr, stream));
    std::swap(particles, particles_swap);
    if (have_ll) std::swap(ll_follow, ll_follow_swap);
    GMM_MCL_CUDA_CHECK(cuda::launchFill(n_out, 1.0 / n_out, weights.data(), stream));
    n = n_out;
    resampled_since_evaluation = true;
    changed();
  }
  int groupsFor(int n_out) const { return std::max(1, std::min(params.resample_groups, n_out)); }
  void drawOffsets(int groups) {
    offsets.reserve(groups, stream);
    GMM_MCL_CUDA_CHECK(cuda::launchOffsets(groups, nextCall(), offsets.data(), stream));
  }
  int countBins(int m) {
    bins.reserve(m, stream);
    bins_sorted.reserve(m, stream);
    GMM_MCL_CUDA_CHECK(cuda::launchBinKeys(m, indices.data(), particles.data(),
                                           1.0 / params.kld_bin_m, 1.0 / params.kld_bin_rad,
                                           bins.data(), stream));
    runCub([&](void* t, size_t* b) {
      return cuda::sortKeysU64(t, b, bins.data(), bins_sorted.data(), m, stream);
    });
    GMM_MCL_CUDA_CHECK(cuda::launchCountDistinct(m, bins_sorted.data(), count.data(), stream));
    GMM_MCL_CUDA_CHECK(
        cudaMemcpyAsync(h_count.data(), count.data(), sizeof(int), cudaMemcpyDeviceToHost, stream));
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream));
    return h_count[0];
  }
  void normaliseWeights() {
    GMM_MCL_CUDA_CHECK(cuda::launchSum(n, weights.data(), total.data(), scratch(), stream));
    GMM_MCL_CUDA_CHECK(cuda::launchDivide(n, total.data(), weights.data(), stream));
  }
  void computeEstimate() const;
  void growCandidates(int m) {
    growKeeping(&cand, m, cand_count, stream);
    growKeeping(&cand_ll, m, cand_scored, stream);
  }
  void scorePoses(const MeasurementContext& ctx, const ParticleState* p, int m,
                  RigidTransformF* Tm, RigidTransformF* Tc, double* out_ll, int* out_hits,
                  long long* out_evals, long long* out_pairs) {
    if (ctx.params == nullptr) throw std::invalid_argument("device particle filter: no parameters");
    if (!backend->hasDeviceFrame()) {
      if (ctx.frame == nullptr) {
        throw std::invalid_argument("device particle filter: no frame (prepareDeviceFrame first)");
      }
      backend->uploadDeviceFrame(*ctx.frame);
    }
    GMM_MCL_CUDA_CHECK(cuda::launchCameraPoses(m, p, toMount(ctx), Tm, Tc, stream));
    backend->evaluateDevicePoses(m, Tm, Tc, *ctx.params, out_ll, out_hits, out_evals, out_pairs);
  }
};

void CudaParticleFilter::Impl::computeEstimate() const {
  Impl& d = const_cast<Impl&>(*this);
  GMM_MCL_CUDA_CHECK(cuda::launchEstimate(n, particles.data(), weights.data(), d.estate.data(),
                                          d.scratch(), stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_estate.data(), estate.data(), sizeof(cuda::EstimateState),
                                     cudaMemcpyDeviceToHost, stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream));
  const cuda::EstimateState& e = d.h_estate[0];
  Particle mean;
  mean.x_m = e.mean[0];
  mean.y_m = e.mean[1];
  mean.z_m = e.mean[2];
  mean.yaw_rad = e.mean[3];
  Eigen::Matrix4d c;
  int k = 0;
  for (int r = 0; r < 4; ++r) {
    for (int col = r; col < 4; ++col) {
      c(r, col) = c(col, r) = e.cov[k++];
    }
  }
  estimate_value = poseEstimateFromMoments(mean, c, params);
  neff_value = e.neff;
  estimate_cached = neff_cached = true;
}

CudaParticleFilter::CudaParticleFilter(const ParticleFilterParams& params, CudaBackend* backend) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument("particle filter parameters: " + err);
  if (backend == nullptr) throw std::invalid_argument("device particle filter: no CUDA backend");
  impl_.reset(new Impl(params));
  Impl& d = *impl_;
  d.backend = backend;
  d.device = backend->deviceOrdinal();
  d.stream = static_cast<cudaStream_t>(backend->streamHandle());
  const cuda::DeviceScope scope(d.device);
  d.partials.reserve(size_t(cuda::kReduceBlocks) * cuda::kReduceMaxValues, d.stream);
  d.counter.reserve(1, d.stream);
  d.wstate.reserve(1, d.stream);
  d.estate.reserve(1, d.stream);
  d.total.reserve(1, d.stream);
  d.count.reserve(1, d.stream);
  d.count_sums.reserve(2, d.stream);
  d.h_wstate.reserve(1);
  d.h_estate.reserve(1);
  d.h_count.reserve(1);
  d.h_count_sums.reserve(2);
  GMM_MCL_CUDA_CHECK(cudaMemsetAsync(d.counter.data(), 0, sizeof(unsigned), d.stream));
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
  const int groups = d.groupsFor(n_out);
  d.randomOrder(d.n);
  d.drawOffsets(groups);
  d.stratifiedIndices(n_out, groups);
  d.gatherResampled(n_out);
}
int CudaParticleFilter::size() const { return impl_->n; }

const std::vector<Particle>& CudaParticleFilter::particles() const {
  Impl& d = *impl_;
  if (!d.particles_cached) {
    const cuda::DeviceScope scope(d.device);
    d.h_particles.resize(d.n);
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_particles.data(), d.particles.data(),
                                       d.n * sizeof(ParticleState), cudaMemcpyDeviceToHost,
                                       d.stream));
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
    d.particles_cached = true;
  }
  return d.h_particles;
}

const std::vector<double>& CudaParticleFilter::weights() const {
  Impl& d = *impl_;
  if (!d.weights_cached) {
    const cuda::DeviceScope scope(d.device);
    d.h_weights.resize(d.n);
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_weights.data(), d.weights.data(), d.n * sizeof(double),
                                       cudaMemcpyDeviceToHost, d.stream));
    GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
    d.weights_cached = true;
  }
  return d.h_weights;
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
  d.ll_count = 0;
  d.n = 0;  // nothing to keep
  d.reserveParticles(m);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.particles.data(), particles.data(),
                                     m * sizeof(ParticleState), cudaMemcpyHostToDevice, d.stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.weights.data(), w.data(), m * sizeof(double),
                                     cudaMemcpyHostToDevice, d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));  // the host vectors go away
  d.n = m;
  d.frame_ll_valid = false;
  d.have_ws = false;
  d.changed();
}

void CudaParticleFilter::initialiseUniform(const InitRegion& region) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.ll_count = 0;
  d.n = 0;
  d.reserveParticles(d.params.num_particles);
  d.n = d.params.num_particles;
  GMM_MCL_CUDA_CHECK(cuda::launchUniform(d.n, d.nextCall(), toBox(region), d.particles.data(),
                                         d.weights.data(), 1.0 / d.n, d.stream));
  d.augmented.reset();
  d.frame_ll_valid = false;
  d.have_ws = false;
  d.changed();
}

void CudaParticleFilter::initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  d.ll_count = 0;
  d.n = 0;
  d.reserveParticles(d.params.num_particles);
  d.n = d.params.num_particles;
  const ParticleState m{mean.x_m, mean.y_m, mean.z_m, mean.yaw_rad};
  const double s[4] = {sigma[0], sigma[1], sigma[2], sigma[3]};
  GMM_MCL_CUDA_CHECK(cuda::launchGaussian(d.n, d.nextCall(), m, s, d.particles.data(),
                                          d.weights.data(), 1.0 / d.n, d.stream));
  d.augmented.reset();
  d.frame_ll_valid = false;
  d.have_ws = false;
  d.changed();
}

void CudaParticleFilter::predict(const PlanarDelta& delta) {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  cuda::PredictConfig cfg;
  cfg.delta[0] = delta.translation_m.x();
  cfg.delta[1] = delta.translation_m.y();
  cfg.delta[2] = delta.translation_m.z();
  cfg.delta[3] = delta.yaw_rad;
  cfg.sigma_m = d.params.sigma_translation_m;
  cfg.sigma_rad = d.params.sigma_yaw_rad;
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
  GMM_MCL_CUDA_CHECK(cuda::launchSumCounts(d.n, d.evals.data(), d.pairs.data(),
                                           d.count_sums.data(), d.stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_count_sums.data(), d.count_sums.data(),
                                     2 * sizeof(unsigned long long), cudaMemcpyDeviceToHost,
                                     d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
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
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_wstate.data(), d.wstate.data(), sizeof(cuda::WeightState),
                                     cudaMemcpyDeviceToHost, d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  if (d.h_wstate[0].bisect == cuda::kExponentBisected) {
    GMM_MCL_CUDA_CHECK(cuda::launchWeightBisection(d.n, cfg, kBisectionIterations, d.ll.data(),
                                                   d.weights.data(), d.wstate.data(), d.scratch(),
                                                   d.stream));
  }
  GMM_MCL_CUDA_CHECK(cuda::launchWeightFinish(d.n, cfg, d.ll.data(), d.hits.data(),
                                              d.weights.data(), d.w_new.data(), d.wstate.data(),
                                              d.scratch(), d.stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.h_wstate.data(), d.wstate.data(), sizeof(cuda::WeightState),
                                     cudaMemcpyDeviceToHost, d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
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
  const Impl& d = *impl_;
  if (!d.estimate_cached) {
    const cuda::DeviceScope scope(d.device);
    d.computeEstimate();
  }
  return d.estimate_value;
}

double CudaParticleFilter::effectiveSampleSize() const {
  const Impl& d = *impl_;
  if (!d.neff_cached) {
    const cuda::DeviceScope scope(d.device);
    d.computeEstimate();
  }
  return d.neff_value;
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
    const int groups = d.groupsFor(d.n);
    d.randomOrder(d.n);
    d.drawOffsets(groups);
    d.stratifiedIndices(d.n, groups);
    const int bound = kldParticleBound(d.countBins(d.n), p.kld_epsilon, p.kld_z);
    n_out = std::max(p.min_particles, std::min(p.num_particles, bound));
  }
  const int groups = d.groupsFor(n_out);
  d.randomOrder(d.n);
  d.drawOffsets(groups);
  d.stratifiedIndices(n_out, groups);
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
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.values_sorted.data(), order.data(), d.n * sizeof(int),
                                     cudaMemcpyHostToDevice, d.stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.offsets.data(), offsets.data(),
                                     offsets.size() * sizeof(double), cudaMemcpyHostToDevice,
                                     d.stream));
  d.stratifiedIndices(n_out, static_cast<int>(offsets.size()));
  std::vector<int> indices = lastResampleIndices();
  d.gatherResampled(n_out);
  return indices;
}

std::vector<int> CudaParticleFilter::lastResampleIndices() const {
  const Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  std::vector<int> out(d.last_indices);
  if (!out.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(out.data(), d.indices.data(), out.size() * sizeof(int),
                                       cudaMemcpyDeviceToHost, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  return out;
}

int CudaParticleFilter::occupiedBins() const {
  Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  // The identity as indices.
  std::vector<int> iota(d.n);
  for (int i = 0; i < d.n; ++i) iota[i] = i;
  d.indices.reserve(std::max(d.n, 1), d.stream);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.indices.data(), iota.data(), d.n * sizeof(int),
                                     cudaMemcpyHostToDevice, d.stream));
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
                                              toBox(region), d.particles.data(), d.weights.data(),
                                              1.0 / d.n, d.stream));
  d.normaliseWeights();
  d.changed();
  return count;
}

void CudaParticleFilter::clearCandidates() {
  impl_->cand_count = impl_->cand_scored = 0;
}

void CudaParticleFilter::drawUniformCandidates(const InitRegion& region, int n) {
  Impl& d = *impl_;
  if (n <= 0) return;
  const cuda::DeviceScope scope(d.device);
  d.growCandidates(d.cand_count + n);
  GMM_MCL_CUDA_CHECK(cuda::launchUniform(n, d.nextCall(), toBox(region), d.cand.data() + d.cand_count,
                                         nullptr, 0.0, d.stream));
  d.cand_count += n;
}

void CudaParticleFilter::scoreCandidates(const MeasurementContext& ctx) {
  Impl& d = *impl_;
  const int m = d.cand_count - d.cand_scored;
  if (m <= 0) return;
  const cuda::DeviceScope scope(d.device);
  d.growCandidates(d.cand_count);
  d.cand_T_map_cam.reserve(m, d.stream);
  d.cand_T_cam_map.reserve(m, d.stream);
  d.cand_hits.reserve(m, d.stream);
  d.cand_evals.reserve(m, d.stream);
  d.cand_pairs.reserve(m, d.stream);
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
    d.orderByScore(d.cand_ll.data(), d.cand_scored);
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
  d.orderByScore(d.cand_ll.data(), d.cand_scored);
  GMM_MCL_CUDA_CHECK(cuda::launchGather(d.n, d.values_sorted.data(), d.cand.data(), nullptr,
                                        d.particles_swap.data(), nullptr, d.stream));
  std::swap(d.particles, d.particles_swap);
  GMM_MCL_CUDA_CHECK(cuda::launchFill(d.n, 1.0 / d.n, d.weights.data(), d.stream));
  d.ll_count = 0;
  d.frame_ll_valid = false;
  d.have_ws = false;
  d.changed();
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
    GMM_MCL_CUDA_CHECK(cuda::launchGather(keep, d.values_sorted.data(), d.particles.data(),
                                          nullptr, d.particles_swap.data(), nullptr, d.stream));
    GMM_MCL_CUDA_CHECK(cuda::launchGatherValues(keep, d.values_sorted.data(), d.weights.data(),
                                                d.weights_swap.data(), d.stream));
  }
  if (count > 0) {
    d.orderByScore(d.cand_ll.data(), d.cand_scored);
    GMM_MCL_CUDA_CHECK(cuda::launchGather(count, d.values_sorted.data(), d.cand.data(), nullptr,
                                          d.particles_swap.data() + keep, nullptr, d.stream));
    GMM_MCL_CUDA_CHECK(cuda::launchFill(count, 1.0 / n, d.weights_swap.data() + keep, d.stream));
  }
  std::swap(d.particles, d.particles_swap);
  std::swap(d.weights, d.weights_swap);
  d.n = m;
  d.ll_count = 0;  // the frame's likelihoods no longer match the set
  d.frame_ll_valid = false;
  d.have_ws = false;
  d.normaliseWeights();
  d.changed();
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
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.ll.data(), log_likelihood.data(), d.n * sizeof(double),
                                     cudaMemcpyHostToDevice, d.stream));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.hits.data(), floor_hits.data(), d.n * sizeof(int),
                                     cudaMemcpyHostToDevice, d.stream));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  d.ll_count = d.n;
  d.resampled_since_evaluation = false;
  d.frame_ll_valid = true;
  d.have_ws = false;
}

std::vector<double> CudaParticleFilter::frameLogLikelihoods() const {
  const Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  std::vector<double> out(d.ll_count);
  if (!out.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(out.data(), d.ll.data(), out.size() * sizeof(double),
                                       cudaMemcpyDeviceToHost, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  return out;
}

std::vector<Particle> CudaParticleFilter::candidateParticles() const {
  const Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  std::vector<Particle> out(d.cand_count);
  if (!out.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(out.data(), d.cand.data(),
                                       out.size() * sizeof(ParticleState),
                                       cudaMemcpyDeviceToHost, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  return out;
}

std::vector<std::pair<double, Particle>> CudaParticleFilter::candidatePool() const {
  const Impl& d = *impl_;
  const std::vector<Particle> p = candidateParticles();
  const cuda::DeviceScope scope(d.device);
  std::vector<double> ll(d.cand_scored);
  if (!ll.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(ll.data(), d.cand_ll.data(), ll.size() * sizeof(double),
                                       cudaMemcpyDeviceToHost, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
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
  if (m > 0) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.cand.data(), p.data(), m * sizeof(ParticleState),
                                       cudaMemcpyHostToDevice, d.stream));
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(d.cand_ll.data(), ll.data(), m * sizeof(double),
                                       cudaMemcpyHostToDevice, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  d.cand_count = d.cand_scored = m;
}

std::vector<Particle> CudaParticleFilter::candidateCentres() const {
  const Impl& d = *impl_;
  const cuda::DeviceScope scope(d.device);
  std::vector<Particle> out(d.num_centres);
  if (!out.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(out.data(), d.centres.data(),
                                       out.size() * sizeof(ParticleState),
                                       cudaMemcpyDeviceToHost, d.stream));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
  return out;
}

// The factory's entry (particle_filter_factory.cpp): the device filter on the CUDA backend.
std::unique_ptr<ParticleFilterBase> makeCudaParticleFilter(const ParticleFilterParams& params,
                                                           LikelihoodBackend* backend) {
  CudaBackend* cuda_backend = dynamic_cast<CudaBackend*>(backend);
  if (cuda_backend == nullptr) return nullptr;
  return std::unique_ptr<ParticleFilterBase>(new CudaParticleFilter(params, cuda_backend));
}

}  // namespace gmm_mcl
