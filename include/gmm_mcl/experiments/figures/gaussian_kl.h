// Gaussian summaries of a particle set and their Kullback-Leibler divergence: the measure of the
// paper's Sensitivity Analysis (the particle set taken as a unimodal Gaussian after convergence).
#pragma once

#include <Eigen/Core>

#include "gmm_mcl/filter/particle_filter.h"

namespace gmm_mcl {
namespace figures {

// A Gaussian over the 4-DoF state (x, y, z in m, yaw in rad).
struct StateGaussian {
  Eigen::Vector4d mean = Eigen::Vector4d::Zero();
  Eigen::Matrix4d cov = Eigen::Matrix4d::Identity();
};

// The (x, y, z, yaw) block of a filter estimate: weighted mean (circular for yaw) and weighted
// covariance with wrapped yaw differences (ParticleFilter::estimate()).
StateGaussian stateGaussian(const PoseEstimate& estimate);

// KL(p || q) between two k-variate Gaussians in closed form:
// 0.5 (tr(Sq^-1 Sp) + d^T Sq^-1 d - k + ln det Sq - ln det Sp), d = mu_q - mu_p.
// `regularisation` is added to both covariance diagonals first (0: none). Returns +inf when a
// covariance is not positive-definite.
double gaussianKl(const Eigen::VectorXd& mean_p, const Eigen::MatrixXd& cov_p,
                  const Eigen::VectorXd& mean_q, const Eigen::MatrixXd& cov_q,
                  double regularisation = 0.0);

// The same for state Gaussians, with the yaw difference of the means wrapped into [-pi, pi).
double stateKl(const StateGaussian& p, const StateGaussian& q, double regularisation);

}  // namespace figures
}  // namespace gmm_mcl
