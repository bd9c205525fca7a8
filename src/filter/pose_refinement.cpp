#include "gmm_mcl/filter/pose_refinement.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include <Eigen/Cholesky>

#include "gmm_mcl/measurement/likelihood.h"

namespace gmm_mcl {
namespace {

// Responsibility below which a (pixel, component) pair is left out of the normal equations.
constexpr double kMinResponsibility = 1e-6;
// Steps after which the membership and the noise-convolved forms are recomputed.
constexpr double kRelineariseM = 0.01;
constexpr double kRelineariseRad = 0.01;

// The frame's log-likelihood at a pose and the Gauss-Newton normal equations of the EM objective sum_ij gamma_ij |y_ij|^2 (y = U q + c, the component's
// whitened residual scaled by 1/sqrt(2)) in (x, y, z, yaw).
struct Linearisation {
  double loglik = 0.0;
  Eigen::Matrix4d H = Eigen::Matrix4d::Zero();
  Eigen::Vector4d g = Eigen::Vector4d::Zero();
};

class Objective {
 public:
  Objective(const std::vector<ComponentF>& components, const DepthFrame& frame, double roll_rad,
            double pitch_rad, const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params)
      : components_(components), frame_(frame), roll_(roll_rad), pitch_(pitch_rad),
        T_base_cam_(T_base_cam), params_(params) {
    makeEvalComponents(components_, &base_eval_);
    // Gravity-aligned, yaw-free points: v = R(roll, pitch) (T_base_cam p_cam); the map point of
    // pose (x, y, z, yaw) is Rz(yaw) v + t.
    const Eigen::Isometry3d T_rp_cam =
        Eigen::Isometry3d(rotationFromRpy(roll_rad, pitch_rad, 0.0)) * T_base_cam;
    v_.resize(frame.size());
    for (size_t i = 0; i < frame.size(); ++i) {
      v_[i] = T_rp_cam * Eigen::Vector3d(frame.x_m[i], frame.y_m[i], frame.z_m[i]);
    }
  }

  // Membership and evaluation forms (with the depth noise) at `pose`; kept for the iterations
  // that follow, whose steps are small beside the membership's 3-sigma-plus-half-patch margin
  // (the objective stays one function while it is maximised).
  void linearisePatches(const Particle& pose) {
    const Eigen::Isometry3d T_map_cam = particleToPose(pose, roll_, pitch_) * T_base_cam_;
    const RigidTransformF T_cam_map = toRigidF(T_map_cam.inverse());
    computeMembership(components_, T_cam_map, frame_.intrinsics, frame_.grid, params_,
                      &projected_, &valid_, &membership_);
    eval_ = noisyEvalComponents(components_, base_eval_, valid_, T_cam_map, params_.depth_noise,
                                &noisy_);
  }

  Linearisation evaluate(const Particle& pose, bool linearise) {
    const EvalComponentF* eval = eval_;
    const double c = std::cos(pose.yaw_rad), s = std::sin(pose.yaw_rad);
    const double floor = params_.floor_log_density;
    Linearisation out;
    // Normal equations accumulated by hand: J = U [I | d], d = dq/dyaw = (dqx, dqy, 0), U upper
    // triangular, so J^T J = [U^T U, U^T U d; d^T U^T U, d^T U^T U d] and J^T y = [U^T y; d.U^T y].
    double h[10] = {0};  // upper triangle of H: 00 01 02 03 11 12 13 22 23 33
    double g[4] = {0};
    for (int p = 0; p < frame_.grid.count(); ++p) {
      const int b = frame_.patch_begin[p], e = frame_.patch_begin[p + 1];
      if (b == e) continue;
      const int k = membership_.countFor(p);
      if (k == 0) {
        out.loglik += floor * (e - b);
        continue;
      }
      const int* members = membership_.comps.data() + membership_.begin[p];
      t_.resize(k);
      y_.resize(3 * k);
      for (int i = b; i < e; ++i) {
        const Eigen::Vector3d& v = v_[i];
        const double qx = c * v.x() - s * v.y() + pose.x_m;
        const double qy = s * v.x() + c * v.y() + pose.y_m;
        const double qz = v.z() + pose.z_m;
        double mx = floor;
        for (int j = 0; j < k; ++j) {
          const EvalComponentF& ev = eval[members[j]];
          const double y0 = ev.u00 * qx + ev.u01 * qy + ev.u02 * qz + ev.c[0];
          const double y1 = ev.u11 * qy + ev.u12 * qz + ev.c[1];
          const double y2 = ev.u22 * qz + ev.c[2];
          y_[3 * j] = y0;
          y_[3 * j + 1] = y1;
          y_[3 * j + 2] = y2;
          t_[j] = ev.log_norm - (y0 * y0 + y1 * y1 + y2 * y2);
          mx = std::max(mx, t_[j]);
        }
        double sum = std::exp(floor - mx);
        for (int j = 0; j < k; ++j) {
          t_[j] = std::exp(t_[j] - mx);
          sum += t_[j];
        }
        out.loglik += mx + std::log(sum);
        if (!linearise) continue;
        const double dqx = -(s * v.x() + c * v.y()), dqy = c * v.x() - s * v.y();
        const double inv_sum = 1.0 / sum;
        for (int j = 0; j < k; ++j) {
          const double gamma = t_[j] * inv_sum;
          if (gamma < kMinResponsibility) continue;
          const EvalComponentF& ev = eval[members[j]];
          // Columns of J: a = U e_x, b = U e_y, c3 = U e_z, d = U (dqx, dqy, 0).
          const double a0 = ev.u00;
          const double b0 = ev.u01, b1 = ev.u11;
          const double c0 = ev.u02, c1 = ev.u12, c2 = ev.u22;
          const double d0 = ev.u00 * dqx + ev.u01 * dqy, d1 = ev.u11 * dqy;
          const double y0 = y_[3 * j], y1 = y_[3 * j + 1], y2 = y_[3 * j + 2];
          h[0] += gamma * a0 * a0;
          h[1] += gamma * a0 * b0;
          h[2] += gamma * a0 * c0;
          h[3] += gamma * a0 * d0;
          h[4] += gamma * (b0 * b0 + b1 * b1);
          h[5] += gamma * (b0 * c0 + b1 * c1);
          h[6] += gamma * (b0 * d0 + b1 * d1);
          h[7] += gamma * (c0 * c0 + c1 * c1 + c2 * c2);
          h[8] += gamma * (c0 * d0 + c1 * d1);
          h[9] += gamma * (d0 * d0 + d1 * d1);
          g[0] += gamma * a0 * y0;
          g[1] += gamma * (b0 * y0 + b1 * y1);
          g[2] += gamma * (c0 * y0 + c1 * y1 + c2 * y2);
          g[3] += gamma * (d0 * y0 + d1 * y1);
        }
      }
    }
    out.H << h[0], h[1], h[2], h[3], h[1], h[4], h[5], h[6], h[2], h[5], h[7], h[8], h[3], h[6],
        h[8], h[9];
    out.g << g[0], g[1], g[2], g[3];
    return out;
  }

