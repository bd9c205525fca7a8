#include "gmm_mcl/measurement/likelihood.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "gmm_mcl/internal/cpu_simd.h"
#include "gmm_mcl/internal/fast_math.h"
#include "gmm_mcl/measurement/depth_noise.h"

// 32-byte vector locals (cpu_simd.h): without AVX, GCC warns about an ABI change that does not
// concern these file-local functions.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace gmm_mcl {
namespace {

using simd::v4d;
using simd::v8f;
using simd::v8i;

// Exponents more than this far below the floor's (ln(exp(floor) / exp(shift))) are left out of
// a pixel's sum: each such term is below e^-25 = 1.4e-11 times the floor term that the sum is
// added to, so ln(floor term + sum) moves by less than 1e-9 nats per pixel with 70 of them.
constexpr float kNegligibleBelowFloor = 25.f;

// acc[v] = sum over the k members j of exp(base_j - shift - |U_j p + c_j|^2) for the 8V points
// p of x[v], y[v], z[v] (shift >= every member's base, so every exponent is <= 0), leaving out
// the vectors whose used lanes (used[v]) all have exponents below `negligible`. Two passes: the
// exponents of all members (9 FMA per vector, each member's 10 constants broadcast once for all
// V vectors), with the indices of the non-negligible vectors; then exp and the sum over those
// only, in member order (no branch per member: on the benchmark most (member, patch) pairs are
// negligible, in an unpredictable pattern; the share is in docs/benchmark.md). Scratch: t_out
// [k][V][8] exponents, kept [V][k] the members with a used lane kept (the caller's: a
// thread_local looked up here, once per call, cost 3% of the CPU backend's update).
template <int V>
__attribute__((noinline)) void patchMixture(const EvalComponentF* __restrict comps,
                                            const int* __restrict members, int k, float shift,
                                            float negligible, const v8f* __restrict x,
                                            const v8f* __restrict y, const v8f* __restrict z,
                                            const v8i* __restrict used, float* __restrict t_out,
                                            int* __restrict kept, v8f* __restrict acc) {
  v8f px[V], py[V], pz[V];
  v8i use[V];
  int n[V];
  for (int v = 0; v < V; ++v) {
    px[v] = x[v];
    py[v] = y[v];
    pz[v] = z[v];
    use[v] = used[v];
    n[v] = 0;
  }
  const v8f low = simd::splat(negligible);
  for (int j = 0; j < k; ++j) {
    const EvalComponentF& e = comps[members[j]];
    const v8f b = simd::splat(e.base - shift);
    const v8f c0 = simd::splat(e.c[0]), c1 = simd::splat(e.c[1]), c2 = simd::splat(e.c[2]);
    const v8f u00 = simd::splat(e.u00), u01 = simd::splat(e.u01), u02 = simd::splat(e.u02);
    const v8f u11 = simd::splat(e.u11), u12 = simd::splat(e.u12), u22 = simd::splat(e.u22);
    for (int v = 0; v < V; ++v) {
      const v8f y0 = u00 * px[v] + (u01 * py[v] + (u02 * pz[v] + c0));
      const v8f y1 = u11 * py[v] + (u12 * pz[v] + c1);
      const v8f y2 = u22 * pz[v] + c2;
      const v8f t = b - y0 * y0 - y1 * y1 - y2 * y2;
      simd::store(t_out + (j * V + v) * 8, t);
      kept[v * k + n[v]] = j;
      n[v] += simd::any(use[v] & (t >= low)) ? 1 : 0;
    }
  }
  for (int v = 0; v < V; ++v) {
    v8f a = simd::splat(0.f);
    const int* __restrict kv = kept + v * k;
    for (int m = 0; m < n[v]; ++m) {
      a += simd::expNonPositive8(simd::load(t_out + (kv[m] * V + v) * 8));
    }
    acc[v] = a;
  }
}

#if defined(GMM_MCL_SIMD_16)
#define GMM_MCL_LIKELIHOOD_16 1
// patchMixture<2> for the 16 points of one 16-lane vector (AVX-512) in one pass: the same
// exponents lane by lane, exp of every member's, added where patchMixture<2> adds it (the
// 8-lane halves with a used lane at or above `negligible`; masked adds, so that acc's two halves
// are patchMixture<2>'s two sums to the bit). On the `cpu` workload (docs/benchmark.md) 16 lanes
// in two passes took 8% less time in the likelihood than patchMixture<2>, and one pass, without
// the stores of the exponents, 4% less again, though about half its exps add nothing; inlined
// into frameLogLikelihood, 6% less than as a call per patch. used: the lanes holding points.
inline void patchMixture16(const EvalComponentF* __restrict comps, const int* __restrict members,
                           int k, float shift, float negligible, const simd::v16f* __restrict x,
                           const simd::v16f* __restrict y, const simd::v16f* __restrict z,
                           __mmask16 used, simd::v16f* __restrict acc) {
  using simd::splatAs;
  using simd::v16f;
  const v16f px = *x, py = *y, pz = *z;
  const __m512 low = _mm512_set1_ps(negligible);
  __m512 a = _mm512_setzero_ps();
  for (int j = 0; j < k; ++j) {
    const EvalComponentF& e = comps[members[j]];
    const v16f b = splatAs<v16f>(e.base - shift);
    const v16f c0 = splatAs<v16f>(e.c[0]), c1 = splatAs<v16f>(e.c[1]);
    const v16f c2 = splatAs<v16f>(e.c[2]);
    const v16f u00 = splatAs<v16f>(e.u00), u01 = splatAs<v16f>(e.u01);
    const v16f u02 = splatAs<v16f>(e.u02), u11 = splatAs<v16f>(e.u11);
    const v16f u12 = splatAs<v16f>(e.u12), u22 = splatAs<v16f>(e.u22);
    const v16f y0 = u00 * px + (u01 * py + (u02 * pz + c0));
    const v16f y1 = u11 * py + (u12 * pz + c1);
    const v16f y2 = u22 * pz + c2;
    const v16f t = b - y0 * y0 - y1 * y1 - y2 * y2;
    // The halves with a lane kept, as arithmetic (GCC branches on ?:, and the outcome is hard
    // to predict): (x + 255) >> 8 is 1 for x in [1, 255], 0 for x = 0.
    const unsigned in = _mm512_mask_cmp_ps_mask(used, (__m512)t, low, _CMP_GE_OQ);
    const unsigned lo = ((in & 0xffu) + 0xffu) >> 8, hi = ((in >> 8) + 0xffu) >> 8;
    const __mmask16 halves = static_cast<__mmask16>(lo * 0xffu + hi * 0xff00u);
    a = _mm512_mask_add_ps(a, halves, a, (__m512)simd::expNonPositive16(t));
  }
  *acc = (v16f)a;
}
#endif

// Points per kernel call: two 8-lane vectors or one 16-lane vector (a 4x4 patch at stride 8 is
// one call).
constexpr int kKernelPoints = 16;

// frameLogLikelihood's and noisyEvalComponents' per-thread buffers, looked up by a call of its
// own (membership.cpp's threadMembershipBuffers says why).
struct LikelihoodBuffers {
  std::vector<float> points;     // the frame's points in the map frame: x, y, z rows
  std::vector<float> exponents;  // patchMixture's scratch (not patchMixture16's)
  std::vector<int> keep;
  std::vector<float> own_soa, form;  // noisyEvalComponents: componentSoA, noisyFormsAll's rows
  std::vector<int> ok;
  std::vector<int> members;       // noisyEvalComponents: the valid components
  std::vector<float> member_soa;  // noisyEvalComponents: their rows of the structure of arrays
};
__attribute__((noinline)) LikelihoodBuffers& threadLikelihoodBuffers() {
  static thread_local LikelihoodBuffers buffers;
  return buffers;
}

}  // namespace

