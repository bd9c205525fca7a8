// Particle set over (x, y, z, yaw) with seeded sampling, prediction, weighting, resampling,
// augmented-MCL reinitialisation and the pose estimate.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "gmm_mcl/filter/params.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {

// Mean base pose and its covariance in ROS order (x, y, z, roll, pitch, yaw): the weighted
// particle spread plus one step of process noise (at least 1e-8 per diagonal entry), so it is
// positive-definite even when the set has collapsed to copies of one particle.
struct PoseEstimate {
  Particle mean;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

class ParticleFilter {
 public:
  explicit ParticleFilter(const ParticleFilterParams& params);  // throws std::invalid_argument

  const ParticleFilterParams& params() const { return params_; }
  // New parameters for the same particle set (throws std::invalid_argument when invalid; the
  // seed is the generator's and stays). A count the new range does not allow (num_particles,
  // or [min_particles, num_particles] when adaptive) is resampled to the nearest allowed one.
  void setParams(const ParticleFilterParams& params);
  const std::vector<Particle>& particles() const { return particles_; }
  const std::vector<double>& weights() const { return weights_; }
  int size() const { return static_cast<int>(particles_.size()); }

  // Uniform over the region; equal weights; resets the augmented-MCL averages.
  void initialiseUniform(const InitRegion& region);
  // Gaussian around a pose (sigmas for x, y, z, yaw); equal weights.
  void initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma);
  // Applies the odometry delta in each particle's yaw frame, then process noise.
  void predict(const PlanarDelta& delta);

  // Turns per-particle log-likelihoods into weights (multiplied into the current ones) with the
  // configured mode. Non-finite entries get zero weight. Returns false, leaving the weights
  // unchanged, when no entry is finite or all weights would vanish.
  bool updateWeights(const std::vector<double>& log_likelihood, int pixels);
  // kTempered: the exponent used in the last update as a fraction of 1 / (T * pixels)
  // (below 1 when the Neff floor limited it).
  double lastBetaFraction() const { return last_beta_fraction_; }
  double effectiveSampleSize() const { return gmm_mcl::effectiveSampleSize(weights_); }
  // Resamples when Neff < resample_neff_fraction * N; returns whether it did.
  bool resampleIfNeeded();
  // Stratified low-variance resampling; with an adaptive count (params().adaptive()) the new
  // count is the KLD bound of the bins that the resampled set occupies.
  void resample();
  // Source index of every particle in the last resample().
  const std::vector<int>& lastResampleIndices() const { return indices_; }
  // Augmented MCL: feeds the frame's average per-pixel likelihood and reinitialises that many
  // randomly chosen particles from `region`. Returns the count.
  int recover(const std::vector<double>& log_likelihood, int pixels, const InitRegion& region);

  // Keeps the `keep` best particles (highest log_likelihood; non-finite last) with their weights
  // and adds `replacements`, each with the old average weight 1/N; the count becomes keep +
  // replacements (keep < 0: N - replacements, the count stays). Weights normalised.
  void replaceWorst(const std::vector<double>& log_likelihood,
                    const std::vector<Particle>& replacements, int keep = -1);
  // Replaces the whole set (equal weights), e.g. by screened uniform candidates.
  void replaceAll(const std::vector<Particle>& particles);
  // n uniform draws from the region with the filter's generator.
  void sampleRegion(const InitRegion& region, int n, std::vector<Particle>* out);
  // n draws around the centres (in turn), Gaussian with sigma_m per axis and sigma_rad in yaw.
  void sampleAround(const std::vector<Particle>& centres, double sigma_m, double sigma_rad, int n,
                    std::vector<Particle>* out);

  PoseEstimate estimate() const;
  // Overrides the particle set (tests, tools); weights normalised here.
  void setParticles(const std::vector<Particle>& particles, const std::vector<double>& weights);

 private:
  Particle sampleUniform(const InitRegion& region);
  // Distinct KLD bins among the particles at `indices`.
  int occupiedBins(const std::vector<int>& indices) const;

  ParticleFilterParams params_;
  std::mt19937_64 rng_;
  std::vector<Particle> particles_;
  std::vector<double> weights_;
  AugmentedMcl augmented_;
  std::vector<int> indices_;
  double last_beta_fraction_ = 1.0;
  std::vector<Particle> swap_;
  mutable std::vector<uint64_t> keys_;
};

}  // namespace gmm_mcl
