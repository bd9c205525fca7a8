#include "gmm_mcl/measurement/membership.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "gmm_mcl/internal/fast_math.h"
#include "gmm_mcl/measurement/depth_noise_preset.h"

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace gmm_mcl {
namespace {

// projectAll is written without selects that have a constant arm or guard a computation: GCC
// specialises such a select into a branch with the computation under one arm, cannot
// if-convert that (a floating-point operation may trap), and leaves the whole loop scalar. Its
// helpers (sqrtVec, maxZero, ceilInt, floorInt) are in fast_math.h.

// Output of projectAll: projectComponent's results for m components, structure of arrays, plus
// each component's clamped patch bounding box (the box computeMembership tests).
struct ProjectedSoA {
  float *u, *v, *cuu, *cuv, *cvv, *quu, *quv, *qvv, *hw, *hh, *depth, *margin;
  int *ok, *col0, *col1, *row0, *row1, *exact;
};

// projectAll's per-frame constants: the pose, the intrinsics and the patch grid's geometry.
struct ProjectConstants {
  float R[9], t[3];
  float fx, fy, cx, cy, ps, c0, col_hi, row_hi;
  int last_col, last_row;
};

static inline ProjectConstants projectConstants(const RigidTransformF& T, const Intrinsics& K,
                                                const PatchGrid& grid) {
  ProjectConstants f;
  for (int k = 0; k < 9; ++k) f.R[k] = T.R[k];
  for (int k = 0; k < 3; ++k) f.t[k] = T.t[k];
  f.fx = K.fx_px;
  f.fy = K.fy_px;
  f.cx = K.cx_px;
  f.cy = K.cy_px;
  f.ps = static_cast<float>(grid.patch_size_px);
  f.c0 = 0.5f * (f.ps - 1.f);
  f.last_col = grid.cols - 1;
  f.last_row = grid.rows - 1;
  f.col_hi = static_cast<float>(grid.cols) + 1.f;
  f.row_hi = static_cast<float>(grid.rows) + 1.f;
  return f;
}

// in_view[i] = componentInView for the m components of the structure of arrays in (mean x, y, z,
// covariance 0..5: [9][m]) seen from T, one loop the compiler vectorises (projection.h's
// sphereInView arithmetic, up to FMA contraction).
__attribute__((noinline)) void inViewAll(const float* __restrict in, int m, int stride,
                                         const RigidTransformF& T, const Intrinsics& K,
                                         const ViewReach& r, float sigma_bound,
                                         int* __restrict in_view) {
  const float* __restrict mx = in, * __restrict my = in + stride, * __restrict mz = in + 2 * stride;
  const float* __restrict s0 = in + 3 * stride, * __restrict s3 = in + 6 * stride;
  const float* __restrict s5 = in + 8 * stride;
  float R[9], t[3];
  for (int k = 0; k < 9; ++k) R[k] = T.R[k];
  for (int k = 0; k < 3; ++k) t[k] = T.t[k];
  const float fx = K.fx_px, fy = K.fy_px;
#pragma omp simd
  for (int i = 0; i < m; ++i) {
    const float x = R[0] * mx[i] + R[1] * my[i] + R[2] * mz[i] + t[0];
    const float y = R[3] * mx[i] + R[4] * my[i] + R[5] * mz[i] + t[1];
    const float z = R[6] * mx[i] + R[7] * my[i] + R[8] * mz[i] + t[2];
    const float rho = sigma_bound * sqrtVec(s0[i] + s3[i] + s5[i]) + r.margin_m;
    in_view[i] = (z - rho <= r.far_m) & (fx * x - r.u0_px * z >= -rho * r.n_u0) &
                 (r.u1_px * z - fx * x >= -rho * r.n_u1) & (fy * y - r.v0_px * z >= -rho * r.n_v0) &
                 (r.v1_px * z - fy * y >= -rho * r.n_v1);
  }
}

// For MemberDepthPrune: depth[i] the camera depth of component i's mean and dz2_max[i] the
// largest squared depth gap at which its term can reach exp(floor - kDepthPruneNats),
// 2 (a^T Sigma a + sigma(z)^2) (log_norm - floor + kDepthPruneNats) (negative: nowhere), for the
// m components of the structure of arrays in (as inViewAll's) seen from T. Vectorised.
__attribute__((noinline)) void depthReachAll(const float* __restrict in, int m, int stride,
                                             const RigidTransformF& T,
                                             const MemberDepthPrune& prune, float* __restrict depth,
                                             float* __restrict dz2_max) {
  const float* __restrict mx = in, * __restrict my = in + stride, * __restrict mz = in + 2 * stride;
  const float* __restrict s0 = in + 3 * stride, * __restrict s1 = in + 4 * stride;
  const float* __restrict s2 = in + 5 * stride, * __restrict s3 = in + 6 * stride;
  const float* __restrict s4 = in + 7 * stride, * __restrict s5 = in + 8 * stride;
  const float* __restrict log_norm = prune.log_norm;
  const float a0 = T.R[6], a1 = T.R[7], a2 = T.R[8], tz = T.t[2];
  const bool noisy = prune.noise.enabled();
  const float na = noisy ? prune.noise.a_m : 0.f, nb = noisy ? prune.noise.b_per_m : 0.f;
  const float z0 = prune.noise.z0_m;
  const float budget0 = kDepthPruneNats - prune.floor_log_density;
#pragma omp simd
  for (int i = 0; i < m; ++i) {
    const float z = a0 * mx[i] + a1 * my[i] + a2 * mz[i] + tz;
    const float var = a0 * (a0 * s0[i] + 2.f * (a1 * s1[i] + a2 * s2[i])) +
                      a1 * (a1 * s3[i] + 2.f * a2 * s4[i]) + a2 * a2 * s5[i];
    const float dz = z - z0;
    const float sigma = na + nb * dz * dz;
    depth[i] = z;
    dz2_max[i] = 2.f * (var + sigma * sigma) * (log_norm[i] + budget0);
  }
}

// Whether the depth gap between a component at depth z and the range [lo, hi] is within
// sqrt(dz2_max) (MemberDepthPrune; false for a patch without points).
inline bool depthReaches(float lo, float hi, float z, float dz2_max) {
  const float gap = maxf(0.f, maxf(lo - z, z - hi));
  return gap * gap <= dz2_max;
}

// projectComponent for m components at once over structure-of-arrays inputs (mean x, y, z and
// the 6 covariance entries), one branch-free loop that the compiler vectorises (8 components
// per AVX2 instruction). The expressions are projectComponent's, in the same order, but the
// compiler contracts multiply-adds into FMA differently in this loop than in the scalar
// function, so the results can differ from projectComponent's in the last bits (measured: a few
// ulp). computeMembership therefore only trusts a result far from every decision boundary:
// exact[i] = 1 where projectComponent's outcome could differ (the mean within 1e-4 m of the near
// limit, a bounding-box edge within tolerance of a patch-centre row or column, anything not
// finite), and margin[i] bounds how far a patch centre's quadratic form may be from 1 before its
// ellipse test needs projectComponent (1e-4 times a bound on the form's terms over the box).
// ok[i] = 0 where the mean is nearer than min_depth_m (the other outputs are then meaningless).
__attribute__((noinline)) void projectAll(const float* __restrict in, int m, int stride,
                                          const RigidTransformF& T, const Intrinsics& K,
                                          const PatchGrid& grid, float min_depth_m,
                                          float sigma_bound, float inflate_px,
                                          const ProjectedSoA& o) {
  const float* __restrict mx = in, * __restrict my = in + stride, * __restrict mz = in + 2 * stride;
  const float* __restrict s0 = in + 3 * stride, * __restrict s1 = in + 4 * stride;
  const float* __restrict s2 = in + 5 * stride, * __restrict s3 = in + 6 * stride;
  const float* __restrict s4 = in + 7 * stride, * __restrict s5 = in + 8 * stride;
  float* __restrict ou = o.u, * __restrict ov = o.v, * __restrict ocuu = o.cuu;
  float* __restrict ocuv = o.cuv, * __restrict ocvv = o.cvv, * __restrict oquu = o.quu;
  float* __restrict oquv = o.quv, * __restrict oqvv = o.qvv, * __restrict ohw = o.hw;
  float* __restrict ohh = o.hh, * __restrict odepth = o.depth, * __restrict omargin = o.margin;
  int* __restrict oexact = o.exact, * __restrict ook = o.ok, * __restrict oc0 = o.col0;
  int* __restrict oc1 = o.col1, * __restrict or0 = o.row0, * __restrict or1 = o.row1;
  const ProjectConstants f = projectConstants(T, K, grid);
  const float(&R)[9] = f.R, (&t)[3] = f.t;
  const float fx = f.fx, fy = f.fy, cx = f.cx, cy = f.cy, ps = f.ps, c0 = f.c0;
  const float col_hi = f.col_hi, row_hi = f.row_hi;
  const int last_col = f.last_col, last_row = f.last_row;
#pragma omp simd
  for (int i = 0; i < m; ++i) {
    const float p[3] = {mx[i], my[i], mz[i]};
    const float S[6] = {s0[i], s1[i], s2[i], s3[i], s4[i], s5[i]};
    float mm[3];
    mm[0] = R[0] * p[0] + R[1] * p[1] + R[2] * p[2] + t[0];
    mm[1] = R[3] * p[0] + R[4] * p[1] + R[5] * p[2] + t[1];
    mm[2] = R[6] * p[0] + R[7] * p[1] + R[8] * p[2] + t[2];
    const float z_raw = mm[2];
    const bool ok = mm[2] >= min_depth_m;  // else the results are not used
    // projectComponent's arithmetic: the covariance through projection.h's rotateCovariance
    // (scalar arguments), the rest written out here: with projectComponent itself (its arrays
    // and output pointer) GCC 12 no longer vectorises this loop (`omp simd` private copies).
    const SymMat3F C = rotateCovariance(R, S[0], S[1], S[2], S[3], S[4], S[5]);
    const float iz = 1.f / mm[2];
    const float j00 = fx * iz, j02 = -fx * mm[0] * iz * iz;
    const float j11 = fy * iz, j12 = -fy * mm[1] * iz * iz;
    const float suu = j00 * j00 * C.xx + 2.f * j00 * j02 * C.xz + j02 * j02 * C.zz;
    const float suv = j00 * j11 * C.xy + j00 * j12 * C.xz + j02 * j11 * C.yz + j02 * j12 * C.zz;
    const float svv = j11 * j11 * C.yy + 2.f * j11 * j12 * C.yz + j12 * j12 * C.zz;
    const float u = cx + fx * mm[0] * iz;
    const float v = cy + fy * mm[1] * iz;
    const float half_tr = 0.5f * (suu + svv);
    const float diff = 0.5f * (suu - svv);
    const float rad = sqrtVec(diff * diff + suv * suv);
    const float l1p = half_tr + rad, l2p = half_tr - rad;
    const float l1 = maxZero(l1p);
    const float l2 = maxZero(l2p);
    // projectComponent's rad > 0 branch; rad <= 1e-20 (or NaN) is flagged for it below.
    const float h = 0.5f / rad;
    const float cu2 = (rad + diff) * h;
    const float cv2 = (rad - diff) * h;
    const float cuv = suv * h;
    const float a = sigma_bound * sqrtVec(l1) + inflate_px;
    const float b = sigma_bound * sqrtVec(l2) + inflate_px;
    const float ia2 = 1.f / (a * a), ib2 = 1.f / (b * b);
    const float hw = sqrtVec(a * a * cu2 + b * b * cv2);
    const float hh = sqrtVec(a * a * cv2 + b * b * cu2);
    ou[i] = u;
    ov[i] = v;
    ocuu[i] = suu;
    ocuv[i] = suv;
    ocvv[i] = svv;
    odepth[i] = mm[2];
    const float quu = cu2 * ia2 + cv2 * ib2;
    const float qvv = cv2 * ia2 + cu2 * ib2;
    oquu[i] = quu;
    oquv[i] = cuv * (ia2 - ib2);
    oqvv[i] = qvv;
    ohw[i] = hw;
    ohh[i] = hh;
    ook[i] = ok ? 1 : 0;
    const float x0 = (u - hw - c0) / ps, x1 = (u + hw - c0) / ps;
    const float y0 = (v - hh - c0) / ps, y1 = (v + hh - c0) / ps;
    // The indices only matter inside [-2, cols + 1] (they are clamped to the grid below): bound
    // them first, NaN included, so that no float outside int's range is converted (undefined
    // behaviour, UBSan). Both bounds give the same clamped box as the unbounded values would.
    const int col0 = ceilInt(clampTo(x0, -4.f, col_hi + 2.f));
    const int col1 = floorInt(clampTo(x1, -4.f, col_hi + 2.f));
    const int row0 = ceilInt(clampTo(y0, -4.f, row_hi + 2.f));
    const int row1 = floorInt(clampTo(y1, -4.f, row_hi + 2.f));
    // A box edge decides differently from projectComponent's only if a patch-centre index lies
    // between the two results; outside [-2, cols + 1] the clamping makes both boxes the same.
    const float tol_u = 1e-4f + 1e-5f * (std::fabs(u) + hw) / ps;
    const float tol_v = 1e-4f + 1e-5f * (std::fabs(v) + hh) / ps;
    // (Bitwise & and | instead of && and ||: no control flow, which blocks vectorisation.)
    const int near_x0 = (!(std::fabs(x0 - rintf(x0)) > tol_u)) & (x0 >= -2.f) & (x0 <= col_hi);
    const int near_x1 = (!(std::fabs(x1 - rintf(x1)) > tol_u)) & (x1 >= -2.f) & (x1 <= col_hi);
    const int near_y0 = (!(std::fabs(y0 - rintf(y0)) > tol_v)) & (y0 >= -2.f) & (y0 <= row_hi);
    const int near_y1 = (!(std::fabs(y1 - rintf(y1)) > tol_v)) & (y1 >= -2.f) & (y1 <= row_hi);
    const int near_z = !(std::fabs(z_raw - min_depth_m) > 1e-4f);
    const int finite =
        (std::fabs(u) < 1e30f) & (std::fabs(v) < 1e30f) & (hw < 1e30f) & (hh < 1e30f);  // 0 for NaN
    const int round = !(rad > 1e-20f);
    oexact[i] =
        (static_cast<int>(ok) & (near_x0 | near_x1 | near_y0 | near_y1 | round | (finite ^ 1))) |
        near_z;
    // |form - projectComponent's form| <= few ulp * (q_uu + q_vv)(du^2 + dv^2) for every patch
    // centre of the box (|du| <= hw + ps, |dv| <= hh + ps).
    const float ew = hw + ps, eh = hh + ps;
    omargin[i] = 1e-4f * (1.f + (quu + qvv) * (ew * ew + eh * eh));
    oc0[i] = col0 > 0 ? col0 : 0;
    oc1[i] = col1 < last_col ? col1 : last_col;
    or0[i] = row0 > 0 ? row0 : 0;
    or1[i] = row1 < last_row ? row1 : last_row;
  }
}

// The patches of one component's box whose centre lies in its ellipse: ellipseContains with its
// contraction written out (the same bits as the compiled ellipseContains: with FMA,
// fma(du, q_uu du, 2 q_uv du dv), then fma(dv, q_vv dv, .); without, as written), without a
// branch per test (the outcome is hard to
// predict): every tested patch is written at hp[hits] and hits advances by the outcome. Returns
// true when some centre's form is within `margin` of 1 (or not a number): then the outcome may
// depend on the last bits of the projection. margin < 0: no check. With kPrune, a centre also needs
// depthReaches(zlo[patch], zhi[patch], z, dz2_max).
template <bool kPrune>
inline bool testBox(const PatchGrid& grid, int col0, int col1, int row0, int row1, float pu,
                    float pv, float quu, float quv, float qvv, float margin, int* __restrict hp,
                    size_t* hits_io, const float* zlo = nullptr, const float* zhi = nullptr,
                    float z = 0.f, float dz2_max = 0.f) {
  const float ps = static_cast<float>(grid.patch_size_px);
  const float q2uv = 2.f * quv;
  size_t hits = *hits_io;
  bool near = false;
  // Patch centres are integers + 0.5 (or integers): exact in float, so stepping by the patch
  // size gives the same values as centreU(c) / centreV(r).
  float v = grid.centreV(row0);
  const float u0 = grid.centreU(col0);
  for (int r = row0; r <= row1; ++r, v += ps) {
    const float dv = v - pv;
    const float dvv = qvv * dv;
    float u = u0;
    int patch = r * grid.cols + col0;
    for (int c = col0; c <= col1; ++c, u += ps, ++patch) {
      const float du = u - pu;
#if defined(GMM_MCL_EXPLICIT_FMA)  // ellipseContains' order, bit for bit
      const float s = fmaf(dv, dvv, fmaf(du, quu * du, q2uv * du * dv));
#else  // no FMA: ellipseContains' order without fusing
      const float s = (du * (quu * du) + q2uv * du * dv) + dv * dvv;
#endif
      int in_ellipse = s <= 1.f ? 1 : 0;
      near |= !(std::fabs(s - 1.f) > margin);
      if (kPrune) in_ellipse &= depthReaches(zlo[patch], zhi[patch], z, dz2_max) ? 1 : 0;
      hp[hits] = patch;
      hits += static_cast<size_t>(in_ellipse);
    }
  }
  *hits_io = hits;
  return near;
}

#if defined(__AVX2__) && defined(__FMA__)
// testBox (with the margin check) 8 patch centres of a row at a time, AVX2: the same form and
// FMA arithmetic per centre, lane by lane. The centres inside form a run of the row's patches
// (the ellipse is convex; a mask that is not one run, only conceivable through rounding, takes
// the per-bit path): one store of 8 patch indices at hp[hits] (hp needs 8 entries of slack past
// the box's cells).
// With kPrune, a centre also needs depthReaches (testBox).
template <bool kPrune>
inline bool testBoxVec(const PatchGrid& grid, int col0, int col1, int row0, int row1, float pu,
                       float pv, float quu, float quv, float qvv, float margin, int* __restrict hp,
                       size_t* hits_io, const float* zlo = nullptr, const float* zhi = nullptr,
                       float z = 0.f, float dz2_max = 0.f) {
  const float ps = static_cast<float>(grid.patch_size_px);
  const __m256 lane = _mm256_setr_ps(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f);
  const __m256i lane_i = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 vps = _mm256_set1_ps(ps);
  const __m256 vquu = _mm256_set1_ps(quu), vq2uv = _mm256_set1_ps(2.f * quv);
  const __m256 one = _mm256_set1_ps(1.f), vmargin = _mm256_set1_ps(margin);
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  size_t hits = *hits_io;
  __m256 near = _mm256_setzero_ps();
  float v = grid.centreV(row0);
  for (int r = row0; r <= row1; ++r, v += ps) {
    const float dv = v - pv;
    const __m256 vdv = _mm256_set1_ps(dv), vdvv = _mm256_set1_ps(qvv * dv);
    const int row_base = r * grid.cols;
    for (int c = col0; c <= col1; c += 8) {
      const int ncols = col1 - c + 1 < 8 ? col1 - c + 1 : 8;
      const __m256i live_i = _mm256_cmpgt_epi32(_mm256_set1_epi32(ncols), lane_i);
      const __m256 live = _mm256_castsi256_ps(live_i);
      // Centres c, c + 1, ...: integers + 0.5 (or integers), exact.
      const __m256 u = _mm256_fmadd_ps(lane, vps, _mm256_set1_ps(grid.centreU(c)));
      const __m256 du = _mm256_sub_ps(u, _mm256_set1_ps(pu));
      const __m256 t = _mm256_mul_ps(_mm256_mul_ps(vq2uv, du), vdv);
      const __m256 s = _mm256_fmadd_ps(vdv, vdvv, _mm256_fmadd_ps(du, _mm256_mul_ps(vquu, du), t));
      __m256 in = _mm256_and_ps(_mm256_cmp_ps(s, one, _CMP_LE_OQ), live);
      const __m256 dist = _mm256_and_ps(_mm256_sub_ps(s, one), abs_mask);
      near = _mm256_or_ps(near, _mm256_and_ps(_mm256_cmp_ps(dist, vmargin, _CMP_NGT_UQ), live));
      if (kPrune) {  // depthReaches on 8 patches (zlo, zhi have 8 entries of slack)
        const __m256 vz = _mm256_set1_ps(z);
        const __m256 gap =
            _mm256_max_ps(_mm256_setzero_ps(),
                          _mm256_max_ps(_mm256_sub_ps(_mm256_loadu_ps(zlo + row_base + c), vz),
                                        _mm256_sub_ps(vz, _mm256_loadu_ps(zhi + row_base + c))));
        in = _mm256_and_ps(
            in, _mm256_cmp_ps(_mm256_mul_ps(gap, gap), _mm256_set1_ps(dz2_max), _CMP_LE_OQ));
      }
      unsigned bits = static_cast<unsigned>(_mm256_movemask_ps(in));
      if (bits == 0) continue;
      const int first = __builtin_ctz(bits);
      const unsigned run = bits >> first;
      const int patch0 = row_base + c + first;
      if ((run & (run + 1)) == 0) {  // one run of len patches from patch0
        const int len = __builtin_popcount(run);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(hp + hits),
                            _mm256_add_epi32(_mm256_set1_epi32(patch0), lane_i));
        hits += static_cast<size_t>(len);
      } else {
        for (unsigned b = bits; b != 0; b &= b - 1) {
          const int patch = row_base + c + __builtin_ctz(b);
          hp[hits++] = patch;
        }
      }
    }
  }
  *hits_io = hits;
  return _mm256_movemask_ps(near) != 0;
}
#endif

#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__FMA__)
#define GMM_MCL_BOX_TILES 1
// testBox (with the margin check) over tiles of 4 x 4 patch centres, AVX-512: the same form
// and FMA arithmetic per centre as testBoxVec, lane by lane. A box is 3.3 rows of 3-4 patches on
// the `cpu` workload, so one tile holds most boxes where testBoxVec took a vector (and a
// branch) per row. The tile's hits are written compressed at hp[hits] (hp needs 16 entries of
// slack past the box's cells). With kPrune, a centre also needs depthReaches (testBox); zlo, zhi
// need 3 entries of slack past the last patch.
template <bool kPrune>
inline bool testBoxTiles(const PatchGrid& grid, int col0, int col1, int row0, int row1, float pu,
                         float pv, float quu, float quv, float qvv, float margin,
                         int* __restrict hp, size_t* hits_io, const float* zlo, const float* zhi,
                         float z, float dz2_max) {
  const int cols = grid.cols;
  const float ps = static_cast<float>(grid.patch_size_px);
  // Lane 4 i + j: row i, column j of the tile.
  const __m512 tile_col = _mm512_setr_ps(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3);
  const __m512 tile_row = _mm512_setr_ps(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3);
  const __m512i lane_col = _mm512_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3);
  const __m512i lane_row = _mm512_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3);
  const __m512i patch_offset =
      _mm512_add_epi32(_mm512_mullo_epi32(lane_row, _mm512_set1_epi32(cols)), lane_col);
  const __m512 vps = _mm512_set1_ps(ps);
  const __m512 vquu = _mm512_set1_ps(quu), vq2uv = _mm512_set1_ps(2.f * quv);
  const __m512 vqvv = _mm512_set1_ps(qvv), one = _mm512_set1_ps(1.f);
  const __m512 vmargin = _mm512_set1_ps(margin), vpu = _mm512_set1_ps(pu);
  const __m512 vz = _mm512_set1_ps(z), vdz2 = _mm512_set1_ps(dz2_max);
  size_t hits = *hits_io;
  __mmask16 near = 0;
  for (int r = row0; r <= row1; r += 4) {
    const int nr = row1 - r + 1 < 4 ? row1 - r + 1 : 4;
    const __mmask16 live_rows = _mm512_cmplt_epi32_mask(lane_row, _mm512_set1_epi32(nr));
    // Centres are integers + 0.5 (or integers): exact, as centreV(r + i).
    const __m512 v = _mm512_fmadd_ps(tile_row, vps, _mm512_set1_ps(grid.centreV(r)));
    const __m512 dv = _mm512_sub_ps(v, _mm512_set1_ps(pv));
    const __m512 dvv = _mm512_mul_ps(vqvv, dv);
    for (int c = col0; c <= col1; c += 4) {
      const int nc = col1 - c + 1 < 4 ? col1 - c + 1 : 4;
      const __mmask16 live = live_rows & _mm512_cmplt_epi32_mask(lane_col, _mm512_set1_epi32(nc));
      const __m512 u = _mm512_fmadd_ps(tile_col, vps, _mm512_set1_ps(grid.centreU(c)));
      const __m512 du = _mm512_sub_ps(u, vpu);
      const __m512 t = _mm512_mul_ps(_mm512_mul_ps(vq2uv, du), dv);
      const __m512 s = _mm512_fmadd_ps(dv, dvv, _mm512_fmadd_ps(du, _mm512_mul_ps(vquu, du), t));
      __mmask16 in = _mm512_mask_cmp_ps_mask(live, s, one, _CMP_LE_OQ);
      near |=
          _mm512_mask_cmp_ps_mask(live, _mm512_abs_ps(_mm512_sub_ps(s, one)), vmargin, _CMP_NGT_UQ);
      const int base = r * cols + c;
      if (kPrune && in != 0) {  // depthReaches: the tile's rows (the last box row repeated)
        const float* lo_row[4];
        const float* hi_row[4];
        for (int i = 0; i < 4; ++i) {
          const int at = base + (i < nr ? i : nr - 1) * cols;
          lo_row[i] = zlo + at;
          hi_row[i] = zhi + at;
        }
        const __m512 lo = _mm512_insertf32x4(
            _mm512_insertf32x4(_mm512_insertf32x4(_mm512_zextps128_ps512(_mm_loadu_ps(lo_row[0])),
                                                  _mm_loadu_ps(lo_row[1]), 1),
                               _mm_loadu_ps(lo_row[2]), 2),
            _mm_loadu_ps(lo_row[3]), 3);
        const __m512 hi = _mm512_insertf32x4(
            _mm512_insertf32x4(_mm512_insertf32x4(_mm512_zextps128_ps512(_mm_loadu_ps(hi_row[0])),
                                                  _mm_loadu_ps(hi_row[1]), 1),
                               _mm_loadu_ps(hi_row[2]), 2),
            _mm_loadu_ps(hi_row[3]), 3);
        // (maskz_max: GCC 12's _mm512_max_ps warns of its own undefined source operand.)
        const __m512 gap = _mm512_maskz_max_ps(
            0xffff, _mm512_setzero_ps(),
            _mm512_maskz_max_ps(0xffff, _mm512_sub_ps(lo, vz), _mm512_sub_ps(vz, hi)));
        in = _mm512_mask_cmp_ps_mask(in, _mm512_mul_ps(gap, gap), vdz2, _CMP_LE_OQ);
      }
      if (in == 0) continue;
      const __m512i patch = _mm512_add_epi32(_mm512_set1_epi32(base), patch_offset);
      _mm512_storeu_si512(hp + hits, _mm512_maskz_compress_epi32(in, patch));
      hits += static_cast<size_t>(__builtin_popcount(in));
    }
  }
  *hits_io = hits;
  return near != 0;
}
#endif

