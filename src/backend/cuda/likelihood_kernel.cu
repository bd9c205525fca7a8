// Per-pixel log-sum over the relevant components of each patch, and the per-particle reduction.
//
// One warp per work item; an item is a band of consecutive patches of one particle (so that the
// warp's partial sums are reduced and written once per band, not per patch). For each patch of
// the band the warp expands the patch's membership bitmask into a list of members in shared
// memory (ascending, fixed order), then evaluates chunks of PXG * PX pixels: lane l holds PX
// pixels of pixel group l % PXG and evaluates the members of slice l / PXG (members s, s + C,
// s + 2C, ... with C = 32 / PXG slices), so a patch of few pixels still keeps every lane busy;
// the slices' partial sums are then added with shuffles. All lanes of a warp work on one patch:
// no divergence between items inside a warp.
//
// One evaluation (gmm_mcl/measurement/eval_component.h, log2 units):
//   t = (base - S2) - |U p + c|^2 = 9 FMA, then sum += exp2(t) (1 add, exp2 on the SFU).
// The sum is shifted by the patch's largest member log-normaliser S (>= the floor): every
// exponent is <= 0 and no second pass for the maximum is needed; per pixel
// ll = S + ln(exp(floor - S) + sum).
#include <math.h>

#include "cuda/kernels.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kThreads = 256;
constexpr int kWarps = kThreads / 32;
constexpr float kLog2e = 1.4426950408889634f;
constexpr float kLn2 = 0.6931471805599453f;
// Member records staged per warp at a time (48 bytes each: 3 KB per warp).
constexpr int kStage = 64;
// Resident blocks per multiprocessor the register allocation must allow: 4 (64 registers on an
// H100, 32 warps) for 1 or 2 pixels per lane; 3 (80 registers) for 4, which would spill at 64.
// Measured on an H100 (paper workload, 32 x 2): 0.313 ms at 4 blocks, 0.332 ms at 3; full
// workload (32 x 4): 3.05 ms at 3, 3.24 ms at 4.
template <int PX>
struct LikelihoodMinBlocks {
  static constexpr int value = PX >= 4 ? 3 : 4;
};

