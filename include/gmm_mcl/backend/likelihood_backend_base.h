// The likelihood stage behind one interface: project every component for every particle,
// patch membership, per-pixel log-sum over relevant components, per-particle reduction.
// CPU (OpenMP, the reference) and CUDA implement it; the core never knows which one runs.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
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
};

// "cpu" or "cuda". When CUDA is asked for but not built or no device is usable, returns the CPU
// backend and sets *warning to say why. Throws std::invalid_argument for an unknown name.
std::unique_ptr<LikelihoodBackend> makeBackend(const std::string& name, std::string* warning);
bool cudaBackendCompiled();

}  // namespace gmm_mcl
