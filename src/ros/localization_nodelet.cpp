#include "gmm_mcl/ros/localization_nodelet.h"

#include <chrono>
#include <pluginlib/class_list_macros.hpp>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {
namespace {
// A frame stamp earlier than the last one by more than this is a jump back (a looped bag).
constexpr double kTimeJumpToleranceS = 1e-3;
double nowS() { return ros::Time::now().toSec(); }
}  // namespace

LocalizationNodelet::LocalizationNodelet() = default;
LocalizationNodelet::~LocalizationNodelet() = default;

void LocalizationNodelet::onInit() {
  // Named after this nodelet, not its manager.
  updater_.reset(
      new diagnostic_updater::Updater(getNodeHandle(), getPrivateNodeHandle(), getName()));
  updater_->setHardwareID("gmm_mcl");
  updater_->add("localization", this, &LocalizationNodelet::diagnose);
  std::vector<std::string> unknown;
  const bool ok = configure(&unknown);
  for (const std::string& u : unknown)
    NODELET_WARN("gmm_mcl: %s is not a parameter (ignored)", u.c_str());
  if (ok) {
    NODELET_INFO("gmm_mcl: %zu components from %s, %s backend, %d particles\n%s",
                 localizer_->map().size(), opts_.map_path.c_str(),
                 localizer_->backend().name().c_str(), localizer_->filter().size(),
                 describeParams(params_, opts_).c_str());
    for (const RigCameraParams& c : rig_) {
      NODELET_INFO(
          "gmm_mcl: camera '%s': %s on %s/, pixel_stride %d, range %.2f-%.2f m, depth noise "
          "%s (a %.4g m, b %.4g 1/m, z0 %.3g m)",
          c.name.c_str(), c.depth_input.c_str(), c.name.c_str(), c.frame.pixel_stride,
          c.frame.min_range_m, c.frame.max_range_m, c.measurement.depth_noise_preset.c_str(),
          c.measurement.depth_noise.a_m, c.measurement.depth_noise.b_per_m,
          c.measurement.depth_noise.z0_m);
    }
    if (!localizer_->backendWarning().empty())
      NODELET_WARN("gmm_mcl: %s", localizer_->backendWarning().c_str());
    advertise();
  } else {  // a bad config starts nothing: no subscriptions; the node stays up and says why
    NODELET_FATAL("gmm_mcl: bad configuration, not subscribing: %s",
                  health_.snapshot().config_error.c_str());
  }
  // Diagnostics and the markers are due on ROS time, polled on wall time (PeriodicSchedule).
  diagnostics_due_.period_s = opts_.diagnostics_period_s;
  markers_.setPeriod(opts_.markers_period_s);
  poll_timer_ = getMTPrivateNodeHandle().createWallTimer(
      ros::WallDuration(0.05), [this](const ros::WallTimerEvent&) {
        if (nowS() > 0 && diagnostics_due_.due(nowS())) updater_->force_update();
        markers_.poll(nowS());
        pose_saver_.flush(getPrivateNodeHandle());
      });
}

bool LocalizationNodelet::configure(std::vector<std::string>* unknown) {
  std::string error = loadRosParams(getPrivateNodeHandle(), &params_, &opts_, unknown);
  error += loadRigCameras(getPrivateNodeHandle(), params_, opts_, &rig_, unknown);
  if (error.empty()) localizer_ = makeLocalizer(&params_, opts_, &error);
  health_.setWarnLimits(opts_.warn_sigma_xy_m, opts_.warn_sigma_yaw_rad);
  health_.set([&](NodeHealth* h) { h->config_error = error; });
  if (localizer_) health_.setBackend(localizer_->backend().name(), localizer_->backendWarning());
  if (!error.empty()) return false;
  budget_ = UpdateBudget(opts_.budget, params_);
  applyOptions();
  if (opts_.hasInitialPose()) {  // a single-pose start (or the pose saved by save_pose_rate)
    PoseResetRequest start;
    initialPose(opts_, &start.T_map_base, &start.covariance);
    std::string message;
    resetTo(start, "single-pose start: ", &message);
  }
  return true;
}

