// Device helpers of the device particle filter's kernels (filter_*_kernels.cu): the block size,
// a launcher over n threads, and deterministic reductions. Reductions are deterministic: each
// block reduces its elements in a fixed tree, and the last block to finish (elected by an atomic
// ticket) adds the blocks' partials in block order, so a result depends on n only, not on
// timing. nvcc only.
#pragma once

#include <math.h>

#include "cuda/filter_kernels.cuh"

namespace gmm_mcl {
namespace cuda {

constexpr int kThreads = 256;

inline int blocksFor(int n) { return (n + kThreads - 1) / kThreads; }
inline int reduceBlocksFor(int n) {
  const int b = blocksFor(n);
  return b < 1 ? 1 : (b > kReduceBlocks ? kReduceBlocks : b);
}

// kernel<<<blocksFor(n), kThreads>>>(args...) on `stream`; nothing when n <= 0.
template <typename... Params, typename... Args>
cudaError_t launchOver(int n, cudaStream_t stream, void (*kernel)(Params...), Args... args) {
  if (n <= 0) return cudaSuccess;
  kernel<<<blocksFor(n), kThreads, 0, stream>>>(args...);
  return cudaGetLastError();
}

// ---- deterministic reductions of K doubles ----------------------------------------------------

template <int K>
struct Vec {
  double v[K];
};

// Tree reduction of one value per thread (all kThreads threads call it).
template <int K, typename Op>
__device__ Vec<K> blockReduce(const Vec<K>& mine, const Op& op) {
  __shared__ double s[K][kThreads];
  for (int k = 0; k < K; ++k) s[k][threadIdx.x] = mine.v[k];
  __syncthreads();
  for (int width = kThreads / 2; width > 0; width >>= 1) {
    if (threadIdx.x < width) {
      Vec<K> a, b;
      for (int k = 0; k < K; ++k) {
        a.v[k] = s[k][threadIdx.x];
        b.v[k] = s[k][threadIdx.x + width];
      }
      op(&a, b);
      for (int k = 0; k < K; ++k) s[k][threadIdx.x] = a.v[k];
    }
    __syncthreads();
  }
  Vec<K> out;
  for (int k = 0; k < K; ++k) out.v[k] = s[k][0];
  __syncthreads();  // s is reused by the next call
  return out;
}

// Grid-wide reduction: true in the last block to finish, whose *result is the reduction of every
// block's value in block order (all its threads get it).
template <int K, typename Op>
__device__ bool gridReduce(const Vec<K>& mine, const Vec<K>& identity, const Op& op,
                           const ReduceScratch& scratch, Vec<K>* result) {
  static_assert(K <= kReduceMaxValues, "too many values per partial");
  const Vec<K> b = blockReduce<K>(mine, op);
  __shared__ bool s_last;
  if (threadIdx.x == 0) {
    for (int k = 0; k < K; ++k) scratch.partials[blockIdx.x * kReduceMaxValues + k] = b.v[k];
    __threadfence();
    const unsigned ticket = atomicInc(scratch.counter, gridDim.x - 1);  // wraps to 0: reset
    s_last = ticket == gridDim.x - 1;
  }
  __syncthreads();
  if (!s_last) return false;
  __threadfence();
  Vec<K> acc = identity;
  for (int blk = threadIdx.x; blk < static_cast<int>(gridDim.x); blk += kThreads) {
    Vec<K> x;
    for (int k = 0; k < K; ++k) x.v[k] = __ldcg(&scratch.partials[blk * kReduceMaxValues + k]);
    op(&acc, x);
  }
  *result = blockReduce<K>(acc, op);
  return true;
}

template <int K>
struct SumOp {
  __device__ void operator()(Vec<K>* a, const Vec<K>& b) const {
    for (int k = 0; k < K; ++k) a->v[k] += b.v[k];
  }
};

template <int K>
__device__ Vec<K> zeros() {
  Vec<K> z;
  for (int k = 0; k < K; ++k) z.v[k] = 0.0;
  return z;
}

}  // namespace cuda
}  // namespace gmm_mcl
