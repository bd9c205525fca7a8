#include "gmm_mcl/map/gmm_map.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
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

double estimateSurfaceArea(const std::vector<GaussianComponent>& components) {
  std::vector<std::pair<double, double>> area_per_weight;  // (area / weight, weight)
  area_per_weight.reserve(components.size());
  double total = 0.0;
  for (const GaussianComponent& c : components) {
    const Eigen::Vector3d s =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c.cov_m2, Eigen::EigenvaluesOnly)
            .eigenvalues();  // ascending
    const double area = 4.0 * M_PI * std::sqrt(std::max(s(1), 0.0) * std::max(s(2), 0.0));
    if (!(c.weight > 0.0) || !(area > 0.0)) continue;
    area_per_weight.emplace_back(area / c.weight, c.weight);
    total += c.weight;
  }
  if (area_per_weight.empty()) return kReferenceSurfaceAreaM2;
  std::sort(area_per_weight.begin(), area_per_weight.end());
  double acc = 0.0;
  for (const auto& a : area_per_weight) {
    acc += a.second;
    if (acc >= 0.5 * total) return a.first;
  }
  return area_per_weight.back().first;
}

GmmMap::GmmMap(std::vector<GaussianComponent> components, const std::string& source,
               double surface_area_m2)
    : components_(std::move(components)) {
  validateComponents(components_, source);
  surface_area_m2_ = surface_area_m2 > 0.0 ? surface_area_m2 : estimateSurfaceArea(components_);
  log_weight_scale_ = std::log(surface_area_m2_ / kReferenceSurfaceAreaM2);
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
    p.log_weight = static_cast<float>(modelLogWeight(i) - 1.5 * kLog2Pi);
    p.log_norm = static_cast<float>(modelLogWeight(i) - 1.5 * kLog2Pi -
                                    0.5 * std::log(c.cov_m2.determinant()));
    half_extent_m_[i] = 3.0 * c.cov_m2.diagonal().cwiseSqrt();
    min_bound_m_ = min_bound_m_.cwiseMin(c.mean_m);
    max_bound_m_ = max_bound_m_.cwiseMax(c.mean_m);
  }
  std::vector<Box3> boxes(components_.size());
  for (size_t i = 0; i < components_.size(); ++i) boxes[i] = threeSigmaBox(i);
  grid_ = ComponentGrid(boxes);
}

Box3 GmmMap::threeSigmaBox(size_t i) const {
  Box3 b;
  b.lo = components_[i].mean_m - half_extent_m_[i];
  b.hi = components_[i].mean_m + half_extent_m_[i];
  return b;
}

std::vector<GaussianComponent> mergedByCell(const std::vector<GaussianComponent>& components,
                                            double cell_m) {
  if (!(cell_m > 0.0) || !std::isfinite(cell_m)) return components;
  // Per cube: the sums of w, w mu and w (Sigma + mu mu^T); then the moments.
  struct Sums {
    double w = 0.0;
    Eigen::Vector3d wm = Eigen::Vector3d::Zero();
    Eigen::Matrix3d ws = Eigen::Matrix3d::Zero();
    int count = 0;
  };
  std::map<std::array<long long, 3>, int> cube_of;
  std::vector<Sums> sums;
  std::vector<int> single;  // the cube's only component while it has one
  for (size_t i = 0; i < components.size(); ++i) {
    const GaussianComponent& c = components[i];
    std::array<long long, 3> key;
    for (int a = 0; a < 3; ++a) key[a] = static_cast<long long>(std::floor(c.mean_m[a] / cell_m));
    const auto it = cube_of.emplace(key, static_cast<int>(sums.size())).first;
    if (it->second == static_cast<int>(sums.size())) {
      sums.emplace_back();
      single.push_back(static_cast<int>(i));
    }
    Sums& s = sums[it->second];
    s.w += c.weight;
    s.wm += c.weight * c.mean_m;
    s.ws += c.weight * (c.cov_m2 + c.mean_m * c.mean_m.transpose());
    ++s.count;
  }
  std::vector<GaussianComponent> merged(sums.size());
  for (size_t k = 0; k < sums.size(); ++k) {
    const Sums& s = sums[k];
    if (s.count == 1) {  // unchanged, bit for bit
      merged[k] = components[single[k]];
      continue;
    }
    GaussianComponent& m = merged[k];
    m.weight = s.w;
    m.mean_m = s.wm / s.w;
    m.cov_m2 = s.ws / s.w - m.mean_m * m.mean_m.transpose();
    m.cov_m2 = 0.5 * (m.cov_m2 + m.cov_m2.transpose());
  }
  return merged;
}

GmmMap tiledMap(const GmmMap& room, int nx, int ny, double spacing_m, const std::string& source) {
  if (nx < 1 || ny < 1 || !(spacing_m > 0.0)) {
    throw MapError(source + ": tiling needs nx, ny >= 1 and a positive spacing");
  }
  const Eigen::Vector3d centre = 0.5 * (room.minBound() + room.maxBound());
  std::vector<GaussianComponent> out;
  out.reserve(room.size() * static_cast<size_t>(nx) * static_cast<size_t>(ny));
  const double share = 1.0 / (static_cast<double>(nx) * ny);
  for (int ix = 0; ix < nx; ++ix) {
    for (int iy = 0; iy < ny; ++iy) {
      const Eigen::Matrix3d R =
          Eigen::AngleAxisd(0.5 * M_PI * ((ix + iy) % 4), Eigen::Vector3d::UnitZ()).matrix();
      const Eigen::Vector3d shift(ix * spacing_m, iy * spacing_m, 0.0);
      for (const GaussianComponent& c : room.components()) {
        GaussianComponent t;
        t.weight = c.weight * share;
        t.mean_m = centre + R * (c.mean_m - centre) + shift;
        t.cov_m2 = R * c.cov_m2 * R.transpose();
        t.cov_m2 = 0.5 * (t.cov_m2 + t.cov_m2.transpose());
        out.push_back(t);
      }
    }
  }
  return GmmMap(std::move(out), source);
}

double GmmMap::modelLogWeight(size_t i) const {
  return std::log(components_[i].weight) + log_weight_scale_;
}

double GmmMap::logDensity(const Eigen::Vector3d& p_map) const {
  // Log-sum-exp over all components, in double.
  double max_term = -std::numeric_limits<double>::infinity();
  std::vector<double> terms(components_.size());
  for (size_t i = 0; i < components_.size(); ++i) {
    const GaussianComponent& c = components_[i];
    const Eigen::Vector3d d = p_map - c.mean_m;
    const double q = d.dot(c.cov_m2.ldlt().solve(d));
    terms[i] = modelLogWeight(i) - 1.5 * kLog2Pi - 0.5 * std::log(c.cov_m2.determinant()) - 0.5 * q;
    max_term = std::max(max_term, terms[i]);
  }
  double sum = 0.0;
  for (double t : terms) sum += std::exp(t - max_term);
  return max_term + std::log(sum);
}

}  // namespace gmm_mcl
