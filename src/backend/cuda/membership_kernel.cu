// Projection of every component for every particle and the patch membership bitmasks.
// One block per particle; the bitmask of the whole patch grid is built in shared memory with
// atomicOr and written out coalesced. Same math as the CPU (gmm_mcl/measurement/projection.h).
#include <math.h>

#include <algorithm>
#include <mutex>

#include "cuda/block_scan.cuh"
#include "cuda/kernels.cuh"
#include "gmm_mcl/measurement/depth_noise.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kMaxDevices = 64;  // devices with their own shared-memory limit

constexpr int kMembershipThreads = 256;
// Survivors of the cull queued per warp (at most 31 waiting + 32 new).
constexpr int kQueuePerWarp = 64;
// Blocks per multiprocessor the register allocation must allow (five ~40 KB bitmasks fit in an
// H100's shared memory); sm_75 runs at most 1024 threads per multiprocessor.
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ == 750
constexpr int kMembershipMinBlocks = 4;
#else
constexpr int kMembershipMinBlocks = 5;
#endif

// Order-preserving map of a float onto a signed int (for atomicMax on floats of any sign).
__device__ __forceinline__ int floatToOrderedInt(float f) {
  const int b = __float_as_int(f);
  return b >= 0 ? b : b ^ 0x7fffffff;
}
__device__ __forceinline__ float orderedIntToFloat(int k) {
  return __int_as_float(k >= 0 ? k : k ^ 0x7fffffff);
}

// The view cull's tests of one component for one pose (membership and the local count).
__device__ __forceinline__ bool componentKept(const ComponentF& c, const RigidTransformF& T,
                                              const MembershipConfig& cfg) {
  return componentMayTouchGrid(c, T, cfg.cam.K, cfg.cam.patch_size_px, cfg.cam.patch_cols,
                               cfg.cam.patch_rows, cfg.min_depth_m, cfg.sigma_bound,
                               cfg.inflate_px) &&
         componentInView(c, T, cfg.cam.K, cfg.reach, cfg.sigma_bound);
}

// Whether chunk ch of the set (components [ch * kComponentChunk, ...)) may hold a component in
// the pose's view volume: its bounding ball (chunkSpheresKernel) against the view's planes.
// Without chunk balls (null) every chunk may.
__device__ __forceinline__ bool chunkMaySee(const float4* __restrict__ chunks, int ch,
                                            const RigidTransformF& T, const MembershipConfig& cfg) {
  if (chunks == nullptr) return true;
  const float4 q = chunks[ch];
  if (q.w < 0.f) return false;  // an empty chunk
  const float c[3] = {q.x, q.y, q.z};
  float m[3];
  transformPoint(T, c, m);
  return ballInView(m[0], m[1], m[2], q.w + cfg.reach.margin_m, cfg.cam.K, cfg.reach);
}

// The chunks of [chunk_begin, chunk_end) that the pose may see, a window of up to blockDim.x of
// them at a time, in ascending order: visit(chunk) for each, called by every thread of the block
// alike (block-uniform), so that it may synchronise the block. `seen` is shared memory for
// blockDim.x chunk indices, `scan` a BlockScan in shared memory.
template <typename Visit>
__device__ __forceinline__ void forSeenChunks(int chunk_begin, int chunk_end,
                                              const float4* __restrict__ chunks,
                                              const RigidTransformF& T, const MembershipConfig& cfg,
                                              int* seen, BlockScan* scan, Visit visit) {
  for (int win = chunk_begin; win < chunk_end; win += blockDim.x) {
    const int ch = win + threadIdx.x;
    const bool in = ch < chunk_end && chunkMaySee(chunks, ch, T, cfg);
    blockScanBegin(scan);
    const int at = blockScanRound(in ? 1 : 0, scan);
    if (in) seen[at] = ch;
    __syncthreads();
    const int count = scan->carry;
    for (int k = 0; k < count; ++k) visit(seen[k]);
    __syncthreads();  // seen[] and the scan are reused by the next window
  }
}

