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

GMM_MCL_HD float bitsToFloat(int32_t bits) {
#if defined(__CUDA_ARCH__)
  return __int_as_float(bits);
#elif defined(__has_builtin)
#if __has_builtin(__builtin_bit_cast)
  return __builtin_bit_cast(float, bits);  // vectorises where memcpy into a local does not
#else
  float f;
  memcpy(&f, &bits, sizeof(f));
  return f;
#endif
#else
  float f;
  memcpy(&f, &bits, sizeof(f));
  return f;
#endif
}

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

}  // namespace gmm_mcl
