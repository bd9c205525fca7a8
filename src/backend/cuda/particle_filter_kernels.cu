// Kernels of the device particle filter: sampling with counter-based random numbers (Philox,
// curand's device API), camera poses, the tempered weight update with its Neff-floor bisection,
// the estimate, the stratified low-variance resampling and the KLD bins. Reductions are
// deterministic: each block reduces its elements in a fixed tree, and the last block to finish
// (elected by an atomic ticket) adds the blocks' partials in block order, so a result depends on
// n only, not on timing. Host/device math from gmm_mcl/internal/particle_math.h.
#include <curand_kernel.h>
#include <math.h>

#include "cuda/filter_kernels.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

constexpr int kThreads = 256;

int blocksFor(int n) { return (n + kThreads - 1) / kThreads; }
int reduceBlocksFor(int n) {
  const int b = blocksFor(n);
  return b < 1 ? 1 : (b > kReduceBlocks ? kReduceBlocks : b);
}

__device__ __forceinline__ curandStatePhilox4_32_10_t randomState(const RandomCall& rc, int i) {
  curandStatePhilox4_32_10_t st;
  curand_init(rc.seed, (rc.call << 32) + static_cast<unsigned long long>(i), 0, &st);
  return st;
}

// Uniform in [-1, 1).
__device__ __forceinline__ double symmetricUniform(curandStatePhilox4_32_10_t* st) {
  return 1.0 - 2.0 * curand_uniform_double(st);  // curand_uniform_double is in (0, 1]
}

// ---- deterministic reductions of K doubles ----------------------------------------------------

template <int K>
struct Vec {
  double v[K];
};

// Tree reduction of one value per thread (all kThreads threads call it).
template <int K, typename Op>
__device__ Vec<K> blockReduce(const Vec<K>& mine, const Op& op) {
  __shared__ double s[K][kThreads];
  for (int k = 0; k < K; ++k) s[k][threadIdx.x] = mine.v[k];
  __syncthreads();
  for (int width = kThreads / 2; width > 0; width >>= 1) {
    if (threadIdx.x < width) {
      Vec<K> a, b;
      for (int k = 0; k < K; ++k) {
        a.v[k] = s[k][threadIdx.x];
        b.v[k] = s[k][threadIdx.x + width];
      }
      op(&a, b);
      for (int k = 0; k < K; ++k) s[k][threadIdx.x] = a.v[k];
    }
    __syncthreads();
  }
  Vec<K> out;
  for (int k = 0; k < K; ++k) out.v[k] = s[k][0];
  __syncthreads();  // s is reused by the next call
  return out;
}

// Grid-wide reduction: true in the last block to finish, whose *result is the reduction of every
// block's value in block order (all its threads get it).
template <int K, typename Op>
__device__ bool gridReduce(const Vec<K>& mine, const Vec<K>& identity, const Op& op,
                           const ReduceScratch& scratch, Vec<K>* result) {
  static_assert(K <= kReduceMaxValues, "too many values per partial");
  const Vec<K> b = blockReduce<K>(mine, op);
  __shared__ bool s_last;
  if (threadIdx.x == 0) {
    for (int k = 0; k < K; ++k) scratch.partials[blockIdx.x * kReduceMaxValues + k] = b.v[k];
    __threadfence();
    const unsigned ticket = atomicInc(scratch.counter, gridDim.x - 1);  // wraps to 0: reset
    s_last = ticket == gridDim.x - 1;
  }
  __syncthreads();
  if (!s_last) return false;
  __threadfence();
  Vec<K> acc = identity;
  for (int blk = threadIdx.x; blk < static_cast<int>(gridDim.x); blk += kThreads) {
    Vec<K> x;
    for (int k = 0; k < K; ++k) x.v[k] = __ldcg(&scratch.partials[blk * kReduceMaxValues + k]);
    op(&acc, x);
  }
  *result = blockReduce<K>(acc, op);
  return true;
}

