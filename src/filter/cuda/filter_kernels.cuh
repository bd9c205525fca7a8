// Launchers of the device particle filter's kernels (cuda/filter_*_kernels.cu) and of the
// sorts and scans it takes from cub (cuda/filter_sort.cu). Plain data only, shared by the host
// code (g++) and the .cu files (nvcc).
#pragma once

#include <cuda_runtime_api.h>
#include <stddef.h>
#include <stdint.h>

#include "gmm_mcl/common/types.h"
#include "gmm_mcl/internal/particle_math.h"

namespace gmm_mcl {
namespace cuda {

// Counter-based random numbers (Philox4x32-10): draw j of thread i of a launch is a pure function
// of (seed, call, i, j), so results do not depend on the grid or the device.
struct RandomCall {
  unsigned long long seed;
  unsigned long long call;  // distinct per launch (the filter counts them)
};

// Scratch of the grid-wide reductions: partial sums of up to kReduceBlocks blocks and the
// counter that elects the last block (it returns to 0 by itself).
constexpr int kReduceBlocks = 256;
constexpr int kReduceMaxValues = 16;  // doubles per partial
struct ReduceScratch {
  double* partials;   // [kReduceBlocks][kReduceMaxValues]
  unsigned* counter;  // [1], 0 between launches
};

// ---- sampling -------------------------------------------------------------------------------
struct PredictConfig {
  double delta[4];  // odometry translation (x, y, z in the yaw frame) and yaw
  double sigma_m;
  double sigma_rad;
};
cudaError_t launchPredict(int n, RandomCall rc, const PredictConfig& cfg, ParticleState* particles,
                          cudaStream_t stream);
// out[i] uniform in the region; weights[i] = weight when weights is not null.
cudaError_t launchUniform(int n, RandomCall rc, const RegionBox& region, ParticleState* out,
                          double* weights, double weight, cudaStream_t stream);
// out[i] Gaussian around mean (sigma[0..3] for x, y, z, yaw); weights[i] = weight.
cudaError_t launchGaussian(int n, RandomCall rc, const ParticleState& mean, const double sigma[4],
                           ParticleState* out, double* weights, double weight, cudaStream_t stream);
// out[i] Gaussian around centres[i % num_centres].
cudaError_t launchAround(int n, RandomCall rc, const ParticleState* centres, int num_centres,
                         double sigma_m, double sigma_rad, ParticleState* out, cudaStream_t stream);
// Camera poses T_map_cam and T_cam_map of every particle.
cudaError_t launchCameraPoses(int n, const ParticleState* particles, const CameraMount& mount,
                              RigidTransformF* T_map_cam, RigidTransformF* T_cam_map,
                              cudaStream_t stream);
cudaError_t launchFill(int n, double value, double* out, cudaStream_t stream);

// ---- weights --------------------------------------------------------------------------------
struct WeightConfig {
  int tempered;  // 1: WeightingMode::kTempered, 0: kPaper
  int pixels;
  double beta_max;      // 1 / (temperature * pixels)
  double neff_floor;    // neff_floor_fraction * N
  double paper_margin;  // paper_min_nll_per_pixel * pixels
};
// WeightState::bisect: the exponent at beta_max, found by bisection (the Neff floor binds), or 0
// (beta_max and 0 both fall below the floor: the prior weights kept, as ParticleFilter does).
constexpr int kExponentMax = 0, kExponentBisected = 1, kExponentZero = 2;
// Device-resident state of one weight update, read back twice.
struct WeightState {
  double best;       // largest finite log-likelihood
  double argmax_ll;  // log-likelihood of the best particle (the first of the largest)
  int argmax;
  int finite;         // particles with a finite log-likelihood
  int bisect;         // kExponentMax, kExponentBisected or kExponentZero
  int ok;             // the weights were updated
  double neff_prior;  // Neff of the prior weights over the finite entries (beta = 0)
  double neff_max;    // Neff at beta_max
  double lo, hi, beta;
  double beta_fraction;
  double recover_sum;  // sum over finite entries of exp(ll / pixels - best / pixels)
  double total;        // sum of the unnormalised new weights
  double mean_ll;      // sum of w_i ll_i over w_i > 0 (normalised weights)
  double neff;         // after the update
  int best_hits;       // floor hits of the best particle
};
// The update in three launches so that the bisection runs only where the floor binds (the
// caller reads state->bisect in between): launchWeightStart (maxima, prior Neff, Neff at
// beta_max and the recovery sum), launchWeightBisection (`iterations` steps, no-ops unless
// state->bisect is 1), launchWeightFinish (the new weights, their normalisation, the scores).
// w_new: scratch [n]. Nothing is synchronised.
cudaError_t launchWeightStart(int n, const WeightConfig& cfg, const double* ll,
                              const double* weights, WeightState* state, ReduceScratch scratch,
                              cudaStream_t stream);
cudaError_t launchWeightBisection(int n, const WeightConfig& cfg, int iterations, const double* ll,
                                  const double* weights, WeightState* state, ReduceScratch scratch,
                                  cudaStream_t stream);
cudaError_t launchWeightFinish(int n, const WeightConfig& cfg, const double* ll,
                               const int* floor_hits, double* weights, double* w_new,
                               WeightState* state, ReduceScratch scratch, cudaStream_t stream);

// ---- estimate -------------------------------------------------------------------------------
struct EstimateState {
  double mean[4];  // x, y, z, yaw (atan2 of the weighted sine and cosine sums)
  double cov[10];  // xx, xy, xz, xa, yy, yz, ya, zz, za, aa (a: yaw, differences wrapped)
  double neff;     // 1 / sum w^2
  double total;    // sum w
};
cudaError_t launchEstimate(int n, const ParticleState* particles, const double* weights,
                           EstimateState* state, ReduceScratch scratch, cudaStream_t stream);
// total[0] = sum of w; w[i] /= total[0].
cudaError_t launchSum(int n, const double* w, double* total, ReduceScratch scratch,
                      cudaStream_t stream);
cudaError_t launchDivide(int n, const double* total, double* w, cudaStream_t stream);
// ll[i] += scale * ll_more[i], hits[i] += hits_more[i] (another camera's frame).
cudaError_t launchAddFrame(int n, double scale, const double* ll_more, const int* hits_more,
                           double* ll, int* hits, cudaStream_t stream);
// sums[0] = sum of a, sums[1] = sum of b (evaluation counts).
cudaError_t launchSumCounts(int n, const long long* a, const long long* b, unsigned long long* sums,
                            cudaStream_t stream);

// ---- resampling -----------------------------------------------------------------------------
// keys[i] random, values[i] = i (a random order after a sort by key).
cudaError_t launchRandomKeys(int n, RandomCall rc, uint32_t* keys, int* values,
                             cudaStream_t stream);
// out[j] = w[order[j]] * n_out / total[0].
cudaError_t launchPermuteScaled(int n, const int* order, const double* w, const double* total,
                                int n_out, double* out, cudaStream_t stream);
// offsets[g] uniform in [0, 1).
cudaError_t launchOffsets(int groups, RandomCall rc, double* offsets, cudaStream_t stream);
// indices[k] = order[min(first j with cumulative[j] > k + offsets[group of k], n - 1)]
// (stratifiedLowVarianceIndices).
cudaError_t launchStratifiedIndices(int n, int n_out, int groups, const double* cumulative,
                                    const int* order, const double* offsets, int* indices,
                                    cudaStream_t stream);
// keys[k] = kldBinKey(particles[indices[k]]).
cudaError_t launchBinKeys(int n, const int* indices, const ParticleState* particles,
                          double inv_bin_m, double inv_bin_rad, uint64_t* keys,
                          cudaStream_t stream);
// count[0] = distinct values of sorted keys[n].
cudaError_t launchCountDistinct(int n, const uint64_t* sorted_keys, int* count,
                                cudaStream_t stream);
// out[k] = in[indices[k]], and out_ll[k] = in_ll[indices[k]] when in_ll is not null.
cudaError_t launchGather(int n, const int* indices, const ParticleState* in, const double* in_ll,
                         ParticleState* out, double* out_ll, cudaStream_t stream);
// out[k] = in[indices[k]] for doubles.
cudaError_t launchGatherValues(int n, const int* indices, const double* in, double* out,
                               cudaStream_t stream);

// ---- recovery and selection -----------------------------------------------------------------
// particles[idx[k]] uniform in the region and weights[idx[k]] = weight, k < count.
cudaError_t launchReinitialise(int count, const int* idx, RandomCall rc, const RegionBox& region,
                               ParticleState* particles, double* weights, double weight,
                               cudaStream_t stream);
// keys[i] = ll[i] (non-finite: -inf), values[i] = i.
cudaError_t launchScoreKeys(int n, const double* ll, double* keys, int* values,
                            cudaStream_t stream);

// ---- cub (cuda/filter_sort.cu) ----------------------------------------------------------------
// Each is called first with temp == nullptr for the bytes of scratch it needs.
cudaError_t sortPairsU32(void* temp, size_t* temp_bytes, const uint32_t* keys_in,
                         uint32_t* keys_out, const int* values_in, int* values_out, int n,
                         cudaStream_t stream);
cudaError_t sortPairsDescendingF64(void* temp, size_t* temp_bytes, const double* keys_in,
                                   double* keys_out, const int* values_in, int* values_out, int n,
                                   cudaStream_t stream);
cudaError_t sortKeysU64(void* temp, size_t* temp_bytes, const uint64_t* keys_in, uint64_t* keys_out,
                        int n, cudaStream_t stream);
cudaError_t inclusiveSumF64(void* temp, size_t* temp_bytes, const double* in, double* out, int n,
                            cudaStream_t stream);

}  // namespace cuda
}  // namespace gmm_mcl
