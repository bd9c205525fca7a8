// Map inspection: summary statistics and k-sigma ellipsoid export (PLY mesh or CSV) for viewing.
#pragma once

#include <Eigen/Core>
#include <ostream>
#include <string>

#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

struct Stat {
  double min = 0.0, median = 0.0, max = 0.0, sum = 0.0;
};

struct MapSummary {
  size_t components = 0;
  Eigen::Vector3d mean_min_m = Eigen::Vector3d::Zero();  // bounds of the means
  Eigen::Vector3d mean_max_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d extent_min_m = Eigen::Vector3d::Zero();  // bounds of the 3-sigma boxes
  Eigen::Vector3d extent_max_m = Eigen::Vector3d::Zero();
  Stat weight;
  Stat volume_m3;    // 3-sigma ellipsoid volumes, 4/3 pi 27 sqrt(det Sigma)
  Stat sigma_min_m;  // smallest standard deviation (principal axis) per component
  Stat sigma_max_m;  // largest
  Stat condition;    // largest / smallest covariance eigenvalue
};

MapSummary summarizeMap(const GmmMap& map);
// Human-readable summary; `file_bytes` is printed when > 0.
void printMapSummary(const MapSummary& s, std::ostream& out, size_t file_bytes = 0);

struct EllipsoidExportParams {
  double sigma = 3.0;  // ellipsoid at this Mahalanobis radius
  int rings = 8;       // latitude bands of each ellipsoid mesh (PLY)
  int segments = 12;   // longitude segments (PLY)
  std::string validate() const;
};

// Binary little-endian PLY: one closed triangle mesh per component, coloured by weight (blue
// light, red heavy). Throws FitError naming the path on failure.
void writeEllipsoidsPly(const GmmMap& map, const std::string& path,
                        const EllipsoidExportParams& params = EllipsoidExportParams());
// CSV, one row per component: index, weight, mean, semi-axis lengths at `sigma` (largest first)
// and their unit axis directions, covariance upper triangle.
void writeEllipsoidsCsv(const GmmMap& map, const std::string& path,
                        const EllipsoidExportParams& params = EllipsoidExportParams());

// A map from a CSV file with a header row naming at least the columns weight, mean_x_m,
// mean_y_m, mean_z_m, cov_xx_m2, cov_xy_m2, cov_xz_m2, cov_yy_m2, cov_yz_m2, cov_zz_m2 (others
// are ignored: writeEllipsoidsCsv's files round-trip; scripts/sklearn_to_gmm_csv.py writes one
// from a scikit-learn GaussianMixture). Weights within 1e-3 of summing to 1 are renormalised.
// Throws FitError naming the file, the line and the fault; MapError for an invalid mixture.
GmmMap readMapCsv(const std::string& path);

}  // namespace gmm_mcl