 private:
  const std::vector<ComponentF>& components_;
  const DepthFrame& frame_;
  double roll_, pitch_;
  Eigen::Isometry3d T_base_cam_;
  MeasurementParams params_;
  std::vector<EvalComponentF> base_eval_, noisy_;
  const EvalComponentF* eval_ = nullptr;
  std::vector<Eigen::Vector3d> v_;
  std::vector<double> t_, y_;
  std::vector<ProjectedComponent> projected_;
  std::vector<char> valid_;
  PatchMembership membership_;
};

}  // namespace

std::string RefinementParams::validate() const {
  std::ostringstream err;
  if (max_iterations < 1) err << "refinement max_iterations must be >= 1; ";
  if (!(max_position_sigma_m > 0.0)) err << "refinement max_position_sigma_m must be positive; ";
  if (!(max_yaw_sigma_rad > 0.0)) err << "refinement max_yaw_sigma_rad must be positive; ";
  if (!(max_correction_m > 0.0)) err << "refinement max_correction_m must be positive; ";
  if (!(max_correction_rad > 0.0)) err << "refinement max_correction_rad must be positive; ";
  if (!(tolerance_m > 0.0)) err << "refinement tolerance_m must be positive; ";
  if (!(tolerance_rad > 0.0)) err << "refinement tolerance_rad must be positive; ";
  return err.str();
}

RefinementResult refinePose(const std::vector<ComponentF>& components, const DepthFrame& frame,
                            const Particle& start, double roll_rad, double pitch_rad,
                            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params,
                            const RefinementParams& refinement) {
  const auto t0 = std::chrono::steady_clock::now();
  RefinementResult r;
  r.pose = start;
  if (frame.empty()) {
    r.why = "no pixels";
    return r;
  }
  Objective objective(components, frame, roll_rad, pitch_rad, T_base_cam, params);
  const double px = static_cast<double>(frame.size());
  Particle pose = start;
  objective.linearisePatches(start);
  Linearisation cur = objective.evaluate(pose, true);
  r.loglik_start = cur.loglik / px;
  double lambda = 1e-3;  // Levenberg-Marquardt damping, relative to the diagonal
  for (int it = 0; it < refinement.max_iterations; ++it) {
    ++r.iterations;
    Eigen::Matrix4d A = cur.H;
    for (int d = 0; d < 4; ++d) A(d, d) += lambda * std::max(cur.H(d, d), 1e-9);
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(A);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::Vector4d delta = -ldlt.solve(cur.g);
    if (!delta.allFinite()) break;
    Particle next = pose;
    next.x_m += delta[0];
    next.y_m += delta[1];
    next.z_m += delta[2];
    next.yaw_rad = wrapAngle(next.yaw_rad + delta[3]);
    Linearisation cand = objective.evaluate(next, true);
    if (cand.loglik > cur.loglik) {
      // A step of more than a centimetre or degree: membership and noise at the new pose.
      if (delta.head<3>().norm() > kRelineariseM || std::abs(delta[3]) > kRelineariseRad) {
        objective.linearisePatches(next);
        cand = objective.evaluate(next, true);
      }
      pose = next;
      cur = cand;
      r.refined = true;
      lambda = std::max(1e-6, 0.3 * lambda);
      if (delta.head<3>().norm() < refinement.tolerance_m &&
          std::abs(delta[3]) < refinement.tolerance_rad) {
        break;
      }
    } else {
      lambda *= 10.0;
      if (lambda > 1e4) break;
    }
  }
  const double dist = std::sqrt(std::pow(pose.x_m - start.x_m, 2) +
                                std::pow(pose.y_m - start.y_m, 2) +
                                std::pow(pose.z_m - start.z_m, 2));
  const double dyaw = std::abs(wrapAngle(pose.yaw_rad - start.yaw_rad));
  if (!r.refined) {
    r.why = "no step raised the likelihood";
  } else if (dist > refinement.max_correction_m || dyaw > refinement.max_correction_rad) {
    std::ostringstream msg;
    msg << "refined pose " << dist << " m / " << dyaw << " rad from the particle mean: rejected";
    r.why = msg.str();
    r.refined = false;
  }
  if (r.refined) {
    r.pose = pose;
    r.loglik_refined = cur.loglik / px;
  } else {
    r.loglik_refined = r.loglik_start;
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace gmm_mcl
