// The device particle filter's shared steps: buffers, sorts, stratified resampling, KLD bins,
// the estimate's read-back and the scoring of poses on the backend's device frame.
#include "cuda/cuda_particle_filter_impl.h"

#include <Eigen/Geometry>
#include <stdexcept>

#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {

namespace cuda {

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

namespace {

// Grows a device array to at least n elements keeping its first `live` ones (geometric growth).
template <typename T>
void growKeeping(DeviceBuffer<T>* b, size_t n, size_t live, cudaStream_t s) {
  if (n <= b->capacity()) return;
  DeviceBuffer<T> bigger(std::max(n, b->capacity() + b->capacity() / 2));
  if (live > 0) {
    GMM_MCL_CUDA_CHECK(
        cudaMemcpyAsync(bigger.data(), b->data(), live * sizeof(T), cudaMemcpyDeviceToDevice, s));
  }
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(s));
  *b = std::move(bigger);
}

}  // namespace
}  // namespace cuda

CudaParticleFilter::Impl::Impl(const ParticleFilterParams& p, CudaBackend* b)
    : params(p), augmented(p.alpha_slow, p.alpha_fast, p.recovery_threshold) {
  backend = b;
  device = b->deviceOrdinal();
  stream = static_cast<cudaStream_t>(b->streamHandle());
  const cuda::DeviceScope scope(device);
  partials.reserve(size_t(cuda::kReduceBlocks) * cuda::kReduceMaxValues, stream);
  cuda::reserveAll(1, stream, counter, wstate, estate, total, count);
  count_sums.reserve(2, stream);
  h_wstate.reserve(1);
  h_estate.reserve(1);
  h_count.reserve(1);
  h_count_sums.reserve(2);
  GMM_MCL_CUDA_CHECK(cudaMemsetAsync(counter.data(), 0, sizeof(unsigned), stream));
}

void CudaParticleFilter::Impl::reserveParticles(size_t m) {
  if (m <= capacity) return;
  const size_t c = std::max(m, capacity + capacity / 2);
  // The live arrays keep their contents.
  cuda::growKeeping(&particles, c, n, stream);
  cuda::growKeeping(&weights, c, n, stream);
  cuda::growKeeping(&ll, c, ll_count, stream);
  cuda::growKeeping(&ll_follow, c, n, stream);
  cuda::growKeeping(&hits, c, ll_count, stream);
  cuda::reserveAll(c, stream, particles_swap, weights_swap, ll_follow_swap, w_new, evals, pairs,
                   T_map_cam, T_cam_map);
  capacity = c;
}

void CudaParticleFilter::Impl::reserveSort(size_t m) {
  cuda::reserveAll(m, stream, keys32, keys32_sorted, keysf, keysf_sorted, values, values_sorted);
}

void CudaParticleFilter::Impl::randomOrder(int m) {
  reserveSort(m);
  GMM_MCL_CUDA_CHECK(cuda::launchRandomKeys(m, nextCall(), keys32.data(), values.data(), stream));
  runCub([&](void* t, size_t* b) {
    return cuda::sortPairsU32(t, b, keys32.data(), keys32_sorted.data(), values.data(),
                              values_sorted.data(), m, stream);
  });
}

void CudaParticleFilter::Impl::orderByScore(const double* scores, int m) {
  reserveSort(m);
  GMM_MCL_CUDA_CHECK(cuda::launchScoreKeys(m, scores, keysf.data(), values.data(), stream));
  runCub([&](void* t, size_t* b) {
    return cuda::sortPairsDescendingF64(t, b, keysf.data(), keysf_sorted.data(), values.data(),
                                        values_sorted.data(), m, stream);
  });
}

void CudaParticleFilter::Impl::stratifiedIndices(int n_out, int groups) {
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

void CudaParticleFilter::Impl::drawStratifiedIndices(int n_out) {
  const int groups = groupsFor(n_out);
  randomOrder(n);
  drawOffsets(groups);
  stratifiedIndices(n_out, groups);
}

void CudaParticleFilter::Impl::gatherResampled(int n_out) {
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

void CudaParticleFilter::Impl::drawOffsets(int groups) {
  offsets.reserve(groups, stream);
  GMM_MCL_CUDA_CHECK(cuda::launchOffsets(groups, nextCall(), offsets.data(), stream));
}

int CudaParticleFilter::Impl::countBins(int m) {
  bins.reserve(m, stream);
  bins_sorted.reserve(m, stream);
  GMM_MCL_CUDA_CHECK(cuda::launchBinKeys(m, indices.data(), particles.data(),
                                         1.0 / params.kld_bin_m, 1.0 / params.kld_bin_rad,
                                         bins.data(), stream));
  runCub([&](void* t, size_t* b) {
    return cuda::sortKeysU64(t, b, bins.data(), bins_sorted.data(), m, stream);
  });
  GMM_MCL_CUDA_CHECK(cuda::launchCountDistinct(m, bins_sorted.data(), count.data(), stream));
  cuda::copyToHost(h_count.data(), count.data(), 1, stream);
  return h_count[0];
}

void CudaParticleFilter::Impl::normaliseWeights() {
  GMM_MCL_CUDA_CHECK(cuda::launchSum(n, weights.data(), total.data(), scratch(), stream));
  GMM_MCL_CUDA_CHECK(cuda::launchDivide(n, total.data(), weights.data(), stream));
}

void CudaParticleFilter::Impl::computeEstimate() const {
  Impl& d = const_cast<Impl&>(*this);
  GMM_MCL_CUDA_CHECK(cuda::launchEstimate(n, particles.data(), weights.data(), d.estate.data(),
                                          d.scratch(), stream));
  cuda::copyToHost(d.h_estate.data(), estate.data(), 1, stream);
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

void CudaParticleFilter::Impl::growCandidates(int m) {
  cuda::growKeeping(&cand, m, cand_count, stream);
  cuda::growKeeping(&cand_ll, m, cand_scored, stream);
}

void CudaParticleFilter::Impl::scorePoses(const MeasurementContext& ctx, const ParticleState* p,
                                          int m, RigidTransformF* Tm, RigidTransformF* Tc,
                                          double* out_ll, int* out_hits, long long* out_evals,
                                          long long* out_pairs) {
  if (ctx.params == nullptr) throw std::invalid_argument("device particle filter: no parameters");
  if (!backend->hasDeviceFrame()) {
    if (ctx.frame == nullptr) {
      throw std::invalid_argument("device particle filter: no frame (prepareDeviceFrame first)");
    }
    backend->uploadDeviceFrame(*ctx.frame);
  }
  GMM_MCL_CUDA_CHECK(cuda::launchCameraPoses(m, p, cuda::toMount(ctx), Tm, Tc, stream));
  backend->evaluateDevicePoses(m, Tm, Tc, *ctx.params, out_ll, out_hits, out_evals, out_pairs);
}

}  // namespace gmm_mcl