// The largest number of the set's components one pose keeps (atomicMax into *most, which the
// caller zeroes). One block per pose; the chunks it cannot see are skipped.
__global__ void __launch_bounds__(kMembershipThreads)
    localCountKernel(int num_particles, int num_components, MembershipConfig cfg,
                     const ComponentF* __restrict__ components, const float4* __restrict__ chunks,
                     const RigidTransformF* __restrict__ T_cam_map, int* most) {
  __shared__ int warp_counts[kMembershipThreads / 32];
  __shared__ int seen[kMembershipThreads];
  __shared__ BlockScan scan;
  const int particle = blockIdx.x;
  if (particle >= num_particles) return;
  const RigidTransformF T = T_cam_map[particle];
  int count = 0;
  const int chunk_end = (num_components + kComponentChunk - 1) / kComponentChunk;
  forSeenChunks(0, chunk_end, chunks, T, cfg, seen, &scan, [&](int ch) {
    const int i = ch * kComponentChunk + static_cast<int>(threadIdx.x);
    count += i < num_components && componentKept(components[i], T, cfg) ? 1 : 0;
  });
#pragma unroll
  for (int off = 16; off > 0; off >>= 1) count += __shfl_down_sync(0xffffffffu, count, off);
  if ((threadIdx.x & 31) == 0) warp_counts[threadIdx.x >> 5] = count;
  __syncthreads();
  if (threadIdx.x == 0) {
    int total = 0;
    for (int w = 0; w < kMembershipThreads / 32; ++w) total += warp_counts[w];
    atomicMax(most, total);
  }
}

// The bounding ball of each chunk of kComponentChunk components (one block per chunk): the
// centre of its means' box, and the largest distance from it to a mean plus that component's
// sigma_bound sqrt(trace) (the radius componentInView uses), with a slack for rounding; radius -1
// for a chunk past the count (*count where given, else num_components).
__global__ void __launch_bounds__(kComponentChunk)
    chunkSpheresKernel(int num_components, const int* __restrict__ count,
                       const ComponentF* __restrict__ components, float sigma_bound,
                       float4* __restrict__ out) {
  __shared__ float part[6][kComponentChunk / 32];
  __shared__ float centre[3];
  const int n = count ? min(*count, num_components) : num_components;
  const int first = blockIdx.x * kComponentChunk;
  if (first >= n) {
    if (threadIdx.x == 0) out[blockIdx.x] = make_float4(0.f, 0.f, 0.f, -1.f);
    return;
  }
  const int i = first + static_cast<int>(threadIdx.x);
  const bool has = i < n;
  const ComponentF c = components[has ? i : first];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = hi[a] = c.mean_m[a];
#pragma unroll
    for (int off = 16; off > 0; off >>= 1) {
      lo[a] = fminf(lo[a], __shfl_xor_sync(0xffffffffu, lo[a], off));
      hi[a] = fmaxf(hi[a], __shfl_xor_sync(0xffffffffu, hi[a], off));
    }
    if (lane == 0) {
      part[a][warp] = lo[a];
      part[3 + a][warp] = hi[a];
    }
  }
  __syncthreads();
  if (threadIdx.x < 3) {
    const int a = threadIdx.x;
    float l = part[a][0], h = part[3 + a][0];
    for (int w = 1; w < kComponentChunk / 32; ++w) {
      l = fminf(l, part[a][w]);
      h = fmaxf(h, part[3 + a][w]);
    }
    centre[a] = 0.5f * (l + h);
  }
  __syncthreads();
  const float dx = c.mean_m[0] - centre[0], dy = c.mean_m[1] - centre[1],
              dz = c.mean_m[2] - centre[2];
  float r = has ? sqrtf(dx * dx + dy * dy + dz * dz) +
                      sigma_bound * sqrtf(c.cov_m2[0] + c.cov_m2[3] + c.cov_m2[5])
                : 0.f;
#pragma unroll
  for (int off = 16; off > 0; off >>= 1) r = fmaxf(r, __shfl_xor_sync(0xffffffffu, r, off));
  __syncthreads();  // part[] is reused
  if (lane == 0) part[0][warp] = r;
  __syncthreads();
  if (threadIdx.x == 0) {
    float rmax = part[0][0];
    for (int w = 1; w < kComponentChunk / 32; ++w) rmax = fmaxf(rmax, part[0][w]);
    // Rounding of the transforms and plane tests is far below a millimetre at a kilometre.
    out[blockIdx.x] = make_float4(centre[0], centre[1], centre[2], rmax * 1.00001f + 1e-3f);
  }
}

