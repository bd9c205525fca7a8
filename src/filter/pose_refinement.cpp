#include "gmm_mcl/filter/pose_refinement.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>

#include "gmm_mcl/measurement/depth_noise.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/normal_equations.h"

namespace gmm_mcl {
namespace {

// Steps after which the membership and the noise-convolved forms are recomputed.
constexpr double kRelineariseM = 0.01;
constexpr double kRelineariseRad = 0.01;

// A 6-DoF pose: the particle state plus the roll and pitch the refinement may adjust.
struct Pose6 {
  Particle p;
  double roll = 0.0, pitch = 0.0;

  // Moved by a step in (x, y, z, roll, pitch, yaw).
  template <typename V>
  Pose6 moved(const V& d) const {
    Pose6 out = *this;
    out.p.x_m += d[0];
    out.p.y_m += d[1];
    out.p.z_m += d[2];
    out.roll += d[3];
    out.pitch += d[4];
    out.p.yaw_rad = wrapAngle(out.p.yaw_rad + d[5]);
    return out;
  }
};

// The frame's log-likelihood at a pose and the Gauss-Newton normal equations of the EM objective
// sum_ij gamma_ij |y_ij|^2 (y = U q + c: the component's whitened residual over sqrt(2)) in
// (x, y, z, roll, pitch, yaw).
// (x, y, z, roll, pitch, yaw, depth scale): the seventh row and column only when the depth
// scale is estimated.
struct Linearisation {
  double loglik = 0.0;
  Eigen::Matrix<double, 7, 7> H = Eigen::Matrix<double, 7, 7>::Zero();
  Eigen::Matrix<double, 7, 1> g = Eigen::Matrix<double, 7, 1>::Zero();
};

// The objective: membership and evaluation forms on the host, the pixel sums in `sums` (the
// host's, or a backend's on its device).
class Objective {
 public:
  Objective(const std::vector<ComponentF>& components, const RefinementFrame& frame,
            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params,
            NormalEquationsEvaluator* sums, bool estimate_scale)
      : scale_(frame.depth_scale),
        components_(components),
        frame_(frame),
        T_base_cam_(T_base_cam),
        params_(params),
        sums_(sums),
        estimate_scale_(estimate_scale) {
    makeEvalComponents(components_, &base_eval_);
    if (frame.points == nullptr) {  // on the evaluator's device already, as they come
      sums_->setPointsFromBackendFrame(T_base_cam);
      points_state_ = 0;
      return;
    }
    setPoints(false);
  }

  // The frame's points (on the host) to the evaluator; with extra_noise, each depth z with a
  // further error drawn from the depth-noise model's N(0, sigma(z)^2) (a fixed seed: the same
  // frame gives the same result), which moves the point along its ray.
  // Nothing to do when the evaluator holds those points already.
  void setPoints(bool extra_noise) {
    const int state = extra_noise ? 1 : 0;
    if (points_state_ == state) return;
    if (frame_.points == nullptr) {
      throw std::logic_error("refinement: extra depth noise needs the frame's points on the host");
    }
    points_state_ = state;
    // Base-frame points; the map point of a pose is R(roll, pitch, yaw) p_base + t.
    const DepthFrame& f = *frame_.points;
    std::vector<double> x(f.size()), y(f.size()), z(f.size());
    std::mt19937_64 rng(1);
    std::normal_distribution<double> gauss(0.0, 1.0);
    for (size_t i = 0; i < f.size(); ++i) {
      const double k =
          extra_noise ? 1.0 + depthNoiseSigma(params_.depth_noise, f.z_m[i]) * gauss(rng) / f.z_m[i]
                      : 1.0;
      const Eigen::Vector3d p =
          T_base_cam_ * Eigen::Vector3d(k * f.x_m[i], k * f.y_m[i], k * f.z_m[i]);
      x[i] = p.x();
      y[i] = p.y();
      z[i] = p.z();
    }
    sums_->setPoints(x, y, z, f.patch_begin);
  }