// 2^x on the special-function unit (relative error ~2^-22; results below 2^-126 flush to 0,
// which is negligible next to the floor term).
__device__ __forceinline__ float exp2Approx(float x) {
  float y;
  asm("ex2.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
}
// log2(x) on the special-function unit (x > 0 normal; error ~2 ulp of the result).
__device__ __forceinline__ float log2Approx(float x) {
  float y;
  asm("lg2.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
}

// The sum of x over the warp's lanes, at lane 0, in a fixed order (deterministic).
template <typename T>
__device__ __forceinline__ T warpSumToLane0(T x) {
#pragma unroll
  for (int off = 16; off > 0; off >>= 1) x += __shfl_down_sync(0xffffffffu, x, off);
  return x;
}

// Expands mask words [w0, w0 + 32) of one patch into the warp's member list (ascending
// component index, counted from the round's first component w0 * 32: 16 bits hold it whatever
// the set's size); returns the member count. All 32 lanes call it.
__device__ __forceinline__ int buildMemberList(const uint32_t* __restrict__ row, int w0, int words,
                                               int lane, uint16_t* list) {
  const uint32_t bits = w0 + lane < words ? __ldg(row + w0 + lane) : 0u;
  const int cnt = __popc(bits);
  int incl = cnt;
#pragma unroll
  for (int off = 1; off < 32; off <<= 1) {
    const int t = __shfl_up_sync(0xffffffffu, incl, off);
    if (lane >= off) incl += t;
  }
  const int k = __shfl_sync(0xffffffffu, incl, 31);
  int pos = incl - cnt;
  __syncwarp();  // readers of the previous list are done
  for (uint32_t m = bits; m; m &= m - 1u) {
    list[pos++] = static_cast<uint16_t>((lane << 5) + __ffs(m) - 1);  // within the round
  }
  __syncwarp();
  return k;
}

// sum[q] += exp2(log2(lambda N(p_q)) - S2) for one member's record (ra, rb, rc).
template <int PX>
__device__ __forceinline__ void accumulateRecord(const float4& ra, const float4& rb,
                                                 const float2& rc, float S2, const float (&px)[PX],
                                                 const float (&py)[PX], const float (&pz)[PX],
                                                 float (&sum)[PX]) {
  const float base = ra.w - S2;
#pragma unroll
  for (int q = 0; q < PX; ++q) {
    const float y0 = fmaf(rb.x, px[q], fmaf(rb.y, py[q], fmaf(rb.z, pz[q], ra.x)));
    const float y1 = fmaf(rb.w, py[q], fmaf(rc.x, pz[q], ra.y));
    const float y2 = fmaf(rc.y, pz[q], ra.z);
    float tt = fmaf(-y0, y0, base);
    tt = fmaf(-y1, y1, tt);
    tt = fmaf(-y2, y2, tt);  // log2(lambda N) - S2 <= 0
    sum[q] += exp2Approx(tt);
  }
}

// accumulateRecord over the members slice, slice + C, ... of list (component records read from
// global memory through the L1 cache).
template <int PX, int C>
__device__ __forceinline__ void accumulateListed(const uint16_t* list, int k, int slice,
                                                 const EvalComponentF* __restrict__ comps, float S2,
                                                 const float (&px)[PX], const float (&py)[PX],
                                                 const float (&pz)[PX], float (&sum)[PX]) {
  for (int t = slice; t < k; t += C) {
    const int j = list[t];
    const float4 ra = __ldg(reinterpret_cast<const float4*>(comps + j));
    const float4 rb = __ldg(reinterpret_cast<const float4*>(comps + j) + 1);
    const float2 rc = __ldg(reinterpret_cast<const float2*>(comps + j) + 4);
    accumulateRecord<PX>(ra, rb, rc, S2, px, py, pz, sum);
  }
}

// Copies the records of members list[0 .. n) (n <= kStage) into the warp's staging area, so that
// the evaluation loop reads each member with three broadcast shared-memory loads instead of an
// index load and three dependent global loads. All 32 lanes call it.
__device__ __forceinline__ void stageMembers(const uint16_t* list, int n,
                                             const float4* __restrict__ comps4, int lane,
                                             float4* rec) {
  __syncwarp();  // readers of the previous records are done
  for (int e = lane; e < 3 * n; e += 32) {
    const int m = e / 3;
    rec[e] = __ldg(comps4 + 3 * list[m] + (e - 3 * m));
  }
  __syncwarp();
}

// accumulateRecord over the staged members slice, slice + C, ...
template <int PX, int C>
__device__ __forceinline__ void accumulateStaged(const float4* rec, int n, int slice, float S2,
                                                 const float (&px)[PX], const float (&py)[PX],
                                                 const float (&pz)[PX], float (&sum)[PX]) {
  for (int t = slice; t < n; t += C) {
    const float4 ra = rec[3 * t];
    const float4 rb = rec[3 * t + 1];
    const float2 rc = *reinterpret_cast<const float2*>(rec + 3 * t + 2);
    accumulateRecord<PX>(ra, rb, rc, S2, px, py, pz, sum);
  }
}

// Adds the component slices' partial sums of each pixel: every lane of a pixel group (the lanes
// PXG apart) ends with the total.
template <int PXG, int PX>
__device__ __forceinline__ void sumOverSlices(float (&sum)[PX]) {
#pragma unroll
  for (int off = PXG; off < 32; off <<= 1) {
#pragma unroll
    for (int q = 0; q < PX; ++q) sum[q] += __shfl_xor_sync(0xffffffffu, sum[q], off);
  }
}

template <int PXG, int PX, bool STAGE>
__global__ void __launch_bounds__(kThreads, LikelihoodMinBlocks<PX>::value)
    likelihoodKernel(int num_items, int bands, int band_patches, int num_patches, int words,
                     float floor_log_density,
                     const float* __restrict__ x_m,                  // [pixels] camera frame
                     const float* __restrict__ y_m,                  // [pixels]
                     const float* __restrict__ z_m,                  // [pixels]
                     const int* __restrict__ patch_begin,            // [patches + 1]
                     const EvalComponentF* __restrict__ all_comps,   // [M] or [N][M], log2 form
                     int comps_per_particle,                         // 0 or M
                     const RigidTransformF* __restrict__ T_map_cam,  // [N]
                     const uint32_t* __restrict__ mask,              // [N][patches][words]
                     const float* __restrict__ shift,                // [N][patches], nats
                     double* __restrict__ item_ll,                   // [N * bands], nats
                     int* __restrict__ item_hits,                    // [N * bands]
                     int* __restrict__ item_evals,                   // [N * bands]
                     int* __restrict__ item_relevant) {              // [N * bands]
  constexpr int C = 32 / PXG;                                        // component slices
  constexpr int kChunk = PXG * PX;
  // [kWarps][kStage * 3] member records, then [kWarps][min(words, 32) * 32] member lists.
  extern __shared__ float4 s_rec[];
  const int warp = threadIdx.x >> 5;
  const int lane = threadIdx.x & 31;
  const int item = blockIdx.x * kWarps + warp;
  if (item >= num_items) return;  // whole warps leave together
  const int list_cap = min(words, 32) * 32;
  float4* rec = s_rec + warp * (3 * kStage);  // only when STAGE
  uint16_t* list =
      reinterpret_cast<uint16_t*>(s_rec + (STAGE ? kWarps * 3 * kStage : 0)) + warp * list_cap;
  const int particle = item / bands;
  const EvalComponentF* __restrict__ comps =
      all_comps + static_cast<size_t>(particle) * comps_per_particle;
  const float4* comps4 = reinterpret_cast<const float4*>(comps);
  const int p0 = (item - particle * bands) * band_patches;
  const int p1 = min(p0 + band_patches, num_patches);
  const int g = lane % PXG;   // pixel group
  const int sl = lane / PXG;  // component slice
  const RigidTransformF T = T_map_cam[particle];
  const float floor2 = floor_log_density * kLog2e;
  float ll = 0.f;  // this lane's pixels of the band, nats
  int hits = 0;
  int evals = 0, relevant = 0;  // counted on every lane alike (warp-uniform)
  for (int p = p0; p < p1; ++p) {
    const int b = __ldg(patch_begin + p), e = __ldg(patch_begin + p + 1);
    if (b >= e) continue;
    const uint32_t* row = mask + (static_cast<size_t>(particle) * num_patches + p) * words;
    const float S = __ldg(shift + static_cast<size_t>(particle) * num_patches + p);
    const float S2 = S * kLog2e;
    const float floor_term = exp2Approx(floor2 - S2);  // exp(floor) relative to exp(S)
    // Members in rounds of 1024 components: for M <= 1024 one list per patch, built once;
    // otherwise one list per round and chunk.
    const bool one_round = words <= 32;
    int k_total = 0;
    if (one_round) k_total = buildMemberList(row, 0, words, lane, list);
    for (int c0 = b; c0 < e; c0 += kChunk) {
      float px[PX], py[PX], pz[PX], sum[PX];
#pragma unroll
      for (int q = 0; q < PX; ++q) {
        const int i = min(c0 + q * PXG + g, e - 1);
        const float cx = __ldg(x_m + i), cy = __ldg(y_m + i), cz = __ldg(z_m + i);
        px[q] = T.R[0] * cx + T.R[1] * cy + T.R[2] * cz + T.t[0];
        py[q] = T.R[3] * cx + T.R[4] * cy + T.R[5] * cz + T.t[1];
        pz[q] = T.R[6] * cx + T.R[7] * cy + T.R[8] * cz + T.t[2];
        sum[q] = 0.f;
      }
      if (!STAGE) {
        if (one_round) {
          accumulateListed<PX, C>(list, k_total, sl, comps, S2, px, py, pz, sum);
        } else {
          for (int w0 = 0; w0 < words; w0 += 32) {
            const int k = buildMemberList(row, w0, words, lane, list);
            if (c0 == b) k_total += k;
            accumulateListed<PX, C>(list, k, sl, comps + w0 * 32, S2, px, py, pz, sum);
          }
        }
      } else if (one_round) {
        // Members in pieces of kStage; staged once per patch when they fit in one piece.
        for (int t0 = 0; t0 < k_total; t0 += kStage) {
          const int n = min(kStage, k_total - t0);
          if (c0 == b || k_total > kStage) stageMembers(list + t0, n, comps4, lane, rec);
          accumulateStaged<PX, C>(rec, n, sl, S2, px, py, pz, sum);
        }
      } else {
        for (int w0 = 0; w0 < words; w0 += 32) {
          const int k = buildMemberList(row, w0, words, lane, list);
          if (c0 == b) k_total += k;
          for (int t0 = 0; t0 < k; t0 += kStage) {
            const int n = min(kStage, k - t0);
            stageMembers(list + t0, n, comps4 + 3 * (w0 * 32), lane, rec);
            accumulateStaged<PX, C>(rec, n, sl, S2, px, py, pz, sum);
          }
        }
      }
      sumOverSlices<PXG, PX>(sum);
      if (sl == 0) {
#pragma unroll
        for (int q = 0; q < PX; ++q) {
          if (c0 + q * PXG + g < e) {
            ll += S + kLn2 * log2Approx(floor_term + sum[q]);
            hits += sum[q] < floor_term ? 1 : 0;  // mixture density below exp(floor)
          }
        }
      }
    }
    evals += k_total * (e - b);
    relevant += k_total;
  }
  // Warp reduction in a fixed order (deterministic); lane 0 writes the item.
  const double dll = warpSumToLane0(static_cast<double>(ll));
  hits = warpSumToLane0(hits);
  if (lane == 0) {
    item_ll[item] = dll;
    item_hits[item] = hits;
    item_evals[item] = evals;
    item_relevant[item] = relevant;
  }
}

// One warp per particle sums its items' partials (fixed order).
__global__ void __launch_bounds__(kThreads)
    reduceKernel(int num_particles, int num_items,
                 const double* __restrict__ item_ll,      // [N * items]
                 const int* __restrict__ item_hits,       // [N * items]
                 const int* __restrict__ item_evals,      // [N * items]
                 const int* __restrict__ item_relevant,   // [N * items]
                 double* __restrict__ log_likelihood,     // [N] nats
                 int* __restrict__ floor_hits,            // [N]
                 long long* __restrict__ evaluations,     // [N]
                 long long* __restrict__ relevant_pairs,  // [N]
                 const int* __restrict__ order) {         // [N] output index of each; null: itself
  const int particle = (blockIdx.x * kThreads + threadIdx.x) / 32;
  const int lane = threadIdx.x & 31;
  if (particle >= num_particles) return;  // whole warps leave together
  double ll = 0.0;
  int hits = 0;
  long long evals = 0, pairs = 0;
  const size_t base = static_cast<size_t>(particle) * num_items;
  for (int p = lane; p < num_items; p += 32) {
    ll += item_ll[base + p];
    hits += item_hits[base + p];
    evals += item_evals[base + p];
    pairs += item_relevant[base + p];
  }
  ll = warpSumToLane0(ll);
  hits = warpSumToLane0(hits);
  evals = warpSumToLane0(evals);
  pairs = warpSumToLane0(pairs);
  if (lane == 0) {
    const int out = order ? order[particle] : particle;
    log_likelihood[out] = ll;
    floor_hits[out] = hits;
    evaluations[out] = evals;
    relevant_pairs[out] = pairs;
  }
}

}  // namespace

size_t likelihoodSharedBytes(const LikelihoodShape& shape, int words) {
  return (shape.stage_members ? sizeof(float4) * kWarps * 3 * kStage : 0) +
         sizeof(uint16_t) * static_cast<size_t>(kWarps) * (words < 32 ? words : 32) * 32;
}

// Measured on an H100 (7-Scenes M=1000, bench workloads); the parameter cuda_likelihood_shape
// overrides.
LikelihoodShape chooseLikelihoodShape(int max_patch_pixels) {
  LikelihoodShape s;
  if (max_patch_pixels <= 16) {
    s.lanes = 8;  // stride 8: 16 px = 8 groups x 2 px, 4 component slices
    s.pixels_per_lane = 2;
  } else if (max_patch_pixels <= 64) {
    s.lanes = 32;  // stride 4: 64 px = 32 x 2 px
    s.pixels_per_lane = 2;
  } else {
    s.lanes = 32;  // stride 1: 1024 px in chunks of 128
    s.pixels_per_lane = 4;
    // Members' records staged in shared memory once per patch and reused by its 8 chunks
    // (measured: full 3.04 -> 2.81 ms; at strides 4 and 8, one chunk per patch, staging cost
    // more than it saved: paper 0.312 -> 0.332 ms).
    s.stage_members = true;
  }
  s.band_patches = 10;
  return s;
}

int likelihoodItemsPerParticle(const LikelihoodShape& shape, int num_patches) {
  const int band = shape.band_patches > 0 ? shape.band_patches : 1;
  return (num_patches + band - 1) / band;
}

cudaError_t launchLikelihood(int num_particles, const LikelihoodInputs& in,
                             const LikelihoodShape& shape, float floor_log_density,
                             const ItemPartials& partials, cudaStream_t stream) {
  const int bands = likelihoodItemsPerParticle(shape, in.num_patches);
  const long long items = static_cast<long long>(num_particles) * bands;
  if (items <= 0 || in.words <= 0) return cudaSuccess;
  const int band = shape.band_patches > 0 ? shape.band_patches : 1;
  const dim3 grid(static_cast<unsigned>((items + kWarps - 1) / kWarps)), block(kThreads);
  const size_t smem = likelihoodSharedBytes(shape, in.words);
#define GMM_MCL_LAUNCH(PXG, PX, STAGE)                                                           \
  likelihoodKernel<PXG, PX, STAGE><<<grid, block, smem, stream>>>(                               \
      static_cast<int>(items), bands, band, in.num_patches, in.words, floor_log_density, in.x_m, \
      in.y_m, in.z_m, in.patch_begin, in.components, in.components_per_particle, in.T_map_cam,   \
      in.mask, in.shift, partials.log_likelihood, partials.floor_hits, partials.evaluations,     \
      partials.relevant)
  if (shape.stage_members) {
    if (shape.lanes != 32 || shape.pixels_per_lane != 4) return cudaErrorInvalidValue;
    GMM_MCL_LAUNCH(32, 4, true);
    return cudaGetLastError();
  }
  switch (shape.lanes * 10 + shape.pixels_per_lane) {
    case 324:
      GMM_MCL_LAUNCH(32, 4, false);
      break;
    case 322:
      GMM_MCL_LAUNCH(32, 2, false);
      break;
    case 321:
      GMM_MCL_LAUNCH(32, 1, false);
      break;
    case 164:
      GMM_MCL_LAUNCH(16, 4, false);
      break;
    case 162:
      GMM_MCL_LAUNCH(16, 2, false);
      break;
    case 161:
      GMM_MCL_LAUNCH(16, 1, false);
      break;
    case 84:
      GMM_MCL_LAUNCH(8, 4, false);
      break;
    case 82:
      GMM_MCL_LAUNCH(8, 2, false);
      break;
    case 81:
      GMM_MCL_LAUNCH(8, 1, false);
      break;
    case 44:
      GMM_MCL_LAUNCH(4, 4, false);
      break;
    case 42:
      GMM_MCL_LAUNCH(4, 2, false);
      break;
    default:
      return cudaErrorInvalidValue;
  }
#undef GMM_MCL_LAUNCH
  return cudaGetLastError();
}

cudaError_t launchReduce(int num_particles, int items_per_particle, const ItemPartials& partials,
                         double* log_likelihood, int* floor_hits, long long* evaluations,
                         long long* relevant_pairs, const int* order, cudaStream_t stream) {
  if (num_particles <= 0 || items_per_particle <= 0) return cudaSuccess;
  const long long threads = static_cast<long long>(num_particles) * 32;
  const dim3 grid(static_cast<unsigned>((threads + kThreads - 1) / kThreads)), block(kThreads);
  reduceKernel<<<grid, block, 0, stream>>>(num_particles, items_per_particle,
                                           partials.log_likelihood, partials.floor_hits,
                                           partials.evaluations, partials.relevant, log_likelihood,
                                           floor_hits, evaluations, relevant_pairs, order);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