// The membership kernel of a tracking cloud: every component of the set tested in rounds, no
// local lists or chunks. It repeats membershipKernel's projection on purpose: it is the kernel
// of the earlier version unchanged (its sm_90 machine code byte for byte), since the general
// kernel with local lists and chunks off ran the `paper` workload's membership in 0.145 ms
// against 0.104 ms on an H100, and sharing the projection as an inlined function changed 1,051
// of its 1,568 instructions (not measured on a GPU, so not kept).
__global__ void __launch_bounds__(kMembershipThreads, kMembershipMinBlocks)
    plainMembershipKernel(int num_particles, int num_components, int words, int pass_words,
                          MembershipConfig cfg,
                          const ComponentF* __restrict__ components,      // [M], map frame, metres
                          const EvalComponentF* __restrict__ eval,        // [M], log2 form
                          const RigidTransformF* __restrict__ T_cam_map,  // [N]
                          uint32_t* __restrict__ mask_out,                // [N][patches][words]
                          float* __restrict__ shift_out,                  // [N][passes][patches]
                          EvalComponentF* __restrict__ eval_out) {        // [N][M] (depth noise on)
  extern __shared__ uint32_t smem[];
  const int particle = blockIdx.x;
  if (particle >= num_particles) return;
  // Pass blockIdx.y: bitmask words [w0, w0 + nw) of every patch, components [c_begin, c_end).
  const int pass = blockIdx.y;
  const int w0 = pass * pass_words;
  const int nw = min(pass_words, words - w0);
  const int c_begin = w0 * 32;
  const int c_end = min(num_components, (w0 + nw) * 32);
  const int patches = cfg.cam.patch_cols * cfg.cam.patch_rows;
  uint32_t* mask = smem;                                         // [patches][nw]
  int* shift_key = reinterpret_cast<int*>(smem + patches * nw);  // [patches]
  for (int i = threadIdx.x; i < patches * nw; i += blockDim.x) mask[i] = 0u;
  const int floor_key = floatToOrderedInt(cfg.floor_log_density);
  for (int i = threadIdx.x; i < patches; i += blockDim.x) shift_key[i] = floor_key;
  __syncthreads();

  const RigidTransformF T = T_cam_map[particle];
  const float ps = static_cast<float>(cfg.cam.patch_size_px);
  const float c0 = 0.5f * (ps - 1.f);  // centre of patch 0, as PatchGrid::centreU
  // Cull 32 components per warp (one per lane), queue the survivors in shared memory and
  // project them 32 at a time, so that the projection and the box tests run with full warps
  // instead of the few lanes whose component survived the cull.
  const int lane = threadIdx.x & 31;
  int* queue = shift_key + patches + (threadIdx.x >> 5) * kQueuePerWarp;  // [kQueuePerWarp]
  int queued = 0;                                                         // warp-uniform
  const int rounds = (c_end - c_begin + blockDim.x - 1) / blockDim.x;
  for (int round = 0; round < rounds; ++round) {
    const int i = c_begin + round * blockDim.x + threadIdx.x;
    // The view cull's tests: no patch centre within reach, or outside the view volume (as the
    // CPU backend's cull before its membership): no projection.
    const bool keep = i < c_end &&
                      componentMayTouchGrid(components[i], T, cfg.cam.K, cfg.cam.patch_size_px,
                                            cfg.cam.patch_cols, cfg.cam.patch_rows, cfg.min_depth_m,
                                            cfg.sigma_bound, cfg.inflate_px) &&
                      componentInView(components[i], T, cfg.cam.K, cfg.reach, cfg.sigma_bound);
    const uint32_t ballot = __ballot_sync(0xffffffffu, keep);
    if (keep) queue[queued + __popc(ballot & ((1u << lane) - 1u))] = i;
    queued += __popc(ballot);
    __syncwarp();
    while (queued >= 32 || (round == rounds - 1 && queued > 0)) {
      const int cnt = min(queued, 32);
      const int j = lane < cnt ? queue[lane] : -1;
      __syncwarp();
      if (lane + 32 < queued) queue[lane] = queue[lane + 32];
      __syncwarp();
      queued -= cnt;
      if (j < 0) continue;
      const ComponentF c = components[j];
      ProjectedComponent p;
      if (!projectComponent(c, T, cfg.cam.K, cfg.min_depth_m, cfg.sigma_bound, cfg.inflate_px,
                            &p)) {
        continue;
      }
      // Candidate patches from the inflated ellipse's bounding box (as computeMembership).
      const int col0 = max(0, static_cast<int>(ceilf((p.u_px - p.half_w_px - c0) / ps)));
      const int col1 =
          min(cfg.cam.patch_cols - 1, static_cast<int>(floorf((p.u_px + p.half_w_px - c0) / ps)));
      const int row0 = max(0, static_cast<int>(ceilf((p.v_px - p.half_h_px - c0) / ps)));
      const int row1 =
          min(cfg.cam.patch_rows - 1, static_cast<int>(floorf((p.v_px + p.half_h_px - c0) / ps)));
      const uint32_t bit = 1u << (j & 31);
      const int word = (j >> 5) - w0;
      float log_norm = c.log_norm;
      if (eval_out) {
        // The depth noise convolved into this pose's evaluation form (as the CPU backend).
        EvalComponentF e;
        if (!makeNoisyEvalComponent(c, T, cfg.depth_noise, kEvalScaleLog2, &e)) e = eval[j];
        eval_out[static_cast<size_t>(particle) * num_components + j] = e;
        log_norm = e.log_norm;
      }
      const int key = floatToOrderedInt(log_norm);
      for (int r = row0; r <= row1; ++r) {
        const float v = static_cast<float>(r * cfg.cam.patch_size_px) + c0;
        for (int col = col0; col <= col1; ++col) {
          const float u = static_cast<float>(col * cfg.cam.patch_size_px) + c0;
          if (ellipseContains(p, u, v)) {
            const int patch = r * cfg.cam.patch_cols + col;
            atomicOr(&mask[patch * nw + word], bit);
            atomicMax(&shift_key[patch], key);
          }
        }
      }
    }
  }
  __syncthreads();
  uint32_t* out = mask_out + static_cast<size_t>(particle) * patches * words;
  if (nw == words) {
    for (int i = threadIdx.x; i < patches * words; i += blockDim.x) out[i] = mask[i];
  } else {
    for (int i = threadIdx.x; i < patches * nw; i += blockDim.x) {
      const int patch = i / nw;
      out[patch * words + w0 + (i - patch * nw)] = mask[i];
    }
  }
  float* shift = shift_out + (static_cast<size_t>(particle) * gridDim.y + pass) * patches;
  for (int i = threadIdx.x; i < patches; i += blockDim.x)
    shift[i] = orderedIntToFloat(shift_key[i]);
}