void makeEvalComponents(const std::vector<ComponentF>& components,
                        std::vector<EvalComponentF>* out) {
  out->resize(components.size());
  for (size_t i = 0; i < components.size(); ++i) {
    (*out)[i] = makeEvalComponentF(components[i], kEvalScaleNats);
  }
}

namespace {

// makeNoisyEvalComponent (depth_noise.h) for the components of `soa` (componentSoA, `stride`
// lanes) at once, in blocks of kComponentSoALanes that the compiler vectorises whole (no
// remainder loop: a component's form does not depend on its position in the list): the same
// steps, with sqrtVec and logPositive (fast_math.h) for sqrtf and logf. Writes the form's 11
// numbers as rows [11][stride] of `form` (c0 c1 c2 base u00 u01 u02 u11 u12 u22 log_norm) and
// ok[i] = 0 where makeNoisyEvalComponent returns false.
__attribute__((noinline)) void noisyFormsAll(const float* __restrict soa, int stride,
                                             const RigidTransformF& T, const DepthNoiseModel& noise,
                                             float scale, float* __restrict form,
                                             int* __restrict ok) {
  const int m = stride;
  const float* __restrict mx = soa, * __restrict my = soa + m, * __restrict mz = soa + 2 * m;
  const float* __restrict s0 = soa + 3 * m, * __restrict s1 = soa + 4 * m;
  const float* __restrict s2 = soa + 5 * m, * __restrict s3 = soa + 6 * m;
  const float* __restrict s4 = soa + 7 * m, * __restrict s5 = soa + 8 * m;
  const float* __restrict lw = soa + 9 * m;
  float* __restrict o[11];
  for (int r = 0; r < 11; ++r) o[r] = form + static_cast<size_t>(r) * m;
  float R[9], t[3];
  for (int k = 0; k < 9; ++k) R[k] = T.R[k];
  for (int k = 0; k < 3; ++k) t[k] = T.t[k];
  const float na = noise.a_m, nb = noise.b_per_m, z0 = noise.z0_m;
  const float h = sqrtf(0.5f * scale);
  for (int block = 0; block < m; block += kComponentSoALanes) {
#pragma omp simd
    for (int i = block; i < block + kComponentSoALanes; ++i) {
      const float px = mx[i], py = my[i], pz = mz[i];
      const float m0 = R[0] * px + R[1] * py + R[2] * pz + t[0];
      const float m1 = R[3] * px + R[4] * py + R[5] * pz + t[1];
      const float m2 = R[6] * px + R[7] * py + R[8] * pz + t[2];
      const float range = sqrtVec(m0 * m0 + m1 * m1 + m2 * m2);
      const float d = m2 - z0;
      const float s = (na + nb * d * d) * range / m2;
      const float k = s / range;
      const float rx = k * (R[0] * m0 + R[3] * m1 + R[6] * m2);
      const float ry = k * (R[1] * m0 + R[4] * m1 + R[7] * m2);
      const float rz = k * (R[2] * m0 + R[5] * m1 + R[8] * m2);
      const float sxx = s0[i] + rx * rx, sxy = s1[i] + rx * ry, sxz = s2[i] + rx * rz;
      const float syy = s3[i] + ry * ry, syz = s4[i] + ry * rz, szz = s5[i] + rz * rz;
      const float v22 = sqrtVec(maxZero(szz));
      const float v12 = syz / v22, v02 = sxz / v22;
      const float d11 = syy - v12 * v12;
      const float v11 = sqrtVec(maxZero(d11));
      const float v01 = (sxy - v02 * v12) / v11;
      const float d00 = sxx - v01 * v01 - v02 * v02;
      const float v00 = sqrtVec(maxZero(d00));
      const float w00 = 1.f / v00, w11 = 1.f / v11, w22 = 1.f / v22;
      const float w12 = -v12 * w22 * w11;
      const float w01 = -v01 * w11 * w00;
      const float w02 = -(v01 * w12 + v02 * w22) * w00;
      const float u00 = h * w00, u01 = h * w01, u02 = h * w02;
      const float u11 = h * w11, u12 = h * w12, u22 = h * w22;
      o[0][i] = -(u00 * px + u01 * py + u02 * pz);
      o[1][i] = -(u11 * py + u12 * pz);
      o[2][i] = -(u22 * pz);
      // (maxf keeps the log's argument positive where the factorisation failed: not used there.)
      const float log_norm = lw[i] - logPositive(maxf(v00 * v11 * v22, 1e-30f));
      o[3][i] = scale * log_norm;
      o[4][i] = u00;
      o[5][i] = u01;
      o[6][i] = u02;
      o[7][i] = u11;
      o[8][i] = u12;
      o[9][i] = u22;
      o[10][i] = log_norm;
      // (Bitwise &: no control flow.) NaN compares false: not ok.
      ok[i] = (m2 > 0.f) & (szz > 0.f) & (d11 > 0.f) & (d00 > 0.f) & (log_norm == log_norm);
    }
  }
}

}  // namespace

