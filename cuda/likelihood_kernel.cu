// Per-pixel log-sum over the relevant components of each patch, and the per-particle reduction.
// Work items are (particle, patch) pairs; a group of LANES lanes (a warp or a part of one) takes
// one item, each lane keeping PX pixels of the patch in registers so that each component is
// loaded once per PX evaluations. Items are small and many, so the grid has no tail to speak
// of. The sum is shifted by the patch's largest member log-normaliser (>= the floor): every
// exponent is <= 0 and no second pass for the maximum is needed; the floor term
// exp(floor - shift) stays far above underflow for any map whose log-normalisers are within
// ~60 nats of the floor.
#include <math.h>

#include "cuda/kernels.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kThreads = 256;
constexpr float kLog2e = 1.4426950408889634f;

// 2^x on the special-function unit (relative error ~2^-22; results below 2^-126 flush to 0,
// which is negligible next to the floor term).
__device__ __forceinline__ float exp2Approx(float x) {
  float y;
  asm("ex2.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
}

template <int LANES, int PX>
__global__ void __launch_bounds__(kThreads)
    likelihoodKernel(int num_items, int num_patches, int words, float floor_log_density,
                     const float* __restrict__ x_m,            // [pixels] camera frame, by patch
                     const float* __restrict__ y_m,            // [pixels]
                     const float* __restrict__ z_m,            // [pixels]
                     const int* __restrict__ patch_begin,      // [patches + 1]
                     const EvalComponent* __restrict__ comps,  // [M]
                     const RigidTransformF* __restrict__ T_map_cam,  // [N]
                     const uint32_t* __restrict__ mask,              // [N][patches][words]
                     const uint32_t* __restrict__ summary,  // [N][patches][ceil(words / 32)]
                     const float* __restrict__ shift,       // [N][patches], nats
                     double* __restrict__ item_ll,          // [N * patches], nats
                     int* __restrict__ item_hits,           // [N * patches]
                     int* __restrict__ item_evals,          // [N * patches]
                     int* __restrict__ item_relevant) {     // [N * patches]
  extern __shared__ uint32_t s_words[];                     // [kThreads / LANES groups][words]
  const int gid = blockIdx.x * kThreads + threadIdx.x;
  const int item = gid / LANES;
  const int sub = gid % LANES;
  const bool live = item < num_items;
  double ll = 0.0;
  int hits = 0, evals = 0, relevant = 0;
  int b = 0, e = 0;
  const int particle = live ? item / num_patches : 0;
  if (live) {
    const int patch = item - particle * num_patches;
    b = __ldg(patch_begin + patch);
    e = __ldg(patch_begin + patch + 1);
  }
  // The item's mask row in one coalesced load (instead of one dependent load per word).
  uint32_t* words_smem = s_words + (threadIdx.x / LANES) * words;
  {
    const uint32_t* row = mask + static_cast<size_t>(item) * words;
    for (int w = sub; w < words; w += LANES) words_smem[w] = b < e ? __ldg(row + w) : 0u;
  }
  __syncwarp();
  if (b < e) {
    const RigidTransformF T = T_map_cam[particle];
    const float S = __ldg(shift + item);
    const float S2 = S * kLog2e;
    const float floor_term = expf(floor_log_density - S);  // exp(floor) relative to exp(S)
    const int swords = (words + 31) >> 5;
    const uint32_t* srow = summary + static_cast<size_t>(item) * swords;
    for (int c0 = b; c0 < e; c0 += LANES * PX) {
      float px[PX], py[PX], pz[PX], sum[PX];
      bool ok[PX];
#pragma unroll
      for (int q = 0; q < PX; ++q) {
        const int i = c0 + q * LANES + sub;
        ok[q] = i < e;
        const int j = ok[q] ? i : b;
        const float cx = __ldg(x_m + j), cy = __ldg(y_m + j), cz = __ldg(z_m + j);
        px[q] = T.R[0] * cx + T.R[1] * cy + T.R[2] * cz + T.t[0];
        py[q] = T.R[3] * cx + T.R[4] * cy + T.R[5] * cz + T.t[1];
        pz[q] = T.R[6] * cx + T.R[7] * cy + T.R[8] * cz + T.t[2];
        sum[q] = 0.f;
      }
      int k = 0;
      for (int sw = 0; sw < swords; ++sw) {
        uint32_t nonzero = __ldg(srow + sw);
        while (nonzero) {
          const int w = (sw << 5) + __ffs(nonzero) - 1;
          nonzero &= nonzero - 1u;
          uint32_t bits = words_smem[w];
          while (bits) {
            const int j = (w << 5) + __ffs(bits) - 1;
            bits &= bits - 1u;
            ++k;
            const float4 a = __ldg(reinterpret_cast<const float4*>(comps[j].a));
            const float4 pb = __ldg(reinterpret_cast<const float4*>(comps[j].b));
            const float4 pc = __ldg(reinterpret_cast<const float4*>(comps[j].c));
            const float base = a.w - S2;
#pragma unroll
            for (int q = 0; q < PX; ++q) {
              const float dx = px[q] - a.x, dy = py[q] - a.y, dz = pz[q] - a.z;
              const float qa = pb.x * dx + pb.y * dy + pb.z * dz;
              const float qb = pb.w * dy + pc.x * dz;
              const float qc = pc.y * dz;
              const float t = base + dx * qa + dy * qb + dz * qc;  // log2(lambda N) - S2 <= 0
              sum[q] += exp2Approx(t);
            }
          }
        }
      }
#pragma unroll
      for (int q = 0; q < PX; ++q) {
        if (ok[q]) {
          ll += static_cast<double>(S + logf(floor_term + sum[q]));
          hits += sum[q] < floor_term ? 1 : 0;  // mixture density below exp(floor)
          evals += k;
        }
      }
      relevant = k;
    }
  }
  // Reduce within the group (fixed order), the group's first lane writes the item.
#pragma unroll
  for (int off = LANES / 2; off > 0; off >>= 1) {
    ll += __shfl_down_sync(0xffffffffu, ll, off, LANES);
    hits += __shfl_down_sync(0xffffffffu, hits, off, LANES);
    evals += __shfl_down_sync(0xffffffffu, evals, off, LANES);
  }
  if (live && sub == 0) {
    item_ll[item] = ll;
    item_hits[item] = hits;
    item_evals[item] = evals;
    item_relevant[item] = relevant;
  }
}

// The same computation with each item's members first expanded into a list in shared memory
// (rounds of 2 x LANES mask words), so that the evaluation loop is one flat loop over the list:
// no nested bit-scanning loops, and the groups of a warp diverge only in their trip counts.
template <int LANES, int PX>
__global__ void __launch_bounds__(kThreads)
    likelihoodListKernel(int num_items, int num_patches, int words, float floor_log_density,
                         const float* __restrict__ x_m,                  // [pixels] camera frame
                         const float* __restrict__ y_m,                  // [pixels]
                         const float* __restrict__ z_m,                  // [pixels]
                         const int* __restrict__ patch_begin,            // [patches + 1]
                         const EvalComponent* __restrict__ comps,        // [M]
                         const RigidTransformF* __restrict__ T_map_cam,  // [N]
                         const uint32_t* __restrict__ mask,              // [N][patches][words]
                         const float* __restrict__ shift,                // [N][patches], nats
                         double* __restrict__ item_ll,                   // [N * patches], nats
                         int* __restrict__ item_hits,                    // [N * patches]
                         int* __restrict__ item_evals,                   // [N * patches]
                         int* __restrict__ item_relevant) {              // [N * patches]
  constexpr int kRoundWords = 2 * LANES;
  extern __shared__ uint16_t s_list[];  // [kThreads / LANES groups][kRoundWords * 32]
  const int gid = blockIdx.x * kThreads + threadIdx.x;
  const int item = gid / LANES;
  const int sub = gid % LANES;
  const bool live = item < num_items;
  double ll = 0.0;
  int hits = 0, evals = 0, relevant = 0;
  int b = 0, e = 0;
  const int particle = live ? item / num_patches : 0;
  if (live) {
    const int patch = item - particle * num_patches;
    b = __ldg(patch_begin + patch);
    e = __ldg(patch_begin + patch + 1);
  }
  uint16_t* list = s_list + (threadIdx.x / LANES) * (kRoundWords * 32);
  const uint32_t* row = mask + static_cast<size_t>(live ? item : 0) * words;
  // Chunk count made uniform over the warp: every lane takes part in the group shuffles.
  const int my_chunks = (e - b + LANES * PX - 1) / (LANES * PX);
  int max_chunks = my_chunks;
#pragma unroll
  for (int off = 16; off > 0; off >>= 1) {
    max_chunks = max(max_chunks, __shfl_xor_sync(0xffffffffu, max_chunks, off));
  }
  const RigidTransformF T = T_map_cam[particle];
  const float S = b < e ? __ldg(shift + (live ? item : 0)) : floor_log_density;
  const float S2 = S * kLog2e;
  const float floor_term = expf(floor_log_density - S);  // exp(floor) relative to exp(S)
  for (int c = 0; c < max_chunks; ++c) {
    const bool active = c < my_chunks;
    const int c0 = b + c * LANES * PX;
    float px[PX], py[PX], pz[PX], sum[PX];
    bool ok[PX];
#pragma unroll
    for (int q = 0; q < PX; ++q) {
      const int i = c0 + q * LANES + sub;
      ok[q] = active && i < e;
      const int j = ok[q] ? i : 0;
      const float cx = ok[q] ? __ldg(x_m + j) : 0.f;
      const float cy = ok[q] ? __ldg(y_m + j) : 0.f;
      const float cz = ok[q] ? __ldg(z_m + j) : 0.f;
      px[q] = T.R[0] * cx + T.R[1] * cy + T.R[2] * cz + T.t[0];
      py[q] = T.R[3] * cx + T.R[4] * cy + T.R[5] * cz + T.t[1];
      pz[q] = T.R[6] * cx + T.R[7] * cy + T.R[8] * cz + T.t[2];
      sum[q] = 0.f;
    }
    int k = 0;
    for (int w0 = 0; w0 < words; w0 += kRoundWords) {
      const int wa = w0 + sub, wb = w0 + LANES + sub;
      const uint32_t ma = active && wa < words ? __ldg(row + wa) : 0u;
      const uint32_t mb = active && wb < words ? __ldg(row + wb) : 0u;
      const int cnt = __popc(ma) + __popc(mb);
      int incl = cnt;
#pragma unroll
      for (int off = 1; off < LANES; off <<= 1) {
        const int t = __shfl_up_sync(0xffffffffu, incl, off, LANES);
        if (sub >= off) incl += t;
      }
      const int total = __shfl_sync(0xffffffffu, incl, LANES - 1, LANES);
      int pos = incl - cnt;
      for (uint32_t bits = ma; bits; bits &= bits - 1u) list[pos++] = (wa << 5) + __ffs(bits) - 1;
      for (uint32_t bits = mb; bits; bits &= bits - 1u) list[pos++] = (wb << 5) + __ffs(bits) - 1;
      __syncwarp();
      for (int t = 0; t < total; ++t) {
        const int j = list[t];
        const float4 a = __ldg(reinterpret_cast<const float4*>(comps[j].a));
        const float4 pb = __ldg(reinterpret_cast<const float4*>(comps[j].b));
        const float4 pc = __ldg(reinterpret_cast<const float4*>(comps[j].c));
        const float base = a.w - S2;
#pragma unroll
        for (int q = 0; q < PX; ++q) {
          const float dx = px[q] - a.x, dy = py[q] - a.y, dz = pz[q] - a.z;
          const float qa = pb.x * dx + pb.y * dy + pb.z * dz;
          const float qb = pb.w * dy + pc.x * dz;
          const float qc = pc.y * dz;
          const float tt = base + dx * qa + dy * qb + dz * qc;  // log2(lambda N) - S2 <= 0
          sum[q] += exp2Approx(tt);
        }
      }
      k += total;
      __syncwarp();
    }
#pragma unroll
    for (int q = 0; q < PX; ++q) {
      if (ok[q]) {
        ll += static_cast<double>(S + logf(floor_term + sum[q]));
        hits += sum[q] < floor_term ? 1 : 0;  // mixture density below exp(floor)
        evals += k;
      }
    }
    if (active) relevant = k;
  }
#pragma unroll
  for (int off = LANES / 2; off > 0; off >>= 1) {
    ll += __shfl_down_sync(0xffffffffu, ll, off, LANES);
    hits += __shfl_down_sync(0xffffffffu, hits, off, LANES);
    evals += __shfl_down_sync(0xffffffffu, evals, off, LANES);
  }
  if (live && sub == 0) {
    item_ll[item] = ll;
    item_hits[item] = hits;
    item_evals[item] = evals;
    item_relevant[item] = relevant;
  }
}

// One warp per particle sums its patches' partials.
__global__ void __launch_bounds__(kThreads)
    reduceKernel(int num_particles, int num_patches,
                 const double* __restrict__ item_ll,        // [N * patches]
                 const int* __restrict__ item_hits,         // [N * patches]
                 const int* __restrict__ item_evals,        // [N * patches]
                 const int* __restrict__ item_relevant,     // [N * patches]
                 double* __restrict__ log_likelihood,       // [N] nats
                 int* __restrict__ floor_hits,              // [N]
                 long long* __restrict__ evaluations,       // [N]
                 long long* __restrict__ relevant_pairs) {  // [N]
  const int particle = (blockIdx.x * kThreads + threadIdx.x) / 32;
  const int lane = threadIdx.x & 31;
  if (particle >= num_particles) return;  // whole warps leave together
  double ll = 0.0;
  int hits = 0;
  long long evals = 0, pairs = 0;
  const size_t base = static_cast<size_t>(particle) * num_patches;
  for (int p = lane; p < num_patches; p += 32) {
    ll += item_ll[base + p];
    hits += item_hits[base + p];
    evals += item_evals[base + p];
    pairs += item_relevant[base + p];
  }
#pragma unroll
  for (int off = 16; off > 0; off >>= 1) {
    ll += __shfl_down_sync(0xffffffffu, ll, off);
    hits += __shfl_down_sync(0xffffffffu, hits, off);
    evals += __shfl_down_sync(0xffffffffu, evals, off);
    pairs += __shfl_down_sync(0xffffffffu, pairs, off);
  }
  if (lane == 0) {
    log_likelihood[particle] = ll;
    floor_hits[particle] = hits;
    evaluations[particle] = evals;
    relevant_pairs[particle] = pairs;
  }
}

}  // namespace

