// Projection of a 3D GMM component into the image (paper Eq. proj) and the inflated 3-sigma
// ellipse test of patch membership. Shared by the CPU and CUDA backends.
#pragma once

#include <math.h>

#include "gmm_mcl/common/host_device.h"
#include "gmm_mcl/common/types.h"
#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {

// 2D Gaussian of a projected component plus its inflated membership ellipse in the form
// (c - mean)^T Q (c - mean) <= 1, and the half-extent of that ellipse's bounding box.
struct ProjectedComponent {
  float u_px, v_px;              // pi(T_cam_map mu)
  float cov_uu, cov_uv, cov_vv;  // J R Sigma R^T J^T (px^2)
  float q_uu, q_uv, q_vv;        // quadratic form of the inflated ellipse (1/px^2)
  float half_w_px, half_h_px;    // bounding-box half extent of the inflated ellipse
  float depth_m;                 // z of the mean in the camera frame
};

// A symmetric 3x3 matrix (its upper triangle).
struct SymMat3F {
  float xx, xy, xz, yy, yz, zz;
};

// R S R^T for a row-major rotation R = R_a_b: a covariance S (xx .. zz, its upper triangle) of
// frame b, expressed in frame a. S comes as scalars: membership.cpp's `omp simd` loop calls
// this, and GCC 12 no longer vectorises that loop when S is an array or a struct (it keeps a
// private copy per lane).
GMM_MCL_HD SymMat3F rotateCovariance(const float* R, float xx, float xy, float xz, float yy,
                                     float yz, float zz) {
  float A[9];  // R S
  for (int r = 0; r < 3; ++r) {
    const float r0 = R[r * 3 + 0], r1 = R[r * 3 + 1], r2 = R[r * 3 + 2];
    A[r * 3 + 0] = r0 * xx + r1 * xy + r2 * xz;
    A[r * 3 + 1] = r0 * xy + r1 * yy + r2 * yz;
    A[r * 3 + 2] = r0 * xz + r1 * yz + r2 * zz;
  }
  SymMat3F C;  // A R^T
  C.xx = A[0] * R[0] + A[1] * R[1] + A[2] * R[2];
  C.xy = A[0] * R[3] + A[1] * R[4] + A[2] * R[5];
  C.xz = A[0] * R[6] + A[1] * R[7] + A[2] * R[8];
  C.yy = A[3] * R[3] + A[4] * R[4] + A[5] * R[5];
  C.yz = A[3] * R[6] + A[4] * R[7] + A[5] * R[8];
  C.zz = A[6] * R[6] + A[7] * R[7] + A[8] * R[8];
  return C;
}

// Projects component c (map frame) seen from a camera at T_cam_map. Returns false when the
// mean is behind the camera or nearer than min_depth_m (the component is dropped).
// sigma_bound: ellipse radius in standard deviations (3); inflate_px: added to both semi-axes
// (half the patch diagonal).
GMM_MCL_HD bool projectComponent(const ComponentF& c, const RigidTransformF& T_cam_map,
                                 const Intrinsics& K, float min_depth_m, float sigma_bound,
                                 float inflate_px, ProjectedComponent* out) {
  float m[3];
  transformPoint(T_cam_map, c.mean_m, m);
  if (!(m[2] >= min_depth_m)) return false;
  const float* S = c.cov_m2;  // xx xy xz yy yz zz
  // The camera-frame covariance.
  const SymMat3F C = rotateCovariance(T_cam_map.R, S[0], S[1], S[2], S[3], S[4], S[5]);
  // Pinhole Jacobian at the mean: J = [[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]].
  const float iz = 1.f / m[2];
  const float j00 = K.fx_px * iz, j02 = -K.fx_px * m[0] * iz * iz;
  const float j11 = K.fy_px * iz, j12 = -K.fy_px * m[1] * iz * iz;
  // Sigma2 = J C J^T.
  const float suu = j00 * j00 * C.xx + 2.f * j00 * j02 * C.xz + j02 * j02 * C.zz;
  const float suv = j00 * j11 * C.xy + j00 * j12 * C.xz + j02 * j11 * C.yz + j02 * j12 * C.zz;
  const float svv = j11 * j11 * C.yy + 2.f * j11 * j12 * C.yz + j12 * j12 * C.zz;
  out->u_px = K.cx_px + K.fx_px * m[0] * iz;
  out->v_px = K.cy_px + K.fy_px * m[1] * iz;
  out->cov_uu = suu;
  out->cov_uv = suv;
  out->cov_vv = svv;
  out->depth_m = m[2];
  // Eigen-decomposition of the symmetric 2x2 covariance, without trigonometry: with
  // l1 >= l2 its eigenvalues and e1 the unit eigenvector of l1, the projector e1 e1^T equals
  // (Sigma2 - l2 I) / (l1 - l2), so e1u^2 = (rad + diff) / (2 rad), e1v^2 = (rad - diff) / (2 rad)
  // and e1u e1v = suv / (2 rad) (the same quantities as cos^2, sin^2 and cos sin of half the
  // angle atan2(suv, diff); only rounding differs).
  const float half_tr = 0.5f * (suu + svv);
  const float diff = 0.5f * (suu - svv);
  const float rad = sqrtf(diff * diff + suv * suv);
  const float l1 = fmaxf(half_tr + rad, 0.f);
  const float l2 = fmaxf(half_tr - rad, 0.f);
  float cu2 = 1.f, cv2 = 0.f, cuv = 0.f;  // e1u^2, e1v^2, e1u e1v
  if (rad > 0.f) {
    const float h = 0.5f / rad;
    cu2 = (rad + diff) * h;
    cv2 = (rad - diff) * h;
    cuv = suv * h;
  }
  const float a = sigma_bound * sqrtf(l1) + inflate_px;  // semi-axis along e1
  const float b = sigma_bound * sqrtf(l2) + inflate_px;  // semi-axis along e2 = (-e1v, e1u)
  const float ia2 = 1.f / (a * a), ib2 = 1.f / (b * b);
  out->q_uu = cu2 * ia2 + cv2 * ib2;
  out->q_uv = cuv * (ia2 - ib2);
  out->q_vv = cv2 * ia2 + cu2 * ib2;
  out->half_w_px = sqrtf(a * a * cu2 + b * b * cv2);
  out->half_h_px = sqrtf(a * a * cv2 + b * b * cu2);
  return true;
}