const EvalComponentF* noisyEvalComponents(
    const std::vector<ComponentF>& components, const std::vector<EvalComponentF>& base,
    const std::vector<char>& valid, const RigidTransformF& T_cam_map, const DepthNoiseModel& noise,
    std::vector<EvalComponentF>* out, const std::vector<float>* soa) {
  if (!noise.enabled()) return base.data();
  const int m = static_cast<int>(components.size());
  const int stride = componentSoAStride(m);
  LikelihoodBuffers& buffers = threadLikelihoodBuffers();
  std::vector<float>& own_soa = buffers.own_soa;
  std::vector<float>& form = buffers.form;
  std::vector<int>& ok = buffers.ok;
  if (!soa) {
    componentSoA(components, &own_soa);
    soa = &own_soa;
  }
  out->resize(m);
  // Only members are read: their indices first, without a branch each (about half the
  // components are members, in no pattern the branch predictor learns).
  std::vector<int>& members = buffers.members;
  members.resize(m);
  int num_members = 0;
  for (int i = 0; i < m; ++i) {
    members[num_members] = i;
    num_members += valid[i] ? 1 : 0;
  }
  // The members' rows of the structure of arrays gathered (padded with copies of the last
  // member to whole blocks), and their forms only: each lane's form is the same wherever it
  // sits in the list (noisyFormsAll).
  const int ms = componentSoAStride(num_members);
  std::vector<float>& msoa = buffers.member_soa;
  msoa.resize(kComponentSoARows * static_cast<size_t>(ms));
  for (int r = 0; r < kComponentSoARows; ++r) {
    const float* __restrict src = soa->data() + static_cast<size_t>(r) * stride;
    float* __restrict dst = msoa.data() + static_cast<size_t>(r) * ms;
    for (int t = 0; t < num_members; ++t) dst[t] = src[members[t]];
    for (int t = num_members; t < ms; ++t) dst[t] = dst[num_members - 1];  // ms = 0 if none
  }
  form.resize(11 * static_cast<size_t>(ms));
  ok.resize(ms);
  noisyFormsAll(msoa.data(), ms, T_cam_map, noise, kEvalScaleNats, form.data(), ok.data());
  const float* f = form.data();
  for (int t = 0; t < num_members; ++t) {
    const int i = members[t];
    EvalComponentF& e = (*out)[i];
    if (!ok[t]) {
      e = base[i];
      continue;
    }
    e.c[0] = f[t];
    e.c[1] = f[ms + t];
    e.c[2] = f[2 * ms + t];
    e.base = f[3 * ms + t];
    e.u00 = f[4 * ms + t];
    e.u01 = f[5 * ms + t];
    e.u02 = f[6 * ms + t];
    e.u11 = f[7 * ms + t];
    e.u12 = f[8 * ms + t];
    e.u22 = f[9 * ms + t];
    e.log_norm = f[10 * ms + t];
    e.pad = 0.f;
  }
  return out->data();
}