// The layout of the membership kernel's shared memory after the bitmask and the shifts: the
// per-warp queues of component indices, with local lists their bits, with local lists or chunks
// the scans, with chunks the seen chunks. Sized by what is used, so that the plain kernel keeps
// its occupancy (five ~40 KB blocks per multiprocessor of an H100).
struct MembershipTail {
  size_t queue, queue_bit, scans, seen, end;  // ints from the tail's start
  __host__ __device__ MembershipTail(bool local, bool chunked) {
    const size_t q = (kMembershipThreads / 32) * kQueuePerWarp;
    const size_t scan_ints = sizeof(BlockScan) / sizeof(int);
    queue = 0;
    queue_bit = q;
    scans = queue_bit + (local ? q : 0);
    seen = scans + (local || chunked ? 2 * scan_ints : 0);
    end = seen + (chunked ? kMembershipThreads : 0);
  }
};

template <bool CHUNKED>
__global__ void __launch_bounds__(kMembershipThreads, kMembershipMinBlocks)
    membershipKernel(int num_particles, int num_components, int words, int pass_words,
                     int local_stride, MembershipConfig cfg,
                     const ComponentF* __restrict__ components,      // [M], map frame, metres
                     const float4* __restrict__ chunks,              // [M / chunk] or null
                     const EvalComponentF* __restrict__ eval,        // [M], log2 form
                     const RigidTransformF* __restrict__ T_cam_map,  // [N]
                     uint32_t* __restrict__ mask_out,                // [N][patches][words]
                     float* __restrict__ shift_out,                  // [N][passes][patches]
                     EvalComponentF* __restrict__ eval_out) {        // [N][M] or [N][local_stride]
  extern __shared__ uint32_t smem[];
  const int particle = blockIdx.x;
  if (particle >= num_particles) return;
  // Pass blockIdx.y: bitmask words [w0, w0 + nw) of every patch, components [c_begin, c_end).
  const int pass = blockIdx.y;
  const int w0 = pass * pass_words;
  const int nw = min(pass_words, words - w0);
  // Bits [lo, hi) of the pass: of the set's components (c_begin.. c_end), or of the pose's own
  // list of the components it keeps (local lists: every pass tests the whole set).
  const bool local = local_stride > 0;
  const int lo = w0 * 32, hi = (w0 + nw) * 32;
  const int c_begin = local ? 0 : lo;
  const int c_end = local ? num_components : min(num_components, hi);
  const int patches = cfg.cam.patch_cols * cfg.cam.patch_rows;
  uint32_t* mask = smem;                                         // [patches][nw]
  int* shift_key = reinterpret_cast<int*>(smem + patches * nw);  // [patches]
  for (int i = threadIdx.x; i < patches * nw; i += blockDim.x) mask[i] = 0u;
  const int floor_key = floatToOrderedInt(cfg.floor_log_density);
  for (int i = threadIdx.x; i < patches; i += blockDim.x) shift_key[i] = floor_key;
  __syncthreads();

  const RigidTransformF T = T_cam_map[particle];
  const float ps = static_cast<float>(cfg.cam.patch_size_px);
  const float c0 = 0.5f * (ps - 1.f);  // centre of patch 0, as PatchGrid::centreU
  // Cull 32 components per warp (one per lane), queue the survivors in shared memory and
  // project them 32 at a time, so that the projection and the box tests run with full warps
  // instead of the few lanes whose component survived the cull.
  const int lane = threadIdx.x & 31;
  const MembershipTail L(local, CHUNKED);
  int* tail = shift_key + patches;
  int* queue = tail + L.queue + (threadIdx.x >> 5) * kQueuePerWarp;          // [kQueuePerWarp]
  int* queue_bit = tail + L.queue_bit + (threadIdx.x >> 5) * kQueuePerWarp;  // local lists
  BlockScan* scan = reinterpret_cast<BlockScan*>(tail + L.scans);
  BlockScan* chunk_scan = scan + 1;
  int* seen = tail + L.seen;  // [kMembershipThreads], chunks
  int queued = 0;             // warp-uniform
  // Projects the queued components (32 at a time) while at least `least` are queued.
  auto drain = [&](int least) {
    while (queued >= least) {
      const int cnt = min(queued, 32);
      const int j = lane < cnt ? queue[lane] : -1;
      const int jb = lane < cnt ? (local ? queue_bit[lane] : j) : -1;
      __syncwarp();
      if (lane + 32 < queued) {
        queue[lane] = queue[lane + 32];
        if (local) queue_bit[lane] = queue_bit[lane + 32];
      }
      __syncwarp();
      queued -= cnt;
      if (j < 0) continue;
      const ComponentF c = components[j];
      ProjectedComponent p;
      if (!projectComponent(c, T, cfg.cam.K, cfg.min_depth_m, cfg.sigma_bound, cfg.inflate_px,
                            &p)) {
        continue;
      }
      // Candidate patches from the inflated ellipse's bounding box (as computeMembership).
      const int col0 = max(0, static_cast<int>(ceilf((p.u_px - p.half_w_px - c0) / ps)));
      const int col1 =
          min(cfg.cam.patch_cols - 1, static_cast<int>(floorf((p.u_px + p.half_w_px - c0) / ps)));
      const int row0 = max(0, static_cast<int>(ceilf((p.v_px - p.half_h_px - c0) / ps)));
      const int row1 =
          min(cfg.cam.patch_rows - 1, static_cast<int>(floorf((p.v_px + p.half_h_px - c0) / ps)));
      const uint32_t bit = 1u << (jb & 31);
      const int word = (jb >> 5) - w0;
      float log_norm = c.log_norm;
      if (eval_out) {
        // The depth noise convolved into this pose's evaluation form (as the CPU backend); with
        // local lists the pose's own copy of the form even without the noise.
        EvalComponentF e = eval[j];
        if (cfg.depth_noise.a_m > 0.f || cfg.depth_noise.b_per_m > 0.f) {
          if (!makeNoisyEvalComponent(c, T, cfg.depth_noise, kEvalScaleLog2, &e)) e = eval[j];
          log_norm = e.log_norm;
        }
        eval_out[static_cast<size_t>(particle) * (local ? local_stride : num_components) + jb] = e;
      }
      const int key = floatToOrderedInt(log_norm);
      for (int r = row0; r <= row1; ++r) {
        const float v = static_cast<float>(r * cfg.cam.patch_size_px) + c0;
        for (int col = col0; col <= col1; ++col) {
          const float u = static_cast<float>(col * cfg.cam.patch_size_px) + c0;
          if (ellipseContains(p, u, v)) {
            const int patch = r * cfg.cam.patch_cols + col;
            atomicOr(&mask[patch * nw + word], bit);
            atomicMax(&shift_key[patch], key);
          }
        }
      }
    }
  };
  // One round of the block's threads over components [first, first + blockDim.x).
  auto round = [&](int first) {
    const int i = first + static_cast<int>(threadIdx.x);
    // The view cull's tests: no patch centre within reach, or outside the view volume (as the
    // CPU backend's cull before its membership): no projection.
    bool keep = i >= c_begin && i < c_end && componentKept(components[i], T, cfg);
    // The component's bit: its set index, or its place in the pose's own list (ascending in
    // the set's order, so that the members are summed in the same order either way).
    int b = i;
    if (local) {
      b = blockScanRound(keep ? 1 : 0, scan);
      keep = keep && b >= lo && b < hi;
    }
    const uint32_t ballot = __ballot_sync(0xffffffffu, keep);
    if (keep) {
      const int at = queued + __popc(ballot & ((1u << lane) - 1u));
      queue[at] = i;
      if (local) queue_bit[at] = b;
    }
    queued += __popc(ballot);
    __syncwarp();
    drain(32);
  };
  if (local) blockScanBegin(scan);
  if (CHUNKED) {
    // One round per chunk of the set the pose may see (its bounding ball in the view volume).
    const int chunk_begin = c_begin / kComponentChunk;
    const int chunk_end = (c_end + kComponentChunk - 1) / kComponentChunk;
    forSeenChunks(chunk_begin, chunk_end, chunks, T, cfg, seen, chunk_scan,
                  [&](int ch) { round(ch * kComponentChunk); });
  } else {
    for (int first = c_begin; first < c_end; first += blockDim.x) round(first);
  }
  drain(1);
  __syncthreads();
  uint32_t* out = mask_out + static_cast<size_t>(particle) * patches * words;
  if (nw == words) {
    for (int i = threadIdx.x; i < patches * words; i += blockDim.x) out[i] = mask[i];
  } else {
    for (int i = threadIdx.x; i < patches * nw; i += blockDim.x) {
      const int patch = i / nw;
      out[patch * words + w0 + (i - patch * nw)] = mask[i];
    }
  }
  float* shift = shift_out + (static_cast<size_t>(particle) * gridDim.y + pass) * patches;
  for (int i = threadIdx.x; i < patches; i += blockDim.x)
    shift[i] = orderedIntToFloat(shift_key[i]);
}