template <int K>
struct SumOp {
  __device__ void operator()(Vec<K>* a, const Vec<K>& b) const {
    for (int k = 0; k < K; ++k) a->v[k] += b.v[k];
  }
};

template <int K>
__device__ Vec<K> zeros() {
  Vec<K> z;
  for (int k = 0; k < K; ++k) z.v[k] = 0.0;
  return z;
}

// ---- sampling ---------------------------------------------------------------------------------

__global__ void __launch_bounds__(kThreads)
    predictKernel(int n, RandomCall rc, PredictConfig cfg,
                  ParticleState* __restrict__ particles) {  // [n] in/out
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  const double2 a = curand_normal2_double(&st);
  const double2 b = curand_normal2_double(&st);
  const double noise[4] = {a.x, a.y, b.x, b.y};
  ParticleState p = particles[i];
  predictParticle(cfg.delta, noise, cfg.sigma_m, cfg.sigma_rad, &p);
  particles[i] = p;
}

__global__ void __launch_bounds__(kThreads)
    uniformKernel(int n, RandomCall rc, RegionBox region, ParticleState* __restrict__ out,
                  double* __restrict__ weights, double weight) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  double u[4];
  for (int k = 0; k < 4; ++k) u[k] = symmetricUniform(&st);
  out[i] = regionPoint(region, u);
  if (weights) weights[i] = weight;
}

__global__ void __launch_bounds__(kThreads)
    gaussianKernel(int n, RandomCall rc, ParticleState mean, double sx, double sy, double sz,
                   double sa, ParticleState* __restrict__ out, double* __restrict__ weights,
                   double weight) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  const double2 a = curand_normal2_double(&st);
  const double2 b = curand_normal2_double(&st);
  ParticleState p;
  p.x_m = mean.x_m + sx * a.x;
  p.y_m = mean.y_m + sy * a.y;
  p.z_m = mean.z_m + sz * b.x;
  p.yaw_rad = wrapAngleHD(mean.yaw_rad + sa * b.y);
  out[i] = p;
  if (weights) weights[i] = weight;
}

__global__ void __launch_bounds__(kThreads)
    aroundKernel(int n, RandomCall rc, const ParticleState* __restrict__ centres,  // [num_centres]
                 int num_centres, double sigma_m, double sigma_rad,
                 ParticleState* __restrict__ out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  const double2 a = curand_normal2_double(&st);
  const double2 b = curand_normal2_double(&st);
  const ParticleState c = centres[i % num_centres];
  ParticleState p;
  p.x_m = c.x_m + sigma_m * a.x;
  p.y_m = c.y_m + sigma_m * a.y;
  p.z_m = c.z_m + sigma_m * b.x;
  p.yaw_rad = wrapAngleHD(c.yaw_rad + sigma_rad * b.y);
  out[i] = p;
}

__global__ void __launch_bounds__(kThreads)
    cameraPosesKernel(int n, const ParticleState* __restrict__ particles, CameraMount mount,
                      RigidTransformF* __restrict__ T_map_cam,
                      RigidTransformF* __restrict__ T_cam_map) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const RigidTransformF T = cameraPoseOf(particles[i], mount);
  T_map_cam[i] = T;
  T_cam_map[i] = invertRigid(T);  // as the CUDA backend's host staging does
}

__global__ void __launch_bounds__(kThreads) fillKernel(int n, double value, double* __restrict__ out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = value;
}

// ---- weights ----------------------------------------------------------------------------------

// (best finite, argmax value, -argmax index, finite count, prior sum, prior sum of squares)
struct StartOp {
  __device__ void operator()(Vec<6>* a, const Vec<6>& b) const {
    a->v[0] = fmax(a->v[0], b.v[0]);
    // The first of the largest: larger value, or equal value and smaller index.
    if (b.v[1] > a->v[1] || (b.v[1] == a->v[1] && b.v[2] > a->v[2])) {
      a->v[1] = b.v[1];
      a->v[2] = b.v[2];
    }
    a->v[3] += b.v[3];
    a->v[4] += b.v[4];
    a->v[5] += b.v[5];
  }
};