FrameLikelihood frameLogLikelihood(const EvalComponentF* eval, const DepthFrame& frame,
                                   const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density) {
  FrameLikelihood out;
  const int total = static_cast<int>(frame.size());
  out.pixels = total;
  if (total == 0) return out;
  const int num_patches = frame.grid.count();
  // All points into the map frame at once (one vectorised loop), padded by a kernel call's
  // points so that a call may read past the last patch (the padding lanes are masked out).
  LikelihoodBuffers& buffers = threadLikelihoodBuffers();
  std::vector<float>& buf = buffers.points;
#if !defined(GMM_MCL_LIKELIHOOD_16)
  std::vector<float>& exponents = buffers.exponents;
  std::vector<int>& keep = buffers.keep;
#endif
  const size_t stride = static_cast<size_t>(total) + kKernelPoints;
  buf.resize(3 * stride);
  float* __restrict wx = buf.data();
  float* __restrict wy = wx + stride;
  float* __restrict wz = wy + stride;
  {
    const float* __restrict x = frame.x_m.data();
    const float* __restrict y = frame.y_m.data();
    const float* __restrict z = frame.z_m.data();
    const float* R = T_map_cam.R;
    const float* t = T_map_cam.t;
    const float r0 = R[0], r1 = R[1], r2 = R[2], r3 = R[3], r4 = R[4], r5 = R[5];
    const float r6 = R[6], r7 = R[7], r8 = R[8], t0 = t[0], t1 = t[1], t2 = t[2];
#pragma omp simd
    for (int i = 0; i < total; ++i) {
      wx[i] = r0 * x[i] + r1 * y[i] + r2 * z[i] + t0;
      wy[i] = r3 * x[i] + r4 * y[i] + r5 * z[i] + t1;
      wz[i] = r6 * x[i] + r7 * y[i] + r8 * z[i] + t2;
    }
    for (int i = total; i < total + kKernelPoints; ++i) {
      wx[i] = wx[0];
      wy[i] = wy[0];
      wz[i] = wz[0];
    }
  }
#if defined(GMM_MCL_LIKELIHOOD_16)
  const simd::v16i lane = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  simd::v16i hits = {};  // minus the floor hits per lane
#else
  const v8i lane = {0, 1, 2, 3, 4, 5, 6, 7};
  v8i hits = simd::splati(0);  // minus the floor hits per lane
#endif
  v4d lsum = {0.0, 0.0, 0.0, 0.0};  // sum of ln(floor_term + mixture) over pixels
  double shifts = 0.0;              // sum of the patches' shifts over their pixels
  double floors = 0.0;              // pixels of patches without components: floor each
  for (int p = 0; p < num_patches; ++p) {
    const int b = frame.patch_begin[p];
    const int e = frame.patch_begin[p + 1];
    if (b == e) continue;
    const int k = membership.countFor(p);
    if (k == 0) {
      floors += static_cast<double>(floor_log_density) * (e - b);
      out.floor_hits += e - b;
      continue;
    }
    const int* members = membership.comps.data() + membership.begin[p];
#if !defined(GMM_MCL_LIKELIHOOD_16)
    if (keep.size() < 2 * static_cast<size_t>(k)) {
      exponents.resize(16 * static_cast<size_t>(k));
      keep.resize(2 * static_cast<size_t>(k));
    }
#endif
    float shift = floor_log_density;
    for (int j = 0; j < k; ++j) shift = maxf(shift, eval[members[j]].log_norm);
#if defined(GMM_MCL_LIKELIHOOD_16)
    const simd::v16f floor_term =
        simd::splatAs<simd::v16f>(expNonPositive(floor_log_density - shift));
#else
    const v8f floor_term = simd::splat(expNonPositive(floor_log_density - shift));
#endif
    const float negligible = floor_log_density - shift - kNegligibleBelowFloor;
    shifts += static_cast<double>(shift) * (e - b);
    out.evaluations += static_cast<long long>(k) * (e - b);
    for (int c = b; c < e; c += kKernelPoints) {
      const int n = std::min(kKernelPoints, e - c);
#if defined(GMM_MCL_LIKELIHOOD_16)
      const simd::v16f x = simd::load16(wx + c), y = simd::load16(wy + c);
      const simd::v16f z = simd::load16(wz + c);
      const simd::v16i used = lane < n;  // lanes holding this patch's pixels
      simd::v16f acc;
      patchMixture16(eval, members, k, shift, negligible, &x, &y, &z,
                     static_cast<__mmask16>((1u << n) - 1u), &acc);
      const simd::v16f lv = simd::selectAs<simd::v16f, simd::v16i>(
          used, simd::logPositive16(floor_term + acc), simd::splatAs<simd::v16f>(0.f));
      // In patchMixture<2>'s order: lanes 0-3 + 4-7, then 8-11 + 12-15 (zeros when n <= 8,
      // which leave the sum as it is), each half converted to 8 doubles at once. (The maskz
      // forms with all lanes set: GCC 12's plain ones, the casts to 256 bits included, warn of
      // their own undefined operand.)
      const __m512d lvd = _mm512_castps_pd((__m512)lv);
      const __m512d d0 = _mm512_maskz_cvtps_pd(
          0xff, _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(0xf, lvd, 0)));  // lanes 0-7
      const __m512d d1 = _mm512_maskz_cvtps_pd(
          0xff, _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(0xf, lvd, 1)));  // 8-15
      const __m512d quads =
          _mm512_add_pd(_mm512_maskz_shuffle_f64x2(0xff, d0, d1, 0x44),   // 0-3, 8-11
                        _mm512_maskz_shuffle_f64x2(0xff, d0, d1, 0xee));  // 4-7, 12-15
      lsum += (v4d)_mm512_maskz_extractf64x4_pd(0xf, quads, 0);
      lsum += (v4d)_mm512_maskz_extractf64x4_pd(0xf, quads, 1);
      hits += used & (acc < floor_term);  // mixture density below exp(floor): -1
#else
      v8f x[2], y[2], z[2], acc[2];
      const int vectors = n > 8 ? 2 : 1;
      for (int v = 0; v < vectors; ++v) {
        x[v] = simd::load(wx + c + 8 * v);
        y[v] = simd::load(wy + c + 8 * v);
        z[v] = simd::load(wz + c + 8 * v);
      }
      v8i used[2];  // lanes holding this patch's pixels
      for (int v = 0; v < vectors; ++v) used[v] = lane < simd::splati(n - 8 * v);
      if (vectors == 2) {
        patchMixture<2>(eval, members, k, shift, negligible, x, y, z, used, exponents.data(),
                        keep.data(), acc);
      } else {
        patchMixture<1>(eval, members, k, shift, negligible, x, y, z, used, exponents.data(),
                        keep.data(), acc);
      }
      for (int v = 0; v < vectors; ++v) {
        const v8f lv =
            simd::select(used[v], simd::logPositive8(floor_term + acc[v]), simd::splat(0.f));
        lsum += simd::lowToDouble(lv) + simd::highToDouble(lv);
        hits += used[v] & (acc[v] < floor_term);  // mixture density below exp(floor): -1
      }
#endif
    }
  }
  double l = lsum[0] + lsum[1] + lsum[2] + lsum[3];
  int h = 0;
  for (size_t i = 0; i < sizeof(hits) / sizeof(hits[0]); ++i) h -= hits[i];
  out.floor_hits += h;
  out.log_likelihood = floors + (shifts + l);
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
  const RigidTransformF T_cam_map = invertRigid(T_map_cam);
  makeEvalComponents(components, &scratch->eval);
  // The backends' members: those within the pose's view volume, pruned by the frame's depths.
  static thread_local std::vector<float> min_z, max_z, log_norm;
  patchDepthRanges(frame, &min_z, &max_z);
  log_norm.resize(components.size());
  for (size_t i = 0; i < components.size(); ++i) log_norm[i] = scratch->eval[i].log_norm;
  const MemberDepthPrune prune = memberDepthPrune(min_z, max_z, log_norm.data(), params);
  const ViewReach reach = viewReach(frame, params);
  computeMembership(components, T_cam_map, frame.intrinsics, frame.grid, params,
                    &scratch->projected, &scratch->valid, &scratch->membership, &reach, &prune);
  const EvalComponentF* eval = noisyEvalComponents(components, scratch->eval, scratch->valid,
                                                   T_cam_map, params.depth_noise, &scratch->noisy);
  return frameLogLikelihood(eval, frame, T_map_cam, scratch->membership, params.floor_log_density);
}

