#include "cuda/cuda_normal_equations.h"

#include <Eigen/Core>
#include <stdexcept>

#include "cuda/normal_equations_kernel.cuh"

namespace gmm_mcl {
namespace cuda {

void CudaNormalEquations::setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                                    const std::vector<double>& z_m,
                                    const std::vector<int>& patch_begin) {
  GMM_MCL_CUDA_CHECK(cudaSetDevice(device_));
  const int n = static_cast<int>(x_m.size());
  if (y_m.size() != x_m.size() || z_m.size() != x_m.size() || patch_begin.empty() ||
      patch_begin.back() != n) {
    throw std::invalid_argument("normal equations: points and patch ranges disagree");
  }
  num_pixels_ = n;
  // The linearisation holds while the patches stay (new depths along the same rays, as the
  // depth scale's noise correction sets them).
  if (static_cast<int>(patch_begin.size()) - 1 != linearisation_patches_) {
    have_linearisation_ = false;
  }
  if (n == 0) return;
  host_points_.resize(3 * static_cast<size_t>(n));
  pixel_patch_.resize(n);
  for (int i = 0; i < n; ++i) {
    host_points_[i] = static_cast<float>(x_m[i]);
    host_points_[n + i] = static_cast<float>(y_m[i]);
    host_points_[2 * n + i] = static_cast<float>(z_m[i]);
  }
  for (size_t p = 0; p + 1 < patch_begin.size(); ++p) {
    for (int i = patch_begin[p]; i < patch_begin[p + 1]; ++i) pixel_patch_[i] = static_cast<int>(p);
  }
  points_.reserve(host_points_.size());
  pixel_patch_dev_.reserve(n);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(points_.data(), host_points_.data(),
                                     host_points_.size() * sizeof(float), cudaMemcpyHostToDevice,
                                     stream_));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(pixel_patch_dev_.data(), pixel_patch_.data(), n * sizeof(int),
                                     cudaMemcpyHostToDevice, stream_));
  // The host vectors are read by the copies until the stream passes them.
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream_));
  x_ = points_.data();
  y_ = x_ + n;
  z_ = x_ + 2 * n;
  T_base_points_ = Eigen::Isometry3d::Identity();
}

bool CudaNormalEquations::hasBackendFrame() const {
  BackendFrameRef ref;
  return frame_source_ && frame_source_(&ref);
}

int CudaNormalEquations::setPointsFromBackendFrame(const Eigen::Isometry3d& T_base_cam) {
  BackendFrameRef ref;
  if (!frame_source_ || !frame_source_(&ref)) {
    throw std::logic_error("normal equations: the backend holds no device frame");
  }
  GMM_MCL_CUDA_CHECK(cudaSetDevice(device_));
  num_pixels_ = ref.pixels;
  if (ref.patches != linearisation_patches_) have_linearisation_ = false;
  x_ = ref.x_m;
  y_ = ref.y_m;
  z_ = ref.z_m;
  T_base_points_ = T_base_cam;
  if (num_pixels_ > 0) {
    pixel_patch_dev_.reserve(num_pixels_);
    GMM_MCL_CUDA_CHECK(
        launchFillPixelPatch(ref.patches, ref.patch_begin, pixel_patch_dev_.data(), stream_));
  }
  return num_pixels_;
}

void CudaNormalEquations::setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                                           const PatchMembership& membership) {
  GMM_MCL_CUDA_CHECK(cudaSetDevice(device_));
  if (membership.begin.empty()) throw std::invalid_argument("normal equations: no membership");
  eval_.reserve(eval_nats.size() > 0 ? eval_nats.size() : 1);
  member_begin_.reserve(membership.begin.size());
  members_.reserve(membership.comps.size() > 0 ? membership.comps.size() : 1);
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(eval_.data(), eval_nats.data(),
                                     eval_nats.size() * sizeof(EvalComponentF),
                                     cudaMemcpyHostToDevice, stream_));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(member_begin_.data(), membership.begin.data(),
                                     membership.begin.size() * sizeof(int), cudaMemcpyHostToDevice,
                                     stream_));
  if (!membership.comps.empty()) {
    GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(members_.data(), membership.comps.data(),
                                       membership.comps.size() * sizeof(int),
                                       cudaMemcpyHostToDevice, stream_));
  }
  // The caller may change its vectors after this returns.
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream_));
  have_linearisation_ = true;
  linearisation_patches_ = static_cast<int>(membership.begin.size()) - 1;
}

