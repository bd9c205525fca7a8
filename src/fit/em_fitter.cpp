#include "gmm_mcl/fit/em_fitter.h"

#include <omp.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/random.h"

namespace gmm_mcl {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;
// scikit-learn adds 10 * machine epsilon to every component's responsibility sum.
constexpr double kNkFloor = 10.0 * std::numeric_limits<double>::epsilon();
// Responsibilities below this are not accumulated (their effect is below double rounding of a
// component's sums).
constexpr double kMinResponsibility = 1e-12;
// Statistics accumulated per component: N, S1 (3), S2 upper triangle (6).
constexpr int kStats = 10;
// Pruning grid: at most this many occupied cells times components box tests per iteration.
constexpr double kMaxCellTests = 4e8;

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Points in structure-of-arrays double layout.
struct PointsSoA {
  std::vector<double> x, y, z;
  size_t size() const { return x.size(); }
};

// One component ready for evaluation: mean, inverse of the covariance's Cholesky factor
// (lower triangular, L^-1), and ln(weight) - 1.5 ln(2 pi) - 0.5 ln det(Sigma).
struct EvalSoA {
  std::vector<double> mx, my, mz, a00, a10, a11, a20, a21, a22, log_norm;
  void resize(size_t n) {
    for (auto* v : {&mx, &my, &mz, &a00, &a10, &a11, &a20, &a21, &a22, &log_norm}) v->resize(n);
  }
};

// Fixed ranges of work whose partial sums are added in order (determinism for any thread count).
std::vector<size_t> splitEven(size_t n, int parts) {
  const size_t p = std::max<size_t>(1, std::min<size_t>(static_cast<size_t>(parts), n));
  std::vector<size_t> bounds(p + 1);
  for (size_t i = 0; i <= p; ++i) bounds[i] = n * i / p;
  return bounds;
}

// Cholesky of a covariance with extra diagonal loading when it is not numerically SPD.
// Returns L (lower); *loaded is set when loading was needed.
Eigen::Matrix3d robustCholesky(Eigen::Matrix3d* cov, double reg, bool* loaded) {
  *loaded = false;
  double jitter = std::max(reg, 1e-12);
  for (int attempt = 0; attempt < 30; ++attempt) {
    Eigen::LLT<Eigen::Matrix3d> llt(*cov);
    if (llt.info() == Eigen::Success) {
      const Eigen::Matrix3d L = llt.matrixL();
      if (L.diagonal().minCoeff() > 0.0 && L.allFinite()) return L;
    }
    *loaded = true;
    cov->diagonal().array() += jitter;
    jitter *= 10.0;
  }
  throw FitError("EM: covariance could not be made positive-definite (non-finite values?)");
}

struct Model {
  std::vector<GaussianComponent> comps;
  EvalSoA eval;
  std::vector<Eigen::Vector3d> half_extent_1sigma_m;  // sqrt(diag Sigma)
  int loaded = 0;

  // Completes eval data from comps (covariances may receive diagonal loading).
  void prepare(double reg) {
    const size_t m = comps.size();
    eval.resize(m);
    half_extent_1sigma_m.resize(m);
    loaded = 0;
    for (size_t k = 0; k < m; ++k) {
      GaussianComponent& c = comps[k];
      c.cov_m2 = 0.5 * (c.cov_m2 + c.cov_m2.transpose());
      bool was_loaded = false;
      const Eigen::Matrix3d L = robustCholesky(&c.cov_m2, reg, &was_loaded);
      loaded += was_loaded ? 1 : 0;
      const Eigen::Matrix3d A = L.triangularView<Eigen::Lower>().solve(Eigen::Matrix3d::Identity());
      eval.mx[k] = c.mean_m.x();
      eval.my[k] = c.mean_m.y();
      eval.mz[k] = c.mean_m.z();
      eval.a00[k] = A(0, 0);
      eval.a10[k] = A(1, 0);
      eval.a11[k] = A(1, 1);
      eval.a20[k] = A(2, 0);
      eval.a21[k] = A(2, 1);
      eval.a22[k] = A(2, 2);
      const double half_log_det = L.diagonal().array().log().sum();
      eval.log_norm[k] = std::log(c.weight) - 1.5 * kLog2Pi - half_log_det;
      half_extent_1sigma_m[k] = c.cov_m2.diagonal().cwiseSqrt();
    }
  }
};

// Uniform grid over the points, points sorted by cell; per iteration each occupied cell gets the
// list of components whose prune box overlaps it.
struct PruneGrid {
  bool exact = true;
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  double cell_m = 1.0;
  std::vector<size_t> cell_begin;           // occupied cell c holds sorted points [b[c], b[c+1])
  std::vector<Eigen::Vector3i> cell_index;  // integer cell coordinates of occupied cell c
  std::vector<size_t> cand_begin;           // candidates of cell c: cand[cand_begin[c]..]
  std::vector<int> cand;
  std::vector<size_t> chunk_cells;  // chunk i holds cells [chunk_cells[i], [i+1])