// shift[n][p] = max over the passes of pass_shift[n][q][p].
__global__ void combineShiftKernel(int count, int patches, int passes,
                                   const float* __restrict__ pass_shift,
                                   float* __restrict__ shift) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= count) return;
  const int n = i / patches, p = i - n * patches;
  const float* src = pass_shift + static_cast<size_t>(n) * passes * patches + p;
  float s = src[0];
  for (int q = 1; q < passes; ++q) s = fmaxf(s, src[q * patches]);
  shift[i] = s;
}

// Per-update view cull: visible[t] = 1 when componentMayTouchGrid holds for the t-th tested
// component (candidates[t], or component t without candidates) and some particle. One thread per
// component, blockIdx.y a slice of kCullParticles particles; a component already found visible
// stops testing.
constexpr int kCullThreads = 128;
constexpr int kCullParticles = 16;
// At most this many blocks per component range: more particles are taken in turns, so that a
// component found visible stops early (measured on an H100, 100,000 particles: 326 us with one
// block per 16 particles).
constexpr int kCullSlices = 256;

__global__ void __launch_bounds__(kCullThreads)
    viewCullKernel(int num_particles, int num_tested, MembershipConfig cfg,
                   const ComponentF* __restrict__ components,
                   const RigidTransformF* __restrict__ T_cam_map,
                   const int* __restrict__ candidates, int* visible) {
  __shared__ RigidTransformF s_T[kCullParticles];
  const int t = blockIdx.x * blockDim.x + threadIdx.x;
  // The component this thread tests: a grid candidate, or the map's t-th.
  const int i = t < num_tested ? (candidates ? candidates[t] : t) : -1;
  // Slices blockIdx.y, blockIdx.y + gridDim.y, ... (the grid's y extent is limited).
  for (int first = blockIdx.y * kCullParticles; first < num_particles;
       first += gridDim.y * kCullParticles) {
    const int count = min(kCullParticles, num_particles - first);
    __syncthreads();  // the previous slice's poses are no longer read
    for (int k = threadIdx.x; k < count; k += blockDim.x) s_T[k] = T_cam_map[first + k];
    __syncthreads();
    if (i < 0 || *reinterpret_cast<volatile int*>(visible + t)) continue;
    const ComponentF c = components[i];
    for (int k = 0; k < count; ++k) {
      if (componentInView(c, s_T[k], cfg.cam.K, cfg.reach, cfg.sigma_bound) &&
          componentMayTouchGrid(c, s_T[k], cfg.cam.K, cfg.cam.patch_size_px, cfg.cam.patch_cols,
                                cfg.cam.patch_rows, cfg.min_depth_m, cfg.sigma_bound,
                                cfg.inflate_px)) {
        visible[t] = 1;
        break;
      }
    }
  }
}

