// The pose refinement's pixel sums (gmm_mcl/measurement/normal_equations.h) on the GPU: one
// thread per pixel, looping over its patch's members three times (the maximum exponent, the
// log-sum, then the responsibilities and the normal equations), in float; each block's 36 sums
// are reduced in double by a fixed tree (warp shuffles, then the warps in order), so the result
// is the same on every run.
#include <math.h>

#include "cuda/normal_equations_kernel.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kWarps = kNormalEquationThreads / 32;
constexpr float kMinResponsibilityF = 1e-6f;

__device__ __forceinline__ void residual(const EvalComponentF& e, const float q[3], float y[3]) {
  y[0] = e.u00 * q[0] + e.u01 * q[1] + e.u02 * q[2] + e.c[0];
  y[1] = e.u11 * q[1] + e.u12 * q[2] + e.c[1];
  y[2] = e.u22 * q[2] + e.c[2];
}

__global__ void __launch_bounds__(kNormalEquationThreads)
    normalEquationsKernel(int num_pixels, NormalEquationPose pose, float floor_log_density,
                          int linearise, int with_scale, const float* __restrict__ x_m,
                          const float* __restrict__ y_m, const float* __restrict__ z_m,
                          const int* __restrict__ pixel_patch, const int* __restrict__ member_begin,
                          const int* __restrict__ members, const EvalComponentF* __restrict__ eval,
                          double* __restrict__ partials_out) {
  float acc[kNormalEquationValues];
#pragma unroll
  for (int v = 0; v < kNormalEquationValues; ++v) acc[v] = 0.f;
  const int i = blockIdx.x * kNormalEquationThreads + threadIdx.x;
  if (i < num_pixels) {
    const float p[3] = {x_m[i], y_m[i], z_m[i]};
    float q[3];
    for (int r = 0; r < 3; ++r) {
      q[r] = pose.R[3 * r] * p[0] + pose.R[3 * r + 1] * p[1] + pose.R[3 * r + 2] * p[2] + pose.t[r];
    }
    const int patch = pixel_patch[i];
    const int b = member_begin[patch], e = member_begin[patch + 1];
    float mx = floor_log_density;
    for (int m = b; m < e; ++m) {
      float y[3];
      const EvalComponentF ev = eval[members[m]];
      residual(ev, q, y);
      mx = fmaxf(mx, ev.log_norm - (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]));
    }
    float sum = expf(floor_log_density - mx);
    for (int m = b; m < e; ++m) {
      float y[3];
      const EvalComponentF ev = eval[members[m]];
      residual(ev, q, y);
      sum += expf(ev.log_norm - (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - mx);
    }
    acc[0] = mx + logf(sum);
    if (linearise && e > b) {
      // dq / d(roll, pitch, yaw).
      float dq[3][3];
      for (int a = 0; a < 3; ++a) {
        for (int r = 0; r < 3; ++r) {
          dq[a][r] = pose.dR[a][3 * r] * p[0] + pose.dR[a][3 * r + 1] * p[1] +
                     pose.dR[a][3 * r + 2] * p[2] + pose.dt[a][r];
        }
      }
      // dq / df (the depth scale), when it is estimated.
      float dqs[3] = {0.f, 0.f, 0.f};
      if (with_scale) {
        for (int r = 0; r < 3; ++r) {
          dqs[r] = pose.Rs[3 * r] * p[0] + pose.Rs[3 * r + 1] * p[1] + pose.Rs[3 * r + 2] * p[2] +
                   pose.ts[r];
        }
      }
      const float inv_sum = 1.f / sum;
      for (int m = b; m < e; ++m) {
        float y[3];
        const EvalComponentF ev = eval[members[m]];
        residual(ev, q, y);
        const float gamma =
            expf(ev.log_norm - (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - mx) * inv_sum;
        if (gamma < kMinResponsibilityF) continue;
        // Columns of J = U [I | dq/droll | dq/dpitch | dq/dyaw] (U upper triangular).
        float col[6][3] = {{ev.u00, 0.f, 0.f}, {ev.u01, ev.u11, 0.f}, {ev.u02, ev.u12, ev.u22}};
        for (int a = 0; a < 3; ++a) {
          col[3 + a][0] = ev.u00 * dq[a][0] + ev.u01 * dq[a][1] + ev.u02 * dq[a][2];
          col[3 + a][1] = ev.u11 * dq[a][1] + ev.u12 * dq[a][2];
          col[3 + a][2] = ev.u22 * dq[a][2];
        }
#pragma unroll
        for (int r = 0, idx = 1; r < 6; ++r) {
#pragma unroll
          for (int c = r; c < 6; ++c, ++idx) {
            acc[idx] +=
                gamma * (col[r][0] * col[c][0] + col[r][1] * col[c][1] + col[r][2] * col[c][2]);
          }
          acc[22 + r] += gamma * (col[r][0] * y[0] + col[r][1] * y[1] + col[r][2] * y[2]);
        }
        if (with_scale) {
          const float cs[3] = {ev.u00 * dqs[0] + ev.u01 * dqs[1] + ev.u02 * dqs[2],
                               ev.u11 * dqs[1] + ev.u12 * dqs[2], ev.u22 * dqs[2]};
#pragma unroll
          for (int r = 0; r < 6; ++r) {
            acc[28 + r] += gamma * (col[r][0] * cs[0] + col[r][1] * cs[1] + col[r][2] * cs[2]);
          }
          acc[34] += gamma * (cs[0] * cs[0] + cs[1] * cs[1] + cs[2] * cs[2]);
          acc[35] += gamma * (cs[0] * y[0] + cs[1] * y[1] + cs[2] * y[2]);
        }
      }
    }
  }
  // Block sums in double: within each warp by shuffles, then the warps in order.
  __shared__ double warp_sums[kWarps][kNormalEquationValues];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
#pragma unroll
  for (int v = 0; v < kNormalEquationValues; ++v) {
    double s = acc[v];
#pragma unroll
    for (int off = 16; off > 0; off >>= 1) s += __shfl_down_sync(0xffffffffu, s, off);
    if (lane == 0) warp_sums[warp][v] = s;
  }
  __syncthreads();
  if (threadIdx.x < kNormalEquationValues) {
    double s = 0.0;
    for (int w = 0; w < kWarps; ++w) s += warp_sums[w][threadIdx.x];
    partials_out[static_cast<size_t>(blockIdx.x) * kNormalEquationValues + threadIdx.x] = s;
  }
}

__global__ void fillPixelPatchKernel(int patches, const int* __restrict__ patch_begin,
                                     int* __restrict__ pixel_patch) {
  const int p = blockIdx.x;
  if (p >= patches) return;
  for (int i = patch_begin[p] + threadIdx.x; i < patch_begin[p + 1]; i += blockDim.x) {
    pixel_patch[i] = p;
  }
}

}  // namespace

cudaError_t launchFillPixelPatch(int patches, const int* patch_begin, int* pixel_patch,
                                 cudaStream_t stream) {
  if (patches <= 0) return cudaSuccess;
  fillPixelPatchKernel<<<patches, 64, 0, stream>>>(patches, patch_begin, pixel_patch);
  return cudaGetLastError();
}

cudaError_t launchNormalEquations(int num_pixels, const NormalEquationPose& pose,
                                  float floor_log_density, int linearise, int with_scale,
                                  const float* x_m, const float* y_m, const float* z_m,
                                  const int* pixel_patch, const int* member_begin,
                                  const int* members, const EvalComponentF* eval,
                                  double* partials_out, cudaStream_t stream) {
  if (num_pixels <= 0) return cudaSuccess;
  const int blocks = normalEquationBlocks(num_pixels);
  normalEquationsKernel<<<blocks, kNormalEquationThreads, 0, stream>>>(
      num_pixels, pose, floor_log_density, linearise, with_scale, x_m, y_m, z_m, pixel_patch,
      member_begin, members, eval, partials_out);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