  // Membership and evaluation forms (with the depth noise) at `pose`; kept for the iterations
  // that follow, whose steps are small beside the membership's 3-sigma-plus-half-patch margin
  // (the objective stays one function while it is maximised).
  void linearisePatches(const Pose6& pose) {
    // (The depth scale moves points, not the camera: membership is the camera's.)
    const Eigen::Isometry3d T_map_cam = particleToPose(pose.p, pose.roll, pose.pitch) * T_base_cam_;
    const RigidTransformF T_cam_map = toRigidF(T_map_cam.inverse());
    computeMembership(components_, T_cam_map, frame_.intrinsics, frame_.grid, params_, &projected_,
                      &valid_, &membership_);
    const EvalComponentF* eval = noisyEvalComponents(components_, base_eval_, valid_, T_cam_map,
                                                     params_.depth_noise, &noisy_);
    sums_->setLinearisation(eval == base_eval_.data() ? base_eval_ : noisy_, membership_);
  }

  // The depth scale applied to the frame's points (RefinementFrame::depth_scale at the start).
  double scale() const { return scale_; }
  void setScale(double f) { scale_ = f; }

  Linearisation evaluate(const Pose6& pose, bool linearise) {
    PoseDerivatives d;
    const Eigen::Matrix3d R = rotationFromRpy(pose.roll, pose.pitch, pose.p.yaw_rad);
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
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        d.R[3 * r + c] = R(r, c);
        for (int a = 0; a < 3; ++a) d.dR[a][3 * r + c] = D[a](r, c);
      }
    }
    d.t[0] = pose.p.x_m;
    d.t[1] = pose.p.y_m;
    d.t[2] = pose.p.z_m;
    d.scale = scale_;
    for (int a = 0; a < 3; ++a) d.scale_origin[a] = T_base_cam_.translation()[a];
    d.estimate_scale = estimate_scale_;
    NormalEquationSums s;
    sums_->evaluate(d, params_.floor_log_density, linearise, &s);
    Linearisation out;
    out.loglik = s.loglik;
    for (int r = 0, idx = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c, ++idx) out.H(r, c) = out.H(c, r) = s.h[idx];
      out.g(r) = s.g[r];
    }
    for (int r = 0; r < 7; ++r) out.H(r, 6) = out.H(6, r) = s.hs[r];
    out.g(6) = s.gs;
    return out;
  }

 private:
  double scale_;           // the depth scale applied to this frame's points
  int points_state_ = -1;  // setPoints' last extra_noise (0, 1), -1 before it
  const std::vector<ComponentF>& components_;
  const RefinementFrame& frame_;
  Eigen::Isometry3d T_base_cam_;
  MeasurementParams params_;
  NormalEquationsEvaluator* sums_;
  bool estimate_scale_;
  std::vector<EvalComponentF> base_eval_, noisy_;
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
  if (!(track_max_position_sigma_m > 0.0)) {
    err << "refinement track_max_position_sigma_m must be positive; ";
  }
  if (!(track_max_yaw_sigma_rad > 0.0)) {
    err << "refinement track_max_yaw_sigma_rad must be positive; ";
  }
  if (!(cv_track_max_position_sigma_m > 0.0)) {
    err << "refinement cv_track_max_position_sigma_m must be positive; ";
  }
  if (!(cv_track_max_yaw_sigma_rad > 0.0)) {
    err << "refinement cv_track_max_yaw_sigma_rad must be positive; ";
  }
  if (!(max_correction_m > 0.0)) err << "refinement max_correction_m must be positive; ";
  if (!(max_correction_rad > 0.0)) err << "refinement max_correction_rad must be positive; ";
  if (!(tolerance_m > 0.0)) err << "refinement tolerance_m must be positive; ";
  if (!(tolerance_rad > 0.0)) err << "refinement tolerance_rad must be positive; ";
  if (!(attitude_prior_sigma_rad >= 0.0)) {
    err << "refinement attitude_prior_sigma_rad must be >= 0; ";
  }
  if (!(depth_scale_prior_sigma > 0.0)) {
    err << "refinement depth_scale_prior_sigma must be positive; ";
  }
  if (!(depth_scale_max_error > 0.0 && depth_scale_max_error < 0.5)) {
    err << "refinement depth_scale_max_error must be in (0, 0.5); ";
  }
  if (!(depth_scale_rate > 0.0 && depth_scale_rate <= 1.0)) {
    err << "refinement depth_scale_rate must be in (0, 1]; ";
  }
  if (!(std::abs(depth_scale_initial - 1.0) <= depth_scale_max_error)) {
    err << "refinement depth_scale_initial must be within depth_scale_max_error of 1; ";
  }
  return err.str();
}

