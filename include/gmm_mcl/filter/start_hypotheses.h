// The places a wide start (a whole building, ~global_localization) keeps in play over its first
// frames, beside the particle set (docs/building_scale.md "Global localization in the building
// world").
//
// After the first update of a start spread over a building, the particle set holds many places
// whose first frame scores about as well as the truth's, and the truth's own particles often sit
// a few decimetres outside its likelihood's basin. Weighted resampling then settles on one place
// within a few frames, by a frame's evidence each, and the truth's neighbourhood dies. Here the
// best distinct places of the first update are each followed on their own: moved by the
// step's motion, moved to the best of a few local draws on every frame (a hill climb into the
// basin), and scored by the log of the mean of their draws' per-pixel likelihoods (the
// neighbourhood's evidence: the best draw's score would let a wrong place re-fit every frame),
// summed with exponential forgetting (a place that climbs into its basin is not held back by
// its first frames). None of them is resampled away by another place's frame. After the
// stage's frames the best place seeds the particle set when the set does not already sit there.
// Off by default (LostDetectionParams::start_places): docs/building_scale.md has what it found.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {

struct StartHypothesesParams {
  int places = 256;             // distinct places kept (0: off)
  int draws = 16;               // poses scored per place and frame (the place itself included)
  int frames = 90;              // frames of the stage
  double separation_m = 0.5;    // two places closer than this in position...
  double separation_rad = 0.5;  // ...and in yaw are one place
  // The local draws' spread per frame (per axis; z a fifth of it): a place climbs about this
  // far per frame. Wider draws let every place re-fit each frame on its own, and wrong places
  // then outscore the truth's (docs/building_scale.md: 0.05 m against 0.01 m).
  double sigma_m = 0.01;
  double sigma_rad = 0.005;
  // The score forgets with rate 1 / memory_frames; <= 0: a third of the stage's frames (its
  // last third weighs most, the climb into a basin of its first frames little).
  double memory_frames = 0.0;
};

class StartHypotheses {
 public:
  struct Place {
    Particle pose;
    double score = 0.0;        // forgotten sum of its frames' scores
    double last_loglik = 0.0;  // the last frame's: log mean of the draws' per-pixel likelihoods
  };

  StartHypotheses() = default;
  explicit StartHypotheses(const StartHypothesesParams& params, uint64_t seed);

  // Starts the stage from scored poses (higher first wins): the best distinct places.
  void seed(const std::vector<Particle>& poses, const std::vector<double>& scores);
  bool active() const { return !places_.empty(); }
  void stop() { places_.clear(); }
  bool finished() const { return active() && frames_ >= params_.frames; }

  // Every place moved by the step's motion (in its own heading, without noise).
  void predict(const PlanarDelta& delta);
  // The poses to score on this frame: draws per place, the place itself first.
  const std::vector<Particle>& proposals();
  // Their log-likelihoods (nats, summed over the frame's `pixels`): each place moves to its best
  // draw and adds its per-pixel score; places that met another are merged (the better kept).
  void update(const std::vector<double>& log_likelihood, int pixels);
  // The place with the best score (active() must hold).
  const Place& best() const;
  const std::vector<Place>& places() const { return places_; }

 private:
  bool samePlace(const Particle& a, const Particle& b) const;
  void merge();

  StartHypothesesParams params_;
  std::mt19937_64 rng_;
  std::vector<Place> places_;
  std::vector<Particle> proposals_;
  int frames_ = 0;
};

}  // namespace gmm_mcl