__global__ void __launch_bounds__(kThreads)
    weightStartKernel(int n, WeightConfig cfg, const double* __restrict__ ll,  // [n] nats
                      const double* __restrict__ weights,                      // [n] prior
                      WeightState* __restrict__ state, ReduceScratch scratch) {
  Vec<6> mine;
  mine.v[0] = -INFINITY;
  mine.v[1] = -INFINITY;
  mine.v[2] = -static_cast<double>(n);
  mine.v[3] = mine.v[4] = mine.v[5] = 0.0;
  const Vec<6> identity = mine;
  const StartOp op;
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double l = ll[i];
    Vec<6> x = identity;
    if (isfinite(l)) {
      x.v[0] = l;
      x.v[3] = 1.0;
      x.v[4] = weights[i];
      x.v[5] = weights[i] * weights[i];
    }
    if (!isnan(l)) {
      x.v[1] = l;
      x.v[2] = -static_cast<double>(i);
    }
    op(&mine, x);
  }
  Vec<6> r;
  if (!gridReduce<6>(mine, identity, op, scratch, &r) || threadIdx.x != 0) return;
  WeightState s;
  s.best = r.v[0];
  s.argmax_ll = r.v[1];
  s.argmax = r.v[1] == -INFINITY && r.v[2] == -static_cast<double>(n) ? 0
                                                                        : static_cast<int>(-r.v[2]);
  s.finite = static_cast<int>(r.v[3]);
  s.neff_prior = r.v[5] > 0.0 ? r.v[4] * r.v[4] / r.v[5] : 0.0;
  s.neff_max = 0.0;
  s.bisect = kExponentMax;
  s.ok = 0;
  s.lo = 0.0;
  s.hi = cfg.beta_max;
  s.beta = cfg.beta_max;
  s.beta_fraction = 1.0;
  s.recover_sum = 0.0;
  s.total = 0.0;
  s.mean_ll = 0.0;
  s.neff = 0.0;
  s.best_hits = 0;
  *state = s;
}

// Neff of the tempered weights at beta_max (first: also the recovery sum), or at the bisection's
// midpoint (then a no-op unless the floor binds).
__global__ void __launch_bounds__(kThreads)
    neffKernel(int n, WeightConfig cfg, int first, const double* __restrict__ ll,
               const double* __restrict__ weights, WeightState* __restrict__ state,
               ReduceScratch scratch) {
  const WeightState s = *state;
  if (s.finite == 0 || !cfg.tempered || (!first && s.bisect != kExponentBisected)) return;
  const double beta = first ? cfg.beta_max : 0.5 * (s.lo + s.hi);
  const double px = cfg.pixels;
  const double mx = s.best / px;
  Vec<3> mine = zeros<3>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double l = ll[i];
    if (!isfinite(l)) continue;
    const double w = weights[i] * exp((l - s.best) * beta);
    mine.v[0] += w;
    mine.v[1] += w * w;
    if (first) mine.v[2] += exp(l / px - mx);
  }
  Vec<3> r;
  if (!gridReduce<3>(mine, zeros<3>(), SumOp<3>(), scratch, &r) || threadIdx.x != 0) return;
  const double neff = r.v[1] > 0.0 ? r.v[0] * r.v[0] / r.v[1] : 0.0;
  if (first) {
    state->neff_max = neff;
    state->recover_sum = r.v[2];
    // ParticleFilter::updateWeights: bisect when the update at beta_max would fall below the
    // floor and beta = 0 would not; where both fall below it, the weights of beta = 0 (the
    // prior's) are kept, reported as the full exponent.
    if (neff < cfg.neff_floor) {
      state->bisect = s.neff_prior > cfg.neff_floor ? kExponentBisected : kExponentZero;
    }
  } else if (neff >= cfg.neff_floor) {
    state->lo = beta;
  } else {
    state->hi = beta;
  }
}

