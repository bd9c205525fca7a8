#include "gmm_mcl/ros/node_status.h"

#include <diagnostic_msgs/DiagnosticStatus.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace gmm_mcl {

void FrameCounters::arrived(uint32_t seq) {
  ++received;
  // A smaller seq is a restarted publisher, not a gap.
  if (have_seq_ && seq > last_seq_ + 1) missed_seq += seq - last_seq_ - 1;
  have_seq_ = true;
  last_seq_ = seq;
}

void FrameCounters::drop(FrameDrop reason) {
  ++(reason == FrameDrop::kConversion   ? dropped_conversion
     : reason == FrameDrop::kCameraInfo ? dropped_camera_info
     : reason == FrameDrop::kFrameSet   ? dropped_frame_set
                                        : dropped_extrinsics);
}

constexpr size_t NodeHealth::kRecentProblems;

void NodeHealth::problem(const std::string& what, double now_s) {
  for (auto it = problems.begin(); it != problems.end(); ++it) {
    if (it->first == what) {
      problems.erase(it);
      break;
    }
  }
  problems.emplace_back(what, now_s);
  if (problems.size() > kRecentProblems) problems.erase(problems.begin());
}

void fillStatus(const StepResult& r, const FrameCounters& c, const std::string& backend,
                const std::string& backend_warning, double callback_ms,
                const std::string& input_warnings, FilterStatus* s) {
  s->step_status = stepStatusName(r.status);
  s->message =
      r.message + (input_warnings.empty() ? "" : (r.message.empty() ? "" : "; ") + input_warnings);
  s->backend = backend;
  s->backend_warning = backend_warning;
  s->particles = r.particles;
  s->neff = r.neff;
  s->mean_loglik_per_pixel = r.mean_loglik_per_pixel;
  s->best_loglik_per_pixel = r.best_loglik_per_pixel;
  s->floor_hit_fraction = r.floor_hit_fraction;
  s->pixels = r.pixels;
  s->reinitialised = r.reinitialised;
  s->reinitialised_total = c.reinitialised_total;
  s->lost = r.lost;
  s->lost_reinitialised = r.lost_reinitialised;
  s->screened_candidates = r.screened_candidates;
  s->reference_loglik_per_pixel = r.reference_loglik_per_pixel;
  s->lost_events_total = c.lost_events_total;
  s->resets = static_cast<int32_t>(c.resets);
  s->resampled = r.resampled;
  s->odometry_jump = r.odometry_jump;
  s->motion = r.motion == MotionSource::kConstantVelocity && r.gyro_yaw
                  ? "constant_velocity_gyro"
                  : motionSourceName(r.motion);
  s->backend_fallback = r.backend_fallback;
  s->refined = r.refinement.refined;
  s->refine_why = r.refinement.why;
  s->refined_loglik_per_pixel = r.refinement.refined ? r.refinement.loglik_refined : 0.0;
  s->depth_scale = r.depth_scale;
  s->predict_ms = r.timings.predict_ms;
  s->frame_prep_ms = r.timings.frame_prep_ms;
  s->projection_membership_ms = r.timings.projection_membership_ms;
  s->likelihood_ms = r.timings.likelihood_ms;
  s->weights_ms = r.timings.weights_ms;
  s->resample_ms = r.timings.resample_ms;
  s->estimate_ms = r.timings.estimate_ms;
  s->refine_ms = r.timings.refine_ms;
  s->total_ms = r.timings.total_ms;
  s->callback_ms = callback_ms;
  s->frames_received = c.received;
  s->frames_processed = c.processed;
  s->frames_gated = c.gated;
  s->frames_waiting = c.waiting();
  s->dropped_conversion = c.dropped_conversion;
  s->dropped_camera_info = c.dropped_camera_info;
  s->dropped_extrinsics = c.dropped_extrinsics;
  s->frames_missed_seq = c.missed_seq;
  s->camera_info_received = c.camera_info_received;
  s->imu_received = c.imu_received;
  s->odometry_received = c.odometry_received;
  s->odometry_gaps = c.odometry_gaps;
  s->imu_missing = c.imu_missing;
  s->tf_skipped = c.tf_skipped;
  s->time_jumps = c.time_jumps;
  s->dropped_frame_set = c.dropped_frame_set;
  s->updates_other_cameras = c.updates_other_cameras;
}

