// CUDA likelihood backend: the CPU backend's computation on the GPU (DESIGN.md "Backends").
// Private to the core (and its CUDA tests): a user makes it with makeBackend("cuda") and reaches
// its device side through LikelihoodBackend::device().
// Two kernels per batch of particles: projection + patch membership (one block per particle,
// a bitmask per patch built in shared memory) and the per-pixel log-sum over the relevant
// components with the per-particle reduction (one warp per patch). The depth frame is uploaded
// once per update through pinned memory on the backend's stream. No CUDA header is needed to
// include this file: the device state lives behind a pointer.
#pragma once

#include <memory>
#include <string>

#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

// Floating-point operations the likelihood kernel executes per Gaussian evaluation, counted
// from its instructions (an FMA counts 2): |U p + c|^2 subtracted from the base in the
// Cholesky form of gmm_mcl/measurement/eval_component.h is 9 FMA (U p + c: 6, the three
// squares: 3) and the accumulation 1 addition: 19 FLOP in 10 FP32-pipe instructions. The exp2
// runs on the special-function unit and counts 0; per-pixel and per-member work (pose
// transform, log, loads, member lists) counts 0 too. So the "% of FP32 peak" is a lower bound
// on the FP32 pipe's occupancy by the evaluations themselves, not a count of all issued work.
constexpr double kCudaFlopsPerEvaluation = 19.0;

class CudaBackend : public LikelihoodBackend, public DeviceBackend {
 public:
  // Throws BackendError when the device cannot be used.
  explicit CudaBackend(int device = 0, const CudaTuningParams& tuning = CudaTuningParams());
  ~CudaBackend() override;
  CudaBackend(const CudaBackend&) = delete;
  CudaBackend& operator=(const CudaBackend&) = delete;

  std::string name() const override { return "cuda"; }
  void setMap(const GmmMap& map) override;
  void evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                const MeasurementParams& params, BackendOutput* out) override;
  void membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                  const MeasurementParams& params, PatchMembership* out) override;
  // The pose refinement's pixel sums on this backend's device and stream.
  NormalEquationsEvaluator* normalEquations() override;
  std::unique_ptr<NormalEquationsEvaluator> makeNormalEquations() override;
  DeviceBackend* device() override { return this; }

  // evaluate() with the frame prepared on the GPU from the raw image: uploads the image (not
  // the points) and builds prepareFrame's points, in its order and with its arithmetic.
  // Throws std::invalid_argument for what prepareFrame rejects.
  void evaluateImage(const DepthImage& image, const Intrinsics& K, const FrameParams& frame_params,
                     const std::vector<RigidTransformF>& T_map_cam, const MeasurementParams& params,
                     BackendOutput* out) override;

  // The frame kept on the device for evaluateDevicePoses() (the device particle filter): the
  // raw image uploaded (only the rows on the stride grid) and prepared on the GPU as
  // evaluateImage() does, or a host frame's points uploaded. Synchronises once, for the pixel
  // count. Throws std::invalid_argument for what prepareFrame rejects.
  struct DeviceFrameInfo {
    int pixels = 0;
    long long patches_with_pixels = 0;
  };
  DeviceFrameInfo prepareDeviceFrame(const DepthImage& image, const Intrinsics& K,
                                     const FrameParams& frame_params);
  DeviceFrameInfo uploadDeviceFrame(const DepthFrame& frame);
  bool hasDeviceFrame() const;
  // Per-particle log-likelihoods of n camera poses already on the device (T_map_cam and its
  // inverse, [n] each) on the device frame, written to device arrays [n]. Queued on the
  // backend's stream; nothing is synchronised. After the stream has been synchronised,
  // deviceStageMs() gives the stage times of the last call (events).
  void evaluateDevicePoses(int n, const RigidTransformF* T_map_cam,
                           const RigidTransformF* T_cam_map, const MeasurementParams& params,
                           double* log_likelihood, int* floor_hits, long long* evaluations,
                           long long* relevant_pairs);
  void deviceStageMs(double* projection_membership_ms, double* likelihood_ms) const;
  // The device this backend (and everything using its stream) runs on, and its stream (a
  // cudaStream_t), for work that must be ordered with its evaluations (the device filter).
  int deviceOrdinal() const;
  void* streamHandle() const;

  const BackendDeviceInfo& deviceInfo() const override;
  // Of the last evaluate()/evaluateImage(): upload + download time (ms, events), GPU frame
  // preparation time (ms, 0 for evaluate()), used pixels.
  double lastTransferMs() const override;
  double lastFramePrepMs() const override;
  int lastFramePixels() const override;
  const CudaTuningParams& tuning() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Number of usable CUDA devices (0 when none or no driver); *why says why when 0.
int cudaDeviceCount(std::string* why);

}  // namespace gmm_mcl
