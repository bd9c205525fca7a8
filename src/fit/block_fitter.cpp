#include "gmm_mcl/fit/block_fitter.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <sstream>
#include <utility>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/random.h"

namespace gmm_mcl {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr double kInf = std::numeric_limits<double>::infinity();
// Points sampled per block for its component radius (the automatic margin).
constexpr size_t kRadiusSamples = 16;

// A k-d tree node: its region, the range of the permutation its points occupy, and its cut.
struct Node {
  Eigen::Vector3d lo_m = Eigen::Vector3d::Constant(-kInf);  // region: lo <= p < hi
  Eigen::Vector3d hi_m = Eigen::Vector3d::Constant(kInf);
  size_t begin = 0, end = 0;
  int axis = -1;  // -1: a leaf
  double cut_m = 0.0;
  int left = -1, right = -1;
  int leaf = -1;  // block index of a leaf
};

struct KdTree {
  std::vector<Node> nodes;      // nodes[0] is the root
  std::vector<uint32_t> order;  // points, leaf after leaf
  std::vector<int> leaf_node;   // block b's node
};

// Cuts node `id` into `leaves` leaves (recursively, children appended).
void split(const PointCloud& pts, int id, int leaves, KdTree* tree) {
  if (leaves <= 1) {
    tree->nodes[id].leaf = static_cast<int>(tree->leaf_node.size());
    tree->leaf_node.push_back(id);
    return;
  }
  const size_t begin = tree->nodes[id].begin, end = tree->nodes[id].end;
  // The longest axis of the node's points (x when it has none).
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = -lo;
  for (size_t i = begin; i < end; ++i) {
    lo = lo.cwiseMin(pts[tree->order[i]]);
    hi = hi.cwiseMax(pts[tree->order[i]]);
  }
  int axis = 0;
  if (end > begin) (hi - lo).maxCoeff(&axis);
  // The cut at the quantile of the left side's share; points on the cut go right.
  const int left_leaves = leaves / 2;
  const size_t n = end - begin;
  const size_t q = begin + static_cast<size_t>(static_cast<double>(n) * left_leaves / leaves);
  auto coord = [&](uint32_t i) { return pts[i][axis]; };
  double cut = n > 0 ? static_cast<double>(lo[axis]) : 0.0;
  size_t mid = begin;
  if (n > 0) {
    auto* o = tree->order.data();
    if (q < end) {
      std::nth_element(o + begin, o + q, o + end,
                       [&](uint32_t a, uint32_t b) { return coord(a) < coord(b); });
      cut = coord(o[q]);
    } else {
      cut = static_cast<double>(hi[axis]) + 1.0;  // everything left
    }
    mid = static_cast<size_t>(
        std::partition(o + begin, o + end, [&](uint32_t i) { return coord(i) < cut; }) - o);
  }
  const Node parent = tree->nodes[id];
  Node l = parent, r = parent;
  l.end = r.begin = mid;
  l.hi_m[axis] = r.lo_m[axis] = cut;
  const int li = static_cast<int>(tree->nodes.size());
  tree->nodes.push_back(l);
  tree->nodes.push_back(r);
  tree->nodes[id].axis = axis;
  tree->nodes[id].cut_m = cut;
  tree->nodes[id].left = li;
  tree->nodes[id].right = li + 1;
  split(pts, li, left_leaves, tree);
  split(pts, li + 1, leaves - left_leaves, tree);
}

KdTree buildTree(const PointCloud& pts, int blocks) {
  KdTree tree;
  tree.order.resize(pts.size());
  std::iota(tree.order.begin(), tree.order.end(), 0u);
  Node root;
  root.end = pts.size();
  tree.nodes.push_back(root);
  split(pts, 0, blocks, &tree);
  return tree;
}

bool inRegion(const Node& n, const Eigen::Vector3d& p) {
  return (p.array() >= n.lo_m.array()).all() && (p.array() < n.hi_m.array()).all();
}

double distanceToRegion(const Node& n, const Eigen::Vector3d& p) {
  const Eigen::Vector3d below = (n.lo_m - p).cwiseMax(0.0);
  const Eigen::Vector3d above = (p - n.hi_m).cwiseMax(0.0);
  return (below + above).norm();
}

// Appends the points of leaves other than `self` inside [lo, hi] (closed) to *out.
void gatherMargin(const PointCloud& pts, const KdTree& tree, int id, int self,
                  const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, PointCloud* out) {
  const Node& n = tree.nodes[id];
  if (n.axis < 0) {
    if (id == self) return;
    for (size_t i = n.begin; i < n.end; ++i) {
      const Eigen::Vector3f& p = pts[tree.order[i]];
      const Eigen::Vector3d q = p.cast<double>();
      if ((q.array() >= lo.array()).all() && (q.array() <= hi.array()).all()) out->push_back(p);
    }
    return;
  }
  if (lo[n.axis] < n.cut_m) gatherMargin(pts, tree, n.left, self, lo, hi, out);
  if (hi[n.axis] >= n.cut_m) gatherMargin(pts, tree, n.right, self, lo, hi, out);
}

// The radius of the ball that holds one component's share of a block's points: the median over
// evenly spaced sample points of the distance to their k-th nearest neighbour in the block.
double componentRadius(const PointCloud& own, int components) {
  const size_t n = own.size();
  if (n < 2 || components < 1) return 0.0;
  const size_t k =
      std::min(n - 1, std::max<size_t>(1, (n + static_cast<size_t>(components) - 1) / components));
  const size_t samples = std::min(n, kRadiusSamples);
  std::vector<double> radius, d2(n);
  for (size_t s = 0; s < samples; ++s) {
    const Eigen::Vector3f& c = own[s * n / samples];
    for (size_t i = 0; i < n; ++i) d2[i] = static_cast<double>((own[i] - c).squaredNorm());
    std::nth_element(d2.begin(), d2.begin() + k, d2.end());  // d2[0] = 0 is the point itself
    radius.push_back(std::sqrt(d2[k]));
  }
  std::nth_element(radius.begin(), radius.begin() + radius.size() / 2, radius.end());
  return radius[radius.size() / 2];
}

// M components in proportion to the counts (largest remainders), none above a block's count
// (the floors never are: M <= the total count).
std::vector<int> allocate(const std::vector<size_t>& counts, int m) {
  const size_t b = counts.size();
  const double total = static_cast<double>(std::accumulate(counts.begin(), counts.end(), 0.0));
  std::vector<int> out(b, 0);
  std::vector<std::pair<double, size_t>> rest(b);
  int given = 0;
  for (size_t i = 0; i < b; ++i) {
    const double share = m * static_cast<double>(counts[i]) / total;
    out[i] = static_cast<int>(std::floor(share));
    rest[i] = {share - out[i], i};
    given += out[i];
  }
  std::stable_sort(rest.begin(), rest.end(),
                   [](const std::pair<double, size_t>& a, const std::pair<double, size_t>& c) {
                     return a.first > c.first;
                   });
  for (size_t j = 0; given < m; j = (j + 1) % b) {
    if (counts[rest[j].second] > static_cast<size_t>(out[rest[j].second])) {
      ++out[rest[j].second];
      ++given;
    }
  }
  return out;
}

uint64_t blockSeed(uint64_t seed, size_t block) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ull * (block + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

struct BlockOutput {
  std::vector<GaussianComponent> kept;
  int kept_outside = 0, dropped_inside = 0, regularised = 0;
};

// One block's EM and the components it keeps (weights: points they stand for / all points).
BlockOutput fitBlock(const PointCloud& pts, const KdTree& tree, int b, int m_b,
                     const BlockFitParams& params, BlockInfo* info) {
  const Clock::time_point t0 = Clock::now();
  BlockOutput out;
  const Node& node = tree.nodes[tree.leaf_node[b]];
  PointCloud local;
  local.reserve(node.end - node.begin);
  for (size_t i = node.begin; i < node.end; ++i) local.push_back(pts[tree.order[i]]);
  info->own_points = local.size();
  info->components = m_b;
  info->region_min_m = node.lo_m;
  info->region_max_m = node.hi_m;
  if (m_b == 0) return out;
  const double margin =
      params.margin_m >= 0.0 ? params.margin_m : params.margin_radii * componentRadius(local, m_b);
  info->margin_m = margin;
  if (margin > 0.0) {
    const Eigen::Vector3d grow = Eigen::Vector3d::Constant(margin);
    gatherMargin(pts, tree, 0, tree.leaf_node[b], node.lo_m - grow, node.hi_m + grow, &local);
  }
  info->margin_points = local.size() - info->own_points;
  const double scale = static_cast<double>(local.size()) / static_cast<double>(info->own_points);
  const int m_fit = static_cast<int>(std::min<double>(
      static_cast<double>(local.size()), std::max<double>(m_b, std::round(m_b * scale))));
  EmParams em = params.em;
  em.components = m_fit;
  if (params.block_iterations > 0) em.max_iterations = params.block_iterations;
  em.seed = blockSeed(params.em.seed, static_cast<size_t>(b));
  em.kmeans_max_points = std::max(em.kmeans_max_points, static_cast<size_t>(m_fit));
  EmResult fit = fitGmm(local, em);
  info->fitted_components = m_fit;
  info->iterations = fit.iterations;
  info->converged = fit.converged;
  out.regularised = fit.regularised_components;
  // Inside first (heaviest first), then outside (nearest first); the first m_b are kept.
  std::vector<std::pair<double, int>> inside, outside;
  for (int k = 0; k < m_fit; ++k) {
    const GaussianComponent& c = fit.components[k];
    if (inRegion(node, c.mean_m)) {
      inside.emplace_back(-c.weight, k);
    } else {
      outside.emplace_back(distanceToRegion(node, c.mean_m), k);
    }
  }
  std::sort(inside.begin(), inside.end());
  std::sort(outside.begin(), outside.end());
  std::vector<int> keep;
  for (const auto& e : inside) {
    if (static_cast<int>(keep.size()) < m_b) keep.push_back(e.second);
  }
  out.dropped_inside = static_cast<int>(inside.size()) - static_cast<int>(keep.size());
  for (const auto& e : outside) {
    if (static_cast<int>(keep.size()) >= m_b) break;
    keep.push_back(e.second);
    ++out.kept_outside;
  }
  std::sort(keep.begin(), keep.end());
  const double block_points = static_cast<double>(local.size());
  for (int k : keep) {
    GaussianComponent c = fit.components[k];
    c.weight = std::max(c.weight * block_points, std::numeric_limits<double>::min());
    out.kept.push_back(c);
  }
  info->fit_s = secondsSince(t0);
  return out;
}

}  // namespace

std::string BlockFitParams::validate() const {
  std::ostringstream err;
  const std::string em_fault = em.validate();
  if (!em_fault.empty()) err << em_fault << "; ";
  if (em.init == EmInit::kGivenMeans) err << "block fits take no initial means; ";
  if (blocks < 0) err << "blocks must be >= 0 (0 = automatic; got " << blocks << "); ";
  if (blocks > em.components) {
    err << "blocks (" << blocks << ") must not exceed the components (" << em.components << "); ";
  }
  if (components_per_block < 1) err << "components_per_block must be >= 1; ";
  if (!std::isfinite(margin_m)) err << "margin_m must be finite (< 0 = automatic); ";
  if (!(margin_radii >= 0.0) || !std::isfinite(margin_radii)) {
    err << "margin_radii must be finite and >= 0; ";
  }
  if (block_iterations < 0) err << "block_iterations must be >= 0 (0 = em.max_iterations); ";
  if (reconcile_iterations < 0) err << "reconcile_iterations must be >= 0; ";
  if (reconcile_chunks < 1) err << "reconcile_chunks must be >= 1; ";
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

int autoBlockCount(size_t points, const BlockFitParams& params) {
  const int m = params.em.components;
  if (m <= kAutoBlocksAboveComponents && points <= kAutoBlocksAbovePoints) return 1;
  const int per = std::max(1, params.components_per_block);
  return std::max(2, std::min(m, (m + per - 1) / per));
}

BlockFitResult fitGmmBlocks(const PointCloud& points, const BlockFitParams& params,
                            const BlockProgressFn& progress) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("block fit parameters: " + fault);
  size_t non_finite = 0;
  for (const auto& p : points) non_finite += p.allFinite() ? 0 : 1;
  if (non_finite > 0) {
    throw FitError("EM: " + std::to_string(non_finite) + " of " + std::to_string(points.size()) +
                   " points are NaN or Inf (drop them first)");
  }
  const int m = params.em.components;
  if (points.size() < static_cast<size_t>(m)) {
    throw FitError("EM: " + std::to_string(points.size()) + " points are fewer than the " +
                   std::to_string(m) + " components requested");
  }
  if (points.size() > std::numeric_limits<uint32_t>::max()) {
    throw FitError("block fit: more than 2^32 points");
  }
  const Clock::time_point t0 = Clock::now();
  const int blocks = params.blocks > 0
                         ? params.blocks
                         : std::max(1, std::min(m, (m + params.components_per_block - 1) /
                                                       params.components_per_block));
  BlockFitResult result;
  const KdTree tree = buildTree(points, blocks);
  std::vector<size_t> counts(blocks);
  for (int b = 0; b < blocks; ++b) {
    const Node& n = tree.nodes[tree.leaf_node[b]];
    counts[b] = n.end - n.begin;
  }
  const std::vector<int> m_b = allocate(counts, m);
  result.split_s = secondsSince(t0);

  // Blocks in parallel, largest first; each EM on one thread (results by block index).
  result.blocks.resize(blocks);
  std::vector<BlockOutput> outputs(blocks);
  std::vector<int> schedule(blocks);
  std::iota(schedule.begin(), schedule.end(), 0);
  std::stable_sort(schedule.begin(), schedule.end(),
                   [&](int a, int b) { return counts[a] > counts[b]; });
  std::vector<std::string> errors(blocks);
  BlockProgress state;
  state.blocks_total = blocks;
  state.points_total = points.size();
  const int levels = omp_get_max_active_levels();
  omp_set_max_active_levels(1);
#pragma omp parallel for schedule(dynamic, 1)
  for (int s = 0; s < blocks; ++s) {
    const int b = schedule[s];
    try {
      outputs[b] = fitBlock(points, tree, b, m_b[b], params, &result.blocks[b]);
    } catch (const std::exception& e) {
      errors[b] = e.what();
    }
#pragma omp critical(gmm_mcl_block_progress)
    {
      ++state.blocks_done;
      state.points_done += counts[b];
      state.elapsed_s = secondsSince(t0);
      if (progress) progress(state);
    }
  }
  omp_set_max_active_levels(levels);
  for (int b = 0; b < blocks; ++b) {
    if (!errors[b].empty()) throw FitError("block " + std::to_string(b) + ": " + errors[b]);
  }
  std::vector<GaussianComponent> comps;
  comps.reserve(m);
  int regularised = 0;
  for (int b = 0; b < blocks; ++b) {
    const BlockOutput& o = outputs[b];
    comps.insert(comps.end(), o.kept.begin(), o.kept.end());
    result.kept_outside += o.kept_outside;
    result.dropped_inside += o.dropped_inside;
    regularised += o.regularised;
  }
  outputs.clear();
  double weight_sum = 0.0;
  for (const auto& c : comps) weight_sum += c.weight;
  for (auto& c : comps) c.weight /= weight_sum;
  result.blocks_s = secondsSince(t0) - result.split_s;

  // Reconciliation: EM iterations over all points from the merged components.
  const Clock::time_point t1 = Clock::now();
  if (params.reconcile_iterations > 0) {
    EmParams em = params.em;
    em.max_iterations = params.reconcile_iterations;
    em.chunks = params.reconcile_chunks;
    EmProgress each;
    if (progress) {
      each = [&](const EmIteration& it) {
        BlockProgress p = state;
        p.stage = BlockStage::kReconcile;
        p.iteration = it.iteration;
        p.iterations_total = params.reconcile_iterations;
        p.mean_log_likelihood = it.mean_log_likelihood;
        p.elapsed_s = secondsSince(t0);
        progress(p);
      };
    }
    result.reconcile = refineGmm(points, std::move(comps), em, each);
    comps = std::move(result.reconcile.components);
    result.reconcile.components.clear();
    result.final_mean_log_likelihood = result.reconcile.final_mean_log_likelihood;
    regularised += result.reconcile.regularised_components;
  } else {
    if (progress) {
      BlockProgress p = state;
      p.stage = BlockStage::kScore;
      p.elapsed_s = secondsSince(t0);
      progress(p);
    }
    const double prune = params.em.prune_sigma > 0.0 ? params.em.prune_sigma : 0.0;
    result.final_mean_log_likelihood = meanLogLikelihood(comps, points, prune);
  }
  result.reconcile_s = secondsSince(t1);
  result.regularised_components = regularised;
  const double n = static_cast<double>(points.size());
  for (const auto& c : comps) result.empty_components += (c.weight * n < 1e-6) ? 1 : 0;
  result.components = std::move(comps);
  result.total_s = secondsSince(t0);
  return result;
}

}  // namespace gmm_mcl
