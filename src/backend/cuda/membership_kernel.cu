// Projection of every component for every particle and the patch membership bitmasks.
// One block per particle; the bitmask of the whole patch grid is built in shared memory with
// atomicOr and written out coalesced. Same math as the CPU (gmm_mcl/measurement/projection.h).
#include <math.h>

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

__global__ void __launch_bounds__(kMembershipThreads, kMembershipMinBlocks)
    membershipKernel(int num_particles, int num_components, int words, int pass_words,
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

// Per-update view cull: visible[i] = 1 when componentMayTouchGrid holds for component i and
// some particle. One thread per component, blockIdx.y a slice of kCullParticles particles;
// a component already found visible stops testing.
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
    if (i < 0 || *reinterpret_cast<volatile int*>(visible + i)) continue;
    const ComponentF c = components[i];
    for (int k = 0; k < count; ++k) {
      if (componentInView(c, s_T[k], cfg.cam.K, cfg.reach, cfg.sigma_bound) &&
          componentMayTouchGrid(c, s_T[k], cfg.cam.K, cfg.cam.patch_size_px, cfg.cam.patch_cols,
                                cfg.cam.patch_rows, cfg.min_depth_m, cfg.sigma_bound,
                                cfg.inflate_px)) {
        visible[i] = 1;
        break;
      }
    }
  }
}

// The visible components in ascending order: index list and count. One block; rounds of
// blockDim.x components with a block-wide exclusive scan.
constexpr int kCompactThreads = 1024;

__global__ void __launch_bounds__(kCompactThreads)
    compactKernel(int num_components, const int* __restrict__ visible, int* __restrict__ index_out,
                  int* __restrict__ count_out) {
  __shared__ BlockScan scan;
  blockScanBegin(&scan);
  for (int r = 0; r < num_components; r += blockDim.x) {
    const int i = r + threadIdx.x;
    const bool keep = i < num_components && visible[i] != 0;
    const int at = blockScanRound(keep ? 1 : 0, &scan);
    if (keep) index_out[at] = i;
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

size_t membershipSharedBytes(int patches, int words) {
  return sizeof(uint32_t) * static_cast<size_t>(patches) * words + sizeof(int) * patches +
         sizeof(int) * (kMembershipThreads / 32) * kQueuePerWarp;
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
  err = cudaFuncSetAttribute(membershipKernel, cudaFuncAttributeMaxDynamicSharedMemorySize,
                             static_cast<int>(bytes));
  if (err == cudaSuccess) limit_bytes[slot] = bytes;
  return err;
}

cudaError_t preferSharedMemoryForMembership() {
  // Each block holds ~40 KB of bitmask: ask for the largest shared-memory carveout so that five
  // blocks fit on a multiprocessor where the hardware allows it (a hint; ignored elsewhere).
  return cudaFuncSetAttribute(membershipKernel, cudaFuncAttributePreferredSharedMemoryCarveout,
                              static_cast<int>(cudaSharedmemCarveoutMaxShared));
}

int membershipPasses(int words, int pass_words) {
  return pass_words > 0 && words > pass_words ? (words + pass_words - 1) / pass_words : 1;
}

size_t membershipShiftFloats(int num_particles, int patches, int passes) {
  return static_cast<size_t>(num_particles) * patches * (passes > 1 ? passes + 1 : 1);
}

cudaError_t launchMembership(int num_particles, int num_components, int words, int pass_words,
                             const MembershipConfig& cfg, const ComponentF* components,
                             const EvalComponentF* eval, const RigidTransformF* T_cam_map,
                             uint32_t* mask_out, float* shift_out, EvalComponentF* eval_out,
                             cudaStream_t stream) {
  const int patches = cfg.cam.patch_cols * cfg.cam.patch_rows;
  if (num_particles <= 0 || patches <= 0) return cudaSuccess;
  const bool noise = cfg.depth_noise.a_m > 0.f || cfg.depth_noise.b_per_m > 0.f;
  if (noise && (eval == nullptr || eval_out == nullptr)) return cudaErrorInvalidValue;
  const int passes = membershipPasses(words, pass_words);
  const int nw = passes == 1 ? words : pass_words;
  const size_t smem = membershipSharedBytes(patches, nw);
  // Several passes write their shifts after the combined ones and are reduced into them.
  const size_t combined = static_cast<size_t>(num_particles) * patches;
  float* pass_shift = passes == 1 ? shift_out : shift_out + combined;
  membershipKernel<<<dim3(num_particles, passes), kMembershipThreads, smem, stream>>>(
      num_particles, num_components, words, nw, cfg, components, eval, T_cam_map, mask_out,
      pass_shift, noise ? eval_out : nullptr);
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
  cudaError_t err = cudaMemsetAsync(b.visible, 0, sizeof(int) * (num_components + 1), stream);
  if (err != cudaSuccess) return err;
  const int tested = candidates ? num_candidates : num_components;
  if (num_particles > 0 && tested > 0) {
    const dim3 grid((tested + kCullThreads - 1) / kCullThreads,
                    min((num_particles + kCullParticles - 1) / kCullParticles, kCullSlices));
    viewCullKernel<<<grid, kCullThreads, 0, stream>>>(num_particles, tested, cfg, components,
                                                      T_cam_map, candidates, b.visible);
  }
  compactKernel<<<1, kCompactThreads, 0, stream>>>(num_components, b.visible, b.index, b.count);
  if (num_components > 0) {
    gatherKernel<<<(num_components + 255) / 256, 256, 0, stream>>>(b.index, b.count, components,
                                                                   eval, b.components, b.eval);
  }
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