void LocalizationNodelet::advertise() {
  ros::NodeHandle &nh = getNodeHandle(), &pnh = getPrivateNodeHandle();
  tf_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(30.0));
  // On the single-threaded queue, with the depth input's tf2 message filter (header: Threads).
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_, nh, false);
  inputs_ = std::make_unique<StepInputs>(tf_.get());
  inputs_->setOptions(opts_);
  it_ = std::make_unique<image_transport::ImageTransport>(pnh);
  outputs_.advertise(pnh, *it_);
  markers_.advertise(pnh, "gmm_markers");
  markers_.set(localizer_->map(), opts_.map_frame);
  reconfigure_server_.reset(
      new dynamic_reconfigure::Server<LocalizerConfig>(reconfigure_mutex_, pnh));
  reconfigure_server_->updateConfig(toLocalizerConfig(params_, opts_));
  reconfigure_server_->setCallback(
      [this](LocalizerConfig& c, uint32_t level) { onReconfigure(c, level); });
  initialpose_sub_ = nh.subscribe("initialpose", 2, &LocalizationNodelet::onInitialPose, this);
  // IMU and odometry on the multi-threaded queue: buffered by stamp while an update runs.
  if (opts_.use_imu) {
    imu_sub_ = getMTNodeHandle().subscribe<sensor_msgs::Imu>(
        "imu", 1000, [this](const sensor_msgs::ImuConstPtr& m) {
          if (!inputs_->addImu(*m))
            NODELET_WARN_THROTTLE(5.0, "gmm_mcl: IMU message without orientation ignored");
        });
  }
  if (opts_.odometry_source == "topic") {
    odom_sub_ = getMTNodeHandle().subscribe<nav_msgs::Odometry>(
        "odom", 1000, [this](const nav_msgs::OdometryConstPtr& m) { inputs_->addOdometry(*m); });
  }
  // A frame waits for the first message of a source with a publisher (it may be on its way).
  inputs_->setConnections([this] { return imu_sub_ && imu_sub_.getNumPublishers() > 0; },
                          [this] { return odom_sub_ && odom_sub_.getNumPublishers() > 0; });
  DepthInput::Callbacks cb;
  cb.arrived = [this](const std_msgs::Header& h) { health_.arrived(h.seq, nowS()); };
  cb.camera_info = [this](const std_msgs::Header&) { health_.cameraInfo(nowS()); };
  cb.frame_clock = [this](const std_msgs::Header& h) {  // the budget's frame period
    budget_.frameArrived(h.stamp.toSec(), h.seq, nowS(), ros::WallTime::now().toSec());
  };
  cb.dropped = [this](FrameDrop d, const std::string& why) { onDrop(d, why); };
  cb.frame = [this](const std_msgs::Header& h, const DepthImage& d, const Intrinsics& K) {
    if (sets_) return onCameraFrame(0, h, d, K);
    onFrame(h, d, K);  // one camera: every frame is an update, as it always was
  };
  cb.note = [this](const std::string& note) { NODELET_WARN_ONCE("gmm_mcl: %s", note.c_str()); };
  if (!rig_.empty()) {
    sets_ = std::make_unique<FrameSets>(static_cast<int>(rig_.size()) + 1, FrameSetParams());
    applyOptions();  // the sets' parameters
    cb.arrived = [this](const std_msgs::Header& h) {
      health_.arrived(h.seq, nowS());
      health_.cameraArrived(0);
    };
  }
  input_ = std::make_unique<DepthInput>(nh, pnh, tf_.get(), opts_, cb);
  // The rig's other cameras, each like the first in its own namespace; on the same queue (the
  // tf message filters' rule above), so a set never blocks while it waits for them.
  for (size_t i = 0; i < rig_.size(); ++i) {
    const size_t camera = i + 1;
    const std::string name = rig_[i].name;
    RosOptions o = opts_;
    o.depth_input = rig_[i].depth_input;
    o.image_transport = rig_[i].image_transport;
    DepthInput::Callbacks c;
    c.arrived = [this, camera](const std_msgs::Header&) { health_.cameraArrived(camera); };
    c.camera_info = [](const std_msgs::Header&) {};
    c.frame_clock = [](const std_msgs::Header&) {};  // the budget times the first camera
    c.dropped = [this, camera, name](FrameDrop, const std::string& why) {
      health_.cameraDropped(camera);
      problem("camera '" + name + "': depth frame dropped: " + why);
    };
    c.frame = [this, camera](const std_msgs::Header& h, const DepthImage& d, const Intrinsics& K) {
      onCameraFrame(camera, h, d, K);
    };
    c.note = [this, name](const std::string& note) {
      NODELET_WARN_ONCE("gmm_mcl: camera '%s': %s", name.c_str(), note.c_str());
    };
    more_inputs_.push_back(std::make_unique<DepthInput>(nh, ros::NodeHandle(pnh, name), tf_.get(),
                                                        o, c, name, rig_[i].topic));
  }
  health_.set([this](NodeHealth* h) {
    h->depth_topic = input_->depthTopic(), h->camera_info_topic = input_->cameraInfoTopic();
    h->cameras.clear();
    if (!sets_) return;
    CameraHealth first;
    first.name = "depth";
    first.topic = input_->depthTopic();
    h->cameras.push_back(first);
    for (size_t i = 0; i < rig_.size(); ++i) {
      CameraHealth c;
      c.name = rig_[i].name;
      c.topic = more_inputs_[i]->depthTopic();
      h->cameras.push_back(c);
    }
  });
  // Services last: once they answer, every subscription is in place.
  global_srv_ =
      pnh.advertiseService("global_localization", &LocalizationNodelet::onGlobalLocalization, this);
  reset_srv_ = pnh.advertiseService("reset_to_pose", &LocalizationNodelet::onResetToPose, this);
  map_srv_ = pnh.advertiseService("reload_map", &LocalizationNodelet::onLoadMap, this);
}

