// Launchers of the CUDA backend's kernels. Plain data only (no Eigen, no std::vector), so that
// this header is shared by the host code (g++) and the .cu files (nvcc).
#pragma once

#include <cuda_runtime_api.h>
#include <stdint.h>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {
namespace cuda {

// A component in the layout of the likelihood kernel (48 bytes, three float4 loads):
// a = (mean x, y, z [m], log_norm * log2(e)); b, c = the precision scaled by -0.5 log2(e) with
// off-diagonal terms doubled: b = (P_xx, 2 P_xy, 2 P_xz, P_yy), c = (2 P_yz, P_zz, log_norm, 0).
// The kernel then evaluates log2(lambda N) - shift2 with 6 FMA and 3 multiplications.
struct alignas(16) EvalComponent {
  float a[4];
  float b[4];
  float c[4];
};

EvalComponent makeEvalComponent(const ComponentF& c);

// Geometry of the patch grid and the membership test (DESIGN.md "Measurement model").
struct MembershipConfig {
  Intrinsics K;
  int patch_size_px;
  int patch_cols;
  int patch_rows;
  float min_depth_m;
  float sigma_bound;
  float inflate_px;
  float floor_log_density;
};

// Shared memory the membership kernel needs for a grid of `patches` and `words` bitmask words
// per patch (bytes).
size_t membershipSharedBytes(int patches, int words);
// Raises the kernel's dynamic shared-memory limit to `bytes` (needed above 48 KB).
cudaError_t setMembershipSharedLimit(size_t bytes);
// Asks for the largest shared-memory carveout for the membership kernel (a hint).
cudaError_t preferSharedMemoryForMembership();

// Projection + patch membership for `num_particles` camera poses.
// mask_out: [num_particles][patches][words] bit i%32 of word i/32 set when component i is
// relevant; shift_out: [num_particles][patches] max(floor, max log_norm of the members) (nats);
// summary_out: [num_particles][patches][ceil(words / 32)], bit w set when mask word w is not 0.
cudaError_t launchMembership(int num_particles, int num_components, int words,
                             const MembershipConfig& cfg, const ComponentF* components,
                             const RigidTransformF* T_cam_map, uint32_t* mask_out, float* shift_out,
                             uint32_t* summary_out, cudaStream_t stream);

// How the likelihood kernel maps work onto lanes: a group of `lanes` lanes (8, 16 or 32) per
// (particle, patch) item, each lane keeping `pixels_per_lane` pixels (1, 2 or 4) in registers.
struct LikelihoodShape {
  int lanes = 32;
  int pixels_per_lane = 2;
  bool member_list = true;  // expand members into a shared-memory list (else scan the bits)
};
// The shape for the largest patch of a frame (pixels).
LikelihoodShape chooseLikelihoodShape(int max_patch_pixels);
// Shared memory of the likelihood kernel (each group's mask row), bytes.
// (At most 48 KB: 8 lanes per item hold 48 KB for M = 12288.)
size_t likelihoodSharedBytes(const LikelihoodShape& shape, int words);

// Per-item partial sums of the likelihood kernel, reduced per particle by launchReduce.
struct ItemPartials {
  double* log_likelihood;  // [items] nats
  int* floor_hits;         // [items]
  int* evaluations;        // [items]
  int* relevant;           // [items] members of the patch (0 for patches without pixels)
};

// Per-pixel log-sum over the relevant components for every (particle, patch) item.
cudaError_t launchLikelihood(int num_particles, int num_patches, int words,
                             const LikelihoodShape& shape, float floor_log_density,
                             const float* x_m, const float* y_m, const float* z_m,
                             const int* patch_begin, const EvalComponent* components,
                             const RigidTransformF* T_map_cam, const uint32_t* mask,
                             const uint32_t* summary, const float* shift,
                             const ItemPartials& partials, cudaStream_t stream);

// Per-particle sums of the item partials, in a fixed order (deterministic).
cudaError_t launchReduce(int num_particles, int num_patches, const ItemPartials& partials,
                         double* log_likelihood, int* floor_hits, long long* evaluations,
                         long long* relevant_pairs, cudaStream_t stream);

// Frame preparation on the GPU (prepareFrame's pixels, order and arithmetic).
struct FrameConfig {
  Intrinsics K;
  int patch_size_px;
  int cols, rows;  // patch grid
  int stride_px;
  float min_range_m, max_range_m;
  int millimetres;  // 1: 16UC1 millimetres, 0: 32FC1 metres
  size_t row_bytes;
};
// image: [ceil(height / stride)][row_bytes] raw bytes, the rows v = 0, stride, 2 stride, ...;
// counts: [patches] scratch; patch_begin: [patches + 1]; x_m, y_m, z_m: room for every stride-grid
// pixel.
cudaError_t launchFramePrep(const FrameConfig& cfg, const uint8_t* image, int* counts,
                            int* patch_begin, float* x_m, float* y_m, float* z_m,
                            cudaStream_t stream);

}  // namespace cuda
}  // namespace gmm_mcl
