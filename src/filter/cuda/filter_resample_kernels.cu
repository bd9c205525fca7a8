// Resampling and selection kernels of the device particle filter: the stratified low-variance
// indices over a permuted, scaled cumulative sum, the KLD bins and their count, gathers, and the
// keys of a sort by score.
#include <math.h>

#include "cuda/filter_device.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

// ---- resampling -------------------------------------------------------------------------------

__global__ void __launch_bounds__(kThreads)
    permuteScaledKernel(int n, const int* __restrict__ order, const double* __restrict__ w,
                        const double* __restrict__ total, int n_out, double* __restrict__ out) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= n) return;
  const double scale = n_out / total[0];
  out[j] = w[order[j]] * scale;
}

__global__ void __launch_bounds__(kThreads)
    stratifiedKernel(int n, int n_out, int groups,
                     const double* __restrict__ cumulative,  // [n] inclusive, scaled to n_out
                     const int* __restrict__ order,          // [n]
                     const double* __restrict__ offsets,     // [groups] in [0, 1)
                     int* __restrict__ indices) {            // [n_out]
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n_out) return;
  // Groups of q + 1 outputs first (r of them), then groups of q.
  const int q = n_out / groups, r = n_out % groups;
  const int g = k < r * (q + 1) ? k / (q + 1) : r + (k - r * (q + 1)) / q;
  const double u = k + offsets[g];
  int lo = 0, hi = n;  // first j with cumulative[j] > u
  while (lo < hi) {
    const int mid = (lo + hi) >> 1;
    if (cumulative[mid] <= u) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  indices[k] = order[lo < n - 1 ? lo : n - 1];
}

__global__ void __launch_bounds__(kThreads)
    binKeysKernel(int n, const int* __restrict__ indices, const ParticleState* __restrict__ p,
                  double inv_bin_m, double inv_bin_rad, uint64_t* __restrict__ keys) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) keys[k] = kldBinKey(p[indices[k]], inv_bin_m, inv_bin_rad);
}

__global__ void __launch_bounds__(kThreads)
    countDistinctKernel(int n, const uint64_t* __restrict__ sorted, int* __restrict__ count) {
  __shared__ int s_count;
  if (threadIdx.x == 0) s_count = 0;
  __syncthreads();
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n && (k == 0 || sorted[k] != sorted[k - 1])) atomicAdd(&s_count, 1);
  __syncthreads();
  if (threadIdx.x == 0 && s_count > 0) atomicAdd(count, s_count);  // integer: order-free
}

__global__ void __launch_bounds__(kThreads)
    gatherKernel(int n, const int* __restrict__ indices, const ParticleState* __restrict__ in,
                 const double* __restrict__ in_ll, ParticleState* __restrict__ out,
                 double* __restrict__ out_ll) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const int src = indices[k];
  out[k] = in[src];
  if (in_ll) out_ll[k] = in_ll[src];
}

__global__ void __launch_bounds__(kThreads)
    gatherValuesKernel(int n, const int* __restrict__ indices, const double* __restrict__ in,
                       double* __restrict__ out) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) out[k] = in[indices[k]];
}

__global__ void __launch_bounds__(kThreads)
    scoreKeysKernel(int n, const double* __restrict__ ll, double* __restrict__ keys,
                    int* __restrict__ values) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const double l = ll[i];
  keys[i] = isfinite(l) ? l : -INFINITY;
  values[i] = i;
}

}  // namespace

// ---- launchers --------------------------------------------------------------------------------

cudaError_t launchPermuteScaled(int n, const int* order, const double* w, const double* total,
                                int n_out, double* out, cudaStream_t stream) {
  return launchOver(n, stream, permuteScaledKernel, n, order, w, total, n_out, out);
}

cudaError_t launchStratifiedIndices(int n, int n_out, int groups, const double* cumulative,
                                    const int* order, const double* offsets, int* indices,
                                    cudaStream_t stream) {
  if (n <= 0 || n_out <= 0 || groups <= 0) return cudaSuccess;
  stratifiedKernel<<<blocksFor(n_out), kThreads, 0, stream>>>(n, n_out, groups, cumulative, order,
                                                              offsets, indices);
  return cudaGetLastError();
}

cudaError_t launchBinKeys(int n, const int* indices, const ParticleState* particles,
                          double inv_bin_m, double inv_bin_rad, uint64_t* keys,
                          cudaStream_t stream) {
  return launchOver(n, stream, binKeysKernel, n, indices, particles, inv_bin_m, inv_bin_rad, keys);
}

cudaError_t launchCountDistinct(int n, const uint64_t* sorted_keys, int* count,
                                cudaStream_t stream) {
  cudaError_t err = cudaMemsetAsync(count, 0, sizeof(int), stream);
  if (err != cudaSuccess || n <= 0) return err;
  countDistinctKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, sorted_keys, count);
  return cudaGetLastError();
}

cudaError_t launchGather(int n, const int* indices, const ParticleState* in, const double* in_ll,
                         ParticleState* out, double* out_ll, cudaStream_t stream) {
  return launchOver(n, stream, gatherKernel, n, indices, in, in_ll, out, out_ll);
}

cudaError_t launchGatherValues(int n, const int* indices, const double* in, double* out,
                               cudaStream_t stream) {
  return launchOver(n, stream, gatherValuesKernel, n, indices, in, out);
}

cudaError_t launchScoreKeys(int n, const double* ll, double* keys, int* values,
                            cudaStream_t stream) {
  return launchOver(n, stream, scoreKeysKernel, n, ll, keys, values);
}

}  // namespace cuda
}  // namespace gmm_mcl
