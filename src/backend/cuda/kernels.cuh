// Launchers of the CUDA backend's kernels. Plain data only (no Eigen, no std::vector), so that
// this header is shared by the host code (g++) and the .cu files (nvcc).
#pragma once

#include <cuda_runtime_api.h>
#include <stdint.h>

#include "gmm_mcl/common/types.h"
#include "gmm_mcl/measurement/eval_component.h"
#include "gmm_mcl/measurement/measurement_params.h"
#include "gmm_mcl/measurement/projection.h"

namespace gmm_mcl {
namespace cuda {

// The camera and its grid of patches, as every kernel that works per patch sees them.
struct PatchCamera {
  Intrinsics K;
  int patch_size_px;
  int patch_cols;
  int patch_rows;
};

// Geometry of the patch grid and the membership test (DESIGN.md "Measurement model").
struct MembershipConfig {
  PatchCamera cam;
  float min_depth_m;
  float sigma_bound;
  float inflate_px;
  float floor_log_density;
  DepthNoiseModel depth_noise;  // off (a = b = 0): no per-particle evaluation forms
  ViewReach reach;              // the view volume (view cull only; projection.h)
};

// The membership kernel tests a set's components in chunks of this many, each chunk first by
// its bounding ball (launchViewCull's `chunks`): a pose skips the chunks outside its view.
constexpr int kComponentChunk = 256;
inline int chunkCount(int num_components) {
  return (num_components + kComponentChunk - 1) / kComponentChunk;
}

// Shared memory the membership kernel needs for a grid of `patches` and `words` bitmask words
// per patch (bytes), with local lists and with chunk balls or without.
size_t membershipSharedBytes(int patches, int words, bool local, bool chunked);
// Raises the kernel's dynamic shared-memory limit to `bytes` (needed above 48 KB).
cudaError_t setMembershipSharedLimit(size_t bytes);
// Asks for the largest shared-memory carveout for the membership kernel (a hint).
cudaError_t preferSharedMemoryForMembership();

// Projection + patch membership for `num_particles` camera poses, in membershipPasses(words,
// pass_words) passes of pass_words bitmask words each (one block per particle and pass, a
// bitmask of patches x pass_words words in shared memory; pass_words <= 0 or >= words: one pass
// over all words).
// mask_out: [num_particles][patches][words] bit i%32 of word i/32 set when component i is
// relevant; shift_out: [num_particles][patches] max(floor, max log_norm of the members) (nats),
// followed by the passes' own shifts where there are several (membershipShiftFloats in all).
// Components that componentMayTouchGrid rules out are not projected (same sets).
// With cfg.depth_noise on, eval_out: [num_particles][num_components] each projected component's
// log2 evaluation form convolved with the depth noise for that pose (depth_noise.h; where that
// fails, the noise-free form from `eval`), and the shift uses those forms' log_norm; with it off,
// eval and eval_out are not used (may be null).
// chunks (may be null: every chunk tested): the set's chunk balls (launchViewCull); a pose
// tests only the components of the chunks whose ball meets its view volume, the same ones.
// Local lists (local_stride > 0, at least words * 32): bit k of a pose's mask is the k-th of the
// components it keeps (componentMayTouchGrid and the view volume), in the set's order, and
// eval_out is [num_particles][local_stride], the pose's forms at those places (the noise-free
// form from `eval` with the depth noise off). The bitmask then follows what one pose sees, not
// the union of all poses' views (a cloud spread over a building). Every pass tests the whole set.
int membershipPasses(int words, int pass_words);
// The bitmask words per pass for `words` words where a pass should hold about pass_words: the
// number of passes nearest to words / pass_words (at least one), all of one size, so that no
// pass is a remainder of a few words (each pass costs a block per pose and its bitmask cleared
// and written out however few words it has). Measured on an H100 (17,088 poses spread over the
// 10 x 10 tiling, 42 words): one pass of 42 words, membership 1.97-2.35 ms, against passes of 32
// and 10 words, 2.83-3.21 ms; for the `large` workload (96 words) three passes of 32 words stay
// (0.42 ms, against 0.48 for 64 + 32 and 0.68 for one pass). pass_words <= 0: one pass.
int balancedPassWords(int words, int pass_words);
size_t membershipShiftFloats(int num_particles, int patches, int passes);
cudaError_t launchMembership(int num_particles, int num_components, int words, int pass_words,
                             int local_stride, const MembershipConfig& cfg,
                             const ComponentF* components, const float4* chunks,
                             const EvalComponentF* eval, const RigidTransformF* T_cam_map,
                             uint32_t* mask_out, float* shift_out, EvalComponentF* eval_out,
                             cudaStream_t stream);
// The largest number of the components [0, num_components) that one of the poses keeps (the
// membership kernel's tests), into *most (device; the local lists' size).
cudaError_t launchLocalCount(int num_particles, int num_components, const MembershipConfig& cfg,
                             const ComponentF* components, const float4* chunks,
                             const RigidTransformF* T_cam_map, int* most, cudaStream_t stream);

// The per-update view cull: the components that componentMayTouchGrid keeps for at least one of
// the poses, in ascending order (all others are culled by the membership kernel for every pose,
// so membership and likelihood on this compact list give the same sets and sums).
struct ViewCullBuffers {
  int* visible;            // [M + 1] scratch flags (with candidates: one per candidate)
  int* index;              // [M] compact -> map index
  ComponentF* components;  // [M] compact copy
  EvalComponentF* eval;    // [M] compact copy (log2 form)
  int* count;              // [1] visible count
  float4* chunks;          // [chunkCount(M)] the compact list's chunk balls (x, y, z, radius)
};
// candidates (num_candidates component indices, ascending; null: every component) limits the
// test to the map grid's components near the poses' views, and the flags, their compaction and
// the copies to the candidates: the cost follows the view, not the map (a compaction of all of
// a 100,000-component map's flags took one block about a hundred rounds).
cudaError_t launchViewCull(int num_particles, int num_components, const MembershipConfig& cfg,
                           const ComponentF* components, const EvalComponentF* eval,
                           const RigidTransformF* T_cam_map, const int* candidates,
                           int num_candidates, const ViewCullBuffers& b, cudaStream_t stream);

// How the likelihood kernel maps work onto a warp: one warp per item (a band of
// `band_patches` consecutive patches of one particle); `lanes` pixel groups of
// `pixels_per_lane` pixels each, and 32 / lanes component slices.
struct LikelihoodShape {
  int lanes = 32;              // pixel groups: 4, 8, 16 or 32
  int pixels_per_lane = 2;     // 1, 2 or 4
  int band_patches = 10;       // patches per item
  bool stage_members = false;  // copy the members' records to shared memory per patch (32 x 4)
};
// The shape for the largest patch of a frame (pixels).
LikelihoodShape chooseLikelihoodShape(int max_patch_pixels);
// Items (bands) per particle.
int likelihoodItemsPerParticle(const LikelihoodShape& shape, int num_patches);
// Shared memory of the likelihood kernel (each warp's member list, and staged records), bytes
// (at most 40 KB).
size_t likelihoodSharedBytes(const LikelihoodShape& shape, int words);

// Per-item partial sums of the likelihood kernel, reduced per particle by launchReduce.
struct ItemPartials {
  double* log_likelihood;  // [items] nats
  int* floor_hits;         // [items]
  int* evaluations;        // [items]
  int* relevant;           // [items] members summed over the item's patches with pixels
};

// One batch's inputs of the likelihood kernel (device pointers).
struct LikelihoodInputs {
  int num_patches;
  int words;                     // bitmask words per patch
  const float *x_m, *y_m, *z_m;  // [pixels] camera frame
  const int* patch_begin;        // [patches + 1]
  // The log2 evaluation form (makeEvalComponentF with kEvalScaleLog2): one table for all
  // particles (components_per_particle 0) or one of that many entries per particle
  // (launchMembership's eval_out).
  const EvalComponentF* components;
  int components_per_particle;
  const RigidTransformF* T_map_cam;  // [N]
  const uint32_t* mask;              // [N][patches][words]
  const float* shift;                // [N][patches], nats
};

// Per-pixel log-sum over the relevant components for every (particle, band) item.
cudaError_t launchLikelihood(int num_particles, const LikelihoodInputs& in,
                             const LikelihoodShape& shape, float floor_log_density,
                             const ItemPartials& partials, cudaStream_t stream);

// Per-particle sums of the item partials, in a fixed order (deterministic).
// items_per_particle: likelihoodItemsPerParticle. order (device, may be null): particle i's sums
// go to index order[i] of the outputs (a batch of poses permuted by place).
cudaError_t launchReduce(int num_particles, int items_per_particle, const ItemPartials& partials,
                         double* log_likelihood, int* floor_hits, long long* evaluations,
                         long long* relevant_pairs, const int* order, cudaStream_t stream);

// Frame preparation on the GPU (prepareFrame's pixels, order and arithmetic).
struct FrameConfig {
  PatchCamera cam;
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