// The fastest of the box tests this build has (the same outcome from each): testBoxTiles with
// AVX-512, testBoxVec with AVX2, else testBox.
template <bool kPrune>
inline bool testBoxFastest(const PatchGrid& grid, int col0, int col1, int row0, int row1, float pu,
                           float pv, float quu, float quv, float qvv, float margin,
                           int* __restrict hp, size_t* hits_io, const float* zlo, const float* zhi,
                           float z, float dz2_max) {
#if defined(GMM_MCL_BOX_TILES)
  return testBoxTiles<kPrune>(grid, col0, col1, row0, row1, pu, pv, quu, quv, qvv, margin, hp,
                              hits_io, zlo, zhi, z, dz2_max);
#elif defined(__AVX2__) && defined(__FMA__)
  return testBoxVec<kPrune>(grid, col0, col1, row0, row1, pu, pv, quu, quv, qvv, margin, hp,
                            hits_io, zlo, zhi, z, dz2_max);
#else
  return testBox<kPrune>(grid, col0, col1, row0, row1, pu, pv, quu, quv, qvv, margin, hp, hits_io,
                         zlo, zhi, z, dz2_max);
#endif
}

// computeMembership's per-thread buffers.
struct MembershipBuffers {
  std::vector<float> soa_in;       // mean x, y, z, covariance 0..5: [9][m]
  std::vector<float> soa_f;        // ProjectedSoA floats: [12][m]
  std::vector<int> soa_i;          // ProjectedSoA ints: [6][m]
  std::vector<int> hit_patch;      // pass 1's patches, in component order
  std::vector<int> candidates;     // the components pass 1 tests, ascending
  std::vector<int> hit_comp;       // pass 1's components, one per hit (+ 16 slack)
  std::vector<int> cursor;         // pass 2's next slot per patch
  std::vector<int> in_view;        // [m]: inViewAll
  std::vector<float> depth_reach;  // depth, dz2_max: [2][m]
};