// Conservative test before the full projection, shared by both backends (it never drops a
// component that projectComponent + ellipseContains would find relevant to some patch): the
// inflated ellipse's semi-axes are at most sigma_bound sqrt(l1) + inflate with
// l1 <= ||J||_F^2 lambda_max(Sigma) <= ||J||_F^2 trace(Sigma); false when the square of that
// half-size (plus 1% and 1 px for rounding) around the projected mean holds no patch centre of
// the cols x rows grid, or when the mean is clearly nearer than the near limit.
GMM_MCL_HD bool componentMayTouchGrid(const ComponentF& c, const RigidTransformF& T_cam_map,
                                      const Intrinsics& K, int patch_size_px, int cols, int rows,
                                      float min_depth_m, float sigma_bound, float inflate_px) {
  float m[3];
  transformPoint(T_cam_map, c.mean_m, m);
  if (!(m[2] >= min_depth_m - 1e-4f)) return false;
  const float iz = 1.f / m[2];
  const float iz2 = iz * iz;
  const float jf2 = K.fx_px * K.fx_px * iz2 * (1.f + m[0] * m[0] * iz2) +
                    K.fy_px * K.fy_px * iz2 * (1.f + m[1] * m[1] * iz2);
  const float trace = c.cov_m2[0] + c.cov_m2[3] + c.cov_m2[5];
  const float r = (sigma_bound * sqrtf(jf2 * trace) + inflate_px) * 1.01f + 1.f;
  const float u = K.cx_px + K.fx_px * m[0] * iz;
  const float v = K.cy_px + K.fy_px * m[1] * iz;
  const float ips = 1.f / static_cast<float>(patch_size_px);
  const float c0 = 0.5f * (static_cast<float>(patch_size_px) - 1.f);  // centre of patch 0
  // Patch-centre indices inside [u - r, u + r] x [v - r, v + r], clamped to the grid.
  const float col0 = ceilf((u - r - c0) * ips), col1 = floorf((u + r - c0) * ips);
  const float row0 = ceilf((v - r - c0) * ips), row1 = floorf((v + r - c0) * ips);
  // Each comparison is false for NaN, so a NaN bound culls.
  return col0 <= col1 && col0 <= static_cast<float>(cols - 1) && col1 >= 0.f && row0 <= row1 &&
         row0 <= static_cast<float>(rows - 1) && row1 >= 0.f;
}