void fillCameraStatus(const NodeHealth& h, double set_stamp_s, FilterStatus* s) {
  s->cameras.clear();
  for (const CameraHealth& c : h.cameras) {
    CameraStatus m;
    m.name = c.name;
    m.topic = c.topic;
    m.leads = c.leads;
    m.in_set = c.in_last_set;
    m.used = c.used_last;
    m.pixels = c.pixels;
    m.depth_scale = c.depth_scale;
    m.problem = c.problem;
    m.state = c.sets.last_stamp_s < 0 ? "no_frame_yet" : c.sets.dropped_out ? "dropped_out" : "ok";
    m.frame_age_s = c.sets.last_stamp_s < 0 ? 0.0 : set_stamp_s - c.sets.last_stamp_s;
    m.frames_received = c.sets.frames;
    m.frames_used = c.sets.used;
    m.frames_missing = c.sets.missing;
    m.frames_dropped = c.sets.dropped;
    s->cameras.push_back(m);
  }
}

void recordFrame(const StepResult& r, bool gated, bool sent_tf, double now_s,
                 const LostDetectionParams& lost, const std::string& backend,
                 const std::string& backend_warning, double callback_ms,
                 const std::string& warnings, NodeHealth* h, FilterStatus* status,
                 bool first_camera) {
  FrameCounters& c = h->counters;
  ++(!first_camera ? c.updates_other_cameras : gated ? c.gated : c.processed);
  if (!sent_tf) ++c.tf_skipped;
  if (!gated) {
    c.reinitialised_total += r.reinitialised;
    if (r.lost) ++c.lost_events_total;
    if (r.rival_chosen) ++c.rival_moves_total;
    h->frames_since_lost = r.lost ? 0 : h->frames_since_lost < 0 ? -1 : h->frames_since_lost + 1;
  }
  fillStatus(r, c, backend, backend_warning, callback_ms, warnings, status);
  if (gated) status->step_status = "no_motion";
  h->backend = backend;  // the backend can change at run time (a CPU fallback)
  h->backend_warning = backend_warning;
  h->last_used_s = now_s;
  h->have_step = true;
  h->last_step = r.status;
  h->last_step_message = r.message;
  h->sigma_xy_m = std::sqrt(std::max(r.estimate.covariance(0, 0), r.estimate.covariance(1, 1)));
  h->depth_scale = r.depth_scale;
  h->depth_scale_at_bound = r.depth_scale_at_bound;
  h->sigma_yaw_rad = std::sqrt(r.estimate.covariance(5, 5));
  h->below_lost_reference =
      lost.margin_nats > 0 && r.status == StepStatus::kOk &&
      r.best_loglik_per_pixel < r.reference_loglik_per_pixel - lost.margin_nats;
  h->neff = r.neff;
  h->update_ms = r.timings.total_ms;
}

void fillBudgetStatus(const BudgetState& b, FilterStatus* s) {
  s->budget_enabled = b.enabled;
  s->budget_ms = b.budget_ms;
  s->budget_frame_period_s = b.frame_period_s;
  s->budget_pixel_stride = b.pixel_stride;
  s->budget_particle_cap = b.particle_cap;
  s->budget_refine = b.refine;
  s->budget_cuts = b.cuts;
  s->budget_restores = b.restores;
}

namespace {
// The counters that /diagnostics lists, each under its label.
struct CounterRow {
  const char* label;
  long long FrameCounters::*count;
};
const CounterRow kCounterRows[] = {
    {"frames received", &FrameCounters::received},
    {"frames used", &FrameCounters::processed},
    {"frames not used: no motion", &FrameCounters::gated},
    {"dropped: conversion", &FrameCounters::dropped_conversion},
    {"dropped: camera info", &FrameCounters::dropped_camera_info},
    {"dropped: no extrinsics", &FrameCounters::dropped_extrinsics},
    {"dropped: not in a frame set", &FrameCounters::dropped_frame_set},
    {"updates led by another camera", &FrameCounters::updates_other_cameras},
    {"missed before a callback (seq gaps)", &FrameCounters::missed_seq},
    {"camera infos received", &FrameCounters::camera_info_received},
    {"IMU messages received", &FrameCounters::imu_received},
    {"odometry messages received", &FrameCounters::odometry_received},
    {"tf not published", &FrameCounters::tf_skipped},
    {"reinitialised particles (total)", &FrameCounters::reinitialised_total},
    {"lost events (total)", &FrameCounters::lost_events_total},
    {"moves to a rival place (total)", &FrameCounters::rival_moves_total},
    {"resets", &FrameCounters::resets},
    {"time jumps back", &FrameCounters::time_jumps},
    {"odometry gaps", &FrameCounters::odometry_gaps},
    {"frames without IMU", &FrameCounters::imu_missing},
};
}  // namespace

