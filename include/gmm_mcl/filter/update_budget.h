// A frame-rate budget for the localizer: on a machine where an update takes longer than the
// camera's frame period (a TX2, the CPU backend), frames are skipped, the estimate lags and tf
// goes stale. UpdateBudget watches each update's duration against the budget (max_update_ms, or
// the frame period measured from the frames' stamps) and chooses what the filter evaluates:
// over budget, first a coarser pixel stride (up to max_pixel_stride), then no pose refinement
// (it does not change the particles' belief, and costs about a third of a CPU update at a
// coarse stride: measured on 7-Scenes, docs/ros.md), then fewer particles (down to
// min_particles); with headroom for a while, the same steps back in reverse order. It is a plain
// function of the numbers it is given (durations, stamps, clock readings): no clock of its own, so
// tests drive it with synthetic numbers.
#pragma once

#include <cstdint>
#include <deque>
#include <string>

#include "gmm_mcl/filter/params.h"

namespace gmm_mcl {

class Localizer;
struct StepResult;

struct UpdateBudgetParams {
  bool enabled = true;
  // The budget per update in milliseconds of wall time; 0: the frame period measured from the
  // stamps (divided by the clock's rate: a bag played at rate 0.5 gives twice the time).
  double max_update_ms = 0.0;
  int max_pixel_stride = 16;  // the coarsest stride the budget may choose
  int min_particles = 100;    // the fewest particles it may choose (at most the configured count)
  // Consecutive updates over the budget before it cuts (one slow update is not a trend).
  int over_updates = 3;
  // Stepping back needs this many consecutive updates whose duration, scaled by the cost of the
  // step back, stays under headroom_fraction of the budget (hysteresis: no oscillation).
  int headroom_updates = 30;
  double headroom_fraction = 0.7;
  // A cut aims for this fraction of the budget (cost taken as proportional to particles times
  // pixels; repeated cuts correct the model's error).
  double target_fraction = 0.8;

  std::string validate() const;
};

// What the budget chose; reported in ~status and /diagnostics.
struct BudgetState {
  bool enabled = false;
  double budget_ms = 0.0;       // the budget in force (0: not known yet, no frame period)
  double frame_period_s = 0.0;  // measured from the stamps (0: not yet)
  double clock_rate = 1.0;      // seconds of the stamps' clock per wall second
  int pixel_stride = 1;         // the stride in force
  int particle_cap = 1;         // the largest particle count in force
  bool refine = true;           // the pose refinement in force (off: skipped to save time)
  int cuts = 0, restores = 0;   // changes so far
  bool at_limit = false;        // the cheapest setting it may choose
  double last_update_ms = 0.0;
};

class UpdateBudget {
 public:
  UpdateBudget() = default;
  // The configured stride and particle count are the ones it starts from and returns to.
  UpdateBudget(const UpdateBudgetParams& params, const LocalizerParams& configured);
  // New parameters or configured values (dynamic_reconfigure): the current choice is kept within
  // the new bounds (all the way back to the configured values when disabled).
  void configure(const UpdateBudgetParams& params, const LocalizerParams& configured);

  // A frame arrived: its stamp and header seq (gaps from frames dropped before arriving are
  // divided out), and the clock readings now: clock_s on the stamps' clock (ROS time, simulated
  // under a bag's --clock), wall_s on a wall clock.
  void frameArrived(double stamp_s, uint32_t seq, double clock_s, double wall_s);
  // One update took update_ms of wall time with `particles` particles, refine_ms of it in the
  // pose refinement (0: none). Returns true when the stride, the refinement or the particle cap
  // changed (apply() then gives the parameters to use).
  bool updateTook(double update_ms, int particles, double refine_ms = 0.0);

  // A localizer step's outcome and duration: counted only when it says what an update costs (a
  // plain update: a uniform start or a lost redraw scores many candidates once, a failed frame
  // none). Returns what updateTook() returns.
  bool stepTook(const StepResult& result, double update_ms);

  // The configured parameters with the budget's stride and particle cap.
  LocalizerParams apply(const LocalizerParams& configured) const;
  // apply() given to the localizer (Localizer::setParams keeps the particles): "" or why it was
  // refused.
  std::string applyTo(const LocalizerParams& configured, Localizer* localizer) const;
  // "update budget 33.3 ms (last update 41.0 ms): pixel stride 8, refinement off, at most 400
  // particles", for the log.
  std::string describe() const;
  const BudgetState& state() const { return state_; }
  // The budget in force, ms (0 when unknown).
  double budgetMs() const;

 private:
  void clampToBounds();
  int strideFloor() const { return configured_stride_; }
  int strideCeil() const;
  int particleFloor() const;

  UpdateBudgetParams params_;
  int configured_stride_ = 1;
  int configured_particles_ = 1;
  bool configured_refine_ = false;
  double last_refine_ms_ = -1.0;  // the last refinement's cost (< 0: none seen)
  BudgetState state_;
  int over_count_ = 0, headroom_count_ = 0;
  // Frame period: seq-normalised stamp intervals of the last frames.
  bool have_frame_ = false;
  double last_stamp_s_ = 0.0;
  uint32_t last_seq_ = 0;
  std::deque<double> periods_s_;
  // Clock rate: a reference reading, replaced once wall time moved far enough.
  bool have_clock_ = false;
  double ref_clock_s_ = 0.0, ref_wall_s_ = 0.0;
};

}  // namespace gmm_mcl
