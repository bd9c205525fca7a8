#include "gmm_mcl/measurement/likelihood.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/LU>

#include "gmm_mcl/common/fast_math.h"

namespace gmm_mcl {
namespace {

// sum[i] = sum over the k members of exp(ln(lambda_j N_j(p_i)) - shift) for the n points
// (n a multiple of B, B pixels per block). The pixel loop of one block has a compile-time trip
// count (B / 8 AVX2 vectors), inside the member loop: each member's 10 constants are loaded
// once per block. Every exponent is <= 0 (shift >= every member's log_norm).
template <int B>
__attribute__((noinline)) void patchMixture(const EvalComponentF* __restrict comps,
                                            const int* __restrict members, int k, float shift,
                                            const float* __restrict wx,
                                            const float* __restrict wy,
                                            const float* __restrict wz, int n,
                                            float* __restrict sum) {
  for (int i0 = 0; i0 < n; i0 += B) {
    alignas(32) float acc[B];
    for (int i = 0; i < B; ++i) acc[i] = 0.f;
    const float* __restrict x = wx + i0;
    const float* __restrict y = wy + i0;
    const float* __restrict z = wz + i0;
    for (int j = 0; j < k; ++j) {
      const EvalComponentF& e = comps[members[j]];
      const float b = e.base - shift;
      const float c0 = e.c[0], c1 = e.c[1], c2 = e.c[2];
      const float u00 = e.u00, u01 = e.u01, u02 = e.u02, u11 = e.u11, u12 = e.u12, u22 = e.u22;
#pragma omp simd
      for (int i = 0; i < B; ++i) {
        const float y0 = u00 * x[i] + (u01 * y[i] + (u02 * z[i] + c0));
        const float y1 = u11 * y[i] + (u12 * z[i] + c1);
        const float y2 = u22 * z[i] + c2;
        acc[i] += expNonPositive(b - y0 * y0 - y1 * y1 - y2 * y2);
      }
    }
    for (int i = 0; i < B; ++i) sum[i0 + i] = acc[i];
  }
}

}  // namespace

void makeEvalComponents(const std::vector<ComponentF>& components,
                        std::vector<EvalComponentF>* out) {
  out->resize(components.size());
  for (size_t i = 0; i < components.size(); ++i) {
    (*out)[i] = makeEvalComponentF(components[i], kEvalScaleNats);
  }
}

FrameLikelihood frameLogLikelihood(const EvalComponentF* eval, const DepthFrame& frame,
                                   const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density) {
  FrameLikelihood out;
  out.pixels = static_cast<int>(frame.size());
  const int num_patches = frame.grid.count();
  alignas(32) float wx[kPixelChunk], wy[kPixelChunk], wz[kPixelChunk], sum[kPixelChunk];
  const float* R = T_map_cam.R;
  const float* t = T_map_cam.t;
  double total = 0.0;
  for (int p = 0; p < num_patches; ++p) {
    const int b = frame.patch_begin[p];
    const int e = frame.patch_begin[p + 1];
    if (b == e) continue;
    const int k = membership.countFor(p);
    if (k == 0) {
      total += static_cast<double>(floor_log_density) * (e - b);
      out.floor_hits += e - b;
      continue;
    }
    const int* members = membership.comps.data() + membership.begin[p];
    float shift = floor_log_density;
    for (int j = 0; j < k; ++j) shift = maxf(shift, eval[members[j]].log_norm);
    const float floor_term = expNonPositive(floor_log_density - shift);
    for (int c = b; c < e; c += kPixelChunk) {
      const int n = std::min(kPixelChunk, e - c);
      const float* x = frame.x_m.data() + c;
      const float* y = frame.y_m.data() + c;
      const float* z = frame.z_m.data() + c;
      // Blocks of 8, 16 or 32 pixels; the padding repeats the chunk's first point.
      const int B = n > 16 ? 32 : (n > 8 ? 16 : 8);
      const int padded = (n + B - 1) / B * B;
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        wx[i] = R[0] * x[i] + R[1] * y[i] + R[2] * z[i] + t[0];
        wy[i] = R[3] * x[i] + R[4] * y[i] + R[5] * z[i] + t[1];
        wz[i] = R[6] * x[i] + R[7] * y[i] + R[8] * z[i] + t[2];
      }
      for (int i = n; i < padded; ++i) {
        wx[i] = wx[0];
        wy[i] = wy[0];
        wz[i] = wz[0];
      }
      if (B == 32) {
        patchMixture<32>(eval, members, k, shift, wx, wy, wz, padded, sum);
      } else if (B == 16) {
        patchMixture<16>(eval, members, k, shift, wx, wy, wz, padded, sum);
      } else {
        patchMixture<8>(eval, members, k, shift, wx, wy, wz, padded, sum);
      }
      alignas(32) float lv[kPixelChunk];
#pragma omp simd
      for (int i = 0; i < n; ++i) lv[i] = logPositive(floor_term + sum[i]);
      double acc = 0.0;
      int hits = 0;
      for (int i = 0; i < n; ++i) {
        acc += static_cast<double>(shift + lv[i]);
        hits += sum[i] < floor_term ? 1 : 0;  // mixture density below exp(floor)
      }
      total += acc;
      out.floor_hits += hits;
      out.evaluations += static_cast<long long>(k) * n;
    }
  }
  out.log_likelihood = total;
  return out;
}

FrameLikelihood frameLogLikelihood(const std::vector<ComponentF>& components,
                                   const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density,
                                   std::vector<float>* /*values*/) {
  std::vector<EvalComponentF> eval;
  makeEvalComponents(components, &eval);
  return frameLogLikelihood(eval.data(), frame, T_map_cam, membership, floor_log_density);
}

FrameLikelihood poseLogLikelihood(const std::vector<ComponentF>& components,
                                  const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                  const MeasurementParams& params, LikelihoodScratch* scratch) {
  computeMembership(components, invertRigid(T_map_cam), frame.intrinsics, frame.grid, params,
                    &scratch->projected, &scratch->valid, &scratch->membership);
  makeEvalComponents(components, &scratch->eval);
  return frameLogLikelihood(scratch->eval.data(), frame, T_map_cam, scratch->membership,
                            params.floor_log_density);
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