Diagnosis diagnose(const NodeHealth& h) {
  using S = diagnostic_msgs::DiagnosticStatus;
  Diagnosis d;
  auto find = [&d](uint8_t level, const std::string& what) {
    if (level > d.level) d.level = level;
    d.message += (d.message.empty() ? "" : "; ") + what;
  };
  const FrameCounters& c = h.counters;
  std::ostringstream m;
  if (!h.config_error.empty()) {
    d.level = S::ERROR;
    d.message = "bad configuration: " + h.config_error;
    return d;
  }
  if (h.have_step && h.last_step == StepStatus::kBackendError) {
    find(S::ERROR, "likelihood backend failed: " + h.last_step_message);
  }
  const double quiet_s = h.last_arrival_s < 0 ? -1.0 : h.now_s - h.last_arrival_s;
  if (c.received == 0) {
    find(S::WARN, "no depth frame received on " + h.depth_topic);
  } else if (quiet_s > 3.0) {
    m << "no depth frame for " << quiet_s << " s on " << h.depth_topic;
    find(S::WARN, m.str());
  }
  // Frames arrive but none is used: say why.
  const bool stalled = c.received > 0 && quiet_s >= 0 && quiet_s <= 3.0 &&
                       (h.last_used_s < 0 || h.now_s - h.last_used_s > 3.0);
  if (stalled) {
    m.str("");
    if (!h.camera_info_topic.empty() &&
        (h.last_camera_info_s < 0 || h.now_s - h.last_camera_info_s > 3.0)) {
      m << "depth images arrive on " << h.depth_topic << " (" << c.received << " so far) but no "
        << "CameraInfo on " << h.camera_info_topic
        << (h.last_camera_info_s < 0 ? "" : " for more than 3 s");
    } else if (c.waiting() > 0) {
      m << c.waiting() << " depth frame(s) waiting for tf or a CameraInfo with their stamp";
    } else {
      m << "depth frames arrive but none is used";
    }
    find(S::WARN, m.str());
  }
  // Several cameras: one that dropped out, or never delivered a usable frame.
  for (const CameraHealth& cam : h.cameras) {
    m.str("");
    m.precision(3);
    if (cam.sets.dropped_out) {
      m << "camera '" << cam.name << "': no frame for " << h.now_s - cam.sets.last_stamp_s
        << " s: updating with the others";
    } else if (cam.sets.used == 0 && h.have_step) {
      m << "camera '" << cam.name << "' not used yet: "
        << (cam.arrived == 0 ? "no frame on " + cam.topic
                             : std::to_string(cam.arrived) + " frames arrived, none usable");
    } else {
      continue;
    }
    find(S::WARN, m.str());
  }
  if (h.below_lost_reference || (h.frames_since_lost >= 0 && h.frames_since_lost < 30)) {
    find(S::WARN, "lost: the best particle scores below the lost detector's reference (" +
                      std::to_string(c.lost_events_total) + " lost events)");
  }
  if (h.have_step && (h.sigma_xy_m > h.warn_sigma_xy_m || h.sigma_yaw_rad > h.warn_sigma_yaw_rad)) {
    m.str("");
    m.precision(3);
    m << "not converged: sigma x/y " << h.sigma_xy_m << " m, yaw " << h.sigma_yaw_rad << " rad";
    find(S::WARN, m.str());
  }
  // A rig: each camera's own estimate (the first camera's is h.depth_scale too).
  auto atBound = [&](const std::string& camera, double scale) {
    m.str("");
    m << "depth scale " << scale << camera
      << " held at its bound (refine_depth_scale_max_error): the camera's depths are further "
         "off, or the map does not fit the scene";
    find(S::WARN, m.str());
  };
  if (h.have_step && h.cameras.empty() && h.depth_scale_at_bound) atBound("", h.depth_scale);
  for (const CameraHealth& cam : h.cameras) {
    if (h.have_step && cam.depth_scale_at_bound) {
      atBound(" of camera '" + cam.name + "'", cam.depth_scale);
    }
  }
  if (!h.backend_warning.empty()) find(S::WARN, h.backend_warning);
  if (h.budget.enabled && h.budget.at_limit && h.budget.budget_ms > 0.0 &&
      h.budget.last_update_ms > h.budget.budget_ms) {
    m.str("");
    m.precision(3);
    m << "updates take " << h.budget.last_update_ms << " ms, over the budget of "
      << h.budget.budget_ms << " ms at the cheapest setting (pixel stride " << h.budget.pixel_stride
      << ", no refinement, " << h.budget.particle_cap << " particles): frames are skipped";
    find(S::WARN, m.str());
  }
  for (auto it = h.problems.rbegin(); it != h.problems.rend(); ++it) {  // the latest first
    if (h.now_s - it->second >= 0 && h.now_s - it->second < 5.0) find(S::WARN, it->first);
  }
  if (d.message.empty()) d.message = "localizing";
  auto add = [&d](const std::string& k, const std::string& v) { d.values.emplace_back(k, v); };
  auto num = [](double x) {
    std::ostringstream s;
    s << x;
    return s.str();
  };
  for (const CounterRow& row : kCounterRows) add(row.label, std::to_string(c.*row.count));
  add("frames waiting", std::to_string(c.waiting()));
  add("last step", h.have_step ? stepStatusName(h.last_step) : "none yet");
  add("sigma x/y (m)", num(h.sigma_xy_m));
  add("sigma yaw (rad)", num(h.sigma_yaw_rad));
  add("Neff", num(h.neff));
  add("depth scale", num(h.depth_scale));
  add("update ms", num(h.update_ms));
  add("budget", !h.budget.enabled          ? "off"
                : h.budget.budget_ms > 0.0 ? num(h.budget.budget_ms) + " ms"
                                           : "no frame period yet");
  add("pixel stride", std::to_string(h.budget.pixel_stride));
  add("particle cap", std::to_string(h.budget.particle_cap));
  add("refinement", h.budget.refine ? "as configured" : "off (budget)");
  add("budget cuts / restores",
      std::to_string(h.budget.cuts) + " / " + std::to_string(h.budget.restores));
  if (!h.cameras.empty()) {
    int used = 0;
    for (const CameraHealth& cam : h.cameras) used += cam.used_last;
    add("cameras in the last update", std::to_string(used));
  }
  for (const CameraHealth& cam : h.cameras) {
    const std::string k = "camera " + cam.name + ": ";
    add(k + "state", cam.sets.last_stamp_s < 0 ? "no frame yet"
                     : cam.sets.dropped_out
                         ? "WARN no frame for " + num(h.now_s - cam.sets.last_stamp_s) +
                               " s: updating with the others"
                         : "OK");
    add(k + "frames used", std::to_string(cam.sets.used));
    add(k + "frames missing", std::to_string(cam.sets.missing));
    add(k + "frames dropped", std::to_string(cam.sets.dropped) + " (superseded or late), " +
                                  std::to_string(cam.dropped_input) + " (input)");
    add(k + "last stamp", cam.sets.last_stamp_s < 0 ? "none" : num(cam.sets.last_stamp_s));
    add(k + "topic", cam.topic);
    add(k + "depth scale", num(cam.depth_scale));
    if (!cam.problem.empty()) add(k + "problem", cam.problem);
  }
  add("last problem", h.problems.empty() ? "" : h.problems.back().first);
  add("backend", h.backend);
  return d;
}