  size_t cellCount() const { return cell_index.size(); }
};

// Sorts points into grid cells (stable, deterministic) and returns the permuted SoA.
PointsSoA buildGrid(const PointCloud& cloud, double cell_m, int chunks, PruneGrid* grid) {
  const size_t n = cloud.size();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& p : cloud) lo = lo.cwiseMin(p.cast<double>());
  grid->origin_m = lo;
  grid->cell_m = cell_m;
  std::vector<std::pair<uint64_t, uint32_t>> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d q = (cloud[i].cast<double>() - lo) / cell_m;
    const uint64_t cx = static_cast<uint64_t>(q.x()), cy = static_cast<uint64_t>(q.y()),
                   cz = static_cast<uint64_t>(q.z());
    keyed[i] = {(cx << 42) | (cy << 21) | cz, static_cast<uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  PointsSoA pts;
  pts.x.resize(n);
  pts.y.resize(n);
  pts.z.resize(n);
  grid->cell_begin.clear();
  grid->cell_index.clear();
  for (size_t i = 0; i < n; ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first) {
      grid->cell_begin.push_back(i);
      const uint64_t k = keyed[i].first;
      grid->cell_index.emplace_back(static_cast<int>(k >> 42),
                                    static_cast<int>((k >> 21) & 0x1FFFFF),
                                    static_cast<int>(k & 0x1FFFFF));
    }
    const Eigen::Vector3f& p = cloud[keyed[i].second];
    pts.x[i] = p.x();
    pts.y[i] = p.y();
    pts.z[i] = p.z();
  }
  grid->cell_begin.push_back(n);
  // Chunks of whole cells with about n / chunks points each.
  grid->chunk_cells.assign(1, 0);
  const size_t target = std::max<size_t>(1, n / static_cast<size_t>(std::max(1, chunks)));
  size_t acc = 0;
  for (size_t c = 0; c < grid->cellCount(); ++c) {
    acc += grid->cell_begin[c + 1] - grid->cell_begin[c];
    if (acc >= target) {
      grid->chunk_cells.push_back(c + 1);
      acc = 0;
    }
  }
  if (grid->chunk_cells.back() != grid->cellCount()) grid->chunk_cells.push_back(grid->cellCount());
  return pts;
}

void updateCandidates(const Model& model, double prune_sigma, PruneGrid* grid) {
  const size_t m = model.comps.size();
  const size_t cells = grid->cellCount();
  std::vector<double> lo(3 * m), hi(3 * m);
  for (size_t k = 0; k < m; ++k) {
    for (int a = 0; a < 3; ++a) {
      const double e = prune_sigma * model.half_extent_1sigma_m[k][a];
      lo[3 * k + a] = (model.comps[k].mean_m[a] - e - grid->origin_m[a]) / grid->cell_m;
      hi[3 * k + a] = (model.comps[k].mean_m[a] + e - grid->origin_m[a]) / grid->cell_m;
    }
  }
  std::vector<size_t> count(cells + 1, 0);
  auto overlaps = [&](size_t c, size_t k) {
    const Eigen::Vector3i& ci = grid->cell_index[c];
    for (int a = 0; a < 3; ++a) {
      if (hi[3 * k + a] < ci[a] || lo[3 * k + a] > ci[a] + 1.0) return false;
    }
    return true;
  };
#pragma omp parallel for schedule(static)
  for (long c = 0; c < static_cast<long>(cells); ++c) {
    size_t n = 0;
    for (size_t k = 0; k < m; ++k) n += overlaps(c, k) ? 1 : 0;
    count[c + 1] = n;
  }
  grid->cand_begin.assign(cells + 1, 0);
  for (size_t c = 0; c < cells; ++c) grid->cand_begin[c + 1] = grid->cand_begin[c] + count[c + 1];
  grid->cand.resize(grid->cand_begin[cells]);
#pragma omp parallel for schedule(static)
  for (long c = 0; c < static_cast<long>(cells); ++c) {
    size_t out = grid->cand_begin[c];
    for (size_t k = 0; k < m; ++k) {
      if (overlaps(c, k)) grid->cand[out++] = static_cast<int>(k);
    }
  }
}

