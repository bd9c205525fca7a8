// Spatial Gaussian-mixture map of the environment (paper Eq. gmm), in the map frame, metres.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "gmm_mcl/common/types.h"
#include "gmm_mcl/map/component_grid.h"

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

// The mapped surface (m^2) that the model's densities are normalised to (docs/building_scale.md):
// a mixture's weights sum to 1 over the whole map, so a room inside a map of a building would
// score ln(building / room) per pixel lower than in a map of the room alone. The model weighs
// component i by lambda_i * A / kReferenceSurfaceAreaM2 instead, A being the map's own mapped
// surface (estimateSurfaceArea): densities per cubic metre as if the map held this much surface,
// whatever it holds outside the view. About one room, so one-room maps score as they did.
constexpr double kReferenceSurfaceAreaM2 = 100.0;

// Tolerance on |sum of weights - 1| accepted from a map (float32 storage of ~1000 weights).
constexpr double kWeightSumTolerance = 1e-4;
// Relative tolerance on |Sigma - Sigma^T| accepted from in-memory components.
constexpr double kSymmetryTolerance = 1e-9;

class GmmMap {
 public:
  GmmMap() = default;

  // Validates and precomputes; throws MapError naming `source` and the fault. surface_area_m2 > 0
  // sets the mapped surface instead of estimating it (a map derived from another, such as one
  // blurred for a coarse search, keeps the original's weights).
  explicit GmmMap(std::vector<GaussianComponent> components, const std::string& source = "<memory>",
                  double surface_area_m2 = 0.0);

  size_t size() const { return components_.size(); }
  bool empty() const { return components_.empty(); }
  const std::vector<GaussianComponent>& components() const { return components_; }
  // Backend layout with precision and log-normaliser precomputed (float32).
  const std::vector<ComponentF>& packed() const { return packed_; }
  // Extent of the 3-sigma ellipsoid of component i along each map axis (m).
  const Eigen::Vector3d& threeSigmaHalfExtent(size_t i) const { return half_extent_m_[i]; }
  // The 3-sigma boxes of the components in a sparse grid (the view's candidates).
  const ComponentGrid& grid() const { return grid_; }
  // The box of component i's 3-sigma extent along the map axes (m).
  Box3 threeSigmaBox(size_t i) const;
  // Mapped surface A (m^2, estimateSurfaceArea) and ln(A / kReferenceSurfaceAreaM2), the term
  // that every component's log-weight carries in the model (packed(), logDensity()).
  double surfaceArea() const { return surface_area_m2_; }
  double logWeightScale() const { return log_weight_scale_; }
  // ln of component i's weight in the model: ln(lambda_i) + logWeightScale().
  double modelLogWeight(size_t i) const;
  // Axis-aligned bounds of all means (m).
  const Eigen::Vector3d& minBound() const { return min_bound_m_; }
  const Eigen::Vector3d& maxBound() const { return max_bound_m_; }

  // ln of the model's density at a map-frame point (double, all components; the surface-
  // normalised weights of modelLogWeight).
  double logDensity(const Eigen::Vector3d& p_map) const;

 private:
  std::vector<GaussianComponent> components_;
  std::vector<ComponentF> packed_;
  std::vector<Eigen::Vector3d> half_extent_m_;
  Eigen::Vector3d min_bound_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_bound_m_ = Eigen::Vector3d::Zero();
  double surface_area_m2_ = kReferenceSurfaceAreaM2;
  double log_weight_scale_ = 0.0;
  ComponentGrid grid_;
};

// The mapped surface of a mixture fitted to points spread over surfaces (m^2): each component
// covers about 4 pi sqrt(s1 s2) of surface (s1, s2 its two largest variances: a uniform disc of
// radius r has s = r^2 / 4), so weight / area is the density of the points on the surface; A is
// the weight-weighted median over the components of area / weight. Exact for a mixture tiled
// from copies of one (each copy's weights divided by the number of copies), robust to a few
// odd components (a ground plane, a needle), and for a uniformly sampled surface the sum of
// the areas.
double estimateSurfaceArea(const std::vector<GaussianComponent>& components);

// A building of copies of one map (the cost and invariance case: its rooms are identical): the
// copy (ix, iy) of nx x ny moved by (ix, iy) * spacing_m in x and y and turned by 90 degrees
// (ix + iy) times about the centre of the map's bounds, every weight divided by nx * ny.
GmmMap tiledMap(const GmmMap& room, int nx, int ny, double spacing_m,
                const std::string& source = "<tiled>");

// The mixture with the components whose means fall in one cube of the grid of edge cell_m
// (cubes from the origin) merged into one by moment matching: the cube's total weight, and the
// mean and covariance of its components' mixture. Mass, mean and covariance of every cube are
// kept; the shape within a cube is lost. A coarser map for a coarse search (a lost redraw's
// blurred stage). Merged components come in the order of each cube's first component.
std::vector<GaussianComponent> mergedByCell(const std::vector<GaussianComponent>& components,
                                            double cell_m);

// Throws MapError if the components do not form a valid mixture (names `source` and the fault).
void validateComponents(const std::vector<GaussianComponent>& components,
                        const std::string& source);

}  // namespace gmm_mcl
