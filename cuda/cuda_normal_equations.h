// The pose refinement's pixel sums on the GPU (NormalEquationsEvaluator of the CUDA backend):
// the points and the membership lists are uploaded once per frame and per linearisation, and
// each evaluation is one kernel and one download of the per-block sums, added on the host in
// block order. Uses the backend's device and stream.
#pragma once

#include <cuda_runtime_api.h>

#include <vector>

#include "cuda/device_buffer.cuh"
#include "gmm_mcl/measurement/normal_equations.h"

namespace gmm_mcl {
namespace cuda {

class CudaNormalEquations : public NormalEquationsEvaluator {
 public:
  CudaNormalEquations(int device, cudaStream_t stream) : device_(device), stream_(stream) {}

  void setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                 const std::vector<double>& z_m, const std::vector<int>& patch_begin) override;
  void setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                        const PatchMembership& membership) override;
  void evaluate(const PoseDerivatives& pose, float floor_log_density, bool linearise,
                NormalEquationSums* out) override;

 private:
  int device_;
  cudaStream_t stream_;
  int num_pixels_ = 0;
  std::vector<float> host_points_;  // x, then y, then z
  std::vector<int> pixel_patch_;
  DeviceBuffer<float> points_;      // [3][num_pixels_]
  DeviceBuffer<int> pixel_patch_dev_;
  DeviceBuffer<int> member_begin_, members_;
  DeviceBuffer<EvalComponentF> eval_;
  DeviceBuffer<double> partials_;
  PinnedBuffer<double> h_partials_;
  bool have_linearisation_ = false;
};

}  // namespace cuda
}  // namespace gmm_mcl
