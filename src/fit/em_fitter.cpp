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

#include "em_internal.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/random.h"

namespace gmm_mcl {
namespace {

using em_detail::buildGrid;
using em_detail::initialComponents;
using em_detail::kNkFloor;
using em_detail::PointsSoA;
using em_detail::pruneCellSize;
using em_detail::PruneGrid;
using em_detail::toSoA;
using em_detail::updateCandidates;

constexpr double kLog2Pi = 1.8378770664093453;
// Responsibilities below this are not accumulated (their effect is below double rounding of a
// component's sums).
constexpr double kMinResponsibility = 1e-12;
// A candidate whose density is below e^-50 (2e-22) of the point's largest adds nothing to the
// sum of densities (>= 1 in units of the largest) above double rounding for fewer than 10^5
// candidates, and its responsibility is below kMinResponsibility: exp() is skipped (its
// underflow path was a quarter of the E-step's time).
constexpr double kNegligibleLogRatio = -50.0;
// Statistics accumulated per component: N, S1 (3), S2 upper triangle (6).
constexpr int kStats = 10;

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// One component ready for evaluation: mean, inverse of the covariance's Cholesky factor
// (lower triangular, L^-1), and ln(weight) - 1.5 ln(2 pi) - 0.5 ln det(Sigma).
struct EvalSoA {
  std::vector<double> mx, my, mz, a00, a10, a11, a20, a21, a22, log_norm;
  void resize(size_t n) {
    for (auto* v : {&mx, &my, &mz, &a00, &a10, &a11, &a20, &a21, &a22, &log_norm}) v->resize(n);
  }
};

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
            const double d = tp[j] - tmax;
            tp[j] = d < kNegligibleLogRatio ? 0.0 : std::exp(d);
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

namespace {

void checkPoints(const PointCloud& points) {
  size_t non_finite = 0;
  for (const auto& p : points) non_finite += p.allFinite() ? 0 : 1;
  if (non_finite > 0) {
    throw FitError("EM: " + std::to_string(non_finite) + " of " + std::to_string(points.size()) +
                   " points are NaN or Inf (drop them first)");
  }
}

// The pruning grid over the points, sized from the model's components.
PointsSoA gridFor(const PointCloud& points, const Model& model, const EmParams& params,
                  PruneGrid* grid) {
  grid->exact = params.prune_sigma == 0.0;
  const double cell_m = pruneCellSize(points, model.half_extent_1sigma_m, params, grid->exact);
  return buildGrid(points, cell_m, params.chunks, grid);
}

// EM iterations from the prepared model until converged or params.max_iterations; the result's
// components, history, final log-likelihood and times (init_s: until the grid is built).
void iterate(const PointCloud& points, const EmParams& params, Clock::time_point t0,
             const EmProgress& progress, Model* model, EmResult* result) {
  PruneGrid grid;
  const PointsSoA pts = gridFor(points, *model, params, &grid);
  const size_t chunks = grid.chunk_cells.size() - 1;
  result->init_s = secondsSince(t0);
  const double reg = params.reg_covar_m2;
  const double n = static_cast<double>(points.size());
  double prev_ll = -std::numeric_limits<double>::infinity();
  std::vector<double> acc;
  int loaded = model->loaded;
  for (int it = 1; it <= params.max_iterations; ++it) {
    if (!grid.exact) {
      updateCandidates(model->comps, model->half_extent_1sigma_m, params.prune_sigma, &grid);
    }
    const EStepResult e = eStep(pts, *model, grid, &acc);
    const double ll = e.sum_log_likelihood / n;
    if (!std::isfinite(ll)) throw FitError("EM: log-likelihood became non-finite");
    mStep(acc, chunks, points.size(), reg, model);
    model->prepare(reg);
    loaded = std::max(loaded, model->loaded);
    result->iterations = it;
    EmIteration rec;
    rec.iteration = it;
    rec.mean_log_likelihood = ll;
    rec.elapsed_s = secondsSince(t0);
    rec.mean_candidates = e.evaluations / n;
    result->history.push_back(rec);
    if (progress) progress(rec);
    if (std::abs(ll - prev_ll) < params.tolerance) {
      result->converged = true;
      break;
    }
    prev_ll = ll;
  }
  // Log-likelihood of the returned parameters.
  if (!grid.exact) {
    updateCandidates(model->comps, model->half_extent_1sigma_m, params.prune_sigma, &grid);
  }
  result->final_mean_log_likelihood = eStep(pts, *model, grid, nullptr).sum_log_likelihood / n;
  result->regularised_components = loaded;
  for (const auto& c : model->comps) {
    result->empty_components += (c.weight * n < 1e-6) ? 1 : 0;
  }
  result->components = std::move(model->comps);
  result->total_s = secondsSince(t0);
}

}  // namespace

EmResult fitGmm(const PointCloud& points, const EmParams& params, const EmProgress& progress) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("EM parameters: " + fault);
  checkPoints(points);
  const size_t m = static_cast<size_t>(params.components);
  if (points.size() < m) {
    throw FitError("EM: " + std::to_string(points.size()) + " points are fewer than the " +
                   std::to_string(m) + " components requested");
  }
  const Clock::time_point t0 = Clock::now();
  FitRandom rng(params.seed);
  EmResult result;
  // Initialisation on the points in input order.
  Model model;
  model.comps = initialComponents(toSoA(points), m, params, &rng);
  model.prepare(params.reg_covar_m2);
  iterate(points, params, t0, progress, &model, &result);
  return result;
}

EmResult refineGmm(const PointCloud& points, std::vector<GaussianComponent> initial,
                   const EmParams& params, const EmProgress& progress) {
  if (initial.empty()) throw FitError("EM refinement: no components");
  EmParams p = params;
  p.components = static_cast<int>(initial.size());
  p.init = EmInit::kKMeans;
  p.initial_means_m.clear();
  p.kmeans_max_points = std::max(p.kmeans_max_points, initial.size());
  const std::string fault = p.validate();
  if (!fault.empty()) throw FitError("EM parameters: " + fault);
  checkPoints(points);
  if (points.empty()) throw FitError("EM refinement: no points");
  double weight_sum = 0.0;
  for (size_t k = 0; k < initial.size(); ++k) {
    const GaussianComponent& c = initial[k];
    if (!(c.weight > 0.0) || !std::isfinite(c.weight) || !c.mean_m.allFinite() ||
        !c.cov_m2.allFinite()) {
      throw FitError("EM refinement: component " + std::to_string(k) +
                     " has a non-positive weight or a non-finite value");
    }
    weight_sum += c.weight;
  }
  for (auto& c : initial) c.weight /= weight_sum;
  const Clock::time_point t0 = Clock::now();
  EmResult result;
  Model model;
  model.comps = std::move(initial);
  model.prepare(p.reg_covar_m2);
  iterate(points, p, t0, progress, &model, &result);
  return result;
}

double meanLogLikelihood(const std::vector<GaussianComponent>& components, const PointCloud& points,
                         double prune_sigma) {
  if (components.empty()) throw FitError("meanLogLikelihood: no components");
  if (points.empty()) throw FitError("meanLogLikelihood: no points");
  if (!(prune_sigma == 0.0 || prune_sigma >= 3.0) || !std::isfinite(prune_sigma)) {
    throw FitError("meanLogLikelihood: prune_sigma must be 0 (exact) or >= 3");
  }
  Model model;
  model.comps = components;
  model.prepare(0.0);
  PruneGrid grid;
  PointsSoA pts;
  if (prune_sigma == 0.0) {
    grid.exact = true;
    pts = buildGrid(points, 1e9, 64, &grid);
  } else {
    EmParams p;
    p.prune_sigma = prune_sigma;
    pts = gridFor(points, model, p, &grid);
    updateCandidates(model.comps, model.half_extent_1sigma_m, prune_sigma, &grid);
  }
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
