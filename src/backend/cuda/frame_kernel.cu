// Frame preparation on the GPU: the used pixels of a raw depth image, back-projected into the
// camera frame and grouped by patch, in the order of prepareFrame (patch by patch, rows then
// columns inside each patch) and with its arithmetic (gmm_mcl/camera/depth_frame.h backProject).
#include <math.h>

#include "cuda/block_scan.cuh"
#include "cuda/kernels.cuh"
#include "gmm_mcl/camera/depth_frame.h"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kFrameThreads = 256;

// Depth of pixel (u, v) in metres, NaN when there is no measurement (DepthImage::depthMetres).
__device__ __forceinline__ float depthAt(const FrameConfig& cfg, const uint8_t* __restrict__ img,
                                         int u, int v) {
  const uint8_t* row =
      img + static_cast<size_t>(v / cfg.stride_px) * cfg.row_bytes;  // v on the grid
  if (cfg.millimetres) {
    const uint16_t mm = static_cast<uint16_t>(row[2 * u] | (row[2 * u + 1] << 8));
    if (mm == 0 || mm == 65535) return __int_as_float(0x7fc00000);
    return 0.001f * static_cast<float>(mm);
  }
  const uint32_t bits =
      static_cast<uint32_t>(row[4 * u]) | (static_cast<uint32_t>(row[4 * u + 1]) << 8) |
      (static_cast<uint32_t>(row[4 * u + 2]) << 16) | (static_cast<uint32_t>(row[4 * u + 3]) << 24);
  const float d = __uint_as_float(bits);
  if (!isfinite(d) || d <= 0.f) return __int_as_float(0x7fc00000);
  return d;
}

// The stride-grid pixels of patch p: n_u x n_v starting at (u0, v0).
struct PatchPixels {
  int u0, v0, n_u, n_v;
};
__device__ __forceinline__ PatchPixels patchPixels(const FrameConfig& cfg, int p) {
  const int pr = p / cfg.cam.patch_cols, pc = p - pr * cfg.cam.patch_cols;
  const int ps = cfg.cam.patch_size_px, st = cfg.stride_px;
  PatchPixels q;
  q.v0 = ((pr * ps + st - 1) / st) * st;
  q.u0 = ((pc * ps + st - 1) / st) * st;
  const int v_end = min(cfg.cam.K.height_px, (pr + 1) * ps);
  const int u_end = min(cfg.cam.K.width_px, (pc + 1) * ps);
  q.n_v = q.v0 < v_end ? (v_end - q.v0 + st - 1) / st : 0;
  q.n_u = q.u0 < u_end ? (u_end - q.u0 + st - 1) / st : 0;
  return q;
}

__device__ __forceinline__ bool used(const FrameConfig& cfg, float z) {
  return isfinite(z) && !(z < cfg.min_range_m || z > cfg.max_range_m);
}

__global__ void __launch_bounds__(kFrameThreads)
    frameCountKernel(int num_patches, FrameConfig cfg,
                     const uint8_t* __restrict__ image,  // [height][row_bytes]
                     int* __restrict__ counts) {         // [patches]
  __shared__ int s_count;
  const int p = blockIdx.x;
  if (p >= num_patches) return;
  if (threadIdx.x == 0) s_count = 0;
  __syncthreads();
  const PatchPixels q = patchPixels(cfg, p);
  int c = 0;
  for (int i = threadIdx.x; i < q.n_u * q.n_v; i += blockDim.x) {
    const int v = q.v0 + (i / q.n_u) * cfg.stride_px, u = q.u0 + (i % q.n_u) * cfg.stride_px;
    c += used(cfg, depthAt(cfg, image, u, v)) ? 1 : 0;
  }
  atomicAdd(&s_count, c);
  __syncthreads();
  if (threadIdx.x == 0) counts[p] = s_count;
}

// Exclusive scan of the counts into patch_begin[0 .. patches] (one block, chunks of its size).
__global__ void __launch_bounds__(1024)
    frameScanKernel(int num_patches, const int* __restrict__ counts,  // [patches]
                    int* __restrict__ patch_begin) {                  // [patches + 1]
  __shared__ BlockScan scan;
  blockScanBegin(&scan);
  for (int base = 0; base < num_patches; base += blockDim.x) {
    const int i = base + threadIdx.x;
    const int excl = blockScanRound(i < num_patches ? counts[i] : 0, &scan);
    if (i < num_patches) patch_begin[i] = excl;
  }
  if (threadIdx.x == 0) patch_begin[num_patches] = scan.carry;
}

// Writes the used pixels of each patch, in raster order inside the patch.
__global__ void __launch_bounds__(kFrameThreads)
    frameWriteKernel(int num_patches, FrameConfig cfg,
                     const uint8_t* __restrict__ image,    // [height][row_bytes]
                     const int* __restrict__ patch_begin,  // [patches + 1]
                     float* __restrict__ x_m, float* __restrict__ y_m,
                     float* __restrict__ z_m) {  // [pixels] camera frame
  __shared__ int s_warp[kFrameThreads / 32];
  __shared__ int s_base;
  const int p = blockIdx.x;
  if (p >= num_patches) return;
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  const PatchPixels q = patchPixels(cfg, p);
  if (threadIdx.x == 0) s_base = patch_begin[p];
  __syncthreads();
  for (int r = 0; r < q.n_u * q.n_v; r += blockDim.x) {
    const int i = r + threadIdx.x;
    float z = 0.f;
    int u = 0, v = 0;
    bool ok = false;
    if (i < q.n_u * q.n_v) {
      v = q.v0 + (i / q.n_u) * cfg.stride_px;
      u = q.u0 + (i % q.n_u) * cfg.stride_px;
      z = depthAt(cfg, image, u, v);
      ok = used(cfg, z);
    }
    const uint32_t ballot = __ballot_sync(0xffffffffu, ok);
    if (lane == 0) s_warp[warp] = __popc(ballot);
    __syncthreads();
    int before = s_base;
    for (int w = 0; w < warp; ++w) before += s_warp[w];
    before += __popc(ballot & ((1u << lane) - 1u));
    if (ok) {
      float pt[3];
      backProject(cfg.cam.K, static_cast<float>(u), static_cast<float>(v), z, pt);
      x_m[before] = pt[0];
      y_m[before] = pt[1];
      z_m[before] = pt[2];
    }
    __syncthreads();
    if (threadIdx.x == 0) {
      int total = 0;
      for (int w = 0; w < kFrameThreads / 32; ++w) total += s_warp[w];
      s_base += total;
    }
    __syncthreads();
  }
}

}  // namespace

cudaError_t launchFramePrep(const FrameConfig& cfg, const uint8_t* image, int* counts,
                            int* patch_begin, float* x_m, float* y_m, float* z_m,
                            cudaStream_t stream) {
  const int patches = cfg.cam.patch_cols * cfg.cam.patch_rows;
  if (patches <= 0) return cudaSuccess;
  frameCountKernel<<<patches, kFrameThreads, 0, stream>>>(patches, cfg, image, counts);
  cudaError_t err = cudaGetLastError();
  if (err != cudaSuccess) return err;
  frameScanKernel<<<1, 1024, 0, stream>>>(patches, counts, patch_begin);
  err = cudaGetLastError();
  if (err != cudaSuccess) return err;
  frameWriteKernel<<<patches, kFrameThreads, 0, stream>>>(patches, cfg, image, patch_begin, x_m,
                                                          y_m, z_m);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