// Recovery sum for the paper weighting (no Neff passes run there).
__global__ void __launch_bounds__(kThreads)
    recoverSumKernel(int n, WeightConfig cfg, const double* __restrict__ ll,
                     WeightState* __restrict__ state, ReduceScratch scratch) {
  const WeightState s = *state;
  if (s.finite == 0) return;
  const double px = cfg.pixels;
  const double mx = s.best / px;
  Vec<1> mine = zeros<1>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double l = ll[i];
    if (isfinite(l)) mine.v[0] += exp(l / px - mx);
  }
  Vec<1> r;
  if (!gridReduce<1>(mine, zeros<1>(), SumOp<1>(), scratch, &r) || threadIdx.x != 0) return;
  state->recover_sum = r.v[0];
}

__global__ void __launch_bounds__(kThreads)
    applyWeightsKernel(int n, WeightConfig cfg, const double* __restrict__ ll,
                       const double* __restrict__ weights, double* __restrict__ w_new,
                       WeightState* __restrict__ state, ReduceScratch scratch) {
  const WeightState s = *state;
  if (s.finite == 0) return;
  double beta = cfg.beta_max;
  if (s.bisect == kExponentBisected) beta = s.lo;
  if (s.bisect == kExponentZero) beta = 0.0;
  // kPaper: NLL_i = -L_i, shifted so that the best NLL is at least the margin.
  const double shift = fmax(0.0, cfg.paper_margin - (-s.best));
  const double floor_nll = fmax(cfg.paper_margin, 2.2250738585072014e-308);
  Vec<1> mine = zeros<1>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double l = ll[i];
    double w = 0.0;
    if (isfinite(l)) {
      w = cfg.tempered ? weights[i] * exp((l - s.best) * beta)
                       : weights[i] / fmax(-l + shift, floor_nll);
    }
    w_new[i] = w;
    mine.v[0] += w;
  }
  Vec<1> r;
  if (!gridReduce<1>(mine, zeros<1>(), SumOp<1>(), scratch, &r) || threadIdx.x != 0) return;
  state->total = r.v[0];
  state->ok = r.v[0] > 0.0 && isfinite(r.v[0]) ? 1 : 0;
  state->beta = beta;
  state->beta_fraction = s.bisect == kExponentBisected ? s.lo / cfg.beta_max : 1.0;
}

// Normalised weights (when the update is usable) and the scores over them.
__global__ void __launch_bounds__(kThreads)
    normaliseKernel(int n, const double* __restrict__ ll, const int* __restrict__ floor_hits,
                    const double* __restrict__ w_new, double* __restrict__ weights,
                    WeightState* __restrict__ state, ReduceScratch scratch) {
  const WeightState s = *state;
  if (s.finite == 0 || !s.ok) return;
  Vec<2> mine = zeros<2>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double w = w_new[i] / s.total;
    weights[i] = w;
    if (w > 0.0) mine.v[0] += w * ll[i];
    mine.v[1] += w * w;
  }
  Vec<2> r;
  if (!gridReduce<2>(mine, zeros<2>(), SumOp<2>(), scratch, &r) || threadIdx.x != 0) return;
  state->mean_ll = r.v[0];
  state->neff = r.v[1] > 0.0 ? 1.0 / r.v[1] : 0.0;
  state->best_hits = floor_hits[s.argmax];
}

// ---- estimate ---------------------------------------------------------------------------------

