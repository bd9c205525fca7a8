// The particle set's data-parallel operations behind one interface, so that the localizer's
// predict / update / resample / recover / reset policy is written once: ParticleFilter (host,
// the reference) and CudaParticleFilter (the set lives on the GPU; private to the core,
// src/filter/cuda/cuda_particle_filter.h; made by makeParticleFilter()) implement it. The filter
// holds the last frame's per-particle log-likelihoods (evaluateFrame) and a pool of scored
// candidates (uniform or local draws whose best replace particles).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/filter/params.h"
#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {

// Mean base pose and its covariance in ROS order (x, y, z, roll, pitch, yaw): the weighted
// particle spread plus one step of process noise (at least 1e-8 per diagonal entry), so it is
// positive-definite even when the set has collapsed to copies of one particle.
struct PoseEstimate {
  Particle mean;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

// What scoring particles on a frame needs besides the particles.
struct MeasurementContext {
  LikelihoodBackend* backend = nullptr;
  const DepthFrame* frame = nullptr;  // the frame on the host (the host filter needs it)
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  const MeasurementParams* params = nullptr;
};

// Of one evaluateFrame (all particles).
struct EvaluationStats {
  long long evaluations = 0;
  long long relevant_pairs = 0;       // summed over particles and patches with pixels
  long long patches_with_pixels = 0;  // of the frame (per particle)
  double projection_membership_ms = 0.0;
  double likelihood_ms = 0.0;
};

// What weighFrame reports of the frame's likelihoods.
struct FrameScores {
  double best_loglik = 0.0;  // nats, the best particle's (the first of the largest)
  double mean_loglik = 0.0;  // weighted by the updated weights
  int best_floor_hits = 0;   // pixels at the floor for the best particle
  double beta_fraction = 1.0;
};

// The frame as the device prepared it.
struct DeviceFrameSummary {
  int pixels = 0;
  long long patches_with_pixels = 0;
};

class ParticleFilterBase {
 public:
  virtual ~ParticleFilterBase() = default;
  virtual std::string name() const = 0;  // "host", "cuda"
  virtual const ParticleFilterParams& params() const = 0;
  // New parameters for the same particle set (throws std::invalid_argument when invalid; the
  // seed is the generator's and stays; the augmented-MCL averages stay). A count the new range
  // does not allow (num_particles, or [min_particles, num_particles] when adaptive) is resampled
  // to the nearest allowed one.
  virtual void setParams(const ParticleFilterParams& params) = 0;
  virtual int size() const = 0;
  // The set on the host (the device filter copies it down on each call after a change).
  virtual const std::vector<Particle>& particles() const = 0;
  virtual const std::vector<double>& weights() const = 0;
  // Overrides the particle set (tests, tools, a change of filter); weights normalised here.
  virtual void setParticles(const std::vector<Particle>& particles,
                            const std::vector<double>& weights) = 0;

  // Uniform over the region; equal weights; resets the augmented-MCL averages.
  virtual void initialiseUniform(const InitRegion& region) = 0;
  // Gaussian around a pose (sigmas for x, y, z, yaw); equal weights.
  virtual void initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) = 0;
  // Applies the odometry delta in each particle's yaw frame, then process noise.
  virtual void predict(const PlanarDelta& delta) = 0;

  // Prepares the frame on the device for evaluateFrame/scoreCandidates (the raw image uploaded
  // once): false when this filter scores host frames (MeasurementContext::frame). Throws
  // std::invalid_argument for what prepareFrame rejects, BackendError for a device failure.
  virtual bool prepareDeviceFrame(const DepthImage& image, const Intrinsics& K,
                                  const FrameParams& frame_params, DeviceFrameSummary* summary) {
    (void)image, (void)K, (void)frame_params, (void)summary;
    return false;
  }
  // The log-likelihood of every particle on the frame, kept for the calls below.
  virtual void evaluateFrame(const MeasurementContext& context, EvaluationStats* stats) = 0;
  // Adds every particle's log-likelihood on another camera's frame, times `scale`, to the kept
  // ones (and its floor hits): a camera rig, one update per frame set (the localizer scales
  // each camera to the first one's pixel count, docs/multi_camera.md). After evaluateFrame,
  // before any resampling; throws std::logic_error otherwise. Stats are this camera's.
  virtual void accumulateFrame(const MeasurementContext& context, double scale,
                               EvaluationStats* stats) = 0;
  // The weights from the kept log-likelihoods (ParticleFilterParams::weighting; kTempered with
  // the Neff-floor bisection), and the frame's scores. False (weights unchanged) when no entry
  // is finite or all weights would vanish.
  virtual bool weighFrame(int pixels, FrameScores* scores) = 0;
  virtual PoseEstimate estimate() const = 0;
  virtual double effectiveSampleSize() const = 0;
  // Resamples when Neff < resample_neff_fraction * N; returns whether it did.
  virtual bool resampleIfNeeded() = 0;
  // Resamples now whatever Neff: stratified low-variance sampling; with an adaptive count
  // (params().adaptive()) the new count is the KLD bound of the bins the resampled set occupies.
  virtual void resample() = 0;
  // Augmented MCL on the kept log-likelihoods (as evaluated, before any resampling):
  // reinitialises that many randomly chosen particles from `region`; returns the count.
  virtual int recoverFrame(int pixels, const InitRegion& region) = 0;

  // Candidate pool.
  virtual void clearCandidates() = 0;
  // Appends n uniform draws from the region (not yet scored).
  virtual void drawUniformCandidates(const InitRegion& region, int n) = 0;
  // Scores the unscored candidates on the frame.
  virtual void scoreCandidates(const MeasurementContext& context) = 0;
  virtual int scoredCandidates() const = 0;
  // The `elites` best-scoring candidates become the centres of local draws; with clear_pool the
  // pool is emptied (their scores only chose the centres).
  virtual void selectCandidateCentres(int elites, bool clear_pool) = 0;
  // Appends n draws around the centres in turn (Gaussian, sigma_m per axis, sigma_rad in yaw).
  virtual void drawCandidatesAroundCentres(double sigma_m, double sigma_rad, int n) = 0;
  // The whole set replaced by the `size()` best candidates, equal weights.
  virtual void replaceAllByBestCandidates() = 0;
  // Keeps the `keep` best particles by the frame's likelihood (each particle carries its
  // source's after a resampling; non-finite last) with their weights and adds the `count` best
  // candidates with the old average weight 1/N; the count becomes keep + count; normalised.
  virtual void replaceWorstByBestCandidates(int keep, int count) = 0;

  // Waits for queued device work (benchmark timing); nothing on the host.
  virtual void synchronize() {}
};

// The filter for a backend: the device filter when `device` is asked for and the backend is the
// CUDA backend, else ParticleFilter. *warning says why the device filter was not made where it
// was asked for and could not be (empty otherwise).
std::unique_ptr<ParticleFilterBase> makeParticleFilter(const ParticleFilterParams& params,
                                                       LikelihoodBackend* backend, bool device,
                                                       std::string* warning);

}  // namespace gmm_mcl
