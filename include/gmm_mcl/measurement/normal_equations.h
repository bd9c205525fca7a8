// The frame's log-likelihood at a 6-DoF pose and the Gauss-Newton normal equations of its EM
// objective, summed over the pixels: the inner loop of the pose refinement
// (gmm_mcl/filter/pose_refinement.h), behind one interface so that a backend can run it where
// its frames live (the host, or the GPU of the CUDA backend).
//
// At a pose with rotation R and translation t, pixel i (base-frame point p_i) maps to
// q_i = R p_i + t. For each member j of the pixel's patch, with the evaluation form (nats)
// y_ij = U_j q_i + c_j and t_ij = log_norm_j - |y_ij|^2, the pixel's log-likelihood is
// ln(exp(floor) + sum_j exp(t_ij)); the responsibility gamma_ij = exp(t_ij) / (that sum); and
// H += gamma_ij J_ij^T J_ij, g += gamma_ij J_ij^T y_ij with J_ij = U_j [I | dq/droll | dq/dpitch |
// dq/dyaw] over (x, y, z, roll, pitch, yaw). Pairs with gamma below kMinResponsibility are left
// out of H and g.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "gmm_mcl/measurement/eval_component.h"
#include "gmm_mcl/measurement/membership.h"

namespace gmm_mcl {

// Responsibility below which a (pixel, component) pair is left out of the normal equations.
constexpr double kMinResponsibility = 1e-6;

// The sums at one pose: the log-likelihood (nats), the upper triangle of H row by row
// (H00, H01, ..., H05, H11, ..., H55) and g; with a depth scale estimated (PoseDerivatives::
// estimate_scale), H's seventh column (H0s, ..., H5s, Hss) in hs and g's seventh entry in gs.
struct NormalEquationSums {
  double loglik = 0.0;
  double h[21] = {0};
  double g[6] = {0};
  double hs[7] = {0};
  double gs = 0.0;
};

// A pose as the evaluators take it: R row-major, t, and dR/droll, dR/dpitch, dR/dyaw row-major
// (R = Rz(yaw) Ry(pitch) Rx(roll)). A depth scale f moves each base-frame point p along its ray
// from the camera centre o to o + f (p - o) before the pose applies (q = R (o + f (p - o)) + t);
// evaluators whose supportsDepthScale() is false take f = 1.
struct PoseDerivatives {
  double R[9];
  double t[3];
  double dR[3][9];
  double scale = 1.0;
  double scale_origin[3] = {0.0, 0.0, 0.0};
  bool estimate_scale = false;  // fill hs and gs (dq/df = R (p - o))
};

class NormalEquationsEvaluator {
 public:
  virtual ~NormalEquationsEvaluator() = default;
  // The frame: its points in the base frame (x, y, z, each n long) and patch ranges
  // (patch_begin: patches + 1 entries). Called once per frame.
  virtual void setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                         const std::vector<double>& z_m, const std::vector<int>& patch_begin) = 0;
  // Whether the backend holds the current frame on its device (the frame its last likelihood
  // evaluation used), so that setPointsFromBackendFrame() can replace setPoints().
  virtual bool hasBackendFrame() const { return false; }
  // Whether evaluate() applies PoseDerivatives::scale and fills hs and gs.
  virtual bool supportsDepthScale() const { return false; }
  // That frame's camera points, moved into the base frame by T_base_cam, without a host copy.
  // Returns its pixel count; throws std::logic_error when hasBackendFrame() is false.
  virtual int setPointsFromBackendFrame(const Eigen::Isometry3d& T_base_cam);
  // The linearisation: evaluation forms in nats (indexed like the map's components) and the
  // patch membership. Called whenever either changes.
  virtual void setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                                const PatchMembership& membership) = 0;
  // The sums at a pose; with linearise false only loglik is filled.
  virtual void evaluate(const PoseDerivatives& pose, float floor_log_density, bool linearise,
                        NormalEquationSums* out) = 0;
};

// The host implementation (OpenMP over patches in fixed chunks, double arithmetic; the result
// does not depend on the thread count).
class HostNormalEquations : public NormalEquationsEvaluator {
 public:
  void setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                 const std::vector<double>& z_m, const std::vector<int>& patch_begin) override;
  void setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                        const PatchMembership& membership) override;
  bool supportsDepthScale() const override { return true; }
  void evaluate(const PoseDerivatives& pose, float floor_log_density, bool linearise,
                NormalEquationSums* out) override;

 private:
  std::vector<double> px_, py_, pz_;
  std::vector<int> patch_begin_;
  std::vector<EvalComponentF> eval_;
  PatchMembership membership_;
  std::vector<double> partial_;  // per chunk: loglik, h[21], g[6]
};

}  // namespace gmm_mcl