// Pass 1: sx, sy, sz, sum w cos, sum w sin, sum w^2, sum w.
__global__ void __launch_bounds__(kThreads)
    momentsKernel(int n, const ParticleState* __restrict__ p, const double* __restrict__ w,
                  EstimateState* __restrict__ state, ReduceScratch scratch) {
  Vec<7> mine = zeros<7>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double wi = w[i];
    mine.v[0] += wi * p[i].x_m;
    mine.v[1] += wi * p[i].y_m;
    mine.v[2] += wi * p[i].z_m;
    mine.v[3] += wi * cos(p[i].yaw_rad);
    mine.v[4] += wi * sin(p[i].yaw_rad);
    mine.v[5] += wi * wi;
    mine.v[6] += wi;
  }
  Vec<7> r;
  if (!gridReduce<7>(mine, zeros<7>(), SumOp<7>(), scratch, &r) || threadIdx.x != 0) return;
  state->mean[0] = r.v[0];
  state->mean[1] = r.v[1];
  state->mean[2] = r.v[2];
  state->mean[3] = atan2(r.v[4], r.v[3]);
  state->neff = r.v[5] > 0.0 ? 1.0 / r.v[5] : 0.0;
  state->total = r.v[6];
}

// Pass 2: the weighted covariance of (x, y, z, yaw) around the mean, yaw differences wrapped.
__global__ void __launch_bounds__(kThreads)
    covarianceKernel(int n, const ParticleState* __restrict__ p, const double* __restrict__ w,
                     EstimateState* __restrict__ state, ReduceScratch scratch) {
  const double mx = state->mean[0], my = state->mean[1], mz = state->mean[2],
               ma = state->mean[3];
  Vec<10> mine = zeros<10>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const double wi = w[i];
    const double d[4] = {p[i].x_m - mx, p[i].y_m - my, p[i].z_m - mz,
                         wrapAngleHD(p[i].yaw_rad - ma)};
    int k = 0;
    for (int r = 0; r < 4; ++r) {
      for (int c = r; c < 4; ++c) mine.v[k++] += wi * d[r] * d[c];
    }
  }
  Vec<10> r;
  if (!gridReduce<10>(mine, zeros<10>(), SumOp<10>(), scratch, &r) || threadIdx.x != 0) return;
  for (int k = 0; k < 10; ++k) state->cov[k] = r.v[k];
}

__global__ void __launch_bounds__(kThreads)
    sumKernel(int n, const double* __restrict__ w, double* __restrict__ total,
              ReduceScratch scratch) {
  Vec<1> mine = zeros<1>();
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    mine.v[0] += w[i];
  }
  Vec<1> r;
  if (!gridReduce<1>(mine, zeros<1>(), SumOp<1>(), scratch, &r) || threadIdx.x != 0) return;
  *total = r.v[0];
}

__global__ void __launch_bounds__(kThreads)
    sumCountsKernel(int n, const long long* __restrict__ a, const long long* __restrict__ b,
                    unsigned long long* __restrict__ sums) {  // [2], integers: order-free
  __shared__ unsigned long long s[2];
  if (threadIdx.x < 2) s[threadIdx.x] = 0ull;
  __syncthreads();
  unsigned long long sa = 0ull, sb = 0ull;
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    sa += static_cast<unsigned long long>(a[i]);
    sb += static_cast<unsigned long long>(b[i]);
  }
  atomicAdd(&s[0], sa);
  atomicAdd(&s[1], sb);
  __syncthreads();
  if (threadIdx.x == 0) {
    atomicAdd(&sums[0], s[0]);
    atomicAdd(&sums[1], s[1]);
  }
}

__global__ void __launch_bounds__(kThreads)
    divideKernel(int n, const double* __restrict__ total, double* __restrict__ w) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) w[i] /= total[0];
}

// ---- resampling -------------------------------------------------------------------------------

__global__ void __launch_bounds__(kThreads)
    randomKeysKernel(int n, RandomCall rc, uint32_t* __restrict__ keys, int* __restrict__ values) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  keys[i] = curand(&st);
  values[i] = i;
}

