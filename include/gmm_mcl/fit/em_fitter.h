// Expectation-maximisation for a full-covariance Gaussian mixture (the map builder's fitter).
//
// Same model and update rules as scikit-learn's GaussianMixture(covariance_type="full"):
// responsibilities from the current parameters (E-step), then weights, means and covariances
// from the responsibilities with reg_covar added to every covariance diagonal (M-step); stop
// when the mean log-likelihood per point changes by less than `tolerance` or after
// `max_iterations`. Initialisation: k-means++ seeding, optionally refined by Lloyd k-means, then
// one hard assignment of every point to its nearest mean gives the first weights and covariances
// (scikit-learn's init_params="kmeans"/"k-means++" do the same from their labels).
//
// Speed: the E-step evaluates, for each point, only the components whose prune_sigma ellipsoid
// bounding box overlaps the point's grid cell (points with none fall back to all M). A component
// left out lies more than prune_sigma standard deviations (Mahalanobis) away, so its density is
// below exp(-prune_sigma^2 / 2) of its own peak (6 sigma: 1.5e-8). prune_sigma = 0 evaluates all
// M components for every point (exact, as scikit-learn).
//
// Determinism: the points are split into a fixed number of chunks whose partial sums are reduced
// in chunk order, so a seed gives bit-identical maps for any OpenMP thread count.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gmm_mcl/fit/point_cloud.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

enum class EmInit {
  kKMeans,          // k-means++ seeding then kmeans_iterations Lloyd iterations (default)
  kKMeansPlusPlus,  // k-means++ seeding only
  kGivenMeans,      // EmParams::initial_means_m (e.g. to match another implementation)
};

constexpr int kDefaultMapComponents = 1000;
constexpr double kDefaultRegCovarM2 = 1e-6;   // scikit-learn's reg_covar default
constexpr double kDefaultEmTolerance = 1e-3;  // scikit-learn's tol default (nats per point)

struct EmParams {
  int components = kDefaultMapComponents;
  int max_iterations = 100;                  // EM iterations (scikit-learn max_iter)
  double tolerance = kDefaultEmTolerance;    // on the change of mean log-likelihood per point
  double reg_covar_m2 = kDefaultRegCovarM2;  // added to covariance diagonals (m^2)
  EmInit init = EmInit::kKMeans;
  int kmeans_iterations = 10;                    // Lloyd iterations after k-means++ (kKMeans)
  size_t kmeans_max_points = 500000;             // k-means on a seeded subsample above this size
  std::vector<Eigen::Vector3d> initial_means_m;  // kGivenMeans: exactly `components` means
  uint64_t seed = 1;
  double prune_sigma = 6.0;  // 0 = exact E-step over all components
  double cell_size_m = 0.0;  // pruning grid cell edge; 0 = automatic
  int chunks = 64;           // fixed reduction chunks (determinism)

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

struct EmIteration {
  int iteration = 0;                 // 1-based; 0 = the initialisation
  double mean_log_likelihood = 0.0;  // per point, nats (density per m^3), before this M-step
  double elapsed_s = 0.0;            // since the fit started
  double mean_candidates = 0.0;      // components evaluated per point (pruning effect)
};

struct EmResult {
  std::vector<GaussianComponent> components;
  int iterations = 0;
  bool converged = false;
  double final_mean_log_likelihood = 0.0;  // of the returned components on the training points
  double init_s = 0.0;                     // initialisation wall time
  double total_s = 0.0;                    // whole fit wall time
  int regularised_components = 0;  // covariances that needed more than reg_covar to stay SPD
  int empty_components = 0;        // components with (numerically) no points at the end
  std::vector<EmIteration> history;
};

using EmProgress = std::function<void(const EmIteration&)>;

// Fits. Throws FitError for invalid parameters, non-finite points, or fewer points than
// components. Degenerate (collinear, planar, repeated) clusters give regularised, valid
// components. The result passes GmmMap validation after float32 storage (see makeStorableMap).
EmResult fitGmm(const PointCloud& points, const EmParams& params,
                const EmProgress& progress = EmProgress());

// EM from given components instead of an initialisation (e.g. to reconcile the blocks of a
// block fit, block_fitter.h): the iterations, stopping rule, pruning and determinism of fitGmm;
// params' component count and initialisation fields are ignored, the weights are normalised.
// Throws FitError for invalid parameters, no points, non-finite points or components, or a
// non-positive weight.
EmResult refineGmm(const PointCloud& points, std::vector<GaussianComponent> initial,
                   const EmParams& params, const EmProgress& progress = EmProgress());

// Mean log-likelihood per point of a mixture on points (double). prune_sigma 0: exact, every
// component for every point; >= 3: the E-step's pruning (only components whose prune_sigma box
// overlaps the point's grid cell), for large maps.
double meanLogLikelihood(const std::vector<GaussianComponent>& components, const PointCloud& points,
                         double prune_sigma = 0.0);

// Builds a GmmMap whose covariances stay symmetric positive-definite after the map file's
// float32 rounding: any component whose rounded covariance fails a Cholesky test has its
// eigenvalues raised to at least max(reg_covar_m2, 1e-6 * largest). `repaired` counts them.
GmmMap makeStorableMap(const std::vector<GaussianComponent>& components, double reg_covar_m2,
                       const std::string& source, int* repaired = nullptr);

}  // namespace gmm_mcl