EvalComponent makeEvalComponent(const ComponentF& c) {
  const float s = -0.5f * kLog2e;
  EvalComponent e;
  e.a[0] = c.mean_m[0];
  e.a[1] = c.mean_m[1];
  e.a[2] = c.mean_m[2];
  e.a[3] = c.log_norm * kLog2e;
  e.b[0] = s * c.precision[0];
  e.b[1] = 2.f * s * c.precision[1];
  e.b[2] = 2.f * s * c.precision[2];
  e.b[3] = s * c.precision[3];
  e.c[0] = 2.f * s * c.precision[4];
  e.c[1] = s * c.precision[5];
  e.c[2] = c.log_norm;
  e.c[3] = 0.f;
  return e;
}

size_t likelihoodSharedBytes(const LikelihoodShape& shape, int words) {
  return sizeof(uint32_t) * static_cast<size_t>(kThreads / shape.lanes) * words;
}

// Measured on an H100 (7-Scenes M=1000, bench workloads): four pixels per lane amortise each
// component's loads best; several small patches share a warp rather than leave lanes idle.
LikelihoodShape chooseLikelihoodShape(int max_patch_pixels) {
  LikelihoodShape s;
  s.pixels_per_lane = 4;
  if (max_patch_pixels <= 16) {
    s.lanes = 4;  // stride 8: 16 px per patch, 8 patches per warp
  } else if (max_patch_pixels <= 32) {
    s.lanes = 8;
  } else if (max_patch_pixels <= 64) {
    s.lanes = 16;  // stride 4: 64 px per patch, 2 patches per warp
  } else {
    s.lanes = 32;  // stride 1: 1024 px per patch in chunks of 128
  }
  // The member list pays off where an item's group is large (measured: paper -5%, full -3%,
  // stride 8 +3..5%).
  s.member_list = s.lanes >= 16;
  return s;
}