// The visible components in ascending order: index list and count. One block; rounds of
// blockDim.x flags with a block-wide exclusive scan. Flag t is component candidates[t]
// (ascending), or t without candidates.
constexpr int kCompactThreads = 1024;

__global__ void __launch_bounds__(kCompactThreads)
    compactKernel(int num_tested, const int* __restrict__ visible,
                  const int* __restrict__ candidates, int* __restrict__ index_out,
                  int* __restrict__ count_out) {
  __shared__ BlockScan scan;
  blockScanBegin(&scan);
  for (int r = 0; r < num_tested; r += blockDim.x) {
    const int t = r + threadIdx.x;
    const bool keep = t < num_tested && visible[t] != 0;
    const int at = blockScanRound(keep ? 1 : 0, &scan);
    if (keep) index_out[at] = candidates ? candidates[t] : t;
  }
  if (threadIdx.x == 0) *count_out = scan.carry;
}

// Compact copies of both tables in the order of the index list (one thread per entry).
__global__ void gatherKernel(const int* __restrict__ index, const int* __restrict__ count,
                             const ComponentF* __restrict__ components,
                             const EvalComponentF* __restrict__ eval,
                             ComponentF* __restrict__ components_out,
                             EvalComponentF* __restrict__ eval_out) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= *count) return;
  const int i = index[k];
  components_out[k] = components[i];
  eval_out[k] = eval[i];
}

}  // namespace