__global__ void __launch_bounds__(kThreads)
    permuteScaledKernel(int n, const int* __restrict__ order, const double* __restrict__ w,
                        const double* __restrict__ total, int n_out, double* __restrict__ out) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= n) return;
  const double scale = n_out / total[0];
  out[j] = w[order[j]] * scale;
}

__global__ void offsetsKernel(int groups, RandomCall rc, double* __restrict__ offsets) {
  const int g = blockIdx.x * blockDim.x + threadIdx.x;
  if (g >= groups) return;
  curandStatePhilox4_32_10_t st = randomState(rc, g);
  offsets[g] = 1.0 - curand_uniform_double(&st);  // [0, 1)
}

__global__ void __launch_bounds__(kThreads)
    stratifiedKernel(int n, int n_out, int groups,
                     const double* __restrict__ cumulative,  // [n] inclusive, scaled to n_out
                     const int* __restrict__ order,          // [n]
                     const double* __restrict__ offsets,     // [groups] in [0, 1)
                     int* __restrict__ indices) {            // [n_out]
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n_out) return;
  // Groups of q + 1 outputs first (r of them), then groups of q.
  const int q = n_out / groups, r = n_out % groups;
  const int g = k < r * (q + 1) ? k / (q + 1) : r + (k - r * (q + 1)) / q;
  const double u = k + offsets[g];
  int lo = 0, hi = n;  // first j with cumulative[j] > u
  while (lo < hi) {
    const int mid = (lo + hi) >> 1;
    if (cumulative[mid] <= u) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  indices[k] = order[lo < n - 1 ? lo : n - 1];
}

__global__ void __launch_bounds__(kThreads)
    binKeysKernel(int n, const int* __restrict__ indices, const ParticleState* __restrict__ p,
                  double inv_bin_m, double inv_bin_rad, uint64_t* __restrict__ keys) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) keys[k] = kldBinKey(p[indices[k]], inv_bin_m, inv_bin_rad);
}

__global__ void __launch_bounds__(kThreads)
    countDistinctKernel(int n, const uint64_t* __restrict__ sorted, int* __restrict__ count) {
  __shared__ int s_count;
  if (threadIdx.x == 0) s_count = 0;
  __syncthreads();
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n && (k == 0 || sorted[k] != sorted[k - 1])) atomicAdd(&s_count, 1);
  __syncthreads();
  if (threadIdx.x == 0 && s_count > 0) atomicAdd(count, s_count);  // integer: order-free
}

__global__ void __launch_bounds__(kThreads)
    gatherKernel(int n, const int* __restrict__ indices, const ParticleState* __restrict__ in,
                 const double* __restrict__ in_ll, ParticleState* __restrict__ out,
                 double* __restrict__ out_ll) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const int src = indices[k];
  out[k] = in[src];
  if (in_ll) out_ll[k] = in_ll[src];
}

__global__ void __launch_bounds__(kThreads)
    gatherValuesKernel(int n, const int* __restrict__ indices, const double* __restrict__ in,
                       double* __restrict__ out) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) out[k] = in[indices[k]];
}

__global__ void __launch_bounds__(kThreads)
    reinitialiseKernel(int count, const int* __restrict__ idx, RandomCall rc, RegionBox region,
                       ParticleState* __restrict__ particles, double* __restrict__ weights,
                       double weight) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= count) return;
  curandStatePhilox4_32_10_t st = randomState(rc, k);
  double u[4];
  for (int j = 0; j < 4; ++j) u[j] = symmetricUniform(&st);
  particles[idx[k]] = regionPoint(region, u);
  weights[idx[k]] = weight;
}

__global__ void __launch_bounds__(kThreads)
    scoreKeysKernel(int n, const double* __restrict__ ll, double* __restrict__ keys,
                    int* __restrict__ values) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const double l = ll[i];
  keys[i] = isfinite(l) ? l : -INFINITY;
  values[i] = i;
}

}  // namespace

