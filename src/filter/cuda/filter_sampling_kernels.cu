// Sampling kernels of the device particle filter, with counter-based random numbers (Philox,
// curand's device API): prediction, uniform and Gaussian draws, draws around centres, the
// random keys and offsets of the resampling, and the camera poses of the particles. Host/device
// math from gmm_mcl/internal/particle_math.h.
#include <curand_kernel.h>
#include <math.h>

#include "cuda/filter_device.cuh"

namespace gmm_mcl {
namespace cuda {
namespace {

__device__ __forceinline__ curandStatePhilox4_32_10_t randomState(const RandomCall& rc, int i) {
  curandStatePhilox4_32_10_t st;
  curand_init(rc.seed, (rc.call << 32) + static_cast<unsigned long long>(i), 0, &st);
  return st;
}

// Uniform in [-1, 1).
__device__ __forceinline__ double symmetricUniform(curandStatePhilox4_32_10_t* st) {
  return 1.0 - 2.0 * curand_uniform_double(st);  // curand_uniform_double is in (0, 1]
}

// Uniform in the region.
__device__ __forceinline__ ParticleState uniformInRegion(const RegionBox& region,
                                                         curandStatePhilox4_32_10_t* st) {
  double u[4];
  for (int k = 0; k < 4; ++k) u[k] = symmetricUniform(st);
  return regionPoint(region, u);
}

// c moved by (sx a.x, sy a.y, sz b.x) and turned by sa b.y (wrapped): a and b standard normal.
__device__ __forceinline__ ParticleState jittered(const ParticleState& c, double sx, double sy,
                                                  double sz, double sa, double2 a, double2 b) {
  ParticleState p;
  p.x_m = c.x_m + sx * a.x;
  p.y_m = c.y_m + sy * a.y;
  p.z_m = c.z_m + sz * b.x;
  p.yaw_rad = wrapAngleHD(c.yaw_rad + sa * b.y);
  return p;
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
  out[i] = uniformInRegion(region, &st);
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
  out[i] = jittered(mean, sx, sy, sz, sa, a, b);
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
  out[i] = jittered(centres[i % num_centres], sigma_m, sigma_m, sigma_m, sigma_rad, a, b);
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

__global__ void __launch_bounds__(kThreads)
    fillKernel(int n, double value, double* __restrict__ out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) out[i] = value;
}

__global__ void __launch_bounds__(kThreads)
    randomKeysKernel(int n, RandomCall rc, uint32_t* __restrict__ keys, int* __restrict__ values) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  curandStatePhilox4_32_10_t st = randomState(rc, i);
  keys[i] = curand(&st);
  values[i] = i;
}

__global__ void offsetsKernel(int groups, RandomCall rc, double* __restrict__ offsets) {
  const int g = blockIdx.x * blockDim.x + threadIdx.x;
  if (g >= groups) return;
  curandStatePhilox4_32_10_t st = randomState(rc, g);
  offsets[g] = 1.0 - curand_uniform_double(&st);  // [0, 1)
}

__global__ void __launch_bounds__(kThreads)
    reinitialiseKernel(int count, const int* __restrict__ idx, RandomCall rc, RegionBox region,
                       ParticleState* __restrict__ particles, double* __restrict__ weights,
                       double weight) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= count) return;
  curandStatePhilox4_32_10_t st = randomState(rc, k);
  particles[idx[k]] = uniformInRegion(region, &st);
  weights[idx[k]] = weight;
}

}  // namespace

// ---- launchers --------------------------------------------------------------------------------

cudaError_t launchPredict(int n, RandomCall rc, const PredictConfig& cfg, ParticleState* particles,
                          cudaStream_t stream) {
  return launchOver(n, stream, predictKernel, n, rc, cfg, particles);
}

cudaError_t launchUniform(int n, RandomCall rc, const RegionBox& region, ParticleState* out,
                          double* weights, double weight, cudaStream_t stream) {
  return launchOver(n, stream, uniformKernel, n, rc, region, out, weights, weight);
}

cudaError_t launchGaussian(int n, RandomCall rc, const ParticleState& mean, const double sigma[4],
                           ParticleState* out, double* weights, double weight,
                           cudaStream_t stream) {
  return launchOver(n, stream, gaussianKernel, n, rc, mean, sigma[0], sigma[1], sigma[2], sigma[3],
                    out, weights, weight);
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
  return launchOver(n, stream, cameraPosesKernel, n, particles, mount, T_map_cam, T_cam_map);
}

cudaError_t launchFill(int n, double value, double* out, cudaStream_t stream) {
  return launchOver(n, stream, fillKernel, n, value, out);
}

cudaError_t launchRandomKeys(int n, RandomCall rc, uint32_t* keys, int* values,
                             cudaStream_t stream) {
  return launchOver(n, stream, randomKeysKernel, n, rc, keys, values);
}

cudaError_t launchOffsets(int groups, RandomCall rc, double* offsets, cudaStream_t stream) {
  return launchOver(groups, stream, offsetsKernel, groups, rc, offsets);
}

cudaError_t launchReinitialise(int count, const int* idx, RandomCall rc, const RegionBox& region,
                               ParticleState* particles, double* weights, double weight,
                               cudaStream_t stream) {
  return launchOver(count, stream, reinitialiseKernel, count, idx, rc, region, particles, weights,
                    weight);
}

}  // namespace cuda
}  // namespace gmm_mcl
