// The particle set on the GPU: every ParticleFilterBase operation runs on the CUDA backend's
// device and stream (src/filter/cuda/filter_*_kernels.cu), so that a filter step at
// 10^5 particles fits a 30 Hz camera. Prediction noise and uniform draws come from a
// counter-based generator (Philox); the likelihood is evaluated from device-resident poses on the
// frame the backend keeps on the device; weights, the estimate and the scores are deterministic
// device reductions; resampling is ParticleFilter's stratified low-variance scheme with the
// KLD-sampling count; selections (screening, lost redraws) sort on the device. Per frame only
// scalars and the small estimate come back to the host; the particle array only when
// particles() is called. Results are reproducible run to run (same seed, same device), and
// statistically, not bitwise, those of ParticleFilter (tested against it in
// test_cuda_particle_filter).
// Private to the core (and its CUDA tests): a user makes it with makeParticleFilter(). No CUDA
// header is needed to include this file.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/filter/particle_filter_base.h"

namespace gmm_mcl {

class CudaBackend;

class CudaParticleFilter : public ParticleFilterBase {
 public:
  // Works on `backend`'s device and stream (the backend outlives the filter). Throws
  // BackendError when the device cannot hold the set, std::invalid_argument for bad params.
  CudaParticleFilter(const ParticleFilterParams& params, CudaBackend* backend);
  ~CudaParticleFilter() override;
  CudaParticleFilter(const CudaParticleFilter&) = delete;
  CudaParticleFilter& operator=(const CudaParticleFilter&) = delete;

  std::string name() const override { return "cuda"; }
  const ParticleFilterParams& params() const override;
  void setParams(const ParticleFilterParams& params) override;
  int size() const override;
  const std::vector<Particle>& particles() const override;
  const std::vector<double>& weights() const override;
  void setParticles(const std::vector<Particle>& particles,
                    const std::vector<double>& weights) override;
  void initialiseUniform(const InitRegion& region) override;
  void initialiseGaussian(const Particle& mean, const Eigen::Vector4d& sigma) override;
  void predict(const PlanarDelta& delta) override;
  bool prepareDeviceFrame(const DepthImage& image, const Intrinsics& K,
                          const FrameParams& frame_params, DeviceFrameSummary* summary) override;
  void evaluateFrame(const MeasurementContext& context, EvaluationStats* stats) override;
  void accumulateFrame(const MeasurementContext& context, double scale,
                       EvaluationStats* stats) override;
  bool weighFrame(int pixels, FrameScores* scores) override;
  PoseEstimate estimate() const override;
  double effectiveSampleSize() const override;
  bool resampleIfNeeded() override;
  int recoverFrame(int pixels, const InitRegion& region) override;
  void clearCandidates() override;
  void drawUniformCandidates(const InitRegion& region, int n) override;
  void scoreCandidates(const MeasurementContext& context) override;
  int scoredCandidates() const override;
  void selectCandidateCentres(int elites, bool clear_pool) override;
  void drawCandidatesAroundCentres(double sigma_m, double sigma_rad, int n) override;
  void replaceAllByBestCandidates() override;
  void replaceWorstByBestCandidates(int keep, int count) override;
  void synchronize() override;

  // Stratified low-variance resampling with the KLD-sampling count (ParticleFilter::resample).
  void resample() override;
  // The pieces, for tests against ParticleFilter: resampling with a given order and offsets
  // (stratifiedLowVarianceIndices's arguments; the set becomes n_out particles), returning the
  // source indices; the distinct KLD bins of the set; the kept log-likelihoods; the candidate
  // pool (scored ones first, with their scores) and setting one.
  std::vector<int> resampleWith(const std::vector<int>& order, const std::vector<double>& offsets,
                                int n_out);
  int occupiedBins() const;
  std::vector<int> lastResampleIndices() const;
  void setFrameLogLikelihoods(const std::vector<double>& log_likelihood,
                              const std::vector<int>& floor_hits);
  std::vector<double> frameLogLikelihoods() const;
  std::vector<std::pair<double, Particle>> candidatePool() const;  // scored
  std::vector<Particle> candidateParticles() const;                // all, in pool order
  void setCandidatePool(const std::vector<std::pair<double, Particle>>& scored);
  std::vector<Particle> candidateCentres() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace gmm_mcl
