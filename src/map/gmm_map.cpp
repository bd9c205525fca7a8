#include "gmm_mcl/map/gmm_map.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <sstream>

namespace gmm_mcl {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;

std::string fault(const std::string& source, const std::string& what) {
  return source + ": " + what;
}

bool allFinite(const GaussianComponent& c) {
  return std::isfinite(c.weight) && c.mean_m.allFinite() && c.cov_m2.allFinite();
}

void packSymmetric(const Eigen::Matrix3d& m, float out[6]) {
  out[0] = static_cast<float>(m(0, 0));
  out[1] = static_cast<float>(m(0, 1));
  out[2] = static_cast<float>(m(0, 2));
  out[3] = static_cast<float>(m(1, 1));
  out[4] = static_cast<float>(m(1, 2));
  out[5] = static_cast<float>(m(2, 2));
}

}  // namespace

void validateComponents(const std::vector<GaussianComponent>& components,
                        const std::string& source) {
  if (components.empty()) throw MapError(fault(source, "map has no components"));
  double weight_sum = 0.0;
  for (size_t i = 0; i < components.size(); ++i) {
    const GaussianComponent& c = components[i];
    std::ostringstream id;
    id << "component " << i << ": ";
    if (!allFinite(c)) throw MapError(fault(source, id.str() + "NaN or Inf value"));
    if (!(c.weight > 0.0)) {
      std::ostringstream msg;
      msg << id.str() << "weight " << c.weight << " is not positive";
      throw MapError(fault(source, msg.str()));
    }
    const double scale = c.cov_m2.cwiseAbs().maxCoeff();
    if ((c.cov_m2 - c.cov_m2.transpose()).cwiseAbs().maxCoeff() > kSymmetryTolerance * scale) {
      throw MapError(fault(source, id.str() + "covariance is not symmetric"));
    }
    Eigen::LLT<Eigen::Matrix3d> llt(c.cov_m2);
    if (llt.info() != Eigen::Success || !(c.cov_m2.determinant() > 0.0)) {
      throw MapError(fault(source, id.str() + "covariance is not positive-definite"));
    }
    weight_sum += c.weight;
  }
  if (std::abs(weight_sum - 1.0) > kWeightSumTolerance) {
    std::ostringstream msg;
    msg.precision(9);
    msg << "weights sum to " << weight_sum << ", not 1 (tolerance " << kWeightSumTolerance << ")";
    throw MapError(fault(source, msg.str()));
  }
}

GmmMap::GmmMap(std::vector<GaussianComponent> components, const std::string& source)
    : components_(std::move(components)) {
  validateComponents(components_, source);
  packed_.resize(components_.size());
  half_extent_m_.resize(components_.size());
  min_bound_m_.setConstant(std::numeric_limits<double>::infinity());
  max_bound_m_.setConstant(-std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < components_.size(); ++i) {
    const GaussianComponent& c = components_[i];
    ComponentF& p = packed_[i];
    for (int k = 0; k < 3; ++k) p.mean_m[k] = static_cast<float>(c.mean_m[k]);
    packSymmetric(c.cov_m2, p.cov_m2);
    // Symmetrise the inverse: float evaluation relies on an exactly symmetric precision.
    const Eigen::Matrix3d precision = c.cov_m2.inverse();
    packSymmetric(0.5 * (precision + precision.transpose()), p.precision);
    p.log_weight = static_cast<float>(std::log(c.weight) - 1.5 * kLog2Pi);
    p.log_norm = static_cast<float>(std::log(c.weight) - 1.5 * kLog2Pi -
                                    0.5 * std::log(c.cov_m2.determinant()));
    half_extent_m_[i] = 3.0 * c.cov_m2.diagonal().cwiseSqrt();
    min_bound_m_ = min_bound_m_.cwiseMin(c.mean_m);
    max_bound_m_ = max_bound_m_.cwiseMax(c.mean_m);
  }
}

double GmmMap::logDensity(const Eigen::Vector3d& p_map) const {
  // Log-sum-exp over all components, in double.
  double max_term = -std::numeric_limits<double>::infinity();
  std::vector<double> terms(components_.size());
  for (size_t i = 0; i < components_.size(); ++i) {
    const GaussianComponent& c = components_[i];
    const Eigen::Vector3d d = p_map - c.mean_m;
    const double q = d.dot(c.cov_m2.ldlt().solve(d));
    terms[i] =
        std::log(c.weight) - 1.5 * kLog2Pi - 0.5 * std::log(c.cov_m2.determinant()) - 0.5 * q;
    max_term = std::max(max_term, terms[i]);
  }
  double sum = 0.0;
  for (double t : terms) sum += std::exp(t - max_term);
  return max_term + std::log(sum);
}

}  // namespace gmm_mcl
