// Plain value types that cross the backend boundary (host and device alike).
// Only POD members, float32, fixed layouts: they are copied to the GPU as is.
#pragma once

#include "gmm_mcl/common/host_device.h"

namespace gmm_mcl {

// Pinhole intrinsics of the depth camera (optical frame: x right, y down, z forward).
struct Intrinsics {
  float fx_px = 0.f;
  float fy_px = 0.f;
  float cx_px = 0.f;
  float cy_px = 0.f;
  int width_px = 0;
  int height_px = 0;
};

// Rigid transform T_a_b (maps points in frame b into frame a): p_a = R * p_b + t.
// R is row-major.
struct RigidTransformF {
  float R[9];
  float t[3];
};

GMM_MCL_HD void transformPoint(const RigidTransformF& T, const float p[3], float out[3]) {
  out[0] = T.R[0] * p[0] + T.R[1] * p[1] + T.R[2] * p[2] + T.t[0];
  out[1] = T.R[3] * p[0] + T.R[4] * p[1] + T.R[5] * p[2] + T.t[1];
  out[2] = T.R[6] * p[0] + T.R[7] * p[1] + T.R[8] * p[2] + T.t[2];
}

// Inverse of a rigid transform: T_b_a from T_a_b.
GMM_MCL_HD RigidTransformF invertRigid(const RigidTransformF& T) {
  RigidTransformF inv;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) inv.R[r * 3 + c] = T.R[c * 3 + r];
  }
  for (int r = 0; r < 3; ++r) {
    inv.t[r] = -(inv.R[r * 3 + 0] * T.t[0] + inv.R[r * 3 + 1] * T.t[1] + inv.R[r * 3 + 2] * T.t[2]);
  }
  return inv;
}

// One GMM component in the layout the backends evaluate (world/map frame, metres).
// Symmetric 3x3 matrices are stored as their upper triangle: xx, xy, xz, yy, yz, zz.
struct ComponentF {
  float mean_m[3];
  float cov_m2[6];     // covariance Sigma
  float precision[6];  // Sigma^-1
  float log_norm;      // ln(lambda) - 1.5 ln(2 pi) - 0.5 ln det(Sigma): ln of the peak of lambda*N
  float log_weight;    // ln(lambda) - 1.5 ln(2 pi) (the normaliser without the covariance)
};

// Log of lambda * N(p; mu, Sigma) for a point p in the map frame (nats, density per m^3).
GMM_MCL_HD float componentLogDensity(const ComponentF& c, float px, float py, float pz) {
  const float dx = px - c.mean_m[0];
  const float dy = py - c.mean_m[1];
  const float dz = pz - c.mean_m[2];
  const float* P = c.precision;
  const float q = P[0] * dx * dx + P[3] * dy * dy + P[5] * dz * dz +
                  2.f * (P[1] * dx * dy + P[2] * dx * dz + P[4] * dy * dz);
  return c.log_norm - 0.5f * q;
}

}  // namespace gmm_mcl
