// Spatial Gaussian-mixture map of the environment (paper Eq. gmm), in the map frame, metres.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

// Thrown when a map is invalid; the message names the source (file) and the fault.
class MapError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct GaussianComponent {
  double weight = 0.0;                                   // lambda_i > 0
  Eigen::Vector3d mean_m = Eigen::Vector3d::Zero();      // mu_i
  Eigen::Matrix3d cov_m2 = Eigen::Matrix3d::Identity();  // Sigma_i, symmetric positive-definite
};

// Tolerance on |sum of weights - 1| accepted from a map (float32 storage of ~1000 weights).
constexpr double kWeightSumTolerance = 1e-4;
// Relative tolerance on |Sigma - Sigma^T| accepted from in-memory components.
constexpr double kSymmetryTolerance = 1e-9;

class GmmMap {
 public:
  GmmMap() = default;

  // Validates and precomputes; throws MapError naming `source` and the fault.
  explicit GmmMap(std::vector<GaussianComponent> components,
                  const std::string& source = "<memory>");

  size_t size() const { return components_.size(); }
  bool empty() const { return components_.empty(); }
  const std::vector<GaussianComponent>& components() const { return components_; }
  // Backend layout with precision and log-normaliser precomputed (float32).
  const std::vector<ComponentF>& packed() const { return packed_; }
  // Extent of the 3-sigma ellipsoid of component i along each map axis (m).
  const Eigen::Vector3d& threeSigmaHalfExtent(size_t i) const { return half_extent_m_[i]; }
  // Axis-aligned bounds of all means (m).
  const Eigen::Vector3d& minBound() const { return min_bound_m_; }
  const Eigen::Vector3d& maxBound() const { return max_bound_m_; }

  // ln p(x) of the full mixture at a map-frame point (double, all components).
  double logDensity(const Eigen::Vector3d& p_map) const;

 private:
  std::vector<GaussianComponent> components_;
  std::vector<ComponentF> packed_;
  std::vector<Eigen::Vector3d> half_extent_m_;
  Eigen::Vector3d min_bound_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_bound_m_ = Eigen::Vector3d::Zero();
};

// Throws MapError if the components do not form a valid mixture (names `source` and the fault).
void validateComponents(const std::vector<GaussianComponent>& components,
                        const std::string& source);

}  // namespace gmm_mcl