void HealthMonitor::set(const std::function<void(NodeHealth*)>& change) {
  std::lock_guard<std::mutex> lock(mutex_);
  change(&health_);
}

void HealthMonitor::setWarnLimits(double sigma_xy_m, double sigma_yaw_rad) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.warn_sigma_xy_m = sigma_xy_m;
  health_.warn_sigma_yaw_rad = sigma_yaw_rad;
}

void HealthMonitor::setBackend(const std::string& name, const std::string& warning) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.backend = name;
  health_.backend_warning = warning;
}

NodeHealth HealthMonitor::snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return health_;
}

void HealthMonitor::arrived(uint32_t seq, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.counters.arrived(seq);
  health_.last_arrival_s = now_s;
}

void HealthMonitor::cameraInfo(double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++health_.counters.camera_info_received;
  health_.last_camera_info_s = now_s;
}

void HealthMonitor::dropped(FrameDrop reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.counters.drop(reason);
}

void HealthMonitor::count(long long FrameCounters::*counter) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++(health_.counters.*counter);
}

void HealthMonitor::problem(const std::string& what, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.problem(what, now_s);
}

FilterStatus HealthMonitor::frame(const StepResult& r, bool gated, bool sent_tf, double now_s,
                                  const LostDetectionParams& lost, const std::string& backend,
                                  const std::string& backend_warning, double callback_ms,
                                  const std::string& warnings, long long imu_received,
                                  long long odometry_received, bool first_camera) {
  std::lock_guard<std::mutex> lock(mutex_);
  health_.counters.imu_received = imu_received;
  health_.counters.odometry_received = odometry_received;
  FilterStatus s;
  recordFrame(r, gated, sent_tf, now_s, lost, backend, backend_warning, callback_ms, warnings,
              &health_, &s, first_camera);
  return s;
}

void HealthMonitor::cameraArrived(size_t camera) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (camera < health_.cameras.size()) ++health_.cameras[camera].arrived;
}

void HealthMonitor::cameraDropped(size_t camera) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (camera < health_.cameras.size()) ++health_.cameras[camera].dropped_input;
}

}  // namespace gmm_mcl
