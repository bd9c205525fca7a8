// Frame log-likelihood of a camera pose (paper Eq. approx_likelihood_3d) with the floor of
// MeasurementParams: per pixel ln(exp(floor) + sum over relevant components of lambda_j N_j).
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/eval_component.h"
#include "gmm_mcl/measurement/membership.h"

namespace gmm_mcl {

struct FrameLikelihood {
  double log_likelihood = 0.0;  // nats, sum over used pixels
  int pixels = 0;               // used pixels
  int floor_hits = 0;           // pixels whose mixture density is below exp(floor)
  long long evaluations = 0;    // Gaussian evaluations performed
};

// Reusable per-thread buffers of the CPU evaluation (no allocation per call once warm).
struct LikelihoodScratch {
  std::vector<ProjectedComponent> projected;
  std::vector<char> valid;
  PatchMembership membership;
  std::vector<float> values;          // unused (kept for source compatibility)
  std::vector<EvalComponentF> eval;   // evaluation form of the components (nats)
  std::vector<EvalComponentF> noisy;  // the same convolved with the depth noise, per pose
};

// The components in the CPU kernel's evaluation form (nats); `out` is resized.
void makeEvalComponents(const std::vector<ComponentF>& components,
                        std::vector<EvalComponentF>* out);

// The evaluation form (nats) of every component that `valid` marks (computeMembership's member
// flags) convolved with the depth noise seen from T_cam_map (depth_noise.h's
// makeNoisyEvalComponent, computed for all components at once in a vectorised loop: as close to
// the convolved density); a marked one whose factorisation fails gets `base`'s form, and the
// entries of unmarked ones are left as they were (no table lists them). `out` is resized.
// Returns the evaluation form the kernel should use: `out` when the noise model is on, else
// `base` (nothing computed). `soa`: componentSoA(components), when the caller keeps it across
// poses (else built here).
const EvalComponentF* noisyEvalComponents(
    const std::vector<ComponentF>& components, const std::vector<EvalComponentF>& base,
    const std::vector<char>& valid, const RigidTransformF& T_cam_map, const DepthNoiseModel& noise,
    std::vector<EvalComponentF>* out, const std::vector<float>* soa = nullptr);

// The CPU kernel. Per patch, the log-sum-exp is shifted by
// S = max(floor, max over the patch's members of log_norm) (>= every member's log-density, so one
// pass suffices): per pixel ln(exp(floor) + sum_j lambda_j N_j) = S + ln(exp(floor - S) +
// sum_j exp(ln(lambda_j N_j) - S)), the same function as the CUDA kernel. float32 evaluation,
// double accumulation over pixels. `eval` from makeEvalComponents (indexed like the components).
FrameLikelihood frameLogLikelihood(const EvalComponentF* eval, const DepthFrame& frame,
                                   const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density);

// Approximate likelihood with the given membership (float32 kernel, double accumulation).
// T_map_cam maps camera points into the map frame. Builds the evaluation form on each call;
// `values` is unused.
FrameLikelihood frameLogLikelihood(const std::vector<ComponentF>& components,
                                   const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                   const PatchMembership& membership, float floor_log_density,
                                   std::vector<float>* values);

// Membership plus approximate likelihood for one pose: what a backend computes per particle (the
// members pruned by the frame's depths, membership.h's MemberDepthPrune).
FrameLikelihood poseLogLikelihood(const std::vector<ComponentF>& components,
                                  const DepthFrame& frame, const RigidTransformF& T_map_cam,
                                  const MeasurementParams& params, LikelihoodScratch* scratch);

// Exact reference: every pixel against every component, in double precision, without the depth
// noise (the paper's model).
FrameLikelihood exactFrameLogLikelihood(const GmmMap& map, const DepthFrame& frame,
                                        const Eigen::Isometry3d& T_map_cam,
                                        float floor_log_density);
// The same with params' floor and depth noise: every component in front of the camera convolved
// with the noise at its range (depth_noise.h), in double precision; per_pixel (optional) gets
// each used pixel's log-likelihood in the frame's point order.
FrameLikelihood exactFrameLogLikelihood(const GmmMap& map, const DepthFrame& frame,
                                        const Eigen::Isometry3d& T_map_cam,
                                        const MeasurementParams& params,
                                        std::vector<double>* per_pixel = nullptr);

}  // namespace gmm_mcl
