// The device particle filter's state (CudaParticleFilter::Impl): the set and its frame on the
// device, sort and resampling scratch, the reductions' read-backs, the candidate pool, and the
// steps that the filter's operations share (sorting, stratified resampling, KLD bins, scoring).
// Host code only (the C++ compiler, CUDA runtime API); the kernels are in cuda/filter_kernels.cuh.
#pragma once

#include <cuda_runtime_api.h>

#include <algorithm>
#include <vector>

#include "cuda/cuda_backend.h"
#include "cuda/cuda_particle_filter.h"
#include "cuda/device_buffer.cuh"
#include "cuda/filter_kernels.cuh"
#include "gmm_mcl/filter/particle_filter.h"

namespace gmm_mcl {
namespace cuda {

static_assert(sizeof(Particle) == sizeof(ParticleState), "Particle and ParticleState differ");

RegionBox toBox(const InitRegion& r);
CameraMount toMount(const MeasurementContext& ctx);

}  // namespace cuda

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
  cuda::DeviceBuffer<double> ll_more;  // another camera's (accumulateFrame)
  cuda::DeviceBuffer<int> hits_more;
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

  Impl(const ParticleFilterParams& p, CudaBackend* b);

  cuda::ReduceScratch scratch() { return cuda::ReduceScratch{partials.data(), counter.data()}; }
  cuda::RandomCall nextCall() { return cuda::RandomCall{params.seed, calls++}; }
  void changed() { particles_cached = weights_cached = estimate_cached = neff_cached = false; }
  void weightsChanged() { weights_cached = estimate_cached = neff_cached = false; }
  // The set was replaced: no frame likelihoods, no weight update belong to it any more.
  void setReplaced() {
    frame_ll_valid = false;
    have_ws = false;
    changed();
  }
  // An empty set with room for m particles (the caller fills them and sets n).
  void clearForNewSet(int m) {
    ll_count = 0;
    n = 0;  // nothing to keep
    reserveParticles(m);
  }

  // Every per-particle array holds at least m particles (contents kept only by the caller).
  void reserveParticles(size_t m);
  // Sort scratch for m elements.
  void reserveSort(size_t m);
  // f(temp, bytes): a cub call, once for its scratch size and once to run.
  template <typename F>
  void runCub(F f) {
    size_t bytes = 0;
    GMM_MCL_CUDA_CHECK(f(nullptr, &bytes));
    temp.reserve(std::max<size_t>(bytes, 1), stream);
    GMM_MCL_CUDA_CHECK(f(temp.data(), &bytes));
  }
  // values_sorted[0..m) = 0..m-1 in a random order.
  void randomOrder(int m);
  // values_sorted[0..m) = indices of scores[0..m) by descending score (non-finite last).
  void orderByScore(const double* scores, int m);
  // indices[0..n_out) of the stratified scheme over the current weights, with the order in
  // values_sorted and the offsets in `offsets`.
  void stratifiedIndices(int n_out, int groups);
  // stratifiedIndices over a fresh random order and fresh offsets (ParticleFilter's resampling).
  void drawStratifiedIndices(int n_out);
  // The set becomes particles[indices[0..n_out)], equal weights; each particle's frame
  // likelihood follows its source.
  void gatherResampled(int n_out);
  int groupsFor(int n_out) const { return std::max(1, std::min(params.resample_groups, n_out)); }
  void drawOffsets(int groups);
  // Distinct KLD bins of particles[indices[0..m)].
  int countBins(int m);
  void normaliseWeights();
  // The estimate and Neff on the device, read back (both cached).
  void computeEstimate() const;
  void computeEstimateUnless(bool cached) const {
    if (cached) return;
    const cuda::DeviceScope scope(device);
    computeEstimate();
  }
  void growCandidates(int m);
  // Frame log-likelihoods of m poses p (camera poses in Tm, Tc) on the backend's device frame.
  void scorePoses(const MeasurementContext& ctx, const ParticleState* p, int m, RigidTransformF* Tm,
                  RigidTransformF* Tc, double* out_ll, int* out_hits, long long* out_evals,
                  long long* out_pairs);
  // *out = the first `count` elements of a device array (H: the host type of the same layout),
  // on this filter's device and stream.
  template <typename H, typename T>
  void download(const cuda::DeviceBuffer<T>& device_array, size_t count,
                std::vector<H>* out) const {
    static_assert(sizeof(H) == sizeof(T), "host and device element types differ");
    const cuda::DeviceScope scope(device);
    out->resize(count);
    cuda::copyToHost(out->data(), device_array.data(), count, stream);
  }
  // The host copy *out of a device array, downloaded unless *cached.
  template <typename H, typename T>
  const std::vector<H>& cachedDownload(const cuda::DeviceBuffer<T>& device_array, size_t count,
                                       std::vector<H>* out, bool* cached) const {
    if (!*cached) download(device_array, count, out);
    *cached = true;
    return *out;
  }
  template <typename H, typename T>
  std::vector<H> download(const cuda::DeviceBuffer<T>& device_array, size_t count) const {
    std::vector<H> out;
    download(device_array, count, &out);
    return out;
  }
  // Candidate indices in values_sorted[0..) by descending score.
  void orderCandidates() { orderByScore(cand_ll.data(), cand_scored); }
};

}  // namespace gmm_mcl