struct EStepResult {
  double sum_log_likelihood = 0.0;
  double evaluations = 0.0;
};

// E-step over all points; when `acc` is given, also accumulates the M-step statistics relative
// to each component's current mean into acc (chunk-major: chunks x M x kStats), summed by the
// caller in chunk order.
EStepResult eStep(const PointsSoA& pts, const Model& model, const PruneGrid& grid,
                  std::vector<double>* acc) {
  const size_t m = model.comps.size();
  const size_t chunks = grid.chunk_cells.size() - 1;
  std::vector<double> chunk_ll(chunks, 0.0), chunk_evals(chunks, 0.0);
  if (acc) acc->assign(chunks * m * kStats, 0.0);
  std::vector<int> all(m);
  std::iota(all.begin(), all.end(), 0);
  const EvalSoA& ev = model.eval;

#pragma omp parallel
  {
    EvalSoA local;
    local.resize(m);
    std::vector<double> t(m);
#pragma omp for schedule(dynamic, 1)
    for (long ch = 0; ch < static_cast<long>(chunks); ++ch) {
      double* a = acc ? acc->data() + static_cast<size_t>(ch) * m * kStats : nullptr;
      double ll = 0.0, evals = 0.0;
      for (size_t c = grid.chunk_cells[ch]; c < grid.chunk_cells[ch + 1]; ++c) {
        const int* cand = all.data();
        size_t nc = m;
        if (!grid.exact && grid.cand_begin[c + 1] > grid.cand_begin[c]) {
          cand = grid.cand.data() + grid.cand_begin[c];
          nc = grid.cand_begin[c + 1] - grid.cand_begin[c];
        }
        for (size_t j = 0; j < nc; ++j) {
          const int k = cand[j];
          local.mx[j] = ev.mx[k];
          local.my[j] = ev.my[k];
          local.mz[j] = ev.mz[k];
          local.a00[j] = ev.a00[k];
          local.a10[j] = ev.a10[k];
          local.a11[j] = ev.a11[k];
          local.a20[j] = ev.a20[k];
          local.a21[j] = ev.a21[k];
          local.a22[j] = ev.a22[k];
          local.log_norm[j] = ev.log_norm[k];
        }
        const double* mx = local.mx.data();
        const double* my = local.my.data();
        const double* mz = local.mz.data();
        const double* a00 = local.a00.data();
        const double* a10 = local.a10.data();
        const double* a11 = local.a11.data();
        const double* a20 = local.a20.data();
        const double* a21 = local.a21.data();
        const double* a22 = local.a22.data();
        const double* ln = local.log_norm.data();
        double* tp = t.data();
        const size_t p_end = grid.cell_begin[c + 1];
        for (size_t i = grid.cell_begin[c]; i < p_end; ++i) {
          const double px = pts.x[i], py = pts.y[i], pz = pts.z[i];
          double tmax = -std::numeric_limits<double>::infinity();
#pragma omp simd reduction(max : tmax)
          for (size_t j = 0; j < nc; ++j) {
            const double dx = px - mx[j], dy = py - my[j], dz = pz - mz[j];
            const double y0 = a00[j] * dx;
            const double y1 = a10[j] * dx + a11[j] * dy;
            const double y2 = a20[j] * dx + a21[j] * dy + a22[j] * dz;
            const double v = ln[j] - 0.5 * (y0 * y0 + y1 * y1 + y2 * y2);
            tp[j] = v;
            tmax = std::max(tmax, v);
          }
          double s = 0.0;
          for (size_t j = 0; j < nc; ++j) {
            tp[j] = std::exp(tp[j] - tmax);
            s += tp[j];
          }
          ll += tmax + std::log(s);
          evals += static_cast<double>(nc);
          if (!a) continue;
          const double inv_s = 1.0 / s;
          for (size_t j = 0; j < nc; ++j) {
            const double r = tp[j] * inv_s;
            if (r < kMinResponsibility) continue;
            const double dx = px - mx[j], dy = py - my[j], dz = pz - mz[j];
            double* st = a + static_cast<size_t>(cand[j]) * kStats;
            const double rx = r * dx, ry = r * dy, rz = r * dz;
            st[0] += r;
            st[1] += rx;
            st[2] += ry;
            st[3] += rz;
            st[4] += rx * dx;
            st[5] += rx * dy;
            st[6] += rx * dz;
            st[7] += ry * dy;
            st[8] += ry * dz;
            st[9] += rz * dz;
          }
        }
      }
      chunk_ll[ch] = ll;
      chunk_evals[ch] = evals;
    }
  }
  EStepResult out;
  for (size_t ch = 0; ch < chunks; ++ch) {
    out.sum_log_likelihood += chunk_ll[ch];
    out.evaluations += chunk_evals[ch];
  }
  return out;
}