// What the view culls (both backends) keep: a component whose sphere of sigma_bound standard
// deviations (the square root of its covariance's trace bounds every one), grown by margin_m,
// meets the camera's view volume: depth up to far_m, and inside the four planes through the
// camera centre and the patch grid's edges grown by the membership's inflation (u0_px..u1_px,
// v0_px..v1_px). Outside it, every used pixel's point lies more than sigma_bound standard
// deviations from the component; the membership's linearised ellipse can still reach the grid
// for a component almost in the camera's plane and metres to its side, and the cull drops it.
struct ViewReach {
  float far_m;     // the range window's far end plus margin_m (infinite: no depth bound)
  float margin_m;  // sigma_bound times the depth noise's sigma at the range's far end
  float u0_px, u1_px, v0_px, v1_px;
  float n_u0, n_u1, n_v0, n_v1;  // the planes' normal lengths
};

// max_range_m infinite: no depth bound and no margin (the side planes still hold).
GMM_MCL_HD ViewReach viewReach(const Intrinsics& K, int patch_size_px, int cols, int rows,
                               float inflate_px, float max_range_m, float sigma_bound,
                               const DepthNoiseModel& noise) {
  ViewReach r;
  const float d = max_range_m - noise.z0_m;
  const float sigma =
      noise.a_m > 0.f || noise.b_per_m > 0.f ? noise.a_m + noise.b_per_m * d * d : 0.f;
  const bool bounded = max_range_m < 3.0e38f;  // finite (a NaN range is refused earlier)
  r.margin_m = bounded ? sigma_bound * sigma : 0.f;
  r.far_m = max_range_m + r.margin_m;
  const float reach = inflate_px * 1.01f + 2.f;  // the cull's slack (componentMayTouchGrid)
  r.u0_px = -reach - K.cx_px;
  r.u1_px = static_cast<float>(cols * patch_size_px) + reach - K.cx_px;
  r.v0_px = -reach - K.cy_px;
  r.v1_px = static_cast<float>(rows * patch_size_px) + reach - K.cy_px;
  r.n_u0 = sqrtf(K.fx_px * K.fx_px + r.u0_px * r.u0_px);
  r.n_u1 = sqrtf(K.fx_px * K.fx_px + r.u1_px * r.u1_px);
  r.n_v0 = sqrtf(K.fy_px * K.fy_px + r.v0_px * r.v0_px);
  r.n_v1 = sqrtf(K.fy_px * K.fy_px + r.v1_px * r.v1_px);
  return r;
}

// The test on a sphere of radius rho (the margin included) about (x, y, z), camera frame.
GMM_MCL_HD bool ballInView(float x, float y, float z, float rho, const Intrinsics& K,
                           const ViewReach& r) {
  // Signed distances (scaled by each normal's length) to the planes fx x = u z, fy y = v z.
  return z - rho <= r.far_m && K.fx_px * x - r.u0_px * z >= -rho * r.n_u0 &&
         r.u1_px * z - K.fx_px * x >= -rho * r.n_u1 && K.fy_px * y - r.v0_px * z >= -rho * r.n_v0 &&
         r.v1_px * z - K.fy_px * y >= -rho * r.n_v1;
}

// The test on a component's mean in the camera frame (x, y, z) and its covariance's trace.
GMM_MCL_HD bool sphereInView(float x, float y, float z, float trace, const Intrinsics& K,
                             const ViewReach& r, float sigma_bound) {
  return ballInView(x, y, z, sigma_bound * sqrtf(trace) + r.margin_m, K, r);
}

GMM_MCL_HD bool componentInView(const ComponentF& c, const RigidTransformF& T_cam_map,
                                const Intrinsics& K, const ViewReach& r, float sigma_bound) {
  float m[3];
  transformPoint(T_cam_map, c.mean_m, m);
  return sphereInView(m[0], m[1], m[2], c.cov_m2[0] + c.cov_m2[3] + c.cov_m2[5], K, r, sigma_bound);
}

// True when pixel point (u, v) lies within or on the inflated ellipse. The quadratic form is
// evaluated in one fixed order (explicit FMAs where they are single instructions, none
// elsewhere), so that the result does not depend on how a compiler contracts it: the CPU
// membership's vectorised tests (membership.cpp) reproduce it bit for bit.
GMM_MCL_HD bool ellipseContains(const ProjectedComponent& p, float u, float v) {
  const float du = u - p.u_px;
  const float dv = v - p.v_px;
  const float cross = 2.f * p.q_uv * du * dv;
#if defined(GMM_MCL_EXPLICIT_FMA)
  const float s = fmaf(dv, p.q_vv * dv, fmaf(du, p.q_uu * du, cross));
#else
  const float s = (du * (p.q_uu * du) + cross) + dv * (p.q_vv * dv);
#endif
  return s <= 1.f;
}

}  // namespace gmm_mcl