size_t membershipSharedBytes(int patches, int words, bool local, bool chunked) {
  // The bitmask, the shifts and the tail (queues, scans, seen chunks).
  return sizeof(uint32_t) * static_cast<size_t>(patches) * words + sizeof(int) * patches +
         sizeof(int) * MembershipTail(local, chunked).end;
}

cudaError_t setMembershipSharedLimit(size_t bytes) {
  // The limit is the kernel's, shared by every backend of the process on a device: raised only,
  // so that one localizer never lowers the limit another one's frames need.
  static std::mutex mutex;
  static size_t limit_bytes[kMaxDevices] = {};
  int device = 0;
  cudaError_t err = cudaGetDevice(&device);
  if (err != cudaSuccess) return err;
  const int slot = device < kMaxDevices ? device : kMaxDevices - 1;
  std::lock_guard<std::mutex> lock(mutex);
  if (bytes <= limit_bytes[slot] && device < kMaxDevices) return cudaSuccess;
  err = cudaFuncSetAttribute(membershipKernel<false>, cudaFuncAttributeMaxDynamicSharedMemorySize,
                             static_cast<int>(bytes));
  if (err == cudaSuccess) {
    err = cudaFuncSetAttribute(membershipKernel<true>, cudaFuncAttributeMaxDynamicSharedMemorySize,
                               static_cast<int>(bytes));
  }
  if (err == cudaSuccess) {
    err = cudaFuncSetAttribute(plainMembershipKernel, cudaFuncAttributeMaxDynamicSharedMemorySize,
                               static_cast<int>(bytes));
  }
  if (err == cudaSuccess) limit_bytes[slot] = bytes;
  return err;
}

cudaError_t preferSharedMemoryForMembership() {
  // Each block holds ~40 KB of bitmask: ask for the largest shared-memory carveout so that five
  // blocks fit on a multiprocessor where the hardware allows it (a hint; ignored elsewhere).
  cudaError_t err =
      cudaFuncSetAttribute(plainMembershipKernel, cudaFuncAttributePreferredSharedMemoryCarveout,
                           static_cast<int>(cudaSharedmemCarveoutMaxShared));
  if (err != cudaSuccess) return err;
  err =
      cudaFuncSetAttribute(membershipKernel<false>, cudaFuncAttributePreferredSharedMemoryCarveout,
                           static_cast<int>(cudaSharedmemCarveoutMaxShared));
  if (err != cudaSuccess) return err;
  return cudaFuncSetAttribute(membershipKernel<true>,
                              cudaFuncAttributePreferredSharedMemoryCarveout,
                              static_cast<int>(cudaSharedmemCarveoutMaxShared));
}

int balancedPassWords(int words, int pass_words) {
  if (pass_words <= 0 || words <= pass_words) return words;
  const int passes = std::max(1, (words + pass_words / 2) / pass_words);  // nearest
  return (words + passes - 1) / passes;
}

int membershipPasses(int words, int pass_words) {
  return pass_words > 0 && words > pass_words ? (words + pass_words - 1) / pass_words : 1;
}

size_t membershipShiftFloats(int num_particles, int patches, int passes) {
  return static_cast<size_t>(num_particles) * patches * (passes > 1 ? passes + 1 : 1);
}