FrameLikelihood exactFrameLogLikelihood(const GmmMap& map, const DepthFrame& frame,
                                        const Eigen::Isometry3d& T_map_cam,
                                        float floor_log_density) {
  MeasurementParams params;
  params.floor_log_density = floor_log_density;
  params.depth_noise.a_m = params.depth_noise.b_per_m = 0.f;
  return exactFrameLogLikelihood(map, frame, T_map_cam, params);
}

FrameLikelihood exactFrameLogLikelihood(const GmmMap& map, const DepthFrame& frame,
                                        const Eigen::Isometry3d& T_map_cam,
                                        const MeasurementParams& params,
                                        std::vector<double>* per_pixel) {
  constexpr double kLog2Pi = 1.8378770664093453;
  const double floor_log_density = params.floor_log_density;
  const DepthNoiseModel& noise = params.depth_noise;
  const Eigen::Isometry3d T_cam_map = T_map_cam.inverse();
  const auto& comps = map.components();
  const size_t m = comps.size();
  std::vector<Eigen::Matrix3d> precision(m);
  std::vector<double> log_norm(m);
  for (size_t j = 0; j < m; ++j) {
    Eigen::Matrix3d cov = comps[j].cov_m2;
    const Eigen::Vector3d mean_cam = T_cam_map * comps[j].mean_m;
    if (noise.enabled() && mean_cam.z() > 0.0) {
      const double z = mean_cam.z(), d = z - noise.z0_m;
      const double sigma = (noise.a_m + noise.b_per_m * d * d) * mean_cam.norm() / z;
      const Eigen::Vector3d ray = (comps[j].mean_m - T_map_cam.translation()).normalized();
      cov += sigma * sigma * ray * ray.transpose();
    }
    precision[j] = cov.inverse();
    log_norm[j] = map.modelLogWeight(j) - 1.5 * kLog2Pi - 0.5 * std::log(cov.determinant());
  }
  FrameLikelihood out;
  out.pixels = static_cast<int>(frame.size());
  out.evaluations = static_cast<long long>(m) * frame.size();
  double sum = 0.0;
  int hits = 0;
  if (per_pixel) per_pixel->assign(frame.size(), 0.0);
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
    const double ll = mx + std::log(floor_term + mix);
    if (per_pixel) (*per_pixel)[i] = ll;
    sum += ll;
    hits += mix < floor_term ? 1 : 0;
  }
  out.log_likelihood = sum;
  out.floor_hits = hits;
  return out;
}

}  // namespace gmm_mcl
