#include "gmm_mcl/measurement/likelihood.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/LU>

#include "gmm_mcl/common/fast_math.h"

namespace gmm_mcl {
namespace {

// The inner loops are small functions over restrict pointers: in that form GCC vectorises
// them (AVX2: 8 pixels per instruction); inside one loop nest over local arrays it did not.

// row[i] = ln(lambda N) of one component at each point; mx[i] = max(mx[i], row[i]).
__attribute__((noinline)) void componentLogDensities(const ComponentF& c, const float* __restrict wx,
                           const float* __restrict wy, const float* __restrict wz, int n,
                           float* __restrict row, float* __restrict mx) {
  const float m0 = c.mean_m[0], m1 = c.mean_m[1], m2 = c.mean_m[2];
  const float p0 = c.precision[0], p1 = 2.f * c.precision[1], p2 = 2.f * c.precision[2];
  const float p3 = c.precision[3], p4 = 2.f * c.precision[4], p5 = c.precision[5];
  const float ln = c.log_norm;
  for (int i = 0; i < n; ++i) {
    const float dx = wx[i] - m0, dy = wy[i] - m1, dz = wz[i] - m2;
    const float q = dx * (p0 * dx + p1 * dy + p2 * dz) + dy * (p3 * dy + p4 * dz) + p5 * dz * dz;
    const float v = ln - 0.5f * q;
    row[i] = v;
    mx[i] = maxf(mx[i], v);
  }
}

// sum[i] += exp(row[i] - mx[i]).
__attribute__((noinline)) void accumulateExp(const float* __restrict row, const float* __restrict mx, int n,
                   float* __restrict sum) {
  for (int i = 0; i < n; ++i) sum[i] += expNonPositive(row[i] - mx[i]);
}

// floor_term[i] = exp(floor - mx[i]).
__attribute__((noinline)) void floorTerms(float floor_ld, const float* __restrict mx, int n, float* __restrict out) {
  for (int i = 0; i < n; ++i) out[i] = expNonPositive(floor_ld - mx[i]);
}

// Log-likelihood of up to kPixelChunk map-frame points against `k` relevant components.
// Accumulates into *sum and counts floor hits.
void chunkLogLikelihood(const std::vector<ComponentF>& components, const int* relevant, int k,
                        const float* wx, const float* wy, const float* wz, int n, float floor_ld,
                        float* values, double* sum, int* floor_hits) {
  alignas(32) float mx[kPixelChunk];
  alignas(32) float floor_term[kPixelChunk];
  alignas(32) float mixture[kPixelChunk];  // sum_j exp(v_j - mx): the density relative to exp(mx)
  for (int i = 0; i < n; ++i) {
    mx[i] = floor_ld;
    mixture[i] = 0.f;
  }
  for (int j = 0; j < k; ++j) {
    componentLogDensities(components[relevant[j]], wx, wy, wz, n, values + j * kPixelChunk, mx);
  }
  floorTerms(floor_ld, mx, n, floor_term);
  for (int j = 0; j < k; ++j) accumulateExp(values + j * kPixelChunk, mx, n, mixture);
  double acc = 0.0;
  int hits = 0;
  for (int i = 0; i < n; ++i) {
    acc += static_cast<double>(mx[i] + std::log(floor_term[i] + mixture[i]));
    hits += mixture[i] < floor_term[i] ? 1 : 0;  // mixture density below exp(floor)
  }
  *sum += acc;
  *floor_hits += hits;
}

}  // namespace

FrameLikelihood frameLogLikelihood(const std::vector<ComponentF>& components,
                                   const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density,
                                   std::vector<float>* values) {
  FrameLikelihood out;
  out.pixels = static_cast<int>(frame.size());
  const int num_patches = frame.grid.count();
  float wx[kPixelChunk], wy[kPixelChunk], wz[kPixelChunk];
  const float* R = T_map_cam.R;
  const float* t = T_map_cam.t;
  double sum = 0.0;
  for (int p = 0; p < num_patches; ++p) {
    const int b = frame.patch_begin[p];
    const int e = frame.patch_begin[p + 1];
    if (b == e) continue;
    const int k = membership.countFor(p);
    if (k == 0) {
      sum += static_cast<double>(floor_log_density) * (e - b);
      out.floor_hits += e - b;
      continue;
    }
    const int* relevant = membership.comps.data() + membership.begin[p];
    if (values->size() < static_cast<size_t>(k) * kPixelChunk) values->resize(k * kPixelChunk);
    for (int c = b; c < e; c += kPixelChunk) {
      const int n = std::min(kPixelChunk, e - c);
      const float* x = frame.x_m.data() + c;
      const float* y = frame.y_m.data() + c;
      const float* z = frame.z_m.data() + c;
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        wx[i] = R[0] * x[i] + R[1] * y[i] + R[2] * z[i] + t[0];
        wy[i] = R[3] * x[i] + R[4] * y[i] + R[5] * z[i] + t[1];
        wz[i] = R[6] * x[i] + R[7] * y[i] + R[8] * z[i] + t[2];
      }
      chunkLogLikelihood(components, relevant, k, wx, wy, wz, n, floor_log_density,
                         values->data(), &sum, &out.floor_hits);
      out.evaluations += static_cast<long long>(k) * n;
    }
  }
  out.log_likelihood = sum;
  return out;
}

