// Weight and estimate kernels of the device particle filter: the tempered weight update with its
// Neff-floor bisection (or the paper's weighting), the normalisation and the scores, the
// weighted mean and covariance, and sums. Deterministic reductions (cuda/filter_device.cuh).
#include <math.h>

#include "cuda/filter_device.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

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
  WeightState s = WeightState();  // zero counts and sums; kExponentMax
  s.best = r.v[0];
  s.argmax_ll = r.v[1];
  s.argmax =
      r.v[1] == -INFINITY && r.v[2] == -static_cast<double>(n) ? 0 : static_cast<int>(-r.v[2]);
  s.finite = static_cast<int>(r.v[3]);
  s.neff_prior = r.v[5] > 0.0 ? r.v[4] * r.v[4] / r.v[5] : 0.0;
  s.hi = cfg.beta_max;
  s.beta = cfg.beta_max;
  s.beta_fraction = 1.0;
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
  const double mx = state->mean[0], my = state->mean[1], mz = state->mean[2], ma = state->mean[3];
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

__global__ void __launch_bounds__(kThreads)
    addFrameKernel(int n, double scale, const double* __restrict__ ll_more,
                   const int* __restrict__ hits_more, double* __restrict__ ll,
                   int* __restrict__ hits) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) {
    ll[i] += scale * ll_more[i];
    hits[i] += hits_more[i];
  }
}

}  // namespace

// ---- launchers --------------------------------------------------------------------------------

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

cudaError_t launchWeightBisection(int n, const WeightConfig& cfg, int iterations, const double* ll,
                                  const double* weights, WeightState* state, ReduceScratch scratch,
                                  cudaStream_t stream) {
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

cudaError_t launchSumCounts(int n, const long long* a, const long long* b, unsigned long long* sums,
                            cudaStream_t stream) {
  cudaError_t err = cudaMemsetAsync(sums, 0, 2 * sizeof(unsigned long long), stream);
  if (err != cudaSuccess || n <= 0) return err;
  sumCountsKernel<<<reduceBlocksFor(n), kThreads, 0, stream>>>(n, a, b, sums);
  return cudaGetLastError();
}

cudaError_t launchDivide(int n, const double* total, double* w, cudaStream_t stream) {
  return launchOver(n, stream, divideKernel, n, total, w);
}

cudaError_t launchAddFrame(int n, double scale, const double* ll_more, const int* hits_more,
                           double* ll, int* hits, cudaStream_t stream) {
  return launchOver(n, stream, addFrameKernel, n, scale, ll_more, hits_more, ll, hits);
}

}  // namespace cuda
}  // namespace gmm_mcl
