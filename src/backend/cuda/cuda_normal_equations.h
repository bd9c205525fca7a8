// The pose refinement's pixel sums on the GPU (NormalEquationsEvaluator of the CUDA backend):
// the points and the membership lists are uploaded once per frame and per linearisation, and
// each evaluation is one kernel and one download of the per-block sums, added on the host in
// block order; a depth scale is folded into the pose the kernel applies. Uses the backend's device
// and stream.
#pragma once

#include <cuda_runtime_api.h>

#include <functional>
#include <vector>

#include "cuda/device_buffer.cuh"
#include "gmm_mcl/measurement/normal_equations.h"

namespace gmm_mcl {
namespace cuda {

// The backend's current device frame: camera-frame points and patch starts on the device.
struct BackendFrameRef {
  const float* x_m = nullptr;
  const float* y_m = nullptr;
  const float* z_m = nullptr;
  const int* patch_begin = nullptr;  // [patches + 1]
  int pixels = 0;
  int patches = 0;
};

class CudaNormalEquations : public NormalEquationsEvaluator {
 public:
  // frame_source: fills the backend's current device frame, false when it has none.
  CudaNormalEquations(int device, cudaStream_t stream,
                      std::function<bool(BackendFrameRef*)> frame_source)
      : device_(device), stream_(stream), frame_source_(std::move(frame_source)) {}

  void setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                 const std::vector<double>& z_m, const std::vector<int>& patch_begin) override;
  bool hasBackendFrame() const override;
  int setPointsFromBackendFrame(const Eigen::Isometry3d& T_base_cam) override;
  void setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                        const PatchMembership& membership) override;
  bool supportsDepthScale() const override { return true; }
  void evaluate(const PoseDerivatives& pose, float floor_log_density, bool linearise,
                NormalEquationSums* out) override;

 private:
  int device_;
  cudaStream_t stream_;
  std::function<bool(BackendFrameRef*)> frame_source_;
  int num_pixels_ = 0;
  // Points in use: this evaluator's base-frame copy, or the backend's camera-frame points with
  // the extrinsics folded into each pose.
  const float* x_ = nullptr;
  const float* y_ = nullptr;
  const float* z_ = nullptr;
  Eigen::Isometry3d T_base_points_ = Eigen::Isometry3d::Identity();
  std::vector<float> host_points_;  // x, then y, then z
  std::vector<int> pixel_patch_;
  DeviceBuffer<float> points_;  // [3][num_pixels_]
  DeviceBuffer<int> pixel_patch_dev_;
  DeviceBuffer<int> member_begin_, members_;
  DeviceBuffer<EvalComponentF> eval_;
  DeviceBuffer<double> partials_;
  PinnedBuffer<double> h_partials_;
  bool have_linearisation_ = false;
  int linearisation_patches_ = -1;  // the patch count of its membership
};

}  // namespace cuda
}  // namespace gmm_mcl
