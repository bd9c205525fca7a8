// exp for arguments <= 0 written as plain arithmetic so that the compiler vectorises it on the
// CPU and both backends compute the same bits. Cephes-style range reduction and polynomial;
// relative error below 2e-7 on [-87, 0]; arguments below -87 return ~1.6e-38 (never 0, never
// a denormal).
#pragma once

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gmm_mcl/common/host_device.h"

namespace gmm_mcl {

// The bits of a float as an int32_t and back: the intrinsics on the device; on the host
// __builtin_bit_cast where the compiler has it (it vectorises where memcpy into a local does not).
#if defined(__CUDA_ARCH__)
GMM_MCL_HD float bitsToFloat(int32_t bits) { return __int_as_float(bits); }
GMM_MCL_HD int32_t floatToBits(float f) { return __float_as_int(f); }
#else
#if defined(__has_builtin)
#if __has_builtin(__builtin_bit_cast)
#define GMM_MCL_BUILTIN_BIT_CAST 1
#endif
#endif
template <typename To, typename From>
inline To hostBitCast(From from) {
#if defined(GMM_MCL_BUILTIN_BIT_CAST)
  return __builtin_bit_cast(To, from);
#else
  To to;
  memcpy(&to, &from, sizeof(to));
  return to;
#endif
}
GMM_MCL_HD float bitsToFloat(int32_t bits) { return hostBitCast<float>(bits); }
GMM_MCL_HD int32_t floatToBits(float f) { return hostBitCast<int32_t>(f); }
#endif

// max without fmaxf's NaN rules, which keep GCC from vectorising (maps to vmaxps).
GMM_MCL_HD float maxf(float a, float b) { return a < b ? b : a; }

GMM_MCL_HD float expNonPositive(float x) {
  x = maxf(x, -87.0f);
  // n = round(x / ln 2) by the 1.5 * 2^23 trick (floorf blocks vectorisation in GCC).
  const float kRound = 12582912.0f;
  const float n = (x * 1.44269504088896341f + kRound) - kRound;
  const float r = (x - n * 0.693359375f) + n * 2.12194440e-4f;
  float y = 1.9875691500e-4f;
  y = y * r + 1.3981999507e-3f;
  y = y * r + 8.3334519073e-3f;
  y = y * r + 4.1665795894e-2f;
  y = y * r + 1.6666665459e-1f;
  y = y * r + 5.0000001201e-1f;
  y = y * r * r + r + 1.0f;
  return y * bitsToFloat((static_cast<int32_t>(n) + 127) << 23);
}

// ln(2^fe (1 + m)) for m in [-0.29, 0.41): the polynomial and assembly of logPositive, for a
// float or an 8-lane vector (cpu_simd.h's logPositive8: the same arithmetic, lane by lane).
template <typename T>
GMM_MCL_HD T logFromReduced(T m, T fe) {
  const T z = m * m;
  T y = m * 7.0376836292e-2f - 1.1514610310e-1f;
  y = y * m + 1.1676998740e-1f;
  y = y * m - 1.2420140846e-1f;
  y = y * m + 1.4249322787e-1f;
  y = y * m - 1.6668057665e-1f;
  y = y * m + 2.0000714765e-1f;
  y = y * m - 2.4999993993e-1f;
  y = y * m + 3.3333331174e-1f;
  y = y * m * z;
  y += -2.12194440e-4f * fe;
  y += -0.5f * z;
  return (m + y) + 0.693359375f * fe;
}

// ln(x) for positive normal finite x, as plain arithmetic that the compiler vectorises (the CPU
// kernel's per-pixel log). Cephes-style: x = m 2^e with m in [sqrt(1/2), sqrt(2)), a degree-9
// polynomial in m - 1, ln 2 split in two parts; error below 1e-7 max(1, |ln x|) for x in
// [e^-85, e^85] (test_likelihood checks it).
GMM_MCL_HD float logPositive(float x) {
  const int32_t bits = floatToBits(x);
  int32_t e = ((bits >> 23) & 0xff) - 126;  // x = m 2^e, m in [0.5, 1)
  float m = bitsToFloat((bits & 0x007fffff) | 0x3f000000);
  const bool low = m < 0.70710678118654752f;
  e -= low ? 1 : 0;
  m = low ? (m + m - 1.0f) : (m - 1.0f);  // m - 1 in [-0.29, 0.41)
  return logFromReduced(m, static_cast<float>(e));
}

// Helpers for loops that GCC must vectorise (membership.cpp's projectAll): plain arithmetic,
// no select that guards a computation.

// sqrt(x) for x >= 0 (or NaN) in plain arithmetic that the compiler vectorises (sqrtf does not:
// it may set errno): the bit-trick reciprocal square root of x + 1e-30, three Newton steps,
// then one Newton correction of x * rsqrt. Within a few ulp of sqrtf for x >= 1e-20
// (test_membership checks it), 0 for 0, NaN for NaN.
GMM_MCL_HD float sqrtVec(float x) {
  const float xs = x + 1e-30f;
  float y = bitsToFloat(0x5f375a86 - (floatToBits(xs) >> 1));
  y = y * (1.5f - 0.5f * xs * y * y);
  y = y * (1.5f - 0.5f * xs * y * y);
  y = y * (1.5f - 0.5f * xs * y * y);
  const float r = x * y;
  return r + 0.5f * y * (x - r * r);
}

// max(x, 0) by the sign bit (+0 for -0; NaN stays NaN, where fmaxf(NaN, 0) gives 0: projectAll
// flags non-finite results for projectComponent).
GMM_MCL_HD float maxZero(float x) {
  const int32_t b = floatToBits(x);
  return bitsToFloat(b & ~(b >> 31));
}

// x limited to [lo, hi], NaN to lo (comparisons, no call: vectorises).
GMM_MCL_HD float clampTo(float x, float lo, float hi) {
  const float a = x > lo ? x : lo;  // false for NaN
  return a < hi ? a : hi;
}

// (int)ceil(x) and (int)floor(x) through rint (ceilf and floorf do not vectorise without
// -fno-trapping-math), the correction in integers: the same values for every float.
GMM_MCL_HD int ceilInt(float x) {
  const float r = rintf(x);
  return static_cast<int>(r) + (r < x ? 1 : 0);
}
GMM_MCL_HD int floorInt(float x) {
  const float r = rintf(x);
  return static_cast<int>(r) - (r > x ? 1 : 0);
}

}  // namespace gmm_mcl
