#include "gmm_mcl/experiments/figures/gaussian_kl.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {
namespace figures {

StateGaussian stateGaussian(const PoseEstimate& estimate) {
  StateGaussian g;
  g.mean << estimate.mean.x_m, estimate.mean.y_m, estimate.mean.z_m, estimate.mean.yaw_rad;
  const int idx[4] = {0, 1, 2, 5};  // x, y, z, yaw in ROS order
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) g.cov(r, c) = estimate.covariance(idx[r], idx[c]);
  }
  return g;
}

double gaussianKl(const Eigen::VectorXd& mean_p, const Eigen::MatrixXd& cov_p,
                  const Eigen::VectorXd& mean_q, const Eigen::MatrixXd& cov_q,
                  double regularisation) {
  const Eigen::Index k = mean_p.size();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(k, k);
  const Eigen::MatrixXd Sp = cov_p + regularisation * I;
  const Eigen::MatrixXd Sq = cov_q + regularisation * I;
  const Eigen::LLT<Eigen::MatrixXd> lp(Sp), lq(Sq);
  if (lp.info() != Eigen::Success || lq.info() != Eigen::Success) {
    return std::numeric_limits<double>::infinity();
  }
  // ln det S = 2 sum ln diag(L).
  const Eigen::MatrixXd Lp = lp.matrixL(), Lq = lq.matrixL();
  double logdet_p = 0.0, logdet_q = 0.0;
  for (Eigen::Index i = 0; i < k; ++i) {
    if (!(Lp(i, i) > 0.0) || !(Lq(i, i) > 0.0)) return std::numeric_limits<double>::infinity();
    logdet_p += 2.0 * std::log(Lp(i, i));
    logdet_q += 2.0 * std::log(Lq(i, i));
  }
  const Eigen::VectorXd d = mean_q - mean_p;
  const double trace = lq.solve(Sp).trace();
  const double maha = d.dot(lq.solve(d));
  const double kl = 0.5 * (trace + maha - static_cast<double>(k) + logdet_q - logdet_p);
  return kl < 0.0 ? 0.0 : kl;  // rounding only: KL >= 0
}

double stateKl(const StateGaussian& p, const StateGaussian& q, double regularisation) {
  Eigen::Vector4d mq = q.mean;
  mq[3] = p.mean[3] + wrapAngle(q.mean[3] - p.mean[3]);  // same branch as p's yaw
  return gaussianKl(p.mean, p.cov, mq, q.cov, regularisation);
}

}  // namespace figures
}  // namespace gmm_mcl