// This thread's buffers, looked up by a call of its own: in a shared library a thread_local's
// address comes from __tls_get_addr, and GCC recomputes it at each use under register pressure
// instead of keeping it (2-4% of the CPU backend's update when computeMembership named them).
__attribute__((noinline)) MembershipBuffers& threadMembershipBuffers() {
  static thread_local MembershipBuffers buffers;
  return buffers;
}

// The components' means as a structure of arrays: x at in[0 ..), y at in[stride ..), z at
// in[2 stride ..).
void copyMeans(const std::vector<ComponentF>& components, float* in, size_t stride) {
  for (size_t i = 0; i < components.size(); ++i) {
    for (int a = 0; a < 3; ++a) in[a * stride + i] = components[i].mean_m[a];
  }
}

}  // namespace

std::string MeasurementParams::validate() const {
  std::ostringstream err;
  if (!(min_component_depth_m > 0.f) || !std::isfinite(min_component_depth_m)) {
    err << "min_component_depth_m must be positive (got " << min_component_depth_m << "); ";
  }
  if (!(sigma_bound > 0.f) || !std::isfinite(sigma_bound)) {
    err << "sigma_bound must be positive (got " << sigma_bound << "); ";
  }
  if (!std::isfinite(floor_log_density) || floor_log_density < -80.f) {
    err << "floor_log_density must be finite and >= -80 nats (got " << floor_log_density << "); ";
  }
  const DepthNoiseModel& n = depth_noise;
  if (!(n.a_m >= 0.f) || !(n.b_per_m >= 0.f) || !std::isfinite(n.a_m) ||
      !std::isfinite(n.b_per_m) || !std::isfinite(n.z0_m) || !(n.z0_m >= 0.f)) {
    err << "depth_noise needs finite a >= 0, b >= 0 and z0 >= 0 (got a " << n.a_m << " m, b "
        << n.b_per_m << " 1/m, z0 " << n.z0_m << " m); ";
  }
  DepthNoiseModel preset;
  const std::string preset_error = applyDepthNoisePreset(depth_noise_preset, &preset);
  if (!preset_error.empty()) err << preset_error << "; ";
  return err.str();
}

