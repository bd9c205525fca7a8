// The map builder's EM initialisation: k-means++ seeding, Lloyd refinement and the first
// components from a hard assignment, with fixed work ranges (the same result for any thread
// count).
#include <omp.h>

#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <numeric>
#include <utility>

#include "em_internal.h"

namespace gmm_mcl {
namespace em_detail {
namespace {

struct Centers {
  std::vector<double> x, y, z;
  size_t size() const { return x.size(); }
};

// Index of the nearest center to a point (the first of equals); d2 is scratch for c.size()
// squared distances (the distances vectorise, the branch-free minimum too).
inline int nearest(const Centers& c, double px, double py, double pz, double* d2) {
  const size_t m = c.size();
  const double* cx = c.x.data();
  const double* cy = c.y.data();
  const double* cz = c.z.data();
  for (size_t k = 0; k < m; ++k) {
    const double dx = px - cx[k], dy = py - cy[k], dz = pz - cz[k];
    d2[k] = dx * dx + dy * dy + dz * dz;
  }
  // Eight independent minima (a dependency chain of one would bound the loop).
  double lane[8];
  for (int q = 0; q < 8; ++q) lane[q] = std::numeric_limits<double>::infinity();
  size_t k8 = 0;
  for (; k8 + 8 <= m; k8 += 8) {
    for (int q = 0; q < 8; ++q) lane[q] = std::min(lane[q], d2[k8 + q]);
  }
  for (; k8 < m; ++k8) lane[0] = std::min(lane[0], d2[k8]);
  double best = lane[0];
  for (int q = 1; q < 8; ++q) best = std::min(best, lane[q]);
  size_t k = 0;
  while (k + 1 < m && !(d2[k] <= best)) ++k;
  return static_cast<int>(k);
}

void assignAll(const PointsSoA& pts, const Centers& c, std::vector<int>* labels) {
  labels->resize(pts.size());
#pragma omp parallel
  {
    std::vector<double> d2(c.size());
#pragma omp for schedule(dynamic, 2048)
    for (long i = 0; i < static_cast<long>(pts.size()); ++i) {
      (*labels)[i] = nearest(c, pts.x[i], pts.y[i], pts.z[i], d2.data());
    }
  }
}

Centers kmeansPlusPlus(const PointsSoA& pts, size_t m, FitRandom* rng) {
  const size_t n = pts.size();
  Centers c;
  auto push = [&](size_t i) {
    c.x.push_back(pts.x[i]);
    c.y.push_back(pts.y[i]);
    c.z.push_back(pts.z[i]);
  };
  push(rng->below(n));
  std::vector<double> d2(n, std::numeric_limits<double>::infinity());
  const std::vector<size_t> bounds = splitEven(n, 64);
  const size_t parts = bounds.size() - 1;
  std::vector<double> part_sum(parts);
  for (size_t k = 1; k < m; ++k) {
    const double cx = c.x.back(), cy = c.y.back(), cz = c.z.back();
#pragma omp parallel for schedule(static)
    for (long p = 0; p < static_cast<long>(parts); ++p) {
      double s = 0.0;
      for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
        const double dx = pts.x[i] - cx, dy = pts.y[i] - cy, dz = pts.z[i] - cz;
        d2[i] = std::min(d2[i], dx * dx + dy * dy + dz * dz);
        s += d2[i];
      }
      part_sum[p] = s;
    }
    double total = 0.0;
    for (size_t p = 0; p < parts; ++p) total += part_sum[p];
    if (!(total > 0.0)) {  // every point coincides with a center: any point will do
      push(rng->below(n));
      continue;
    }
    double u = rng->uniform() * total;
    size_t p = 0;
    while (p + 1 < parts && u >= part_sum[p]) u -= part_sum[p++];
    size_t chosen = bounds[p + 1] - 1;
    for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
      if (u < d2[i]) {
        chosen = i;
        break;
      }
      u -= d2[i];
    }
    push(chosen);
  }
  return c;
}

// Per cluster k, W sums at [W k .. W k + W - 1]: add(i, t) adds point i's values to its
// cluster's t[0..W-1]. The fixed ranges' partial sums are added in order (the same sums for any
// thread count).
template <int W, typename AddPoint>
std::vector<double> labelledSums(size_t n, const std::vector<int>& labels, size_t m,
                                 const AddPoint& add) {
  const std::vector<size_t> bounds = splitEven(n, 64);
  const size_t parts = bounds.size() - 1;
  std::vector<double> sums(parts * m * W, 0.0);
#pragma omp parallel for schedule(static)
  for (long p = 0; p < static_cast<long>(parts); ++p) {
    double* s = sums.data() + static_cast<size_t>(p) * m * W;
    for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
      add(i, s + static_cast<size_t>(labels[i]) * W);
    }
  }
  std::vector<double> total(m * W, 0.0);
  for (size_t k = 0; k < m; ++k) {
    double* t = total.data() + k * W;
    for (size_t p = 0; p < parts; ++p) {
      for (int q = 0; q < W; ++q) t[q] += sums[(p * m + k) * W + q];
    }
  }
  return total;
}

