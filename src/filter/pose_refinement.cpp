#include "gmm_mcl/filter/pose_refinement.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "gmm_mcl/measurement/likelihood.h"

namespace gmm_mcl {
namespace {

// Responsibility below which a (pixel, component) pair is left out of the normal equations.
constexpr double kMinResponsibility = 1e-6;
// Steps after which the membership and the noise-convolved forms are recomputed.
constexpr double kRelineariseM = 0.01;
constexpr double kRelineariseRad = 0.01;
// Work split of the pixel loop: patches in this many chunks; per chunk the log-likelihood, the
// 21 entries of the upper triangle of H and the 6 of g.
constexpr int kChunks = 64;
constexpr int kPartial = 28;

// A 6-DoF pose: the particle state plus the roll and pitch the refinement may adjust.
struct Pose6 {
  Particle p;
  double roll = 0.0, pitch = 0.0;
};

// The frame's log-likelihood at a pose and the Gauss-Newton normal equations of the EM objective
// sum_ij gamma_ij |y_ij|^2 (y = U q + c: the component's whitened residual over sqrt(2)) in
// (x, y, z, roll, pitch, yaw).
struct Linearisation {
  double loglik = 0.0;
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
};

class Objective {
 public:
  Objective(const std::vector<ComponentF>& components, const DepthFrame& frame,
            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params)
      : components_(components), frame_(frame), T_base_cam_(T_base_cam), params_(params) {
    makeEvalComponents(components_, &base_eval_);
    // Base-frame points; the map point of a pose is R(roll, pitch, yaw) p_base + t.
    p_base_.resize(frame.size());
    for (size_t i = 0; i < frame.size(); ++i) {
      p_base_[i] = T_base_cam * Eigen::Vector3d(frame.x_m[i], frame.y_m[i], frame.z_m[i]);
    }
  }

  // Membership and evaluation forms (with the depth noise) at `pose`; kept for the iterations
  // that follow, whose steps are small beside the membership's 3-sigma-plus-half-patch margin
  // (the objective stays one function while it is maximised).
  void linearisePatches(const Pose6& pose) {
    const Eigen::Isometry3d T_map_cam = particleToPose(pose.p, pose.roll, pose.pitch) * T_base_cam_;
    const RigidTransformF T_cam_map = toRigidF(T_map_cam.inverse());
    computeMembership(components_, T_cam_map, frame_.intrinsics, frame_.grid, params_, &projected_,
                      &valid_, &membership_);
    eval_ = noisyEvalComponents(components_, base_eval_, valid_, T_cam_map, params_.depth_noise,
                                &noisy_);
  }