// ---- launchers --------------------------------------------------------------------------------

cudaError_t launchPredict(int n, RandomCall rc, const PredictConfig& cfg, ParticleState* particles,
                          cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  predictKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, rc, cfg, particles);
  return cudaGetLastError();
}

cudaError_t launchUniform(int n, RandomCall rc, const RegionBox& region, ParticleState* out,
                          double* weights, double weight, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  uniformKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, rc, region, out, weights, weight);
  return cudaGetLastError();
}

cudaError_t launchGaussian(int n, RandomCall rc, const ParticleState& mean, const double sigma[4],
                           ParticleState* out, double* weights, double weight,
                           cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  gaussianKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, rc, mean, sigma[0], sigma[1], sigma[2],
                                                         sigma[3], out, weights, weight);
  return cudaGetLastError();
}

cudaError_t launchAround(int n, RandomCall rc, const ParticleState* centres, int num_centres,
                         double sigma_m, double sigma_rad, ParticleState* out,
                         cudaStream_t stream) {
  if (n <= 0 || num_centres <= 0) return cudaSuccess;
  aroundKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, rc, centres, num_centres, sigma_m,
                                                       sigma_rad, out);
  return cudaGetLastError();
}

cudaError_t launchCameraPoses(int n, const ParticleState* particles, const CameraMount& mount,
                              RigidTransformF* T_map_cam, RigidTransformF* T_cam_map,
                              cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  cameraPosesKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, particles, mount, T_map_cam,
                                                            T_cam_map);
  return cudaGetLastError();
}

cudaError_t launchFill(int n, double value, double* out, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  fillKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, value, out);
  return cudaGetLastError();
}

cudaError_t launchWeightStart(int n, const WeightConfig& cfg, const double* ll,
                              const double* weights, WeightState* state, ReduceScratch scratch,
                              cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  const int blocks = reduceBlocksFor(n);
  weightStartKernel<<<blocks, kThreads, 0, stream>>>(n, cfg, ll, weights, state, scratch);
  if (cfg.tempered) {
    neffKernel<<<blocks, kThreads, 0, stream>>>(n, cfg, 1, ll, weights, state, scratch);
  } else {
    recoverSumKernel<<<blocks, kThreads, 0, stream>>>(n, cfg, ll, state, scratch);
  }
  return cudaGetLastError();
}

cudaError_t launchWeightBisection(int n, const WeightConfig& cfg, int iterations,
                                  const double* ll, const double* weights, WeightState* state,
                                  ReduceScratch scratch, cudaStream_t stream) {
  if (n <= 0 || !cfg.tempered) return cudaSuccess;
  const int blocks = reduceBlocksFor(n);
  for (int it = 0; it < iterations; ++it) {
    neffKernel<<<blocks, kThreads, 0, stream>>>(n, cfg, 0, ll, weights, state, scratch);
  }
  return cudaGetLastError();
}

cudaError_t launchWeightFinish(int n, const WeightConfig& cfg, const double* ll,
                               const int* floor_hits, double* weights, double* w_new,
                               WeightState* state, ReduceScratch scratch, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  const int blocks = reduceBlocksFor(n);
  applyWeightsKernel<<<blocks, kThreads, 0, stream>>>(n, cfg, ll, weights, w_new, state, scratch);
  normaliseKernel<<<blocks, kThreads, 0, stream>>>(n, ll, floor_hits, w_new, weights, state,
                                                   scratch);
  return cudaGetLastError();
}

cudaError_t launchEstimate(int n, const ParticleState* particles, const double* weights,
                           EstimateState* state, ReduceScratch scratch, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  const int blocks = reduceBlocksFor(n);
  momentsKernel<<<blocks, kThreads, 0, stream>>>(n, particles, weights, state, scratch);
  covarianceKernel<<<blocks, kThreads, 0, stream>>>(n, particles, weights, state, scratch);
  return cudaGetLastError();
}

