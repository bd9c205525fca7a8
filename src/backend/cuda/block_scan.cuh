// Block-wide exclusive prefix sums over rounds of blockDim.x values, for a kernel of one block
// (blockDim.x a multiple of 32, at most 1024): the frame preparation's patch offsets and the view
// cull's compaction.
#pragma once

#include <cuda_runtime.h>

namespace gmm_mcl {
namespace cuda {

// A scan's shared memory: the per-warp totals of the round and the sum of all earlier rounds.
struct BlockScan {
  int warp_totals[32];
  int carry;
};

// Before the first round (every thread of the block).
__device__ __forceinline__ void blockScanBegin(BlockScan* s) {
  if (threadIdx.x == 0) s->carry = 0;
  __syncthreads();
}

// One round (every thread of the block): the sum of the values v of the earlier threads of this
// round and of every earlier round. After the last round, s->carry is the sum of them all.
__device__ __forceinline__ int blockScanRound(int v, BlockScan* s) {
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  int incl = v;
#pragma unroll
  for (int off = 1; off < 32; off <<= 1) {
    const int t = __shfl_up_sync(0xffffffffu, incl, off);
    if (lane >= off) incl += t;
  }
  if (lane == 31) s->warp_totals[warp] = incl;
  __syncthreads();
  if (warp == 0) {
    const int nw = blockDim.x >> 5;
    int w = lane < nw ? s->warp_totals[lane] : 0;
#pragma unroll
    for (int off = 1; off < 32; off <<= 1) {
      const int t = __shfl_up_sync(0xffffffffu, w, off);
      if (lane >= off) w += t;
    }
    if (lane < nw) s->warp_totals[lane] = w;  // inclusive per-warp totals
  }
  __syncthreads();
  const int excl = s->carry + (warp > 0 ? s->warp_totals[warp - 1] : 0) + incl - v;
  __syncthreads();  // every thread has read the carry and the totals
  if (threadIdx.x == blockDim.x - 1) s->carry = excl + v;
  __syncthreads();
  return excl;
}

}  // namespace cuda
}  // namespace gmm_mcl