  Linearisation evaluate(const Pose6& pose, bool linearise) {
    const EvalComponentF* eval = eval_;
    const Eigen::Matrix3d R = rotationFromRpy(pose.roll, pose.pitch, pose.p.yaw_rad);
    const Eigen::Vector3d t(pose.p.x_m, pose.p.y_m, pose.p.z_m);
    // dR / d(roll, pitch, yaw) for R = Rz(yaw) Ry(pitch) Rx(roll).
    const double cr = std::cos(pose.roll), sr = std::sin(pose.roll);
    const double cp = std::cos(pose.pitch), sp = std::sin(pose.pitch);
    const double cy = std::cos(pose.p.yaw_rad), sy = std::sin(pose.p.yaw_rad);
    Eigen::Matrix3d Rx, Ry, Rz, dRx, dRy, dRz;
    Rx << 1, 0, 0, 0, cr, -sr, 0, sr, cr;
    Ry << cp, 0, sp, 0, 1, 0, -sp, 0, cp;
    Rz << cy, -sy, 0, sy, cy, 0, 0, 0, 1;
    dRx << 0, 0, 0, 0, -sr, -cr, 0, cr, -sr;
    dRy << -sp, 0, cp, 0, 0, 0, -cp, 0, -sp;
    dRz << -sy, -cy, 0, cy, -sy, 0, 0, 0, 0;
    const Eigen::Matrix3d D[3] = {Rz * Ry * dRx, Rz * dRy * Rx, dRz * Ry * Rx};
    const double floor = params_.floor_log_density;
    Linearisation out;
    // Patches in fixed chunks, one partial sum per chunk, added in chunk order: the result does
    // not depend on the thread count.
    const int patches = frame_.grid.count();
    const int chunks = std::min(patches, kChunks);
    partial_.assign(static_cast<size_t>(chunks) * kPartial, 0.0);
#pragma omp parallel for schedule(dynamic, 1)
    for (int ch = 0; ch < chunks; ++ch) {
      double* acc = partial_.data() + static_cast<size_t>(ch) * kPartial;  // loglik, h[21], g[6]
      std::vector<double>& t_ = scratch_t();
      std::vector<double>& y_ = scratch_y();
      for (int p = ch * patches / chunks; p < (ch + 1) * patches / chunks; ++p) {
        const int b = frame_.patch_begin[p], e = frame_.patch_begin[p + 1];
        if (b == e) continue;
        const int k = membership_.countFor(p);
        if (k == 0) {
          acc[0] += floor * (e - b);
          continue;
        }
        const int* members = membership_.comps.data() + membership_.begin[p];
        t_.resize(k);
        y_.resize(3 * k);
        for (int i = b; i < e; ++i) {
          const Eigen::Vector3d q = R * p_base_[i] + t;
          double mx = floor;
          for (int j = 0; j < k; ++j) {
            const EvalComponentF& ev = eval[members[j]];
            const double y0 = ev.u00 * q.x() + ev.u01 * q.y() + ev.u02 * q.z() + ev.c[0];
            const double y1 = ev.u11 * q.y() + ev.u12 * q.z() + ev.c[1];
            const double y2 = ev.u22 * q.z() + ev.c[2];
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
          acc[0] += mx + std::log(sum);
          if (!linearise) continue;
          // dq / d(roll, pitch, yaw).
          const Eigen::Vector3d m[3] = {D[0] * p_base_[i], D[1] * p_base_[i], D[2] * p_base_[i]};
          const double inv_sum = 1.0 / sum;
          for (int j = 0; j < k; ++j) {
            const double gamma = t_[j] * inv_sum;
            if (gamma < kMinResponsibility) continue;
            const EvalComponentF& ev = eval[members[j]];
            // Columns of J = U [I | dq/droll | dq/dpitch | dq/dyaw] (U upper triangular).
            double col[6][3] = {
                {ev.u00, 0.0, 0.0}, {ev.u01, ev.u11, 0.0}, {ev.u02, ev.u12, ev.u22}};
            for (int a = 0; a < 3; ++a) {
              col[3 + a][0] = ev.u00 * m[a].x() + ev.u01 * m[a].y() + ev.u02 * m[a].z();
              col[3 + a][1] = ev.u11 * m[a].y() + ev.u12 * m[a].z();
              col[3 + a][2] = ev.u22 * m[a].z();
            }
            const double y[3] = {y_[3 * j], y_[3 * j + 1], y_[3 * j + 2]};
            double* h = acc + 1;
            double* g = acc + 22;
            for (int r = 0, idx = 0; r < 6; ++r) {
              for (int c = r; c < 6; ++c, ++idx) {
                h[idx] +=
                    gamma * (col[r][0] * col[c][0] + col[r][1] * col[c][1] + col[r][2] * col[c][2]);
              }
              g[r] += gamma * (col[r][0] * y[0] + col[r][1] * y[1] + col[r][2] * y[2]);
            }
          }
        }
      }
    }
    double h[6][6] = {{0}};
    double g[6] = {0};
    for (int ch = 0; ch < chunks; ++ch) {
      const double* acc = partial_.data() + static_cast<size_t>(ch) * kPartial;
      out.loglik += acc[0];
      for (int r = 0, idx = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c, ++idx) h[r][c] += acc[1 + idx];
        g[r] += acc[22 + r];
      }
    }
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) out.H(r, c) = out.H(c, r) = h[r][c];
      out.g(r) = g[r];
    }
    return out;
  }

 private:
  const std::vector<ComponentF>& components_;
  const DepthFrame& frame_;
  Eigen::Isometry3d T_base_cam_;
  MeasurementParams params_;
  std::vector<EvalComponentF> base_eval_, noisy_;
  const EvalComponentF* eval_ = nullptr;
  std::vector<Eigen::Vector3d> p_base_;
  std::vector<double> partial_;  // [chunks][kPartial]
  static std::vector<double>& scratch_t() {
    static thread_local std::vector<double> v;
    return v;
  }
  static std::vector<double>& scratch_y() {
    static thread_local std::vector<double> v;
    return v;
  }
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
  if (!(attitude_prior_sigma_rad >= 0.0)) {
    err << "refinement attitude_prior_sigma_rad must be >= 0; ";
  }
  return err.str();
}