cudaError_t launchSum(int n, const double* w, double* total, ReduceScratch scratch,
                      cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  sumKernel<<<reduceBlocksFor(n), kThreads, 0, stream>>>(n, w, total, scratch);
  return cudaGetLastError();
}

cudaError_t launchSumCounts(int n, const long long* a, const long long* b,
                            unsigned long long* sums, cudaStream_t stream) {
  cudaError_t err = cudaMemsetAsync(sums, 0, 2 * sizeof(unsigned long long), stream);
  if (err != cudaSuccess || n <= 0) return err;
  sumCountsKernel<<<reduceBlocksFor(n), kThreads, 0, stream>>>(n, a, b, sums);
  return cudaGetLastError();
}

cudaError_t launchDivide(int n, const double* total, double* w, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  divideKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, total, w);
  return cudaGetLastError();
}

cudaError_t launchRandomKeys(int n, RandomCall rc, uint32_t* keys, int* values,
                             cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  randomKeysKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, rc, keys, values);
  return cudaGetLastError();
}

cudaError_t launchPermuteScaled(int n, const int* order, const double* w, const double* total,
                                int n_out, double* out, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  permuteScaledKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, order, w, total, n_out, out);
  return cudaGetLastError();
}

cudaError_t launchOffsets(int groups, RandomCall rc, double* offsets, cudaStream_t stream) {
  if (groups <= 0) return cudaSuccess;
  offsetsKernel<<<blocksFor(groups), kThreads, 0, stream>>>(groups, rc, offsets);
  return cudaGetLastError();
}

cudaError_t launchStratifiedIndices(int n, int n_out, int groups, const double* cumulative,
                                    const int* order, const double* offsets, int* indices,
                                    cudaStream_t stream) {
  if (n <= 0 || n_out <= 0 || groups <= 0) return cudaSuccess;
  stratifiedKernel<<<blocksFor(n_out), kThreads, 0, stream>>>(n, n_out, groups, cumulative, order,
                                                               offsets, indices);
  return cudaGetLastError();
}

cudaError_t launchBinKeys(int n, const int* indices, const ParticleState* particles,
                          double inv_bin_m, double inv_bin_rad, uint64_t* keys,
                          cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  binKeysKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, indices, particles, inv_bin_m,
                                                        inv_bin_rad, keys);
  return cudaGetLastError();
}

cudaError_t launchCountDistinct(int n, const uint64_t* sorted_keys, int* count,
                                cudaStream_t stream) {
  cudaError_t err = cudaMemsetAsync(count, 0, sizeof(int), stream);
  if (err != cudaSuccess || n <= 0) return err;
  countDistinctKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, sorted_keys, count);
  return cudaGetLastError();
}

cudaError_t launchGather(int n, const int* indices, const ParticleState* in, const double* in_ll,
                         ParticleState* out, double* out_ll, cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  gatherKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, indices, in, in_ll, out, out_ll);
  return cudaGetLastError();
}

cudaError_t launchGatherValues(int n, const int* indices, const double* in, double* out,
                               cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  gatherValuesKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, indices, in, out);
  return cudaGetLastError();
}

cudaError_t launchReinitialise(int count, const int* idx, RandomCall rc, const RegionBox& region,
                               ParticleState* particles, double* weights, double weight,
                               cudaStream_t stream) {
  if (count <= 0) return cudaSuccess;
  reinitialiseKernel<<<blocksFor(count), kThreads, 0, stream>>>(count, idx, rc, region, particles,
                                                                 weights, weight);
  return cudaGetLastError();
}

cudaError_t launchScoreKeys(int n, const double* ll, double* keys, int* values,
                            cudaStream_t stream) {
  if (n <= 0) return cudaSuccess;
  scoreKeysKernel<<<blocksFor(n), kThreads, 0, stream>>>(n, ll, keys, values);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace gmm_mcl
