// The likelihood stage behind one interface: project every component for every particle,
// patch membership, per-pixel log-sum over relevant components, per-particle reduction.
// CPU (OpenMP, the reference) and CUDA implement it; the core never knows which one runs.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/backend/backend_params.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/measurement_params.h"
#include "gmm_mcl/measurement/membership.h"
#include "gmm_mcl/measurement/normal_equations.h"

namespace gmm_mcl {

// A backend failure (device error, out of memory); the localizer turns it into a step status.
class BackendError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct BackendOutput {
  std::vector<double> log_likelihood;  // per particle, nats
  std::vector<int> floor_hits;         // per particle
  long long evaluations = 0;           // Gaussian evaluations, all particles
  long long relevant_pairs = 0;        // sum over particles and patches with pixels of |members|
  long long patches_with_pixels = 0;   // per particle
  double projection_membership_ms = 0.0;
  double likelihood_ms = 0.0;
  int visible_components = -1;  // after the per-update view cull (-1: not culled)
};

// The device a backend runs on (the benchmark's columns).
struct BackendDeviceInfo {
  std::string name;
  int device = 0;
  int compute_capability = 0;  // major * 10 + minor
  int multiprocessors = 0;
  int fp32_lanes_per_sm = 0;      // FP32 cores per multiprocessor (by compute capability)
  double clock_ghz = 0.0;         // peak SM clock
  double fp32_peak_gflops = 0.0;  // 2 (FMA) x lanes x SMs x clock
  size_t shared_per_block_bytes = 0;
  size_t total_memory_bytes = 0;
  // Floating-point operations the likelihood kernel executes per Gaussian evaluation, counted
  // from its instructions (the CUDA backend's: 19, src/backend/cuda/cuda_backend.h): with
  // fp32_peak_gflops, the kernel's fraction of the FP32 peak (a lower bound).
  double flops_per_evaluation = 0.0;
};

// What a backend on a device offers beyond LikelihoodBackend (LikelihoodBackend::device()):
// its device, the update from a raw image prepared on the device, and the last update's
// transfer and preparation times.
class DeviceBackend {
 public:
  virtual ~DeviceBackend() = default;
  virtual const BackendDeviceInfo& deviceInfo() const = 0;
  // evaluate() with the frame prepared on the device from the raw image (prepareFrame's points,
  // in its order and with its arithmetic). Throws std::invalid_argument for what prepareFrame
  // rejects.
  virtual void evaluateImage(const DepthImage& image, const Intrinsics& K,
                             const FrameParams& frame_params,
                             const std::vector<RigidTransformF>& T_map_cam,
                             const MeasurementParams& params, BackendOutput* out) = 0;
  // Of the last evaluate()/evaluateImage(): upload + download time (ms), the frame's preparation
  // on the device (ms, 0 for evaluate()), the pixels used.
  virtual double lastTransferMs() const = 0;
  virtual double lastFramePrepMs() const = 0;
  virtual int lastFramePixels() const = 0;
};

class LikelihoodBackend {
 public:
  virtual ~LikelihoodBackend() = default;
  virtual std::string name() const = 0;
  // Takes (or uploads) the map's packed components; called once per map.
  virtual void setMap(const GmmMap& map) = 0;
  // Per-particle log-likelihood of `frame` for camera poses T_map_cam (one per particle).
  virtual void evaluate(const DepthFrame& frame, const std::vector<RigidTransformF>& T_map_cam,
                        const MeasurementParams& params, BackendOutput* out) = 0;
  // Membership table of one pose (debug image, parity tests).
  virtual void membership(const DepthFrame& frame, const RigidTransformF& T_map_cam,
                          const MeasurementParams& params, PatchMembership* out) = 0;
  // Where the pose refinement's pixel sums run with this backend (owned by it); nullptr: on the
  // host (HostNormalEquations).
  virtual NormalEquationsEvaluator* normalEquations() { return nullptr; }
  // Another evaluator of the backend's for points set from the host (setPoints): a camera
  // rig's other cameras, refined beside the first (owned by the caller, used while the backend
  // lives); nullptr: on the host.
  virtual std::unique_ptr<NormalEquationsEvaluator> makeNormalEquations() { return nullptr; }
  // The backend's device side (the CUDA backend); nullptr: a host backend.
  virtual DeviceBackend* device() { return nullptr; }
};

// "cpu" or "cuda", built with `options` (the CPU backend's threads, the CUDA backend's tuning).
// When CUDA is asked for but not built or no device is usable, returns the CPU backend and sets
// *warning to say why. Throws std::invalid_argument for an unknown name.
std::unique_ptr<LikelihoodBackend> makeBackend(const std::string& name, std::string* warning,
                                               const BackendOptions& options = BackendOptions());
bool cudaBackendCompiled();

}  // namespace gmm_mcl
