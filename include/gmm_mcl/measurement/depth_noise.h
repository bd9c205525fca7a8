// The depth camera's noise in the measurement model (DESIGN.md "Sensor noise"). A map fitted to
// clean points (a mesh, a LiDAR scan) has components a few millimetres thick, while a consumer
// depth camera measures a surface with centimetres of axial noise at a few metres: without the
// noise, the true pose scores far below the map's own self-likelihood and the likelihood's basin
// is narrow. The model convolves each component with the sensor's axial noise at its range:
//
//   Sigma_i' = Sigma_i + s_i^2 r_i r_i^T,   s_i = sigma(z_i) |m_i| / z_i
//
// with m_i the component's mean in the camera frame, z_i its depth, r_i the unit viewing ray
// through it (map frame) and sigma(z) = a + b (z - z0)^2 the depth noise (Nguyen, Izadi and
// Lovell 2012 for a Kinect v1: a = 1.2 mm, b = 1.9 mm/m^2, z0 = 0.4 m). A depth error of
// sigma(z) moves the back-projected point along its ray by sigma(z) |m| / z.
//
// The ray through the mean projects to a single pixel, so the projected 2D covariance, and with
// it the patch membership, is unchanged: only the evaluation form of each component changes,
// once per particle and component. It is computed here in float32 from the covariance (not the
// precision), by an upper-triangular factor Sigma' = V V^T (Cholesky in reverse variable
// order): the evaluation form's U is sqrt(scale / 2) V^-1, upper triangular as
// makeEvalComponentF's. Shared by the CPU and CUDA backends (same operations, same order).
#pragma once

#include <math.h>

#include "gmm_mcl/common/host_device.h"
#include "gmm_mcl/common/types.h"
#include "gmm_mcl/measurement/eval_component.h"
#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {

GMM_MCL_HD float depthNoiseSigma(const DepthNoiseModel& n, float z_m) {
  const float d = z_m - n.z0_m;
  return n.a_m + n.b_per_m * d * d;
}

// The evaluation form (eval_component.h, `scale` as there) of component c convolved with the
// depth noise seen from the camera at T_cam_map. Returns false when the component's mean is not
// in front of the camera (z <= 0) or the factorisation fails (then *out is untouched); callers
// only ask for components that projected in front of the camera.
GMM_MCL_HD bool makeNoisyEvalComponent(const ComponentF& c, const RigidTransformF& T_cam_map,
                                       const DepthNoiseModel& noise, float scale,
                                       EvalComponentF* out) {
  float m[3];
  transformPoint(T_cam_map, c.mean_m, m);
  if (!(m[2] > 0.f)) return false;
  const float range = sqrtf(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
  const float s = depthNoiseSigma(noise, m[2]) * range / m[2];
  // Viewing ray in the map frame (R^T m / |m|), scaled by s.
  const float* R = T_cam_map.R;
  const float k = s / range;
  const float rx = k * (R[0] * m[0] + R[3] * m[1] + R[6] * m[2]);
  const float ry = k * (R[1] * m[0] + R[4] * m[1] + R[7] * m[2]);
  const float rz = k * (R[2] * m[0] + R[5] * m[1] + R[8] * m[2]);
  const float* S = c.cov_m2;  // xx xy xz yy yz zz
  const float sxx = S[0] + rx * rx, sxy = S[1] + rx * ry, sxz = S[2] + rx * rz;
  const float syy = S[3] + ry * ry, syz = S[4] + ry * rz, szz = S[5] + rz * rz;
  // Sigma' = V V^T, V upper triangular (from the last variable up).
  if (!(szz > 0.f)) return false;
  const float v22 = sqrtf(szz);
  const float v12 = syz / v22, v02 = sxz / v22;
  const float d11 = syy - v12 * v12;
  if (!(d11 > 0.f)) return false;
  const float v11 = sqrtf(d11);
  const float v01 = (sxy - v02 * v12) / v11;
  const float d00 = sxx - v01 * v01 - v02 * v02;
  if (!(d00 > 0.f)) return false;
  const float v00 = sqrtf(d00);
  // W = V^-1 (upper triangular): Sigma'^-1 = W^T W.
  const float w00 = 1.f / v00, w11 = 1.f / v11, w22 = 1.f / v22;
  const float w12 = -v12 * w22 * w11;
  const float w01 = -v01 * w11 * w00;
  const float w02 = -(v01 * w12 + v02 * w22) * w00;
  const float h = sqrtf(0.5f * scale);
  EvalComponentF e;
  e.u00 = h * w00;
  e.u01 = h * w01;
  e.u02 = h * w02;
  e.u11 = h * w11;
  e.u12 = h * w12;
  e.u22 = h * w22;
  const float mx = c.mean_m[0], my = c.mean_m[1], mz = c.mean_m[2];
  e.c[0] = -(e.u00 * mx + e.u01 * my + e.u02 * mz);
  e.c[1] = -(e.u11 * my + e.u12 * mz);
  e.c[2] = -(e.u22 * mz);
  // ln(lambda) - 1.5 ln(2 pi) - 0.5 ln det Sigma', with det Sigma' = (v00 v11 v22)^2.
  e.log_norm = c.log_weight - logf(v00 * v11 * v22);
  e.base = scale * e.log_norm;
  e.pad = 0.f;
  *out = e;
  return true;
}

}  // namespace gmm_mcl