// M-step from chunk partial statistics (relative to the current means).
void mStep(const std::vector<double>& acc, size_t chunks, size_t n_points, double reg,
           Model* model) {
  const size_t m = model->comps.size();
  std::vector<double> nk(m);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < static_cast<long>(m); ++k) {
    double s[kStats] = {0};
    for (size_t ch = 0; ch < chunks; ++ch) {
      const double* a = acc.data() + (ch * m + static_cast<size_t>(k)) * kStats;
      for (int q = 0; q < kStats; ++q) s[q] += a[q];
    }
    const double n = s[0] + kNkFloor;
    nk[k] = n;
    const Eigen::Vector3d d(s[1] / n, s[2] / n, s[3] / n);
    Eigen::Matrix3d cov;
    cov << s[4] / n, s[5] / n, s[6] / n, s[5] / n, s[7] / n, s[8] / n, s[6] / n, s[8] / n, s[9] / n;
    cov -= d * d.transpose();
    cov.diagonal().array() += reg;
    GaussianComponent& c = model->comps[k];
    c.mean_m += d;
    c.cov_m2 = cov;
  }
  double total = 0.0;
  for (size_t k = 0; k < m; ++k) total += nk[k];
  (void)n_points;
  for (size_t k = 0; k < m; ++k) model->comps[k].weight = nk[k] / total;
}

// ---- initialisation ---------------------------------------------------------------------------

struct Centers {
  std::vector<double> x, y, z;
  size_t size() const { return x.size(); }
};

// Index of the nearest center to point i, and its squared distance.
inline int nearest(const Centers& c, double px, double py, double pz, double* d2_out) {
  int best = 0;
  double bd = std::numeric_limits<double>::infinity();
  const size_t m = c.size();
  for (size_t k = 0; k < m; ++k) {
    const double dx = px - c.x[k], dy = py - c.y[k], dz = pz - c.z[k];
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < bd) {
      bd = d2;
      best = static_cast<int>(k);
    }
  }
  if (d2_out) *d2_out = bd;
  return best;
}

