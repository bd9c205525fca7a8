// Rival places (LostDetectionParams::rival_*): the estimate checked against the places around it.
// A particle set can settle beside the truth where a wall leaves a direction open: its broad,
// mediocre basin holds more particles than the truth's basin, a decimetre wide, and after a few
// frames none is left in the latter. It scores at the map's level, so the lost detector never
// fires, while the truth scores clearly better (docs/building_scale.md). The check looks for such
// a place and moves the set there. Every stage works on a coarse frame (about 1200 pixels): two
// batches of poses scored by the backend, then one refinement per place, whatever the map.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/filter/localizer.h"

namespace gmm_mcl {
namespace {

// Rivals are distinct places at least this far apart, and this far from the estimate: the
// blurred map's basin around the estimate itself is a few decimetres wide.
constexpr double kRivalSeparationM = 0.5;
// Candidates' height around the estimate's (the floor and ceiling fix it well).
constexpr double kRivalHalfHeightM = 0.1;
// The frame every stage scores on: the step camera's at a multiple of its stride leaving about
// this many pixels (stride 16 at 640 x 480).
constexpr double kRivalFramePixels = 1200.0;
// Each place moves to the best of this many draws around it (itself among them) on the blurred
// map, Gaussian with these spreads (x and y; z a fifth; yaw), before its refinement on the map.
constexpr int kRivalDraws = 32;
constexpr double kRivalClimbSigmaM = 0.15;
constexpr double kRivalClimbSigmaRad = 0.05;
// The estimate's place, refined, must score at most this much below the set's best particle
// (nats per pixel; the coarse frame's pixels are some of the frame's).
constexpr double kRivalOwnSlackNats = 0.5;
// A rival must score at least the lost detector's reference minus this (nats per pixel).
constexpr double kRivalFitNats = 1.0;

double distanceM(const Particle& a, const Particle& b) {
  return std::hypot(std::hypot(a.x_m - b.x_m, a.y_m - b.y_m), a.z_m - b.z_m);
}

}  // namespace

std::vector<double> Localizer::scoreRivalPoses(const std::vector<Particle>& poses,
                                               const GmmMap& map) {
  std::vector<RigidTransformF> T(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    T[i] = toRigidF(particleToPose(poses[i], roll_rad_, pitch_rad_) * cam_.T_base_cam);
  }
  // Another map (a blurred one) for this call only; the localizer's map again after it.
  const bool swap = &map != &map_ && !map.empty();
  BackendOutput out;
  if (swap) backend_->setMap(map);
  try {
    backend_->evaluate(rival_frame_, T, *cam_.measurement, &out);
  } catch (...) {
    if (swap) backend_->setMap(map_);
    throw;
  }
  if (swap) backend_->setMap(map_);
  std::vector<double> per_pixel(poses.size());
  const double pixels = static_cast<double>(rival_frame_.size());
  for (size_t i = 0; i < poses.size(); ++i) per_pixel[i] = out.log_likelihood[i] / pixels;
  return per_pixel;
}

std::vector<Particle> Localizer::proposeRivals(const Particle& centre) {
  const LostDetectionParams& lp = params_.lost;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Particle> candidates(lp.rival_candidates, centre);
  for (Particle& p : candidates) {
    double dx, dy;
    do {
      dx = u(rival_rng_);
      dy = u(rival_rng_);
    } while (dx * dx + dy * dy > 1.0);
    p.x_m += lp.rival_radius_m * dx;
    p.y_m += lp.rival_radius_m * dy;
    p.z_m += kRivalHalfHeightM * u(rival_rng_);
    p.yaw_rad = wrapAngle(p.yaw_rad + lp.rival_yaw_rad * u(rival_rng_));
  }
  // Against the merged blurred map, as a lost redraw's uniform stage: a wide basin, so that a
  // candidate some decimetres from a place still ranks it.
  const std::vector<double> score =
      scoreRivalPoses(candidates, !redraw_map_.empty() ? redraw_map_ : blurred_map_);
  std::vector<int> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return score[a] > score[b]; });
  std::vector<Particle> rivals;
  for (int i : order) {
    if (static_cast<int>(rivals.size()) >= lp.rival_places || !std::isfinite(score[i])) break;
    const Particle& p = candidates[i];
    if (distanceM(p, centre) < kRivalSeparationM) continue;
    if (std::any_of(rivals.begin(), rivals.end(),
                    [&](const Particle& r) { return distanceM(p, r) < kRivalSeparationM; })) {
      continue;
    }
    rivals.push_back(p);
  }
  return rivals;
}

void Localizer::climbRivals(std::vector<Particle>* places) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Particle> poses(places->size() * kRivalDraws);
  for (size_t h = 0; h < places->size(); ++h) {
    const Particle& c = (*places)[h];
    poses[h * kRivalDraws] = c;
    for (int k = 1; k < kRivalDraws; ++k) {
      Particle& p = poses[h * kRivalDraws + k];
      p = c;
      p.x_m += kRivalClimbSigmaM * g(rival_rng_);
      p.y_m += kRivalClimbSigmaM * g(rival_rng_);
      p.z_m += 0.2 * kRivalClimbSigmaM * g(rival_rng_);
      p.yaw_rad = wrapAngle(p.yaw_rad + kRivalClimbSigmaRad * g(rival_rng_));
    }
  }
  // On the blurred map: its wide basin carries a place some decimetres off towards the centre of
  // the place's basin, where the refinement on the map takes over.
  const std::vector<double> s = scoreRivalPoses(poses, blurred_map_);
  for (size_t h = 0; h < places->size(); ++h) {
    double best = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < kRivalDraws; ++k) {
      const size_t i = h * kRivalDraws + k;
      if (s[i] > best) {
        best = s[i];
        (*places)[h] = poses[i];
      }
    }
  }
}

