// A GMM component in the form both likelihood kernels evaluate (CPU and CUDA): the precision's
// Cholesky factor with the mean folded in, so that one evaluation is 9 FMA.
//
//   scale * ln(lambda N(p; mu, Sigma)) = base - |U p + c|^2
//
// with U upper triangular, U^T U = 0.5 * scale * Sigma^-1, c = -U mu and base = scale * log_norm.
// scale = 1 gives nats (CPU), scale = log2(e) gives log2 units (CUDA, for the hardware exp2).
// The factor is computed in double from the packed float precision and rounded once.
#pragma once

#include <math.h>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

// 48 bytes, three 16-byte rows: (c0, c1, c2, base), (u00, u01, u02, u11), (u12, u22, log_norm, 0).
// log_norm stays in nats (the per-patch shift of the log-sum-exp).
struct alignas(16) EvalComponentF {
  float c[3];
  float base;
  float u00, u01, u02, u11;
  float u12, u22;
  float log_norm;  // nats
  float pad;
};

// Log-density constants of log2(e) (CUDA form) and 1 (CPU form).
constexpr float kEvalScaleNats = 1.0f;
constexpr float kEvalScaleLog2 = 1.4426950408889634f;

// Builds the evaluation form of c; scale as above. Host only (double arithmetic).
inline EvalComponentF makeEvalComponentF(const ComponentF& comp, float scale) {
  const double s = 0.5 * static_cast<double>(scale);
  const double p00 = s * comp.precision[0], p01 = s * comp.precision[1];
  const double p02 = s * comp.precision[2], p11 = s * comp.precision[3];
  const double p12 = s * comp.precision[4], p22 = s * comp.precision[5];
  // P = U^T U, U upper triangular (the map loader guarantees a positive-definite covariance;
  // the max() guards keep a rounding-level loss of definiteness from producing NaN).
  const double u00 = sqrt(p00 > 0.0 ? p00 : 0.0);
  const double u01 = u00 > 0.0 ? p01 / u00 : 0.0;
  const double u02 = u00 > 0.0 ? p02 / u00 : 0.0;
  const double d11 = p11 - u01 * u01;
  const double u11 = sqrt(d11 > 0.0 ? d11 : 0.0);
  const double u12 = u11 > 0.0 ? (p12 - u01 * u02) / u11 : 0.0;
  const double d22 = p22 - u02 * u02 - u12 * u12;
  const double u22 = sqrt(d22 > 0.0 ? d22 : 0.0);
  const double mx = comp.mean_m[0], my = comp.mean_m[1], mz = comp.mean_m[2];
  EvalComponentF e;
  e.c[0] = static_cast<float>(-(u00 * mx + u01 * my + u02 * mz));
  e.c[1] = static_cast<float>(-(u11 * my + u12 * mz));
  e.c[2] = static_cast<float>(-(u22 * mz));
  e.base = static_cast<float>(static_cast<double>(scale) * comp.log_norm);
  e.u00 = static_cast<float>(u00);
  e.u01 = static_cast<float>(u01);
  e.u02 = static_cast<float>(u02);
  e.u11 = static_cast<float>(u11);
  e.u12 = static_cast<float>(u12);
  e.u22 = static_cast<float>(u22);
  e.log_norm = comp.log_norm;
  e.pad = 0.f;
  return e;
}

// base - |U p + c|^2 at the map-frame point p (9 FMA; units of the form's scale).
GMM_MCL_HD float evalLogDensity(const EvalComponentF& e, float px, float py, float pz) {
  const float y0 = e.u00 * px + (e.u01 * py + (e.u02 * pz + e.c[0]));
  const float y1 = e.u11 * py + (e.u12 * pz + e.c[1]);
  const float y2 = e.u22 * pz + e.c[2];
  return e.base - y0 * y0 - y1 * y1 - y2 * y2;
}

}  // namespace gmm_mcl