// Per cluster k: its point count and coordinate sums at [4 k .. 4 k + 3].
std::vector<double> clusterSums(const PointsSoA& pts, const std::vector<int>& labels, size_t m) {
  return labelledSums<4>(pts.size(), labels, m, [&pts](size_t i, double* t) {
    t[0] += 1.0;
    t[1] += pts.x[i];
    t[2] += pts.y[i];
    t[3] += pts.z[i];
  });
}

void lloyd(const PointsSoA& pts, int iterations, Centers* c) {
  const size_t m = c->size();
  std::vector<int> labels, previous;
  for (int it = 0; it < iterations; ++it) {
    assignAll(pts, *c, &labels);
    if (labels == previous) break;
    previous = labels;
    const std::vector<double> sums = clusterSums(pts, labels, m);
    for (size_t k = 0; k < m; ++k) {
      const double* t = sums.data() + k * 4;
      if (t[0] > 0.0) {  // an empty cluster keeps its center
        c->x[k] = t[1] / t[0];
        c->y[k] = t[2] / t[0];
        c->z[k] = t[3] / t[0];
      }
    }
  }
}

// First weights and covariances from a hard assignment (scikit-learn _initialize with one-hot
// responsibilities): weight N_k / N, covariance about the cluster centroid plus reg. Means are
// the centroids, or `given` when set (scikit-learn means_init).
std::vector<GaussianComponent> initFromLabels(const PointsSoA& pts, const std::vector<int>& labels,
                                              size_t m, double reg, const Centers* given) {
  const std::vector<double> s1 = clusterSums(pts, labels, m);
  std::vector<Eigen::Vector3d> centroid(m);
  std::vector<double> count(m);
  for (size_t k = 0; k < m; ++k) {
    const double* t = s1.data() + k * 4;
    count[k] = t[0] + kNkFloor;
    centroid[k] = Eigen::Vector3d(t[1], t[2], t[3]) / count[k];
  }
  // Scatter about the centroid, upper triangle (xx, xy, xz, yy, yz, zz).
  const std::vector<double> s2 = labelledSums<6>(pts.size(), labels, m, [&](size_t i, double* t) {
    const Eigen::Vector3d& mu = centroid[labels[i]];
    const double d[3] = {pts.x[i] - mu.x(), pts.y[i] - mu.y(), pts.z[i] - mu.z()};
    for (int a = 0, q = 0; a < 3; ++a) {
      for (int b = a; b < 3; ++b, ++q) t[q] += d[a] * d[b];
    }
  });
  std::vector<GaussianComponent> comps(m);
  const double total = std::accumulate(count.begin(), count.end(), 0.0);
  for (size_t k = 0; k < m; ++k) {
    const double* t = s2.data() + k * 6;
    GaussianComponent& c = comps[k];
    c.weight = count[k] / total;
    c.mean_m = given ? Eigen::Vector3d(given->x[k], given->y[k], given->z[k]) : centroid[k];
    const double n = count[k];
    c.cov_m2 << t[0] / n, t[1] / n, t[2] / n, t[1] / n, t[3] / n, t[4] / n, t[2] / n, t[4] / n,
        t[5] / n;
    c.cov_m2.diagonal().array() += reg;
  }
  return comps;
}

PointsSoA subsample(const PointsSoA& pts, size_t count, FitRandom* rng) {
  std::vector<size_t> idx(pts.size());
  std::iota(idx.begin(), idx.end(), 0);
  for (size_t i = 0; i < count; ++i) std::swap(idx[i], idx[i + rng->below(idx.size() - i)]);
  idx.resize(count);
  std::sort(idx.begin(), idx.end());
  PointsSoA out;
  for (size_t i : idx) {
    out.x.push_back(pts.x[i]);
    out.y.push_back(pts.y[i]);
    out.z.push_back(pts.z[i]);
  }
  return out;
}

}  // namespace

PointsSoA toSoA(const PointCloud& cloud) {
  PointsSoA p;
  p.x.reserve(cloud.size());
  p.y.reserve(cloud.size());
  p.z.reserve(cloud.size());
  for (const auto& q : cloud) {
    p.x.push_back(q.x());
    p.y.push_back(q.y());
    p.z.push_back(q.z());
  }
  return p;
}

std::vector<GaussianComponent> initialComponents(const PointsSoA& all, size_t m,
                                                 const EmParams& params, FitRandom* rng) {
  std::vector<int> labels;
  if (params.init == EmInit::kGivenMeans) {
    Centers given;
    for (const auto& mu : params.initial_means_m) {
      given.x.push_back(mu.x());
      given.y.push_back(mu.y());
      given.z.push_back(mu.z());
    }
    assignAll(all, given, &labels);
    return initFromLabels(all, labels, m, params.reg_covar_m2, &given);
  }
  Centers centers;
  if (all.size() > params.kmeans_max_points) {
    const PointsSoA sub = subsample(all, params.kmeans_max_points, rng);
    centers = kmeansPlusPlus(sub, m, rng);
    if (params.init == EmInit::kKMeans) lloyd(sub, params.kmeans_iterations, &centers);
  } else {
    centers = kmeansPlusPlus(all, m, rng);
    if (params.init == EmInit::kKMeans) lloyd(all, params.kmeans_iterations, &centers);
  }
  assignAll(all, centers, &labels);
  return initFromLabels(all, labels, m, params.reg_covar_m2, nullptr);
}

}  // namespace em_detail
}  // namespace gmm_mcl