RefinementResult refinePose(const std::vector<ComponentF>& components, const RefinementFrame& frame,
                            const Particle& start, double roll_rad, double pitch_rad,
                            const Eigen::Isometry3d& T_base_cam, const MeasurementParams& params,
                            const RefinementParams& refinement, NormalEquationsEvaluator* sums,
                            const std::vector<RefinementView>& more) {
  const auto t0 = std::chrono::steady_clock::now();
  RefinementResult r;
  r.pose = start;
  r.roll_rad = roll_rad;
  r.pitch_rad = pitch_rad;
  if (frame.pixels <= 0) {
    r.why = "no pixels";
    return r;
  }
  if (frame.points == nullptr && (sums == nullptr || !sums->hasBackendFrame())) {
    throw std::invalid_argument(
        "refinePose: the frame's points are neither on the host nor on "
        "the backend's device");
  }
  // The depth scale needs an evaluator that applies it: the host's, with the host's points.
  const bool with_scale = refinement.estimate_depth_scale;
  if (with_scale && sums != nullptr && !sums->supportsDepthScale()) {
    if (frame.points == nullptr) {
      throw std::invalid_argument(
          "refinePose: the depth scale is estimated on the host, and the frame's points are not "
          "there");
    }
    sums = nullptr;
  }
  // Its noise correction draws depth noise on the frame's points, which must be on the host.
  if (with_scale && refinement.depth_scale_noise_correction && frame.points == nullptr) {
    throw std::invalid_argument(
        "refinePose: the depth scale's noise correction needs the frame's points on the host");
  }
  r.sums_on_backend = sums != nullptr;
  HostNormalEquations host_sums;
  // The rig's cameras: the first frame, then `more`, each with its own objective and weight; with
  // the depth scale estimated, each camera's scale of its own.
  std::vector<std::unique_ptr<Objective>> objectives;
  objectives.push_back(std::make_unique<Objective>(components, frame, T_base_cam, params,
                                                   sums ? sums : &host_sums, with_scale));
  std::vector<HostNormalEquations> more_sums(more.size());
  std::vector<double> weights = {1.0};
  double px = static_cast<double>(frame.pixels);
  for (size_t k = 0; k < more.size(); ++k) {
    if (more[k].frame.points == nullptr || more[k].components == nullptr ||
        more[k].params == nullptr) {
      throw std::invalid_argument("refinePose: another frame without host points or parameters");
    }
    NormalEquationsEvaluator* view_sums = more[k].sums;
    if (with_scale && view_sums != nullptr && !view_sums->supportsDepthScale()) {
      view_sums = nullptr;
    }
    objectives.push_back(std::make_unique<Objective>(
        *more[k].components, more[k].frame, more[k].T_base_cam, *more[k].params,
        view_sums ? view_sums : &more_sums[k], with_scale));
    weights.push_back(more[k].weight);
    px += more[k].weight * more[k].frame.pixels;
  }
  const int cameras = static_cast<int>(objectives.size());
  auto lineariseAll = [&](const Pose6& p) {
    for (auto& o : objectives) o->linearisePatches(p);
  };
  // The weighted sum over the cameras (the pose's rows; the seventh, the scale's, is each
  // camera's own, kept in `each`).
  struct RigLinearisation {
    Linearisation sum;
    std::vector<Linearisation> each;
  };
  auto evaluateAll = [&](const Pose6& p) {
    RigLinearisation out;
    out.each.resize(cameras);
    for (int k = 0; k < cameras; ++k) {
      Linearisation l = objectives[k]->evaluate(p, true);
      if (k > 0) {
        l.loglik *= weights[k];
        l.H *= weights[k];
        l.g *= weights[k];
      }
      out.sum.loglik += l.loglik;
      out.sum.H.topLeftCorner<6, 6>() += l.H.topLeftCorner<6, 6>();
      out.sum.g.head<6>() += l.g.head<6>();
      out.each[k] = l;
    }
    return out;
  };
  // Roll and pitch: free with a Gaussian prior at the attitude input (sigma > 0), else fixed.
  const double sigma_att = refinement.attitude_prior_sigma_rad;
  const bool six_dof = sigma_att > 0.0;
  const double prior = six_dof ? 0.5 / (sigma_att * sigma_att) : 0.0;
  // The depth scales: held at the frames' current estimates while the pose is refined; then one
  // step of their own with a Gaussian prior at those estimates, within their bounds.
  std::vector<double> scale0(cameras);
  for (int k = 0; k < cameras; ++k) scale0[k] = objectives[k]->scale();
  const double prior_s =
      with_scale ? 0.5 / (refinement.depth_scale_prior_sigma * refinement.depth_scale_prior_sigma)
                 : 0.0;
  const double scale_lo = 1.0 - refinement.depth_scale_max_error;
  const double scale_hi = 1.0 + refinement.depth_scale_max_error;
  auto logPosterior = [&](const Pose6& p, const RigLinearisation& l) {
    return l.sum.loglik -
           prior * (std::pow(p.roll - roll_rad, 2) + std::pow(p.pitch - pitch_rad, 2));
  };
  Pose6 pose{start, roll_rad, pitch_rad};
  std::vector<double> scales = scale0;
  lineariseAll(pose);
  RigLinearisation cur = evaluateAll(pose);
  double cur_post = logPosterior(pose, cur);
  r.loglik_start = cur.sum.loglik / px;
  double lambda = 1e-3;  // Levenberg-Marquardt damping, relative to the diagonal
  for (int it = 0; it < refinement.max_iterations; ++it) {
    ++r.iterations;
    Eigen::Matrix<double, 7, 7> A = cur.sum.H;
    Eigen::Matrix<double, 7, 1> g = cur.sum.g;
    auto fix = [&](int d) {
      A.row(d).setZero();
      A.col(d).setZero();
      A(d, d) = 1.0;
      g(d) = 0.0;
    };
    if (six_dof) {
      A(3, 3) += prior;
      A(4, 4) += prior;
      g(3) += prior * (pose.roll - roll_rad);
      g(4) += prior * (pose.pitch - pitch_rad);
    } else {
      fix(3);
      fix(4);
    }
    fix(6);
    for (int d = 0; d < 7; ++d) A(d, d) += lambda * std::max(A(d, d), 1e-9);
    const Eigen::LDLT<Eigen::Matrix<double, 7, 7>> ldlt(A);
    if (ldlt.info() != Eigen::Success) break;
    Eigen::Matrix<double, 7, 1> delta = -ldlt.solve(g);
    if (!delta.allFinite()) break;
    const Pose6 next = pose.moved(delta);
    RigLinearisation cand = evaluateAll(next);
    double cand_post = logPosterior(next, cand);
    if (cand_post > cur_post) {
      // A step of more than a centimetre or degree: membership and noise at the new pose.
      if (delta.head<3>().norm() > kRelineariseM ||
          delta.segment<3>(3).cwiseAbs().maxCoeff() > kRelineariseRad) {
        lineariseAll(next);
        cand = evaluateAll(next);
        cand_post = logPosterior(next, cand);
      }
      pose = next;
      cur = cand;
      cur_post = cand_post;
      r.refined = true;
      lambda = std::max(1e-6, 0.3 * lambda);
      if (delta.head<3>().norm() < refinement.tolerance_m &&
          delta.segment<3>(3).cwiseAbs().maxCoeff() < refinement.tolerance_rad) {
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
  std::vector<double> information(cameras, 0.0);
  if (with_scale && r.refined) {
    // Each camera's depth-scale estimate: at the refined pose, a Newton and a secant step in the
    // scales with the pose marginalised out of the normal equations (the pose moving with them to
    // first order), with the prior. The pixels' depth noise biases the steps short (the points'
    // noise lies along the very direction the scale moves them: docs/measurement_model.md, "Depth
    // scale"); the bias is taken out by simulation-extrapolation: the same gradient on the
    // frames with the model's depth noise added once more, extrapolated linearly to no noise.
    // A camera's information: 1 / (M^-1)_kk less its own prior, M the scales' normal equations
    // with the pose marginalised and the priors (one camera: the Schur complement itself).
    Eigen::Matrix<double, 7, 7> A = cur.sum.H;
    if (six_dof) {
      A(3, 3) += prior;
      A(4, 4) += prior;
    } else {
      for (int d = 3; d < 5; ++d) {
        A.row(d).setZero();
        A.col(d).setZero();
        A(d, d) = 1.0;
      }
    }
    const Eigen::Matrix<double, 6, 6> App = A.topLeftCorner<6, 6>();
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(App);
    if (ldlt.info() == Eigen::Success) {
      // B: the pose-scale blocks (6 x cameras); the scales' marginal normal equations S.
      Eigen::MatrixXd B(6, cameras);
      Eigen::VectorXd D(cameras);
      for (int k = 0; k < cameras; ++k) {
        B.col(k) = cur.each[k].H.block<6, 1>(0, 6);
        D(k) = cur.each[k].H(6, 6);
      }
      const Eigen::MatrixXd AinvB = ldlt.solve(B);
      // H is the Gauss-Newton matrix of sum |y|^2, half the Hessian of -loglik: x2.
      const Eigen::MatrixXd S = Eigen::MatrixXd(D.asDiagonal()) - B.transpose() * AinvB;
      // The cameras whose pixels tell something of their scale (the others keep theirs).
      std::vector<int> act;
      for (int k = 0; k < cameras; ++k) {
        if (S(k, k) > 0.0) act.push_back(k);
      }
      const int na = static_cast<int>(act.size());
      Eigen::MatrixXd M(na, na);
      for (int a = 0; a < na; ++a) {
        for (int b = 0; b < na; ++b) M(a, b) = S(act[a], act[b]) + (a == b ? prior_s : 0.0);
      }
      const Eigen::LDLT<Eigen::MatrixXd> mldlt(M);
      const bool m_ok = na > 0 && mldlt.info() == Eigen::Success;
      if (m_ok) {
        const Eigen::MatrixXd Minv = mldlt.solve(Eigen::MatrixXd::Identity(na, na));
        for (int a = 0; a < na; ++a) {
          information[act[a]] = std::max(0.0, 2.0 * (1.0 / Minv(a, a) - prior_s));
        }
      }
      // The pose's gradient at p (with the attitude prior) and the scales' with the pose
      // marginalised, both halves of the gradients of the objective minimised.
      auto poseGradient = [&](const Pose6& p, const RigLinearisation& l) {
        Eigen::Matrix<double, 6, 1> gp = l.sum.g.head<6>();
        if (six_dof) {
          gp(3) += prior * (p.roll - roll_rad);
          gp(4) += prior * (p.pitch - pitch_rad);
        } else {
          gp(3) = gp(4) = 0.0;
        }
        return gp;
      };
      auto marginal = [&](const Pose6& p, const RigLinearisation& l) {
        Eigen::VectorXd m(na);
        const Eigen::Matrix<double, 6, 1> x = ldlt.solve(poseGradient(p, l));
        for (int a = 0; a < na; ++a) m(a) = l.each[act[a]].g(6) - B.col(act[a]).dot(x);
        return m;
      };
      // Simulation-extrapolation of the marginal gradients at p with the scales s: 2 x the
      // frames' minus the frames' with the noise doubled, plus the prior's.
      auto corrected = [&](const Pose6& p, const std::vector<double>& s) {
        for (int k = 0; k < cameras; ++k) {
          objectives[k]->setScale(s[k]);
          objectives[k]->setPoints(false);
        }
        const RigLinearisation obs = evaluateAll(p);
        const Eigen::VectorXd m_obs = marginal(p, obs);
        Eigen::VectorXd m = m_obs;
        if (refinement.depth_scale_noise_correction) {
          for (auto& o : objectives) o->setPoints(true);
          const RigLinearisation aug = evaluateAll(p);
          m = 2.0 * m_obs - marginal(p, aug);
        }
        for (int a = 0; a < na; ++a) m(a) += prior_s * (s[act[a]] - scale0[act[a]]);
        return std::make_pair(m, poseGradient(p, obs));
      };
      if (m_ok) {
        // A Newton step with the Gauss-Newton curvature, then per camera a secant step with the
        // curvature measured along it (the Gauss-Newton one overstates it: the step falls short).
        const auto c0 = corrected(pose, scale0);
        const Eigen::VectorXd d1 = -mldlt.solve(c0.first);
        Eigen::VectorXd full_d1 = Eigen::VectorXd::Zero(cameras);
        for (int a = 0; a < na; ++a) full_d1(act[a]) = d1(a);
        const Eigen::Matrix<double, 6, 1> dp = -ldlt.solve(c0.second + B * full_d1);
        Pose6 p1 = pose.moved(dp);
        std::vector<double> s1 = scale0;
        for (int a = 0; a < na; ++a) s1[act[a]] = scale0[act[a]] + d1(a);
        const Eigen::VectorXd c1 = corrected(p1, s1).first;
        for (int a = 0; a < na; ++a) {
          double step = d1(a);
          const double slope = (c1(a) - c0.first(a)) / d1(a);
          if (std::isfinite(slope) && slope > 0.0) {
            // At most four times the Newton step.
            step = d1(a) - c1(a) / slope;
            if (step / d1(a) > 4.0) step = 4.0 * d1(a);
            if (step / d1(a) < 0.0) step = d1(a);
          }
          if (std::isfinite(step)) {
            scales[act[a]] = std::min(scale_hi, std::max(scale_lo, scale0[act[a]] + step));
          }
        }
      }
    }
  }
  // Unchanged when not estimated or not refined.
  r.depth_scale = scales[0];
  r.depth_scale_information = information[0];
  r.more_depth_scale.assign(scales.begin() + 1, scales.end());
  r.more_depth_scale_information.assign(information.begin() + 1, information.end());
  if (r.refined) {
    r.pose = pose.p;
    r.roll_rad = pose.roll;
    r.pitch_rad = pose.pitch;
    r.loglik_refined = cur.sum.loglik / px;
  } else {
    r.loglik_refined = r.loglik_start;
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

double refinementReach(const RefinementParams& refinement, const ViewReach& reach) {
  constexpr double kAttitudeSlackRad = 0.1;
  return refinement.max_correction_m +
         static_cast<double>(reach.far_m) * (refinement.max_correction_rad + kAttitudeSlackRad);
}

}  // namespace gmm_mcl