FrameLikelihood poseLogLikelihood(const std::vector<ComponentF>& components,
                                  const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                  const MeasurementParams& params, LikelihoodScratch* scratch) {
  computeMembership(components, invertRigid(T_map_cam), frame.intrinsics, frame.grid, params,
                    &scratch->projected, &scratch->valid, &scratch->membership);
  return frameLogLikelihood(components, frame, T_map_cam, scratch->membership,
                            params.floor_log_density, &scratch->values);
}

FrameLikelihood exactFrameLogLikelihood(const GmmMap& map, const DepthFrame& frame,
                                        const Eigen::Isometry3d& T_map_cam,
                                        float floor_log_density) {
  constexpr double kLog2Pi = 1.8378770664093453;
  const auto& comps = map.components();
  const size_t m = comps.size();
  std::vector<Eigen::Matrix3d> precision(m);
  std::vector<double> log_norm(m);
  for (size_t j = 0; j < m; ++j) {
    precision[j] = comps[j].cov_m2.inverse();
    log_norm[j] = std::log(comps[j].weight) - 1.5 * kLog2Pi -
                  0.5 * std::log(comps[j].cov_m2.determinant());
  }
  FrameLikelihood out;
  out.pixels = static_cast<int>(frame.size());
  out.evaluations = static_cast<long long>(m) * frame.size();
  double sum = 0.0;
  int hits = 0;
#pragma omp parallel for reduction(+ : sum, hits) schedule(static)
  for (int i = 0; i < static_cast<int>(frame.size()); ++i) {
    const Eigen::Vector3d p = T_map_cam * Eigen::Vector3d(frame.x_m[i], frame.y_m[i], frame.z_m[i]);
    double mx = floor_log_density;
    std::vector<double> terms(m);
    for (size_t j = 0; j < m; ++j) {
      const Eigen::Vector3d d = p - comps[j].mean_m;
      terms[j] = log_norm[j] - 0.5 * d.dot(precision[j] * d);
      mx = std::max(mx, terms[j]);
    }
    double mix = 0.0;
    for (size_t j = 0; j < m; ++j) mix += std::exp(terms[j] - mx);
    const double floor_term = std::exp(floor_log_density - mx);
    sum += mx + std::log(floor_term + mix);
    hits += mix < floor_term ? 1 : 0;
  }
  out.log_likelihood = sum;
  out.floor_hits = hits;
  return out;
}

}  // namespace gmm_mcl