void LocalizationNodelet::onDrop(FrameDrop reason, const std::string& why) {
  health_.dropped(reason);
  problem("depth frame dropped: " + why);
}

void LocalizationNodelet::problem(const std::string& what, bool warn) {
  if (warn) NODELET_WARN_THROTTLE(2.0, "gmm_mcl: %s", what.c_str());
  health_.problem(what, nowS());
}

void LocalizationNodelet::jumpedBack(const ros::Time& stamp) {
  // A looped bag or a restarted clock: old transforms and odometry are meaningless now; the
  // core re-initialises the filter itself on the earlier stamp (StepStatus::kTimeJumpBack).
  NODELET_WARN(
      "gmm_mcl: time jumped back from %.3f to %.3f s: clearing tf and the buffers, re-initialising",
      last_stamp_.toSec(), stamp.toSec());
  inputs_->timeJumpedBack(stamp);
  have_map_odom_ = have_step_odom_ = false;
  outputs_.restartTransforms();
  pose_saver_.restart();
  gate_.force();
  markers_.publish();  // rviz clears its displays on a jump back
  health_.count(&FrameCounters::time_jumps);
  health_.count(&FrameCounters::resets);
  problem("time jumped back", false);
}

void LocalizationNodelet::onFrame(const std_msgs::Header& header, const DepthImage& depth,
                                  const Intrinsics& K, const FrameSet* set) {
  const auto t0 = std::chrono::steady_clock::now();
  const ros::Time stamp = header.stamp;
  if (have_step_ && (stamp - last_stamp_).toSec() < -kTimeJumpToleranceS) jumpedBack(stamp);
  StepInput in;
  StepInputs::Gaps gaps;
  std::string why;
  std::vector<std::string> problems;
  // A set: every camera's extrinsics by fillCameras (before gather(), which may clear tf); one
  // without them is left out of the set, said why, and the others go on.
  if (set) fillCameras(*set, &in, &problems);
  if (!inputs_->gather(header, &in, &gaps, &why, !set)) return onDrop(FrameDrop::kExtrinsics, why);
  if (gaps.odometry) health_.count(&FrameCounters::odometry_gaps);
  if (gaps.imu) health_.count(&FrameCounters::imu_missing);
  if (gaps.odometry || gaps.imu) problem(gaps.warnings);
  const bool gated = !gate_.shouldUpdate(in.has_odometry, in.T_odom_base);
  Eigen::Isometry3d T_map_base = T_map_odom_ * in.T_odom_base;  // hovering: follows odometry
  if (!gated) {
    if (!set) {
      in.depth = &depth;
      in.intrinsics = K;
    } else if (set->frames[0] && problems[0].empty()) {
      in.depth = &set->frames[0]->depth;
      in.intrinsics = set->frames[0]->intrinsics;
    }
    last_result_ = localizer_->step(in);
    gate_.updated(in.has_odometry, in.T_odom_base);
    T_map_base =
        particleToPose(last_result_.estimate.mean, localizer_->rollRad(), localizer_->pitchRad());
    const StepStatus st = last_result_.status;
    if (st != StepStatus::kOk && st != StepStatus::kTimeJumpBack) {
      problem(std::string("update ") + stepStatusName(st) + ": " + last_result_.message);
    } else if (last_result_.odometry_jump) {
      problem(last_result_.message);
    }
    logMotionSource(in.has_odometry);
  }
  if (opts_.mapToBase() || in.has_odometry) {
    T_map_odom_ = opts_.mapToBase() ? T_map_base : T_map_base * in.T_odom_base.inverse();
    have_map_odom_ = true;
  }
  if (in.has_odometry) T_odom_base_last_ = in.T_odom_base, have_step_odom_ = true;
  have_step_ = true;
  last_stamp_ = stamp;
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (set) recordCameras(*set, last_result_, problems);
  publish(header, last_result_, T_map_base, depth, K, ms, gaps.warnings, gated, set);
  markers_.follow(T_map_base.translation());
  if (!gated) {
    budgetUpdate(
        last_result_,
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    // amcl's pose persistence, written by the poll timer
    CameraScales camera_scales;
    for (size_t c = 1; c < last_result_.cameras.size(); ++c) {
      camera_scales.emplace_back(last_result_.cameras[c].name, last_result_.cameras[c].depth_scale);
    }
    pose_saver_.offer(opts_.save_pose_rate_hz, stamp, last_result_.estimate.mean,
                      last_result_.estimate.covariance, last_result_.depth_scale, camera_scales);
  }
}

void LocalizationNodelet::onCameraFrame(size_t camera, const std_msgs::Header& header,
                                        const DepthImage& depth, const Intrinsics& K) {
  CameraFrame f;
  f.header = header;
  f.depth = depth;
  f.intrinsics = K;
  sets_->add(static_cast<int>(camera), std::move(f));
  drainSets();
}

void LocalizationNodelet::drainSets() {
  FrameSet set;
  while (sets_->takeReady(&set)) {
    if (set.lead != last_lead_) {
      const FrameSetParams& p = sets_->params();
      if (set.lead == 0) {
        NODELET_INFO("gmm_mcl: camera 'depth' delivers again: its frames lead the frame sets");
      } else {
        NODELET_WARN(
            "gmm_mcl: camera '%s' leads the frame sets: no frame of the cameras before it for "
            "more than %.3g s (camera_timeout)",
            rig_[set.lead - 1].name.c_str(), p.timeout_s);
      }
      last_lead_ = set.lead;
    }
    const CameraFrame& lead = *set.frames[set.lead];
    onFrame(lead.header, lead.depth, lead.intrinsics, &set);
  }
  for (const CameraTransition& t : sets_->takeTransitions()) {
    const std::string name = t.camera == 0 ? "depth" : rig_[t.camera - 1].name;
    if (t.dropped_out) {
      NODELET_WARN(
          "gmm_mcl: camera '%s' dropped out: no frame for %.3g s: updating with the others",
          name.c_str(), t.gap_s);
    } else {
      NODELET_INFO("gmm_mcl: camera '%s' is back after %.3g s: used again", name.c_str(), t.gap_s);
    }
  }
  // The first camera's frames that no set took: dropped, so that its frames stay accounted for.
  for (; first_dropped_in_sets_ < sets_->stats(0).dropped; ++first_dropped_in_sets_)
    health_.dropped(FrameDrop::kFrameSet);
  health_.set([this](NodeHealth* h) {
    for (size_t i = 0; i < h->cameras.size(); ++i) h->cameras[i].sets = sets_->stats(i);
  });
  if (!sets_->pending()) {
    set_timer_.stop();
  } else if (armed_generation_ != sets_->generation()) {
    armed_generation_ = sets_->generation();
    const unsigned long generation = armed_generation_;
    set_timer_ = getNodeHandle().createWallTimer(
        ros::WallDuration(std::max(sets_->params().wait_s, 1e-6)),
        [this, generation](const ros::WallTimerEvent&) {
          sets_->expire(generation);
          drainSets();
        },
        true);
  }
}

void LocalizationNodelet::fillCameras(const FrameSet& set, StepInput* in,
                                      std::vector<std::string>* problems) {
  problems->assign(set.frames.size(), "");
  if (!set.frames[0]) {
    (*problems)[0] = "no frame in this set";
  } else {
    in->has_T_base_cam =
        inputs_->extrinsicsAt(set.frames[0]->header, 0, &in->T_base_cam, &(*problems)[0]);
    if (!in->has_T_base_cam) problem("camera 'depth': " + (*problems)[0]);
  }
  for (size_t i = 1; i < set.frames.size(); ++i) {
    const RigCameraParams& p = rig_[i - 1];
    CameraInput c;
    c.name = p.name;
    c.frame = p.frame;
    c.measurement = p.measurement;
    c.depth_scale_initial = p.depth_scale_initial;
    const CameraFrame* f = set.frames[i].get();
    if (!f) {
      (*problems)[i] = "no frame in this set";
    } else if (inputs_->extrinsicsAt(f->header, i, &c.T_base_cam, &(*problems)[i])) {
      c.depth = &f->depth;
      c.intrinsics = f->intrinsics;
    } else {
      problem("camera '" + p.name + "': " + (*problems)[i]);
    }
    in->more_cameras.push_back(c);
  }
}

void LocalizationNodelet::recordCameras(const FrameSet& set, const StepResult& r,
                                        const std::vector<std::string>& problems) {
  health_.set([&](NodeHealth* h) {
    for (size_t i = 0; i < h->cameras.size() && i < set.frames.size(); ++i) {
      CameraHealth& c = h->cameras[i];
      c.leads = static_cast<int>(i) == set.lead;
      c.in_last_set = set.frames[i] != nullptr;
      c.sets = sets_->stats(i);
      if (i < r.cameras.size()) {  // the core's word (one per camera when given more_cameras)
        c.used_last = r.cameras[i].used;
        c.pixels = r.cameras[i].pixels;
        c.depth_scale = r.cameras[i].depth_scale;
        c.depth_scale_at_bound = r.cameras[i].depth_scale_at_bound;
        c.problem = problems[i].empty() ? r.cameras[i].problem : problems[i];
      } else {
        c.used_last = false;
        c.pixels = 0;
        c.problem = problems[i].empty() ? "not reported by the filter" : problems[i];
      }
    }
  });
}

void LocalizationNodelet::logMotionSource(bool has_odometry) {
  // Odometry that appears after the filter ran without it is used from its second message on
  // (the first has no delta); both changes are logged once (docs/no_odometry.md).
  if (has_odometry && frames_without_odometry_ > 0) {
    NODELET_INFO(
        "gmm_mcl: odometry arrived after %d updates without it: the filter predicts with "
        "it from the next update on",
        frames_without_odometry_);
  } else if (!has_odometry && frames_without_odometry_ == 0) {
    NODELET_INFO("gmm_mcl: %s: predicting with %s",
                 opts_.odometry_source == "none" ? "odometry_source none" : "no odometry",
                 localizer_->params().constant_velocity.enabled
                     ? "the constant-velocity model of the filter's own estimates"
                     : "no motion (cv_model false)");
  }
  frames_without_odometry_ = has_odometry ? 0 : frames_without_odometry_ + 1;
}

void LocalizationNodelet::publish(const std_msgs::Header& header, const StepResult& r,
                                  const Eigen::Isometry3d& T_map_base, const DepthImage& depth,
                                  const Intrinsics& K, double callback_ms,
                                  const std::string& warnings, bool gated, const FrameSet* set) {
  outputs_.poses(header, r, T_map_base, gated, opts_.map_frame);
  const std::string& child = opts_.mapToBase() ? opts_.base_frame : opts_.odom_frame;
  const bool send_tf =  // future-dated by transform_tolerance from the frame stamp
      opts_.tf_broadcast && have_map_odom_ &&
      outputs_.transform(T_map_odom_, opts_.map_frame, child,
                         header.stamp + ros::Duration(opts_.transform_tolerance_s));
  outputs_.particles(header, *localizer_, opts_.map_frame);
  FilterStatus s =
      health_.frame(r, gated, send_tf, nowS(), params_.lost, localizer_->backend().name(),
                    localizer_->backendWarning(), callback_ms, warnings, inputs_->imuReceived(),
                    inputs_->odometryReceived(), !set || set->frames[0] != nullptr);
  s.header = header;
  fillBudgetStatus(budget_.state(), &s);
  if (set) fillCameraStatus(health_.snapshot(), header.stamp.toSec(), &s);
  outputs_.status(s);
  outputs_.debugImage(header, depth, K, *localizer_,
                      T_map_base * inputs_->extrinsics(set ? set->lead : 0));
}

void LocalizationNodelet::budgetUpdate(const StepResult& r, double callback_ms) {
  if (budget_.stepTook(r, callback_ms)) {
    applyBudget();
    NODELET_INFO("gmm_mcl: %s", budget_.describe().c_str());
  }
  health_.set([this](NodeHealth* h) { h->budget = budget_.state(); });
}

void LocalizationNodelet::applyBudget() {
  const std::string error = budget_.applyTo(params_, localizer_.get());
  if (!error.empty()) NODELET_ERROR("gmm_mcl: update budget not applied: %s", error.c_str());
}

// ---- resets, services, parameters -----------------------------------------------------------

bool LocalizationNodelet::applyPose(const geometry_msgs::PoseWithCovarianceStamped& msg,
                                    std::string* message) {
  PoseResetRequest r;
  if (!ros_conv::poseResetRequestFromMsg(msg, *tf_, opts_.map_frame, &r, message)) {
    NODELET_ERROR("gmm_mcl: initial pose ignored: %s", message->c_str());
    return false;
  }
  std::string note;  // a stamp older than the last update: carried forward by odometry
  if (have_step_ && have_step_odom_ && !msg.header.stamp.isZero() &&
      msg.header.stamp < last_stamp_) {
    r.carry_forward = inputs_->odometryAt(msg.header.stamp, &r.T_odom_base_then, &note);
    r.T_odom_base_now = T_odom_base_last_;
    r.age_s = (last_stamp_ - msg.header.stamp).toSec();
    if (!r.carry_forward) note = "stale stamp and " + note + ": used as is; ";
  }
  return resetTo(r, note, message);
}

bool LocalizationNodelet::resetTo(const PoseResetRequest& r, const std::string& note,
                                  std::string* message) {
  const PoseEstimate current = localizer_->filter().estimate();
  const PoseReset out = resolvePoseReset(r, have_step_ ? &current : nullptr,
                                         params_.init.centre_m.z(), opts_.defaultPoseSigma());
  *message = note + out.message;
  if (!out.ok) {
    NODELET_ERROR("gmm_mcl: initial pose: %s", message->c_str());
    return false;
  }
  localizer_->resetToPose(out.pose, out.sigma);
  gate_.force();
  health_.count(&FrameCounters::resets);
  NODELET_INFO("gmm_mcl: %s", message->c_str());
  return true;
}

void LocalizationNodelet::onInitialPose(
    const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
  std::string message;  // logged by applyPose
  applyPose(*msg, &message);
}

bool LocalizationNodelet::onResetToPose(ResetToPose::Request& req, ResetToPose::Response& res) {
  res.success = applyPose(req.pose, &res.message);
  return true;
}

bool LocalizationNodelet::onGlobalLocalization(std_srvs::Empty::Request&,
                                               std_srvs::Empty::Response&) {
  const InitRegion r = localizer_->mapBounds();
  localizer_->reset(r);
  gate_.force();
  health_.count(&FrameCounters::resets);
  NODELET_INFO("gmm_mcl: global localization: uniform over the map's %.1f x %.1f x %.1f m",
               2 * r.half_extent_m.x(), 2 * r.half_extent_m.y(), 2 * r.half_extent_m.z());
  return true;
}

bool LocalizationNodelet::onLoadMap(LoadMap::Request& req, LoadMap::Response& res) {
  const std::string path = req.path.empty() ? opts_.map_path : req.path;
  std::string summary;
  try {
    localizer_->setMap(loadNodeMap(path, opts_, &summary));  // a cloud: fitted or its cache
  } catch (const std::exception& e) {
    res.message = "map not loaded, the previous one is kept: " + std::string(e.what());
    NODELET_ERROR("gmm_mcl: %s", res.message.c_str());
    return true;
  }
  opts_.map_path = path;
  gate_.force();
  markers_.set(localizer_->map(), opts_.map_frame);
  res.success = true;
  res.components = static_cast<int32_t>(localizer_->map().size());
  res.message = "loaded: " + summary + "; particles kept";
  NODELET_INFO("gmm_mcl: %s", res.message.c_str());
  return true;
}

void LocalizationNodelet::onReconfigure(LocalizerConfig& config, uint32_t) {
  std::string changes;
  // The new values within the budget's current choice (the budget's own new bounds follow).
  const std::string error = reconfigure(
      &config, &params_, &opts_,
      [this](const LocalizerParams& p) { localizer_->setParams(budget_.apply(p)); }, &changes);
  if (!error.empty()) {
    NODELET_ERROR("gmm_mcl: reconfigure refused, previous values kept: %s", error.c_str());
    return;
  }
  applyOptions();
  if (!changes.empty()) NODELET_INFO("gmm_mcl: reconfigured, particles kept: %s", changes.c_str());
}

// The run-time options (at start and on dynamic_reconfigure), the budget's choice with them.
void LocalizationNodelet::applyOptions() {
  if (inputs_) inputs_->setOptions(opts_);
  if (sets_) {
    FrameSetParams p;
    p.window_s = opts_.camera_set_window_s;
    p.wait_s = opts_.camera_set_wait_s;
    p.timeout_s = opts_.camera_timeout_s;
    sets_->setParams(p);
    health_.set([&p](NodeHealth* h) { h->timeout_s = p.timeout_s; });
  }
  gate_.setThresholds(opts_.update_min_d_m, opts_.update_min_a_rad);
  markers_.setPeriod(opts_.markers_period_s);
  markers_.setLimits(opts_.markers_max, opts_.markers_radius_m);
  health_.setWarnLimits(opts_.warn_sigma_xy_m, opts_.warn_sigma_yaw_rad);
  budget_.configure(opts_.budget, params_);
  applyBudget();
  health_.set([this](NodeHealth* h) { h->budget = budget_.state(); });
}

void LocalizationNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  NodeHealth h = health_.snapshot();
  h.now_s = nowS();
  if (inputs_)
    h.counters.imu_received = inputs_->imuReceived(),
    h.counters.odometry_received = inputs_->odometryReceived();
  const Diagnosis d = gmm_mcl::diagnose(h);  // a plain function of the snapshot (node_status.h)
  stat.summary(d.level, d.message);
  for (const auto& kv : d.values) stat.add(kv.first, kv.second);
}

}  // namespace gmm_mcl

PLUGINLIB_EXPORT_CLASS(gmm_mcl::LocalizationNodelet, nodelet::Nodelet)
