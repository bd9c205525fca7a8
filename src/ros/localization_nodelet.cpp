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
  DepthInput::Callbacks cb;
  cb.arrived = [this](const std_msgs::Header& h) { health_.arrived(h.seq, nowS()); };
  cb.camera_info = [this](const std_msgs::Header&) { health_.cameraInfo(nowS()); };
  cb.frame_clock = [this](const std_msgs::Header& h) {  // the budget's frame period
    budget_.frameArrived(h.stamp.toSec(), h.seq, nowS(), ros::WallTime::now().toSec());
  };
  cb.dropped = [this](FrameDrop d, const std::string& why) { onDrop(d, why); };
  cb.frame = [this](const std_msgs::Header& h, const DepthImage& d, const Intrinsics& K) {
    onFrame(h, d, K);
  };
  cb.note = [this](const std::string& note) { NODELET_WARN_ONCE("gmm_mcl: %s", note.c_str()); };
  input_ = std::make_unique<DepthInput>(nh, pnh, tf_.get(), opts_, cb);
  health_.set([this](NodeHealth* h) {
    h->depth_topic = input_->depthTopic(), h->camera_info_topic = input_->cameraInfoTopic();
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
                                  const Intrinsics& K) {
  const auto t0 = std::chrono::steady_clock::now();
  const ros::Time stamp = header.stamp;
  if (have_step_ && (stamp - last_stamp_).toSec() < -kTimeJumpToleranceS) jumpedBack(stamp);
  StepInput in;
  StepInputs::Gaps gaps;
  std::string why;
  if (!inputs_->gather(header, &in, &gaps, &why)) return onDrop(FrameDrop::kExtrinsics, why);
  if (gaps.odometry) health_.count(&FrameCounters::odometry_gaps);
  if (gaps.imu) health_.count(&FrameCounters::imu_missing);
  if (gaps.odometry || gaps.imu) problem(gaps.warnings);
  const bool gated = !gate_.shouldUpdate(in.has_odometry, in.T_odom_base);
  Eigen::Isometry3d T_map_base = T_map_odom_ * in.T_odom_base;  // hovering: follows odometry
  if (!gated) {
    in.depth = &depth;
    in.intrinsics = K;
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
  publish(header, last_result_, T_map_base, depth, K, ms, gaps.warnings, gated);
  markers_.follow(T_map_base.translation());
  if (!gated) {
    budgetUpdate(
        last_result_,
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    // amcl's pose persistence, written by the poll timer
    pose_saver_.offer(opts_.save_pose_rate_hz, stamp, last_result_.estimate.mean,
                      last_result_.estimate.covariance, last_result_.depth_scale);
  }
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
                                  const std::string& warnings, bool gated) {
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
                    inputs_->odometryReceived());
  s.header = header;
  fillBudgetStatus(budget_.state(), &s);
  outputs_.status(s);
  outputs_.debugImage(header, depth, K, *localizer_, T_map_base * inputs_->extrinsics());
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
