#include "gmm_mcl/filter/update_budget.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "gmm_mcl/filter/localizer.h"

namespace gmm_mcl {
namespace {

// Frame intervals kept for the period's median (about a second at 30 Hz).
constexpr size_t kPeriodWindow = 31;
// An interval longer than this is a pause (a paused bag, a camera restart), not the period.
constexpr double kMaxPeriodS = 5.0;
// The clock's rate is measured over at least this much wall time.
constexpr double kRateWindowS = 2.0;
// A seq step larger than this (or none) is not a count of dropped frames: the publisher does
// not number its messages.
constexpr uint32_t kMaxSeqGap = 1000;
// Particles come back by this factor per step.
constexpr double kRestoreParticleFactor = 1.25;

}  // namespace

std::string UpdateBudgetParams::validate() const {
  std::ostringstream err;
  if (!(max_update_ms >= 0.0) || !std::isfinite(max_update_ms))
    err << "budget: max_update_ms must be >= 0 (got " << max_update_ms << "); ";
  if (max_pixel_stride < 1) err << "budget: max_pixel_stride must be >= 1; ";
  if (min_particles < 1) err << "budget: min_particles must be >= 1; ";
  if (over_updates < 1) err << "budget: over_updates must be >= 1; ";
  if (headroom_updates < 1) err << "budget: headroom_updates must be >= 1; ";
  if (!(headroom_fraction > 0.0 && headroom_fraction < 1.0))
    err << "budget: headroom_fraction must be in (0, 1) (got " << headroom_fraction << "); ";
  if (!(target_fraction > 0.0 && target_fraction <= 1.0))
    err << "budget: target_fraction must be in (0, 1] (got " << target_fraction << "); ";
  return err.str();
}

UpdateBudget::UpdateBudget(const UpdateBudgetParams& params, const LocalizerParams& configured) {
  state_.pixel_stride = configured.frame.pixel_stride;
  state_.particle_cap = configured.filter.num_particles;
  state_.refine = configured.refinement.enabled;
  configure(params, configured);
}

void UpdateBudget::configure(const UpdateBudgetParams& params, const LocalizerParams& configured) {
  params_ = params;
  configured_stride_ = configured.frame.pixel_stride;
  configured_particles_ = configured.filter.num_particles;
  if (configured.refinement.enabled && !configured_refine_) state_.refine = true;  // turned on
  configured_refine_ = configured.refinement.enabled;
  state_.enabled = params.enabled;
  if (!params.enabled) {
    state_.pixel_stride = configured_stride_;
    state_.particle_cap = configured_particles_;
    state_.refine = configured_refine_;
  }
  clampToBounds();
  over_count_ = headroom_count_ = 0;
  state_.budget_ms = budgetMs();
}

int UpdateBudget::strideCeil() const {
  return std::max(configured_stride_, params_.max_pixel_stride);
}

int UpdateBudget::particleFloor() const {
  return std::min(configured_particles_, params_.min_particles);
}

void UpdateBudget::clampToBounds() {
  state_.pixel_stride = std::min(std::max(state_.pixel_stride, strideFloor()), strideCeil());
  state_.particle_cap =
      std::min(std::max(state_.particle_cap, particleFloor()), configured_particles_);
  state_.refine = state_.refine && configured_refine_;
  state_.at_limit = state_.pixel_stride == strideCeil() && !state_.refine &&
                    state_.particle_cap == particleFloor();
}

double UpdateBudget::budgetMs() const {
  if (params_.max_update_ms > 0.0) return params_.max_update_ms;
  if (state_.frame_period_s <= 0.0) return 0.0;
  return 1000.0 * state_.frame_period_s / state_.clock_rate;
}

void UpdateBudget::frameArrived(double stamp_s, uint32_t seq, double clock_s, double wall_s) {
  // The clock's rate (1 in real time; a bag's rate under --clock).
  if (!have_clock_ || clock_s < ref_clock_s_ || wall_s < ref_wall_s_) {
    have_clock_ = true;
    ref_clock_s_ = clock_s;
    ref_wall_s_ = wall_s;
  } else if (wall_s - ref_wall_s_ >= kRateWindowS) {
    const double rate = (clock_s - ref_clock_s_) / (wall_s - ref_wall_s_);
    if (std::isfinite(rate)) state_.clock_rate = std::min(std::max(rate, 1e-2), 1e2);
    ref_clock_s_ = clock_s;
    ref_wall_s_ = wall_s;
  }
  // The frame period: the median of the intervals between arriving frames, each divided by the
  // number of frames it spans (header seq) where the publisher numbers its messages.
  if (have_frame_ && stamp_s > last_stamp_s_) {
    const uint32_t gap = seq - last_seq_;
    const double span = gap >= 1 && gap <= kMaxSeqGap ? static_cast<double>(gap) : 1.0;
    const double dt = (stamp_s - last_stamp_s_) / span;
    if (dt <= kMaxPeriodS) {
      periods_s_.push_back(dt);
      if (periods_s_.size() > kPeriodWindow) periods_s_.pop_front();
      std::vector<double> sorted(periods_s_.begin(), periods_s_.end());
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      state_.frame_period_s = sorted[sorted.size() / 2];
    }
  }
  have_frame_ = true;
  last_stamp_s_ = stamp_s;
  last_seq_ = seq;
  state_.budget_ms = budgetMs();
}

bool UpdateBudget::updateTook(double update_ms, int particles, double refine_ms) {
  state_.last_update_ms = update_ms;
  if (refine_ms > 0.0) last_refine_ms_ = refine_ms;
  const double budget = budgetMs();
  state_.budget_ms = budget;
  if (!params_.enabled || budget <= 0.0 || !std::isfinite(update_ms) || update_ms < 0.0)
    return false;
  const int stride = state_.pixel_stride;
  const int cap = state_.particle_cap;
  const bool refine = state_.refine;
  if (update_ms > budget) {
    headroom_count_ = 0;
    if (++over_count_ < params_.over_updates) return false;
    over_count_ = 0;
    // Cost taken as proportional to particles / stride^2: the factor to remove.
    const double factor = update_ms / (params_.target_fraction * budget);
    if (stride < strideCeil()) {
      const int wanted = static_cast<int>(std::ceil(stride * std::sqrt(factor)));
      state_.pixel_stride = std::min(strideCeil(), std::max(stride + 1, wanted));
    } else if (refine) {
      state_.refine = false;
    } else {
      const int from = std::max(1, std::min(cap, particles));
      const int wanted = static_cast<int>(std::floor(from / factor));
      state_.particle_cap = std::max(particleFloor(), std::min(cap - 1, wanted));
    }
    clampToBounds();
    if (state_.pixel_stride == stride && state_.particle_cap == cap && state_.refine == refine)
      return false;
    ++state_.cuts;
    return true;
  }
  over_count_ = 0;
  // The step back and what it would cost, in the reverse order of the cuts.
  int next_stride = stride, next_cap = cap;
  bool next_refine = refine;
  double predicted_ms = update_ms;
  if (cap < configured_particles_) {
    next_cap =
        std::min(configured_particles_,
                 std::max(cap + 1, static_cast<int>(std::ceil(cap * kRestoreParticleFactor))));
    predicted_ms = update_ms * next_cap / std::max(1, std::min(cap, particles));
  } else if (!refine && configured_refine_) {
    next_refine = true;
    // What it cost when last seen (at a finer stride, so no less); never seen: as much again.
    predicted_ms = update_ms + (last_refine_ms_ >= 0.0 ? last_refine_ms_ : update_ms);
  } else if (stride > strideFloor()) {
    next_stride = stride - 1;
    predicted_ms = update_ms * (static_cast<double>(stride) * stride) / (next_stride * next_stride);
  } else {
    headroom_count_ = 0;  // nothing to give back
    return false;
  }
  if (predicted_ms >= params_.headroom_fraction * budget) {
    headroom_count_ = 0;
    return false;
  }
  if (++headroom_count_ < params_.headroom_updates) return false;
  headroom_count_ = 0;
  state_.pixel_stride = next_stride;
  state_.particle_cap = next_cap;
  state_.refine = next_refine;
  clampToBounds();
  ++state_.restores;
  return true;
}

bool UpdateBudget::stepTook(const StepResult& r, double update_ms) {
  if (r.status != StepStatus::kOk || r.screened_candidates > 0) return false;
  return updateTook(update_ms, r.particles, r.timings.refine_ms);
}

std::string UpdateBudget::applyTo(const LocalizerParams& configured, Localizer* localizer) const {
  try {
    localizer->setParams(apply(configured));
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

std::string UpdateBudget::describe() const {
  std::ostringstream m;
  m << "update budget " << state_.budget_ms << " ms (last update " << state_.last_update_ms
    << " ms): pixel stride " << state_.pixel_stride << ", refinement "
    << (state_.refine ? "on" : "off") << ", at most " << state_.particle_cap << " particles";
  return m.str();
}

LocalizerParams UpdateBudget::apply(const LocalizerParams& configured) const {
  LocalizerParams p = configured;
  if (!params_.enabled) return p;
  p.frame.pixel_stride = state_.pixel_stride;
  p.refinement.enabled = p.refinement.enabled && state_.refine;
  ParticleFilterParams& f = p.filter;
  f.num_particles = std::min(f.num_particles, state_.particle_cap);
  if (f.min_particles > f.num_particles) f.min_particles = f.num_particles;
  // Stratified groups: at most the smallest count.
  const int smallest = f.adaptive() ? f.min_particles : f.num_particles;
  f.resample_groups = std::min(f.resample_groups, smallest);
  return p;
}

}  // namespace gmm_mcl