void computeMembership(const std::vector<ComponentF>& components, const RigidTransformF& T_cam_map,
                       const Intrinsics& K, const PatchGrid& grid, const MeasurementParams& params,
                       std::vector<ProjectedComponent>* projected, std::vector<char>* valid,
                       PatchMembership* out, const ViewReach* reach, const MemberDepthPrune* prune,
                       const float* component_soa) {
  const int m = static_cast<int>(components.size());
  const int num_patches = grid.count();
  const float inflate = patchInflation(grid.patch_size_px);
  const float ps = static_cast<float>(grid.patch_size_px);
  const float c0 = 0.5f * (ps - 1.f);  // centre of patch 0
  if (projected) projected->resize(m);
  valid->assign(m, 0);
  out->begin.assign(num_patches + 1, 0);
  // Per-thread buffers, reused across calls (no allocation once warm).
  MembershipBuffers& buffers = threadMembershipBuffers();
  std::vector<float>& soa_in = buffers.soa_in;
  std::vector<float>& soa_f = buffers.soa_f;
  std::vector<int>& soa_i = buffers.soa_i;
  std::vector<int>& hit_patch = buffers.hit_patch;
  std::vector<int>& candidates = buffers.candidates;
  std::vector<int>& hit_comp = buffers.hit_comp;
  std::vector<int>& cursor = buffers.cursor;
  std::vector<int>& in_view = buffers.in_view;
  std::vector<float>& depth_reach = buffers.depth_reach;
  const size_t ms = static_cast<size_t>(m);
  soa_f.resize(12 * ms);
  soa_i.resize(6 * ms);
  // The components as a structure of arrays: the caller's (componentSoA, kept across poses) or
  // built here.
  const float* in = component_soa;
  int stride = componentSoAStride(m);
  if (!in) {
    stride = m;
    soa_in.resize(9 * ms);
    float* own = soa_in.data();
    copyMeans(components, own, ms);
    for (int i = 0; i < m; ++i) {
      for (int k = 0; k < 6; ++k) own[(3 + k) * ms + i] = components[i].cov_m2[k];
    }
    in = own;
  }
  float* f = soa_f.data();
  int* n = soa_i.data();
  const ProjectedSoA P = {f,          f + ms,     f + 2 * ms, f + 3 * ms, f + 4 * ms,  f + 5 * ms,
                          f + 6 * ms, f + 7 * ms, f + 8 * ms, f + 9 * ms, f + 10 * ms, f + 11 * ms,
                          n,          n + ms,     n + 2 * ms, n + 3 * ms, n + 4 * ms,  n + 5 * ms};
  projectAll(in, m, stride, T_cam_map, K, grid, params.min_component_depth_m, params.sigma_bound,
             inflate, P);
  // The pose's view volume, when given: a component outside it is no member (cullToView).
  if (reach) {
    in_view.resize(ms);
    inViewAll(in, m, stride, T_cam_map, K, *reach, params.sigma_bound, in_view.data());
  }
  const float* zlo = prune ? prune->patch_min_z : nullptr;
  const float* zhi = prune ? prune->patch_max_z : nullptr;
  if (prune) {
    depth_reach.resize(2 * ms);
    depthReachAll(in, m, stride, T_cam_map, *prune, depth_reach.data(), depth_reach.data() + ms);
  }
  const float* comp_z = depth_reach.data();
  const float* comp_dz2 = depth_reach.data() + ms;
  // Pass 1: per component (ascending), the patches whose centre lies in its inflated ellipse,
  // from the vectorised projection; where that could decide differently from projectComponent
  // (P.exact, or a centre within P.margin of the ellipse), the component is redone with
  // projectComponent, so that the table is the brute-force reference's exactly.
  // The components to test, ascending: in the view volume (when given), and with a box on the
  // grid or flagged for projectComponent. Listed without a branch per component (a quarter of
  // them drop out, in no pattern the branch predictor learns).
  candidates.resize(ms);
  int* __restrict cand = candidates.data();
  int num_cand = 0;
  for (int i = 0; i < m; ++i) {
    const int box = P.ok[i] & (P.col0[i] <= P.col1[i] ? 1 : 0) & (P.row0[i] <= P.row1[i] ? 1 : 0);
    cand[num_cand] = i;
    num_cand += (reach ? in_view[i] : 1) & (box | (P.exact[i] != 0 ? 1 : 0));
  }
  // Each hit's component, written beside its patch after the component's box test: 16 at once
  // (the next component's overwrite those beyond its hits), the rest one by one (rare). Pass 2
  // reads them; a loop over the components' runs afterwards cost 2% of the update.
  // Room for `cells` more hits in both lists (kept the same size).
  auto make_room = [&](size_t hits_now, size_t cells) {
    if (hit_patch.size() >= hits_now + cells) return;
    hit_patch.resize(2 * (hits_now + cells));
    hit_comp.resize(hit_patch.size());
  };
  auto note_component = [&](size_t from, size_t to, int comp) {
    int* __restrict hc = hit_comp.data();
    for (int k = 0; k < 16; ++k) hc[from + k] = comp;
    for (size_t k = from + 16; k < to; ++k) hc[k] = comp;
  };
  size_t hits = 0;
  for (int j = 0; j < num_cand; ++j) {
    const int i = cand[j];
    const bool exact = P.exact[i] != 0;
    const int col0 = P.col0[i], col1 = P.col1[i], row0 = P.row0[i], row1 = P.row1[i];
    const size_t first = hits;
    bool redo = exact;
    if (!exact) {
      make_room(hits, static_cast<size_t>(row1 - row0 + 1) * (col1 - col0 + 1) + 16);
      redo = prune ? testBoxFastest<true>(grid, col0, col1, row0, row1, P.u[i], P.v[i], P.quu[i],
                                          P.quv[i], P.qvv[i], P.margin[i], hit_patch.data(), &hits,
                                          zlo, zhi, comp_z[i], comp_dz2[i])
                   : testBoxFastest<false>(grid, col0, col1, row0, row1, P.u[i], P.v[i], P.quu[i],
                                           P.quv[i], P.qvv[i], P.margin[i], hit_patch.data(), &hits,
                                           nullptr, nullptr, 0.f, 0.f);
      if (redo) {
        hits = first;  // undo this component's hits
      } else {
        note_component(first, hits, i);
      }
    }
    ProjectedComponent scratch;
    ProjectedComponent& p = projected ? (*projected)[i] : scratch;
    if (redo) {
      if (!projectComponent(components[i], T_cam_map, K, params.min_component_depth_m,
                            params.sigma_bound, inflate, &p)) {
        continue;
      }
      const int e_col0 = std::max(0, static_cast<int>(std::ceil((p.u_px - p.half_w_px - c0) / ps)));
      const int e_col1 =
          std::min(grid.cols - 1, static_cast<int>(std::floor((p.u_px + p.half_w_px - c0) / ps)));
      const int e_row0 = std::max(0, static_cast<int>(std::ceil((p.v_px - p.half_h_px - c0) / ps)));
      const int e_row1 =
          std::min(grid.rows - 1, static_cast<int>(std::floor((p.v_px + p.half_h_px - c0) / ps)));
      if (e_col0 > e_col1 || e_row0 > e_row1) continue;
      make_room(hits, static_cast<size_t>(e_row1 - e_row0 + 1) * (e_col1 - e_col0 + 1) + 16);
      if (prune) {
        testBox<true>(grid, e_col0, e_col1, e_row0, e_row1, p.u_px, p.v_px, p.q_uu, p.q_uv, p.q_vv,
                      -1.f, hit_patch.data(), &hits, zlo, zhi, comp_z[i], comp_dz2[i]);
      } else {
        testBox<false>(grid, e_col0, e_col1, e_row0, e_row1, p.u_px, p.v_px, p.q_uu, p.q_uv, p.q_vv,
                       -1.f, hit_patch.data(), &hits);
      }
      note_component(first, hits, i);
      if (hits == first) continue;
    } else {
      if (hits == first) continue;
      // projectComponent's result to within float rounding (scratch output), for a caller that
      // keeps it.
      if (!projected) {
        (*valid)[i] = 1;
        continue;
      }
      p.u_px = P.u[i];
      p.v_px = P.v[i];
      p.cov_uu = P.cuu[i];
      p.cov_uv = P.cuv[i];
      p.cov_vv = P.cvv[i];
      p.q_uu = P.quu[i];
      p.q_uv = P.quv[i];
      p.q_vv = P.qvv[i];
      p.half_w_px = P.hw[i];
      p.half_h_px = P.hh[i];
      p.depth_m = P.depth[i];
    }
    (*valid)[i] = 1;
  }
  // Members per patch, counted from the hits in one pass into begin[patch + 1] (zero from the
  // start), then summed in place. Counting in the box tests (a masked load-add-store per tile
  // row, its rows overlapping the previous components' stores by a few patches) cost 3% more of
  // the membership's time on the `cpu` workload.
  int* __restrict begin = out->begin.data();
  for (size_t k = 0; k < hits; ++k) ++begin[hit_patch[k] + 1];
  for (int p = 0; p < num_patches; ++p) begin[p + 1] += begin[p];
  out->comps.resize(out->begin[num_patches]);
  // Pass 2: scatter pass 1's hits by patch (components ascending within each patch), one loop
  // over the hits: a loop per component, whose trip count the branch predictor cannot know, took
  // a quarter of computeMembership's time.
  const size_t total_hits = hits;
  const int* __restrict hc = hit_comp.data();
  cursor.assign(out->begin.begin(), out->begin.end() - 1);
  int* __restrict cur = cursor.data();
  int* __restrict dst = out->comps.data();
  const int* __restrict hp = hit_patch.data();
  for (size_t k = 0; k < total_hits; ++k) dst[cur[hp[k]]++] = hc[k];
}