RefinementResult refinePose(const std::vector<ComponentF>& components, const DepthFrame& frame,
                            const Particle& start, double roll_rad, double pitch_rad,
                            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params,
                            const RefinementParams& refinement) {
  const auto t0 = std::chrono::steady_clock::now();
  RefinementResult r;
  r.pose = start;
  r.roll_rad = roll_rad;
  r.pitch_rad = pitch_rad;
  if (frame.empty()) {
    r.why = "no pixels";
    return r;
  }
  Objective objective(components, frame, T_base_cam, params);
  const double px = static_cast<double>(frame.size());
  // Roll and pitch: free with a Gaussian prior at the attitude input (sigma > 0), else fixed.
  const double sigma_att = refinement.attitude_prior_sigma_rad;
  const bool six_dof = sigma_att > 0.0;
  const double prior = six_dof ? 0.5 / (sigma_att * sigma_att) : 0.0;
  auto logPosterior = [&](const Pose6& p, double loglik) {
    return loglik - prior * (std::pow(p.roll - roll_rad, 2) + std::pow(p.pitch - pitch_rad, 2));
  };
  Pose6 pose{start, roll_rad, pitch_rad};
  objective.linearisePatches(pose);
  Linearisation cur = objective.evaluate(pose, true);
  double cur_post = logPosterior(pose, cur.loglik);
  r.loglik_start = cur.loglik / px;
  double lambda = 1e-3;  // Levenberg-Marquardt damping, relative to the diagonal
  for (int it = 0; it < refinement.max_iterations; ++it) {
    ++r.iterations;
    Eigen::Matrix<double, 6, 6> A = cur.H;
    Eigen::Matrix<double, 6, 1> g = cur.g;
    if (six_dof) {
      A(3, 3) += prior;
      A(4, 4) += prior;
      g(3) += prior * (pose.roll - roll_rad);
      g(4) += prior * (pose.pitch - pitch_rad);
    } else {
      for (int d = 3; d < 5; ++d) {
        A.row(d).setZero();
        A.col(d).setZero();
        A(d, d) = 1.0;
        g(d) = 0.0;
      }
    }
    for (int d = 0; d < 6; ++d) A(d, d) += lambda * std::max(A(d, d), 1e-9);
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(A);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::Matrix<double, 6, 1> delta = -ldlt.solve(g);
    if (!delta.allFinite()) break;
    Pose6 next = pose;
    next.p.x_m += delta[0];
    next.p.y_m += delta[1];
    next.p.z_m += delta[2];
    next.roll += delta[3];
    next.pitch += delta[4];
    next.p.yaw_rad = wrapAngle(next.p.yaw_rad + delta[5]);
    Linearisation cand = objective.evaluate(next, true);
    double cand_post = logPosterior(next, cand.loglik);
    if (cand_post > cur_post) {
      // A step of more than a centimetre or degree: membership and noise at the new pose.
      if (delta.head<3>().norm() > kRelineariseM ||
          delta.tail<3>().cwiseAbs().maxCoeff() > kRelineariseRad) {
        objective.linearisePatches(next);
        cand = objective.evaluate(next, true);
        cand_post = logPosterior(next, cand.loglik);
      }
      pose = next;
      cur = cand;
      cur_post = cand_post;
      r.refined = true;
      lambda = std::max(1e-6, 0.3 * lambda);
      if (delta.head<3>().norm() < refinement.tolerance_m &&
          delta.tail<3>().cwiseAbs().maxCoeff() < refinement.tolerance_rad) {
        break;
      }
    } else {
      lambda *= 10.0;
      if (lambda > 1e4) break;
    }
  }
  const double dist =
      std::sqrt(std::pow(pose.p.x_m - start.x_m, 2) + std::pow(pose.p.y_m - start.y_m, 2) +
                std::pow(pose.p.z_m - start.z_m, 2));
  const double dyaw = std::abs(wrapAngle(pose.p.yaw_rad - start.yaw_rad));
  if (!r.refined) {
    r.why = "no step raised the likelihood";
  } else if (dist > refinement.max_correction_m || dyaw > refinement.max_correction_rad) {
    std::ostringstream msg;
    msg << "refined pose " << dist << " m / " << dyaw << " rad from the particle mean: rejected";
    r.why = msg.str();
    r.refined = false;
  }
  if (r.refined) {
    r.pose = pose.p;
    r.roll_rad = pose.roll;
    r.pitch_rad = pose.pitch;
    r.loglik_refined = cur.loglik / px;
  } else {
    r.loglik_refined = r.loglik_start;
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace gmm_mcl
