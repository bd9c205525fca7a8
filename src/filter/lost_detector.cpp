#include "gmm_mcl/filter/lost_detector.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>

namespace gmm_mcl {

double mapSelfLogDensity(const GmmMap& map, float floor_log_density, int samples, uint64_t seed) {
  DepthNoiseModel off;
  off.a_m = off.b_per_m = 0.f;
  return mapSelfLogDensity(map, floor_log_density, off, samples, seed);
}

double mapSelfLogDensity(const GmmMap& map, float floor_log_density, const DepthNoiseModel& noise,
                         int samples, uint64_t seed, double nominal_range_m) {
  const std::vector<GaussianComponent>& comps = map.components();
  if (comps.empty() || samples <= 0) return floor_log_density;
  // Each component convolved with the depth noise along its normal (the direction of its
  // smallest variance: a surface seen head-on) at the nominal range.
  const double d = nominal_range_m - noise.z0_m;
  const double s_noise = noise.enabled() ? noise.a_m + noise.b_per_m * d * d : 0.0;
  std::vector<Eigen::Matrix3d> L(comps.size());  // Cholesky factors
  std::vector<double> log_norm(comps.size());    // ln(lambda) - ln((2 pi)^1.5 |Sigma|^0.5)
  std::vector<double> cumulative(comps.size());
  double total = 0.0;
  for (size_t j = 0; j < comps.size(); ++j) {
    Eigen::Matrix3d cov = comps[j].cov_m2;
    if (s_noise > 0.0) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      const Eigen::Vector3d n = es.eigenvectors().col(0);
      cov += s_noise * s_noise * n * n.transpose();
    }
    L[j] = cov.llt().matrixL();
    log_norm[j] =
        map.modelLogWeight(j) - 1.5 * std::log(2.0 * M_PI) - L[j].diagonal().array().log().sum();
    total += comps[j].weight;
    cumulative[j] = total;
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pick(0.0, total);
  std::normal_distribution<double> g(0.0, 1.0);
  double sum = 0.0;
  std::vector<double> terms;
  std::vector<int> near;
  for (int s = 0; s < samples; ++s) {
    const size_t j = std::min<size_t>(
        std::lower_bound(cumulative.begin(), cumulative.end(), pick(rng)) - cumulative.begin(),
        comps.size() - 1);
    const Eigen::Vector3d x = comps[j].mean_m + L[j] * Eigen::Vector3d(g(rng), g(rng), g(rng));
    // The components whose 3-sigma box, grown by the noise's, reaches x (the map's grid: the
    // cost follows the neighbourhood, not the map), and the one x was drawn from.
    Box3 around;
    around.extend(x - Eigen::Vector3d::Constant(3.0 * s_noise));
    around.extend(x + Eigen::Vector3d::Constant(3.0 * s_noise));
    map.grid().query(around, &near);
    if (!std::binary_search(near.begin(), near.end(), static_cast<int>(j))) {
      near.insert(std::lower_bound(near.begin(), near.end(), static_cast<int>(j)),
                  static_cast<int>(j));
    }
    terms.resize(near.size());
    double mx = floor_log_density;
    for (size_t q = 0; q < near.size(); ++q) {
      const size_t k = static_cast<size_t>(near[q]);
      const Eigen::Vector3d z = L[k].triangularView<Eigen::Lower>().solve(x - comps[k].mean_m);
      terms[q] = log_norm[k] - 0.5 * z.squaredNorm();
      mx = std::max(mx, terms[q]);
    }
    double acc = std::exp(floor_log_density - mx);
    for (double t : terms) acc += std::exp(t - mx);
    sum += mx + std::log(acc);
  }
  return sum / samples;
}

LostDetector::LostDetector(const LostDetectionParams& params, double initial_reference)
    : params_(params),
      reference_(initial_reference),
      floor_(initial_reference - params.reference_max_drop_nats) {}

void LostDetector::setParams(const LostDetectionParams& params, double initial_reference) {
  params_ = params;
  floor_ = initial_reference - params.reference_max_drop_nats;
  reference_ = std::max(reference_, floor_);
}

void LostDetector::restart() {
  frames_below_ = 0;
  frames_since_restart_ = 0;
}

void LostDetector::rebase() {
  reference_ = floor_;
  frames_below_ = 0;
  restart();
}

bool LostDetector::update(double best) {
  if (!enabled() || !std::isfinite(best)) return false;
  ++frames_since_restart_;
  // The reference follows the best score: quickly up, slowly down, so that a scene whose true
  // pose scores below the map's own level is learned, while a sudden drop stays visible for
  // several seconds.
  const double rate = best > reference_ ? params_.reference_rate_up : params_.reference_rate_down;
  const bool below = best < reference_ - params_.margin_nats;
  reference_ = std::max(floor_, reference_ + rate * (best - reference_));
  frames_below_ = below ? frames_below_ + 1 : 0;
  if (frames_since_restart_ <= params_.grace_frames || frames_below_ < params_.frames) return false;
  restart();
  return true;
}

}  // namespace gmm_mcl