void CudaNormalEquations::evaluate(const PoseDerivatives& pose, float floor_log_density,
                                   bool linearise, NormalEquationSums* out) {
  *out = NormalEquationSums();
  if (num_pixels_ == 0) return;
  if (!have_linearisation_) {
    throw std::logic_error("normal equations: evaluate() before setLinearisation()");
  }
  GMM_MCL_CUDA_CHECK(cudaSetDevice(device_));
  // The pose applied to the points in use p, whose base-frame point is A p + b (A = R_bp, b =
  // t_bp), with the depth scale f about the camera centre o: s = o + f (A p + b - o) = f A p + c,
  // c = o + f (b - o); q = R s + t, dq_a = dR_a s, dq/df = R (A p + b - o).
  const Eigen::Matrix3d Rbp = T_base_points_.linear();
  const Eigen::Vector3d tbp = T_base_points_.translation();
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(pose.R);
  const Eigen::Vector3d o(pose.scale_origin[0], pose.scale_origin[1], pose.scale_origin[2]);
  const double f = pose.scale;
  const Eigen::Matrix3d A = f * Rbp;
  const Eigen::Vector3d c = o + f * (tbp - o);
  const Eigen::Matrix3d Rc = R * A;
  const Eigen::Vector3d tc = R * c + Eigen::Vector3d(pose.t[0], pose.t[1], pose.t[2]);
  const Eigen::Matrix3d Rs = R * Rbp;
  const Eigen::Vector3d ts = R * (tbp - o);
  NormalEquationPose p;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) {
      p.R[3 * r + k] = static_cast<float>(Rc(r, k));
      p.Rs[3 * r + k] = static_cast<float>(Rs(r, k));
    }
    p.t[r] = static_cast<float>(tc[r]);
    p.ts[r] = static_cast<float>(ts[r]);
  }
  for (int a = 0; a < 3; ++a) {
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> dR(pose.dR[a]);
    const Eigen::Matrix3d dRc = dR * A;
    const Eigen::Vector3d dtc = dR * c;
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) p.dR[a][3 * r + k] = static_cast<float>(dRc(r, k));
      p.dt[a][r] = static_cast<float>(dtc[r]);
    }
  }
  const int blocks = normalEquationBlocks(num_pixels_);
  const size_t values = static_cast<size_t>(blocks) * kNormalEquationValues;
  partials_.reserve(values);
  h_partials_.reserve(values);
  GMM_MCL_CUDA_CHECK(launchNormalEquations(
      num_pixels_, p, floor_log_density, linearise ? 1 : 0,
      linearise && pose.estimate_scale ? 1 : 0, x_, y_, z_, pixel_patch_dev_.data(),
      member_begin_.data(), members_.data(), eval_.data(), partials_.data(), stream_));
  GMM_MCL_CUDA_CHECK(cudaMemcpyAsync(h_partials_.data(), partials_.data(), values * sizeof(double),
                                     cudaMemcpyDeviceToHost, stream_));
  GMM_MCL_CUDA_CHECK(cudaStreamSynchronize(stream_));
  for (int b = 0; b < blocks; ++b) {
    const double* v = h_partials_.data() + static_cast<size_t>(b) * kNormalEquationValues;
    out->loglik += v[0];
    for (int k = 0; k < 21; ++k) out->h[k] += v[1 + k];
    for (int k = 0; k < 6; ++k) out->g[k] += v[22 + k];
    for (int k = 0; k < 7; ++k) out->hs[k] += v[28 + k];
    out->gs += v[35];
  }
}

}  // namespace cuda
}  // namespace gmm_mcl
