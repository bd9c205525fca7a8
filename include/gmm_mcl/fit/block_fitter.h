// Map building at scale: EM per spatial block, the blocks' borders reconciled by EM over all
// points (docs/map_builder.md, "Large maps").
//
// Split: a k-d tree cuts the cloud into `blocks` leaves of nearly equal point counts (each cut
// across the longest axis of its points' bounds, at the quantile that gives each side its share
// of leaves); a block's region is its leaf's box, half-open, unbounded at the cloud's outside.
// Block b gets M_b components in proportion to its points (largest remainders, sum M).
//
// Per block: fitGmm (k-means initialisation, then EM) on its own points, optionally plus a
// margin (the points of other blocks within margin_m of its region) with proportionally more
// components, so that components at its border see the points beyond it; it then keeps M_b of
// them: those whose mean lies in its own region (the heaviest if there are more, the nearest
// outside if fewer), each weighted by the points it stands for. Blocks run in parallel (OpenMP,
// one EM per thread).
//
// Reconcile: EM over all points from the merged components (refineGmm, pruned E-step: each point
// evaluates only the components near it) until the mean log-likelihood changes by less than
// em.tolerance or reconcile_iterations. This is what makes the borders right: measured on the
// Replica office (docs/map_builder.md), blocks without a margin and a converged reconciliation
// score as well on held-out points as the whole-map EM, and better than a margin with one
// reconciling iteration, in less time.
//
// Memory: the cloud, a permutation of it and, per thread, one block's EM (no points x components
// matrix anywhere); the reconciliation holds the points once more in double plus per-chunk sums
// of the M components' statistics (reconcile_chunks x M x 80 bytes).
// Determinism: a seed gives the same map for any thread count.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/point_cloud.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

constexpr int kDefaultBlockComponents = 250;      // automatic block count: M / this
constexpr double kDefaultMarginRadii = 3.0;       // automatic margin, in component radii
constexpr int kDefaultReconcileIterations = 100;  // a cap: the reconciliation stops converged
// `--blocks auto` fits per block above either size (the whole-map initialisation costs
// points x M per k-means iteration).
constexpr int kAutoBlocksAboveComponents = 5000;
constexpr size_t kAutoBlocksAbovePoints = 2000000;

struct BlockFitParams {
  EmParams em;     // em.components: the whole map's M; the rest: each block's EM and the seed
  int blocks = 0;  // 0 = automatic: ceil(M / components_per_block)
  int components_per_block = kDefaultBlockComponents;
  // Margin around each block's region (m); 0 = none. < 0: automatic, margin_radii times the
  // block's component radius (the median distance from its points to their k-th nearest
  // neighbour, k its points per component: the ball that holds one component's share of the
  // points).
  double margin_m = 0.0;
  double margin_radii = kDefaultMarginRadii;
  int block_iterations = 0;  // cap on each block's EM iterations; 0 = em.max_iterations
  // EM iterations over all points after merging (stopping earlier when converged, em.tolerance);
  // 0 = none.
  int reconcile_iterations = kDefaultReconcileIterations;
  int reconcile_chunks = 16;  // the reconciliation's fixed reduction chunks (memory: x M x 80 B)

  // Empty when valid, otherwise every fault found.
  std::string validate() const;
};

// The block count for `points` points that `--blocks auto` uses: 1 (whole-map EM) unless M or the
// point count exceeds the kAutoBlocksAbove* sizes, else ceil(M / components_per_block), at
// least 2.
int autoBlockCount(size_t points, const BlockFitParams& params);

struct BlockInfo {
  size_t own_points = 0;     // points in the block's region
  size_t margin_points = 0;  // points of other blocks within margin_m
  int components = 0;        // kept (M_b)
  int fitted_components = 0;
  double margin_m = 0.0;
  int iterations = 0;
  bool converged = false;
  double fit_s = 0.0;
  Eigen::Vector3d region_min_m, region_max_m;  // +-infinity at the cloud's outside
};

struct BlockFitResult {
  std::vector<GaussianComponent> components;  // M, weights summing to 1
  std::vector<BlockInfo> blocks;
  int kept_outside = 0;    // kept although the mean left its block's region (a block had < M_b)
  int dropped_inside = 0;  // dropped although inside (a block had more than M_b inside)
  EmResult reconcile;      // the global iterations (iterations 0 when none; no components)
  double final_mean_log_likelihood = 0.0;  // of the returned components on the points (pruned)
  double split_s = 0.0, blocks_s = 0.0, reconcile_s = 0.0, total_s = 0.0;
  int regularised_components = 0;  // over the blocks' EMs and the reconciliation
  int empty_components = 0;        // of the returned components
};

enum class BlockStage { kBlocks, kReconcile, kScore };

struct BlockProgress {
  BlockStage stage = BlockStage::kBlocks;
  int blocks_done = 0, blocks_total = 0;
  size_t points_done = 0, points_total = 0;  // own points of the blocks done
  int iteration = 0, iterations_total = 0;   // kReconcile
  double mean_log_likelihood = 0.0;          // kReconcile: before this iteration's M-step
  double elapsed_s = 0.0;                    // since the fit started
};

// Called after each block, each reconciliation iteration and before the final scoring, from one
// thread at a time.
using BlockProgressFn = std::function<void(const BlockProgress&)>;

// Fits M = params.em.components components. Throws FitError for invalid parameters, non-finite
// points, or fewer points than components. The result passes GmmMap validation after float32
// storage (makeStorableMap).
BlockFitResult fitGmmBlocks(const PointCloud& points, const BlockFitParams& params,
                            const BlockProgressFn& progress = BlockProgressFn());

}  // namespace gmm_mcl