cudaError_t launchLikelihood(int num_particles, int num_patches, int words,
                             const LikelihoodShape& shape, float floor_log_density,
                             const float* x_m, const float* y_m, const float* z_m,
                             const int* patch_begin, const EvalComponent* components,
                             const RigidTransformF* T_map_cam, const uint32_t* mask,
                             const uint32_t* summary, const float* shift,
                             const ItemPartials& partials, cudaStream_t stream) {
  const long long items = static_cast<long long>(num_particles) * num_patches;
  if (items <= 0) return cudaSuccess;
  const long long threads = items * shape.lanes;
  const dim3 grid(static_cast<unsigned>((threads + kThreads - 1) / kThreads)), block(kThreads);
  const size_t smem = likelihoodSharedBytes(shape, words);
  if (shape.member_list) {
    const size_t list_smem = sizeof(uint16_t) * kThreads * 2 * 32;  // 32 KB
#define GMM_MCL_LAUNCH_LIST(L, PX)                                                                \
  likelihoodListKernel<L, PX><<<grid, block, list_smem, stream>>>(                                \
      static_cast<int>(items), num_patches, words, floor_log_density, x_m, y_m, z_m, patch_begin, \
      components, T_map_cam, mask, shift, partials.log_likelihood, partials.floor_hits,           \
      partials.evaluations, partials.relevant)
    switch (shape.lanes * 10 + shape.pixels_per_lane) {
      case 44:
        GMM_MCL_LAUNCH_LIST(4, 4);
        break;
      case 84:
        GMM_MCL_LAUNCH_LIST(8, 4);
        break;
      case 164:
        GMM_MCL_LAUNCH_LIST(16, 4);
        break;
      case 162:
        GMM_MCL_LAUNCH_LIST(16, 2);
        break;
      case 322:
        GMM_MCL_LAUNCH_LIST(32, 2);
        break;
      case 324:
        GMM_MCL_LAUNCH_LIST(32, 4);
        break;
      default:
        return cudaErrorInvalidValue;
    }
#undef GMM_MCL_LAUNCH_LIST
    return cudaGetLastError();
  }
#define GMM_MCL_LAUNCH(L, PX)                                                                     \
  likelihoodKernel<L, PX><<<grid, block, smem, stream>>>(                                         \
      static_cast<int>(items), num_patches, words, floor_log_density, x_m, y_m, z_m, patch_begin, \
      components, T_map_cam, mask, summary, shift, partials.log_likelihood, partials.floor_hits,  \
      partials.evaluations, partials.relevant)
  const int key = shape.lanes * 10 + shape.pixels_per_lane;
  switch (key) {
    case 44:
      GMM_MCL_LAUNCH(4, 4);
      break;
    case 84:
      GMM_MCL_LAUNCH(8, 4);
      break;
    case 164:
      GMM_MCL_LAUNCH(16, 4);
      break;
    case 81:
      GMM_MCL_LAUNCH(8, 1);
      break;
    case 82:
      GMM_MCL_LAUNCH(8, 2);
      break;
    case 161:
      GMM_MCL_LAUNCH(16, 1);
      break;
    case 162:
      GMM_MCL_LAUNCH(16, 2);
      break;
    case 321:
      GMM_MCL_LAUNCH(32, 1);
      break;
    case 322:
      GMM_MCL_LAUNCH(32, 2);
      break;
    case 324:
      GMM_MCL_LAUNCH(32, 4);
      break;
    default:
      return cudaErrorInvalidValue;
  }
#undef GMM_MCL_LAUNCH
  return cudaGetLastError();
}

cudaError_t launchReduce(int num_particles, int num_patches, const ItemPartials& partials,
                         double* log_likelihood, int* floor_hits, long long* evaluations,
                         long long* relevant_pairs, cudaStream_t stream) {
  if (num_particles <= 0 || num_patches <= 0) return cudaSuccess;
  const long long threads = static_cast<long long>(num_particles) * 32;
  const dim3 grid(static_cast<unsigned>((threads + kThreads - 1) / kThreads)), block(kThreads);
  reduceKernel<<<grid, block, 0, stream>>>(num_particles, num_patches, partials.log_likelihood,
                                           partials.floor_hits, partials.evaluations,
                                           partials.relevant, log_likelihood, floor_hits,
                                           evaluations, relevant_pairs);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