RefinementResult Localizer::refineRival(const Particle& start) {
  RefinementFrame rf = RefinementFrame::of(rival_frame_);
  if (params_.refinement.estimate_depth_scale) rf.depth_scale = depth_scales_[first_camera_];
  refineComponents(start, rf, cam_.T_base_cam, *cam_.frame, *cam_.measurement, &rival_components_);
  return refinePose(rival_components_, rf, start, roll_rad_, pitch_rad_, cam_.T_base_cam,
                    *cam_.measurement, params_.refinement, backend_->normalEquations());
}

void Localizer::checkRivals(StepResult* res) {
  const LostDetectionParams& lp = params_.lost;
  ++frames_since_rival_check_;
  const bool confirm = rival_pending_;
  if (!confirm && frames_since_rival_check_ < lp.rival_check_frames) return;
  rival_pending_ = false;
  // A set spread over more than the search's reach (a start, a redraw), or over several
  // headings, is not settled anywhere.
  double position_sigma, yaw_sigma;
  beliefSpread(res->estimate.covariance, &position_sigma, &yaw_sigma);
  if (res->lost || !(position_sigma <= lp.rival_radius_m) ||
      !(yaw_sigma <= std::max(lp.rival_yaw_rad, params_.refinement.max_yaw_sigma_rad)) ||
      cam_.depth == nullptr) {
    return;
  }
  const Clock::time_point t0 = Clock::now();
  frames_since_rival_check_ = 0;
  // The step camera's frame at the rivals' stride (on the host: it replaces the backend's frame
  // of this step, hence the check comes last).
  FrameParams fp = *cam_.frame;
  const double area = static_cast<double>(cam_.depth->width_px) * cam_.depth->height_px;
  fp.pixel_stride *= std::max(
      1, static_cast<int>(std::floor(std::sqrt(area / kRivalFramePixels) / fp.pixel_stride)));
  fp.patch_size_px = std::max(fp.patch_size_px, 4 * fp.pixel_stride);
  rival_frame_ = prepareFrame(*cam_.depth, cam_.intrinsics, fp);
  if (rival_frame_.empty()) return;
  res->rival_checked = true;
  // The estimate (refined, else the particle mean) is place 0; the rivals follow.
  const Particle own_start = res->refinement.refined ? res->refinement.pose : res->estimate.mean;
  std::vector<Particle> places;
  try {
    if (confirm) {
      places.push_back(rival_);
    } else {
      places = proposeRivals(own_start);
      if (!places.empty()) climbRivals(&places);
    }
  } catch (const BackendError&) {
    throw;
  } catch (const std::exception& e) {
    res->message += std::string(res->message.empty() ? "" : "; ") + "rival places not scored (" +
                    e.what() + ")";
    return;
  }
  // The estimate and each rival at their maxima on the map (the refinement, on the rival frame);
  // the best rival that did not climb back into the estimate's own basin.
  const RefinementResult own = refineRival(own_start);
  // The mean of a set spread over several places lies where no particle is: its maximum then
  // scores well below the set's best particle, and is no reference for rivals.
  if (!(own.loglik_refined >= res->best_loglik_per_pixel - kRivalOwnSlackNats)) {
    res->timings.rival_ms = msSince(t0);
    return;
  }
  bool found = false;
  RefinementResult best;
  for (const Particle& p : places) {
    const RefinementResult r = refineRival(p);
    // A rival must look like a right pose: about the lost detector's reference level (a wrong
    // place elsewhere scores nats below it), not merely better than a set that is lost itself.
    if (!std::isfinite(r.loglik_refined) || distanceM(r.pose, own.pose) < kRivalSeparationM ||
        r.loglik_refined < lost_.reference() - kRivalFitNats) {
      continue;
    }
    if (!found || r.loglik_refined > best.loglik_refined) best = r;
    found = true;
  }
  if (found && std::isfinite(own.loglik_refined)) {
    res->rival_gain_per_pixel = best.loglik_refined - own.loglik_refined;
    if (res->rival_gain_per_pixel > lp.rival_margin_nats) {
      rival_wins_ = confirm ? rival_wins_ + 1 : 1;
      const Particle& r = best.pose;
      if (rival_wins_ >= lp.rival_frames) {
        // The lost detector goes on judging (no grace period): the reference level stays.
        filter_->initialiseGaussian(r, placeSigma());
        have_refined_ = false;  // nothing of the old place carries over
        motion_model_.reset();
        res->rival_chosen = true;
        std::ostringstream msg;
        msg << "rival place: (" << r.x_m << ", " << r.y_m << ", " << r.z_m << ") m, yaw "
            << r.yaw_rad << " rad, " << distanceM(r, own.pose) << " m from the estimate, scored "
            << res->rival_gain_per_pixel << " nats/px above it (more than " << lp.rival_margin_nats
            << " on " << lp.rival_frames << " frames in a row): the particles re-seeded there";
        res->message += (res->message.empty() ? "" : "; ") + msg.str();
      } else {
        // Checked again on the next frame, moved there by that step's motion.
        rival_pending_ = true;
        rival_ = r;
      }
    }
  }
  res->timings.rival_ms = msSince(t0);
}

}  // namespace gmm_mcl