void assignAll(const PointsSoA& pts, const Centers& c, std::vector<int>* labels) {
  labels->resize(pts.size());
#pragma omp parallel for schedule(dynamic, 2048)
  for (long i = 0; i < static_cast<long>(pts.size()); ++i) {
    (*labels)[i] = nearest(c, pts.x[i], pts.y[i], pts.z[i], nullptr);
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

void lloyd(const PointsSoA& pts, int iterations, Centers* c) {
  const size_t m = c->size();
  std::vector<int> labels, previous;
  const std::vector<size_t> bounds = splitEven(pts.size(), 64);
  const size_t parts = bounds.size() - 1;
  std::vector<double> sums(parts * m * 4);
  for (int it = 0; it < iterations; ++it) {
    assignAll(pts, *c, &labels);
    if (labels == previous) break;
    previous = labels;
    std::fill(sums.begin(), sums.end(), 0.0);
#pragma omp parallel for schedule(static)
    for (long p = 0; p < static_cast<long>(parts); ++p) {
      double* s = sums.data() + static_cast<size_t>(p) * m * 4;
      for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
        double* t = s + static_cast<size_t>(labels[i]) * 4;
        t[0] += 1.0;
        t[1] += pts.x[i];
        t[2] += pts.y[i];
        t[3] += pts.z[i];
      }
    }
    for (size_t k = 0; k < m; ++k) {
      double t[4] = {0, 0, 0, 0};
      for (size_t p = 0; p < parts; ++p) {
        for (int q = 0; q < 4; ++q) t[q] += sums[(p * m + k) * 4 + q];
      }
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
void initFromLabels(const PointsSoA& pts, const std::vector<int>& labels, size_t m, double reg,
                    const Centers* given, Model* model) {
  const std::vector<size_t> bounds = splitEven(pts.size(), 64);
  const size_t parts = bounds.size() - 1;
  std::vector<double> s1(parts * m * 4, 0.0);
#pragma omp parallel for schedule(static)
  for (long p = 0; p < static_cast<long>(parts); ++p) {
    double* s = s1.data() + static_cast<size_t>(p) * m * 4;
    for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
      double* t = s + static_cast<size_t>(labels[i]) * 4;
      t[0] += 1.0;
      t[1] += pts.x[i];
      t[2] += pts.y[i];
      t[3] += pts.z[i];
    }
  }
  std::vector<Eigen::Vector3d> centroid(m);
  std::vector<double> count(m);
  for (size_t k = 0; k < m; ++k) {
    double t[4] = {0, 0, 0, 0};
    for (size_t p = 0; p < parts; ++p) {
      for (int q = 0; q < 4; ++q) t[q] += s1[(p * m + k) * 4 + q];
    }
    count[k] = t[0] + kNkFloor;
    centroid[k] = Eigen::Vector3d(t[1], t[2], t[3]) / count[k];
  }
  std::vector<double> s2(parts * m * 6, 0.0);
#pragma omp parallel for schedule(static)
  for (long p = 0; p < static_cast<long>(parts); ++p) {
    double* s = s2.data() + static_cast<size_t>(p) * m * 6;
    for (size_t i = bounds[p]; i < bounds[p + 1]; ++i) {
      const Eigen::Vector3d& mu = centroid[labels[i]];
      const double dx = pts.x[i] - mu.x(), dy = pts.y[i] - mu.y(), dz = pts.z[i] - mu.z();
      double* t = s + static_cast<size_t>(labels[i]) * 6;
      t[0] += dx * dx;
      t[1] += dx * dy;
      t[2] += dx * dz;
      t[3] += dy * dy;
      t[4] += dy * dz;
      t[5] += dz * dz;
    }
  }
  model->comps.assign(m, GaussianComponent());
  const double total = std::accumulate(count.begin(), count.end(), 0.0);
  for (size_t k = 0; k < m; ++k) {
    double t[6] = {0, 0, 0, 0, 0, 0};
    for (size_t p = 0; p < parts; ++p) {
      for (int q = 0; q < 6; ++q) t[q] += s2[(p * m + k) * 6 + q];
    }
    GaussianComponent& c = model->comps[k];
    c.weight = count[k] / total;
    c.mean_m = given ? Eigen::Vector3d(given->x[k], given->y[k], given->z[k]) : centroid[k];
    const double n = count[k];
    c.cov_m2 << t[0] / n, t[1] / n, t[2] / n, t[1] / n, t[3] / n, t[4] / n, t[2] / n, t[4] / n,
        t[5] / n;
    c.cov_m2.diagonal().array() += reg;
  }
}

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

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

std::string EmParams::validate() const {
  std::ostringstream err;
  if (components < 1) err << "components must be >= 1 (got " << components << "); ";
  if (max_iterations < 1) err << "max_iterations must be >= 1 (got " << max_iterations << "); ";
  if (!(tolerance >= 0.0)) err << "tolerance must be >= 0 (got " << tolerance << "); ";
  if (!(reg_covar_m2 >= 0.0) || !std::isfinite(reg_covar_m2)) {
    err << "reg_covar_m2 must be finite and >= 0 (got " << reg_covar_m2 << "); ";
  }
  if (kmeans_iterations < 0) err << "kmeans_iterations must be >= 0; ";
  if (kmeans_max_points < static_cast<size_t>(std::max(components, 1))) {
    err << "kmeans_max_points must be >= components; ";
  }
  if (init == EmInit::kGivenMeans) {
    if (initial_means_m.size() != static_cast<size_t>(std::max(components, 0))) {
      err << "initial_means_m has " << initial_means_m.size() << " means for " << components
          << " components; ";
    }
    for (const auto& m : initial_means_m) {
      if (!m.allFinite()) {
        err << "initial_means_m holds a non-finite mean; ";
        break;
      }
    }
  }
  if (!(prune_sigma == 0.0 || prune_sigma >= 3.0) || !std::isfinite(prune_sigma)) {
    err << "prune_sigma must be 0 (exact) or >= 3 (got " << prune_sigma << "); ";
  }
  if (!(cell_size_m >= 0.0) || !std::isfinite(cell_size_m)) err << "cell_size_m must be >= 0; ";
  if (chunks < 1) err << "chunks must be >= 1; ";
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

EmResult fitGmm(const PointCloud& points, const EmParams& params, const EmProgress& progress) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("EM parameters: " + fault);
  size_t non_finite = 0;
  for (const auto& p : points) non_finite += p.allFinite() ? 0 : 1;
  if (non_finite > 0) {
    throw FitError("EM: " + std::to_string(non_finite) + " of " + std::to_string(points.size()) +
                   " points are NaN or Inf (drop them first)");
  }
  const size_t m = static_cast<size_t>(params.components);
  if (points.size() < m) {
    throw FitError("EM: " + std::to_string(points.size()) + " points are fewer than the " +
                   std::to_string(m) + " components requested");
  }
  const Clock::time_point t0 = Clock::now();
  const double reg = params.reg_covar_m2;
  FitRandom rng(params.seed);
  EmResult result;

  // Initialisation on the points in input order.
  Model model;
  {
    const PointsSoA all = toSoA(points);
    std::vector<int> labels;
    if (params.init == EmInit::kGivenMeans) {
      Centers given;
      for (const auto& mu : params.initial_means_m) {
        given.x.push_back(mu.x());
        given.y.push_back(mu.y());
        given.z.push_back(mu.z());
      }
      assignAll(all, given, &labels);
      initFromLabels(all, labels, m, reg, &given, &model);
    } else {
      Centers centers;
      if (all.size() > params.kmeans_max_points) {
        const PointsSoA sub = subsample(all, params.kmeans_max_points, &rng);
        centers = kmeansPlusPlus(sub, m, &rng);
        if (params.init == EmInit::kKMeans) lloyd(sub, params.kmeans_iterations, &centers);
      } else {
        centers = kmeansPlusPlus(all, m, &rng);
        if (params.init == EmInit::kKMeans) lloyd(all, params.kmeans_iterations, &centers);
      }
      assignAll(all, centers, &labels);
      initFromLabels(all, labels, m, reg, nullptr, &model);
    }
    model.prepare(reg);
  }

  // Pruning grid, sized from the initial components.
  PruneGrid grid;
  grid.exact = params.prune_sigma == 0.0;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  double cell_m = params.cell_size_m;
  if (cell_m <= 0.0) {
    std::vector<double> extent(m);
    for (size_t k = 0; k < m; ++k) {
      extent[k] = params.prune_sigma * model.half_extent_1sigma_m[k].maxCoeff();
    }
    cell_m = std::max(median(extent), 1e-3);
  }
  // Keep the grid within 2^21 cells per axis and bounded box-test work.
  const double span = std::max((hi - lo).maxCoeff(), 1e-9);
  cell_m = std::max(cell_m, span / 2.0e6);
  if (!grid.exact) {
    while (true) {
      const Eigen::Vector3d dims = ((hi - lo) / cell_m).array().floor() + 1.0;
      const double max_cells = dims.prod();
      const double occupied = std::min(max_cells, static_cast<double>(points.size()));
      if (occupied * static_cast<double>(m) <= kMaxCellTests) break;
      cell_m *= 1.5;
    }
  }
  const PointsSoA pts = buildGrid(points, cell_m, params.chunks, &grid);
  const size_t chunks = grid.chunk_cells.size() - 1;
  result.init_s = secondsSince(t0);

  const double n = static_cast<double>(points.size());
  double prev_ll = -std::numeric_limits<double>::infinity();
  std::vector<double> acc;
  int loaded = model.loaded;
  for (int it = 1; it <= params.max_iterations; ++it) {
    if (!grid.exact) updateCandidates(model, params.prune_sigma, &grid);
    const EStepResult e = eStep(pts, model, grid, &acc);
    const double ll = e.sum_log_likelihood / n;
    if (!std::isfinite(ll)) throw FitError("EM: log-likelihood became non-finite");
    mStep(acc, chunks, points.size(), reg, &model);
    model.prepare(reg);
    loaded = std::max(loaded, model.loaded);
    result.iterations = it;
    EmIteration rec;
    rec.iteration = it;
    rec.mean_log_likelihood = ll;
    rec.elapsed_s = secondsSince(t0);
    rec.mean_candidates = e.evaluations / n;
    result.history.push_back(rec);
    if (progress) progress(rec);
    if (std::abs(ll - prev_ll) < params.tolerance) {
      result.converged = true;
      break;
    }
    prev_ll = ll;
  }
  // Log-likelihood of the returned parameters.
  if (!grid.exact) updateCandidates(model, params.prune_sigma, &grid);
  result.final_mean_log_likelihood = eStep(pts, model, grid, nullptr).sum_log_likelihood / n;
  result.regularised_components = loaded;
  for (const auto& c : model.comps) {
    result.empty_components += (c.weight * n < 1e-6) ? 1 : 0;
  }
  result.components = std::move(model.comps);
  result.total_s = secondsSince(t0);
  return result;
}

double meanLogLikelihood(const std::vector<GaussianComponent>& components,
                         const PointCloud& points) {
  if (components.empty()) throw FitError("meanLogLikelihood: no components");
  if (points.empty()) throw FitError("meanLogLikelihood: no points");
  Model model;
  model.comps = components;
  model.prepare(0.0);
  PruneGrid grid;
  grid.exact = true;
  const PointsSoA pts = buildGrid(points, 1e9, 64, &grid);
  return eStep(pts, model, grid, nullptr).sum_log_likelihood / static_cast<double>(points.size());
}

GmmMap makeStorableMap(const std::vector<GaussianComponent>& components, double reg_covar_m2,
                       const std::string& source, int* repaired) {
  std::vector<GaussianComponent> out(components.size());
  double weight_sum = 0.0;
  for (const auto& c : components) weight_sum += c.weight;
  int fixed = 0;
  auto roundF = [](double v) { return static_cast<double>(static_cast<float>(v)); };
  auto roundedSpd = [&](const Eigen::Matrix3d& s, Eigen::Matrix3d* r) {
    for (int i = 0; i < 3; ++i) {
      for (int j = i; j < 3; ++j) (*r)(i, j) = (*r)(j, i) = roundF(0.5 * (s(i, j) + s(j, i)));
    }
    Eigen::LLT<Eigen::Matrix3d> llt(*r);
    return llt.info() == Eigen::Success && r->determinant() > 0.0 && r->allFinite();
  };
  for (size_t k = 0; k < components.size(); ++k) {
    const GaussianComponent& c = components[k];
    GaussianComponent& o = out[k];
    o.weight = roundF(c.weight / weight_sum);
    for (int a = 0; a < 3; ++a) o.mean_m[a] = roundF(c.mean_m[a]);
    if (!roundedSpd(c.cov_m2, &o.cov_m2)) {
      ++fixed;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (c.cov_m2 + c.cov_m2.transpose()));
      Eigen::Vector3d ev = es.eigenvalues();
      double floor = std::max(reg_covar_m2, 1e-6 * std::max(ev.maxCoeff(), 0.0));
      if (!(floor > 0.0)) floor = 1e-12;
      for (int attempt = 0; attempt < 20; ++attempt) {
        const Eigen::Vector3d clamped = ev.cwiseMax(floor);
        const Eigen::Matrix3d s =
            es.eigenvectors() * clamped.asDiagonal() * es.eigenvectors().transpose();
        if (roundedSpd(s, &o.cov_m2)) break;
        floor *= 10.0;
      }
    }
    if (!(o.weight > 0.0)) o.weight = static_cast<double>(std::numeric_limits<float>::min());
  }
  if (repaired) *repaired = fixed;
  return GmmMap(std::move(out), source);
}

}  // namespace gmm_mcl