cudaError_t launchLocalCount(int num_particles, int num_components, const MembershipConfig& cfg,
                             const ComponentF* components, const float4* chunks,
                             const RigidTransformF* T_cam_map, int* most, cudaStream_t stream) {
  cudaError_t err = cudaMemsetAsync(most, 0, sizeof(int), stream);
  if (err != cudaSuccess || num_particles <= 0 || num_components <= 0) return err;
  localCountKernel<<<num_particles, kMembershipThreads, 0, stream>>>(
      num_particles, num_components, cfg, components, chunks, T_cam_map, most);
  return cudaGetLastError();
}

cudaError_t launchMembership(int num_particles, int num_components, int words, int pass_words,
                             int local_stride, const MembershipConfig& cfg,
                             const ComponentF* components, const float4* chunks,
                             const EvalComponentF* eval, const RigidTransformF* T_cam_map,
                             uint32_t* mask_out, float* shift_out, EvalComponentF* eval_out,
                             cudaStream_t stream) {
  const int patches = cfg.cam.patch_cols * cfg.cam.patch_rows;
  if (num_particles <= 0 || patches <= 0) return cudaSuccess;
  const bool noise = cfg.depth_noise.a_m > 0.f || cfg.depth_noise.b_per_m > 0.f;
  const bool local = local_stride > 0;
  if ((noise || local) && (eval == nullptr || eval_out == nullptr)) return cudaErrorInvalidValue;
  if (local && local_stride < words * 32) return cudaErrorInvalidValue;
  const int passes = membershipPasses(words, pass_words);
  const int nw = passes == 1 ? words : pass_words;
  const size_t smem = membershipSharedBytes(patches, nw, local, chunks != nullptr);
  // Several passes write their shifts after the combined ones and are reduced into them.
  const size_t combined = static_cast<size_t>(num_particles) * patches;
  float* pass_shift = passes == 1 ? shift_out : shift_out + combined;
  const dim3 grid(num_particles, passes);
  EvalComponentF* forms_out = noise || local ? eval_out : nullptr;
  if (!local && chunks == nullptr) {
    plainMembershipKernel<<<grid, kMembershipThreads, smem, stream>>>(
        num_particles, num_components, words, nw, cfg, components, eval, T_cam_map, mask_out,
        pass_shift, noise ? eval_out : nullptr);
  } else if (chunks != nullptr) {
    membershipKernel<true><<<grid, kMembershipThreads, smem, stream>>>(
        num_particles, num_components, words, nw, local_stride, cfg, components, chunks, eval,
        T_cam_map, mask_out, pass_shift, forms_out);
  } else {
    membershipKernel<false><<<grid, kMembershipThreads, smem, stream>>>(
        num_particles, num_components, words, nw, local_stride, cfg, components, chunks, eval,
        T_cam_map, mask_out, pass_shift, forms_out);
  }
  if (passes > 1) {
    const int count = static_cast<int>(combined);
    combineShiftKernel<<<(count + 255) / 256, 256, 0, stream>>>(count, patches, passes, pass_shift,
                                                                shift_out);
  }
  return cudaGetLastError();
}

cudaError_t launchViewCull(int num_particles, int num_components, const MembershipConfig& cfg,
                           const ComponentF* components, const EvalComponentF* eval,
                           const RigidTransformF* T_cam_map, const int* candidates,
                           int num_candidates, const ViewCullBuffers& b, cudaStream_t stream) {
  // Flags, compaction, copies and chunk balls over the tested components only (the visible
  // ones are among them).
  const int tested = candidates ? num_candidates : num_components;
  cudaError_t err = cudaMemsetAsync(b.visible, 0, sizeof(int) * (tested + 1), stream);
  if (err != cudaSuccess) return err;
  if (num_particles > 0 && tested > 0) {
    const dim3 grid((tested + kCullThreads - 1) / kCullThreads,
                    min((num_particles + kCullParticles - 1) / kCullParticles, kCullSlices));
    viewCullKernel<<<grid, kCullThreads, 0, stream>>>(num_particles, tested, cfg, components,
                                                      T_cam_map, candidates, b.visible);
  }
  compactKernel<<<1, kCompactThreads, 0, stream>>>(tested, b.visible, candidates, b.index, b.count);
  if (tested > 0) {
    gatherKernel<<<(tested + 255) / 256, 256, 0, stream>>>(b.index, b.count, components, eval,
                                                           b.components, b.eval);
    chunkSpheresKernel<<<chunkCount(tested), kComponentChunk, 0, stream>>>(
        tested, b.count, b.components, cfg.sigma_bound, b.chunks);
  }
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
