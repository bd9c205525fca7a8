// Particle set over (x, y, z, yaw) with seeded sampling, prediction, weighting, resampling,
// augmented-MCL reinitialisation and the pose estimate, on the host: the reference
// implementation of ParticleFilterBase.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "gmm_mcl/filter/params.h"
#include "gmm_mcl/filter/particle_filter_base.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/resampling.h"

namespace gmm_mcl {

// The estimate from the weighted moments: mean and the 4x4 covariance of (x, y, z, yaw) with
// yaw differences wrapped, placed in ROS order with the process-noise floor and the attitude
// variance (shared by both filters).
PoseEstimate poseEstimateFromMoments(const Particle& mean, const Eigen::Matrix4d& covariance,
                                     const ParticleFilterParams& params);

class ParticleFilter : public ParticleFilterBase {
 public:
  explicit ParticleFilter(const ParticleFilterParams& params);  // throws std::invalid_argument

  std::string name() const override { return "host"; }
  const ParticleFilterParams& params() const override { return params_; }
  void setParams(const ParticleFilterParams& params) override;
  const std::vector<Particle>& particles() const override { return particles_; }
  const std::vector<double>& weights() const override { return weights_; }
  int size() const override { return static_cast<int>(particles_.size()); }

  // Uniform over the region; equal weights; resets the augmented-MCL averages.
  void initialiseUniform(const InitRegion& region) override;
  // Gaussian around a pose (sigmas for x, y, z, yaw); equal weights.
  void initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) override;
  // Applies the odometry delta in each particle's yaw frame, then process noise.
  void predict(const PlanarDelta& delta) override;

  // Turns per-particle log-likelihoods into weights (multiplied into the current ones) with the
  // configured mode. Non-finite entries get zero weight. Returns false, leaving the weights
  // unchanged, when no entry is finite or all weights would vanish.
  bool updateWeights(const std::vector<double>& log_likelihood, int pixels);
  // kTempered: the exponent used in the last update as a fraction of 1 / (T * pixels)
  // (below 1 when the Neff floor limited it).
  double lastBetaFraction() const { return last_beta_fraction_; }
  double effectiveSampleSize() const override { return gmm_mcl::effectiveSampleSize(weights_); }
  // Resamples when Neff < resample_neff_fraction * N; returns whether it did.
  bool resampleIfNeeded() override;
  void resample() override;
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

  PoseEstimate estimate() const override;
  // Overrides the particle set (tests, tools); weights normalised here.
  void setParticles(const std::vector<Particle>& particles,
                    const std::vector<double>& weights) override;

  // ParticleFilterBase: the frame's likelihoods from the backend (poses built here), weights,
  // recovery and the candidate pool with the calls above.
  void evaluateFrame(const MeasurementContext& context, EvaluationStats* stats) override;
  void accumulateFrame(const MeasurementContext& context, double scale,
                       EvaluationStats* stats) override;
  bool weighFrame(int pixels, FrameScores* scores) override;
  int recoverFrame(int pixels, const InitRegion& region) override;
  void clearCandidates() override;
  void drawUniformCandidates(const InitRegion& region, int n) override;
  void scoreCandidates(const MeasurementContext& context) override;
  int scoredCandidates() const override { return static_cast<int>(scored_.size()); }
  void selectCandidateCentres(int elites, bool clear_pool) override;
  void drawCandidatesAroundCentres(double sigma_m, double sigma_rad, int n) override;
  void replaceAllByBestCandidates() override;
  void replaceWorstByBestCandidates(int keep, int count) override;
  // The kept log-likelihoods (evaluateFrame), as the backend returned them.
  const std::vector<double>& frameLogLikelihoods() const { return output_.log_likelihood; }
  // Sets them without a backend (tests of the device filter against this reference).
  void setFrameLogLikelihoods(const std::vector<double>& log_likelihood,
                              const std::vector<int>& floor_hits);
  // The scored candidate pool (score, candidate) in the order scored.
  const std::vector<std::pair<double, Particle>>& candidatePool() const { return scored_; }
  // The drawn candidates not yet scored, in the order drawn.
  const std::vector<Particle>& pendingCandidates() const { return pending_; }
  void setCandidatePool(const std::vector<std::pair<double, Particle>>& scored) {
    scored_ = scored;
  }

 private:
  Particle sampleUniform(const InitRegion& region);
  // Distinct KLD bins among the particles at `indices`.
  int occupiedBins(const std::vector<int>& indices) const;
  // The `count` best of the scored pool (any order).
  std::vector<Particle> bestCandidates(int count);
  void evaluatePoses(const MeasurementContext& context, const std::vector<Particle>& particles,
                     BackendOutput* out);

  ParticleFilterParams params_;
  std::mt19937_64 rng_;
  std::vector<Particle> particles_;
  std::vector<double> weights_;
  AugmentedMcl augmented_;
  std::vector<int> indices_;
  double last_beta_fraction_ = 1.0;
  std::vector<Particle> swap_;
  mutable std::vector<uint64_t> keys_;
  // The frame's likelihoods (evaluateFrame) and whether a resampling came after them.
  BackendOutput output_;
  BackendOutput more_output_;  // another camera's (accumulateFrame)
  bool resampled_since_evaluation_ = false;
  std::vector<double> ll_scratch_;
  std::vector<RigidTransformF> poses_;
  // Candidate pool.
  std::vector<std::pair<double, Particle>> scored_;
  std::vector<Particle> pending_;
  std::vector<Particle> centres_;
  BackendOutput candidate_output_;
};

}  // namespace gmm_mcl