int componentSoAStride(int m) {
  return (m + kComponentSoALanes - 1) / kComponentSoALanes * kComponentSoALanes;
}

void componentSoA(const std::vector<ComponentF>& components, std::vector<float>* soa) {
  const int m = static_cast<int>(components.size());
  const size_t stride = static_cast<size_t>(componentSoAStride(m));
  soa->resize(kComponentSoARows * stride);
  float* out = soa->data();
  // Padding lanes: a unit sphere 1 m in front of the map origin (finite, never read back).
  static const ComponentF kPad = {
      {0.f, 0.f, 1.f}, {1.f, 0.f, 0.f, 1.f, 0.f, 1.f}, {1.f, 0.f, 0.f, 1.f, 0.f, 1.f}, 0.f, 0.f};
  for (size_t i = 0; i < stride; ++i) {
    const ComponentF& c = i < components.size() ? components[i] : kPad;
    for (int a = 0; a < 3; ++a) out[a * stride + i] = c.mean_m[a];
    for (int k = 0; k < 6; ++k) out[(3 + k) * stride + i] = c.cov_m2[k];
    out[9 * stride + i] = c.log_weight;
  }
}

void patchDepthRanges(const DepthFrame& frame, std::vector<float>* min_z,
                      std::vector<float>* max_z) {
  const int n = frame.grid.count();
  min_z->assign(static_cast<size_t>(n) + 8, 3e18f);
  max_z->assign(static_cast<size_t>(n) + 8, -3e18f);
  for (int p = 0; p < n; ++p) {
    float lo = 3e18f, hi = -3e18f;
    for (int i = frame.patch_begin[p]; i < frame.patch_begin[p + 1]; ++i) {
      lo = std::min(lo, frame.z_m[i]);
      hi = std::max(hi, frame.z_m[i]);
    }
    (*min_z)[p] = lo;
    (*max_z)[p] = hi;
  }
}

void computeMembershipBruteForce(const std::vector<ComponentF>& components,
                                 const RigidTransformF& T_cam_map, const Intrinsics& K,
                                 const PatchGrid& grid, const MeasurementParams& params,
                                 PatchMembership* out) {
  const float inflate = patchInflation(grid.patch_size_px);
  out->begin.assign(1, 0);
  out->comps.clear();
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      for (size_t i = 0; i < components.size(); ++i) {
        ProjectedComponent p;
        if (projectComponent(components[i], T_cam_map, K, params.min_component_depth_m,
                             params.sigma_bound, inflate, &p) &&
            ellipseContains(p, grid.centreU(c), grid.centreV(r))) {
          out->comps.push_back(static_cast<int>(i));
        }
      }
      out->begin.push_back(static_cast<int>(out->comps.size()));
    }
  }
}

}  // namespace gmm_mcl
