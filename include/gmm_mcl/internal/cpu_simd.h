// 8-lane float vectors for the CPU likelihood kernel (GCC / Clang vector extensions: AVX2 with
// -march=native, pairs of SSE registers otherwise; 16 lanes for its AVX-512 path) and the kernel's
// exp2 and ln on them. Host only. Written with masks and bit operations rather than vector ?:
// (Clang's C++ lacks it for these types).
#pragma once

#include <stdint.h>
#include <string.h>

#include "gmm_mcl/internal/fast_math.h"

#if defined(__AVX__)
#include <immintrin.h>
#endif

// Without AVX, GCC warns that these 32-byte vector types change the ABI of the (always inlined)
// helpers below.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

namespace gmm_mcl {
namespace simd {

typedef float v8f __attribute__((vector_size(32)));
typedef int32_t v8i __attribute__((vector_size(32)));
typedef float v4f __attribute__((vector_size(16)));
typedef double v4d __attribute__((vector_size(32)));

#define GMM_MCL_SIMD_INLINE inline __attribute__((always_inline))

GMM_MCL_SIMD_INLINE v8f splat(float x) { return v8f{x, x, x, x, x, x, x, x}; }
GMM_MCL_SIMD_INLINE v8i splati(int32_t x) { return v8i{x, x, x, x, x, x, x, x}; }
GMM_MCL_SIMD_INLINE v8f load(const float* p) {
  v8f v;
  memcpy(&v, p, sizeof(v));  // unaligned
  return v;
}
GMM_MCL_SIMD_INLINE void store(float* p, v8f v) { memcpy(p, &v, sizeof(v)); }
GMM_MCL_SIMD_INLINE v8i asInt(v8f v) { return (v8i)v; }
GMM_MCL_SIMD_INLINE v8f asFloat(v8i v) { return (v8f)v; }

#if defined(__AVX512F__)
// 16-lane vectors: the kernel's AVX-512 path (likelihood.cpp), one register per 16 points.
#define GMM_MCL_SIMD_16 1
typedef float v16f __attribute__((vector_size(64)));
typedef int32_t v16i __attribute__((vector_size(64)));
GMM_MCL_SIMD_INLINE v16f load16(const float* p) {
  v16f v;
  memcpy(&v, p, sizeof(v));  // unaligned
  return v;
}
GMM_MCL_SIMD_INLINE void store16(float* p, v16f v) { memcpy(p, &v, sizeof(v)); }
#endif

// x in every lane of the float vector F (an initializer list: GCC turns a loop over the lanes
// into one masked broadcast per lane).
template <typename F>
F splatAs(float x);
template <>
GMM_MCL_SIMD_INLINE v8f splatAs<v8f>(float x) {
  return splat(x);
}
#if defined(GMM_MCL_SIMD_16)
template <>
GMM_MCL_SIMD_INLINE v16f splatAs<v16f>(float x) {
  return v16f{x, x, x, x, x, x, x, x, x, x, x, x, x, x, x, x};
}
#endif
// mask ? a : b per lane (mask lanes all ones or all zeros), for the float vector F and the int
// vector I of its lane count.
template <typename F, typename I>
GMM_MCL_SIMD_INLINE F selectAs(I mask, F a, F b) {
  return (F)(((I)a & mask) | ((I)b & ~mask));
}
GMM_MCL_SIMD_INLINE v8f select(v8i mask, v8f a, v8f b) { return selectAs<v8f, v8i>(mask, a, b); }

// exp(x) for x <= 0 lane by lane (F, I: a float vector and the int vector of its lane count):
// expNonPositive's clamp (x >= -87: never 0 or a denormal) and range reduction (n = round(x /
// ln 2), r = x - n ln 2 in two parts), then e^r = 1 + r + r^2 P4(r), P4 a near-minimax fit on
// |r| <= ln(2) / 2 (3.8e-9 relative in exact arithmetic, one fewer multiply-add than
// expNonPositive's; test_likelihood measures the float result). The same bits per lane at any
// lane count.
template <typename F, typename I>
GMM_MCL_SIMD_INLINE F expNonPositiveLanes(F x) {
  const F lo = splatAs<F>(-87.0f);
  x = selectAs<F, I>(x < lo, lo, x);
  const F kRound = splatAs<F>(12582912.0f);  // 1.5 * 2^23: round to nearest
  const F n = (x * 1.44269504088896341f + kRound) - kRound;
  const F r = (x - n * 0.693359375f) + n * 2.12194440e-4f;
  F y = splatAs<F>(1.381461275741458e-3f);
  y = y * r + 8.368710055947304e-3f;
  y = y * r + 4.166838899254799e-2f;
  y = y * r + 1.666652113199234e-1f;
  y = y * r + 4.999999403953552e-1f;
  y = y * (r * r) + r + 1.0f;
  const I e = (__builtin_convertvector(n, I) + 127) << 23;
  return y * (F)e;
}
GMM_MCL_SIMD_INLINE v8f expNonPositive8(v8f x) { return expNonPositiveLanes<v8f, v8i>(x); }
#if defined(GMM_MCL_SIMD_16)
GMM_MCL_SIMD_INLINE v16f expNonPositive16(v16f x) { return expNonPositiveLanes<v16f, v16i>(x); }
#endif

// ln(x) for positive normal finite x lane by lane: logPositive (fast_math.h), the same
// arithmetic.
template <typename F, typename I>
GMM_MCL_SIMD_INLINE F logPositiveLanes(F x) {
  const I bits = (I)x;
  I e = ((bits >> 23) & 0xff) - 126;  // x = m 2^e, m in [0.5, 1)
  F m = (F)((bits & 0x007fffff) | 0x3f000000);
  const I low = m < splatAs<F>(0.70710678118654752f);  // all ones where m < sqrt(1/2)
  e = e + low;                                         // e - 1 there
  m = (m + (F)((I)m & low)) - 1.0f;                    // 2m - 1 there, else m - 1
  return logFromReduced(m, __builtin_convertvector(e, F));
}
GMM_MCL_SIMD_INLINE v8f logPositive8(v8f x) { return logPositiveLanes<v8f, v8i>(x); }
#if defined(GMM_MCL_SIMD_16)
GMM_MCL_SIMD_INLINE v16f logPositive16(v16f x) { return logPositiveLanes<v16f, v16i>(x); }
#endif

// True when some lane of the mask is set.
GMM_MCL_SIMD_INLINE bool any(v8i mask) {
#if defined(__AVX__)
  return _mm256_movemask_ps(reinterpret_cast<__m256>(mask)) != 0;
#else
  v8i m = mask;
  int r = 0;
  for (int i = 0; i < 8; ++i) r |= m[i];
  return r != 0;
#endif
}

// The two halves of v as doubles.
GMM_MCL_SIMD_INLINE v4d lowToDouble(v8f v) {
  v4f h;
  memcpy(&h, &v, sizeof(h));
  return __builtin_convertvector(h, v4d);
}
GMM_MCL_SIMD_INLINE v4d highToDouble(v8f v) {
  v4f h;
  memcpy(&h, reinterpret_cast<const char*>(&v) + sizeof(h), sizeof(h));
  return __builtin_convertvector(h, v4d);
}

}  // namespace simd
}  // namespace gmm_mcl

#pragma GCC diagnostic pop
