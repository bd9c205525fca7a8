// Launcher of the pose refinement's pixel sums on the GPU (gmm_mcl/measurement/normal_equations.h).
// Plain data only, shared by the host code (g++) and the .cu file (nvcc).
#pragma once

#include <cuda_runtime_api.h>

#include "gmm_mcl/measurement/eval_component.h"

namespace gmm_mcl {
namespace cuda {

// Values each block writes: loglik, the 21 entries of H's upper triangle, the 6 of g, then with
// a depth scale H's seventh column (H0s, ..., H5s, Hss) and g's seventh entry (zero without).
constexpr int kNormalEquationValues = 36;
// Threads per block of the kernel (one pixel each).
constexpr int kNormalEquationThreads = 128;

// The pose applied to the kernel's points p: q = R p + t and dq/d(roll, pitch, yaw)_a =
// dR[a] p + dt[a] (R, dR row-major); with a depth scale f estimated, dq/df = Rs p + ts. Base-frame
// points: the pose itself with dt = 0; camera points: the pose composed with the camera's
// extrinsics; a depth scale folded into all of them (CudaNormalEquations::evaluate).
struct NormalEquationPose {
  float R[9];
  float t[3];
  float dR[3][9];
  float dt[3][3];
  float Rs[9];
  float ts[3];
};

// Blocks the kernel uses for n pixels.
inline int normalEquationBlocks(int num_pixels) {
  return (num_pixels + kNormalEquationThreads - 1) / kNormalEquationThreads;
}

// Per block, the sums over its pixels (block b: pixels [b * threads, (b + 1) * threads)), in a
// fixed order: partials_out [blocks][kNormalEquationValues] (H and g zero unless linearise, the
// depth scale's entries zero unless with_scale as well).
// x_m, y_m, z_m: [num_pixels] base-frame points; pixel_patch: [num_pixels] the patch of each
// pixel; member_begin: [patches + 1], members: [member_begin[patches]] component indices;
// eval: [components] evaluation forms in nats.
cudaError_t launchNormalEquations(int num_pixels, const NormalEquationPose& pose,
                                  float floor_log_density, int linearise, int with_scale,
                                  const float* x_m, const float* y_m, const float* z_m,
                                  const int* pixel_patch, const int* member_begin,
                                  const int* members, const EvalComponentF* eval,
                                  double* partials_out, cudaStream_t stream);

// pixel_patch[i] = p for every pixel i of patch p (patch_begin: [patches + 1]).
cudaError_t launchFillPixelPatch(int patches, const int* patch_begin, int* pixel_patch,
                                 cudaStream_t stream);

}  // namespace cuda
}  // namespace gmm_mcl
