#include "gmm_mcl/ros/localization_nodelet.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <pluginlib/class_list_macros.hpp>
#include <visualization_msgs/MarkerArray.h>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros/debug_image.h"

namespace gmm_mcl {
namespace {

double wallNowS() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Odometry history kept for /initialpose carry-forward and the topic source.
constexpr double kOdomHistoryS = 10.0;
// A frame stamp earlier than the last one by more than this is a jump back (looped bag).
constexpr double kTimeJumpToleranceS = 1e-3;

}  // namespace

LocalizationNodelet::LocalizationNodelet() = default;
LocalizationNodelet::~LocalizationNodelet() = default;

void LocalizationNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();

  updater_.reset(new diagnostic_updater::Updater(nh, pnh));
  updater_->setHardwareID("gmm_mcl");
  updater_->add("localization", this, &LocalizationNodelet::diagnose);

  config_error_ = loadRosParams(pnh, &params_, &opts_);
  if (config_error_.empty()) {
    try {
      map_.reset(new GmmMap(loadMap(opts_.map_path)));
    } catch (const std::exception& e) {
      config_error_ = std::string("cannot load the map: ") + e.what();
    }
  }
  if (config_error_.empty() && opts_.init_from_map_bounds) {
    // The same region as Localizer::mapBounds(), computed before the localizer exists.
    Localizer probe(params_, *map_);
    params_.init = probe.mapBounds();
  }
  diagnostics_timer_ = pnh.createTimer(
      ros::Duration(opts_.diagnostics_period_s > 0 ? opts_.diagnostics_period_s : 1.0),
      [this](const ros::TimerEvent&) { updater_->update(); });
  if (!config_error_.empty()) {
    // A bad config starts nothing: no subscriptions; the node stays up and says why.
    NODELET_FATAL("gmm_mcl: bad configuration, not subscribing: %s", config_error_.c_str());
    updater_->force_update();
    return;
  }
  NODELET_INFO("gmm_mcl: %zu components from %s\n  %s", map_->size(), opts_.map_path.c_str(),
               describeParams(params_, opts_).c_str());

  tf_buffer_.reset(new tf2_ros::Buffer(ros::Duration(30.0)));
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  tf_broadcaster_.reset(new tf2_ros::TransformBroadcaster());

  pose_pub_ = pnh.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
  particles_pub_ = pnh.advertise<geometry_msgs::PoseArray>("particles", 2);
  status_pub_ = pnh.advertise<FilterStatus>("status", 10);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("gmm_markers", 1, true);
  debug_image_pub_ = pnh.advertise<sensor_msgs::Image>("debug_image", 1);
  visualization_msgs::MarkerArray markers;
  ros_conv::markersFromMap(*map_, opts_.map_frame, &markers);
  markers_pub_.publish(markers);

  reconfigure_server_.reset(new dynamic_reconfigure::Server<LocalizerConfig>(reconfigure_mutex_, pnh));
  LocalizerConfig initial;
  initial.sigma_translation_m = params_.filter.sigma_translation_m;
  initial.sigma_yaw_rad = params_.filter.sigma_yaw_rad;
  initial.weighting = weightingModeName(params_.filter.weighting);
  initial.temperature = params_.filter.temperature;
  initial.neff_floor_fraction = params_.filter.neff_floor_fraction;
  initial.resample_neff_fraction = params_.filter.resample_neff_fraction;
  initial.alpha_slow = params_.filter.alpha_slow;
  initial.alpha_fast = params_.filter.alpha_fast;
  initial.recovery_threshold = params_.filter.recovery_threshold;
  reconfigure_server_->updateConfig(initial);
  reconfigure_server_->setCallback(
      [this](LocalizerConfig& config, uint32_t level) { reconfigure(config, level); });

  global_srv_ = pnh.advertiseService("global_localization", &LocalizationNodelet::globalLocalization, this);
  reset_srv_ = pnh.advertiseService("reset_to_pose", &LocalizationNodelet::resetToPose, this);
  initialpose_sub_ = nh.subscribe("initialpose", 2, &LocalizationNodelet::initialPoseCallback, this);
  if (opts_.use_imu) imu_sub_ = nh.subscribe("imu", 50, &LocalizationNodelet::imuCallback, this);
  if (opts_.odometry_source == "topic") {
    odom_sub_ = nh.subscribe("odom", 100, &LocalizationNodelet::odomCallback, this);
  }
  if (opts_.depth_input == "image" && opts_.image_transport == "compressedDepth") {
    const std::string image_topic = nh.resolveName("depth/image");
    const std::string info_topic = image_transport::getCameraInfoTopic(image_topic);
    compressed_sub_.reset(new message_filters::Subscriber<sensor_msgs::CompressedImage>(
        nh, image_topic + "/compressedDepth", static_cast<uint32_t>(opts_.queue_size)));
    info_sub_.reset(new message_filters::Subscriber<sensor_msgs::CameraInfo>(
        nh, info_topic, static_cast<uint32_t>(opts_.queue_size)));
    compressed_sync_.reset(new message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>(
        *compressed_sub_, *info_sub_, 5));
    compressed_sync_->registerCallback(
        boost::bind(&LocalizationNodelet::compressedDepthCallback, this, boost::placeholders::_1, boost::placeholders::_2));
  } else if (opts_.depth_input == "image") {
    it_.reset(new image_transport::ImageTransport(nh));
    // ~image_transport (raw, compressedDepth, ...) picks the transport.
    camera_sub_ = it_->subscribeCamera("depth/image", static_cast<uint32_t>(opts_.queue_size),
                                       &LocalizationNodelet::depthCallback, this,
                                       image_transport::TransportHints(opts_.image_transport, ros::TransportHints(), pnh));
  } else {
    cloud_sub_ = nh.subscribe("depth/points", static_cast<uint32_t>(opts_.queue_size),
                              &LocalizationNodelet::cloudCallback, this);
  }
  configured_ = true;
}

// ---- inputs ---------------------------------------------------------------------------------

void LocalizationNodelet::frameReceived(const std_msgs::Header& header) {
  ++frames_received_;
  last_input_wall_ = ros::WallTime::now();
  // A publisher's seq grows by one per message; a smaller one is a restarted publisher.
  if (have_last_seq_ && header.seq > last_seq_ + 1) frames_missed_seq_ += header.seq - last_seq_ - 1;
  have_last_seq_ = true;
  last_seq_ = header.seq;
}

void LocalizationNodelet::frameRejected(const std::string& what, const std::string& why,
                                        long long* reason) {
  ++frames_rejected_;
  ++*reason;
  last_problem_ = what + ": " + why;
  last_problem_time_ = ros::WallTime::now();
  NODELET_ERROR_THROTTLE(2.0, "gmm_mcl: %s dropped: %s", what.c_str(), why.c_str());
}

void LocalizationNodelet::depthCallback(const sensor_msgs::ImageConstPtr& image,
                                        const sensor_msgs::CameraInfoConstPtr& info) {
  const double t0 = wallNowS();
  std::lock_guard<std::mutex> lock(mutex_);
  frameReceived(image->header);
  DepthImage depth;
  std::string why;
  if (!ros_conv::depthImageFromMsg(*image, &depth, &why)) {
    return frameRejected("depth frame", why, &dropped_conversion_);
  }
  Intrinsics K;
  if (!ros_conv::intrinsicsFromCameraInfo(*info, depth.width_px, depth.height_px, &K, &why)) {
    return frameRejected("depth frame", why, &dropped_camera_info_);
  }
  processFrame(image->header, depth, K, t0);
}

void LocalizationNodelet::compressedDepthCallback(const sensor_msgs::CompressedImageConstPtr& image,
                                                  const sensor_msgs::CameraInfoConstPtr& info) {
  const double t0 = wallNowS();
  std::lock_guard<std::mutex> lock(mutex_);
  frameReceived(image->header);
  DepthImage depth;
  std::string why;
  if (!ros_conv::depthImageFromCompressedDepth(*image, &depth, &why)) {
    return frameRejected("depth frame", why, &dropped_conversion_);
  }
  Intrinsics K;
  if (!ros_conv::intrinsicsFromCameraInfo(*info, depth.width_px, depth.height_px, &K, &why)) {
    return frameRejected("depth frame", why, &dropped_camera_info_);
  }
  processFrame(image->header, depth, K, t0);
}

void LocalizationNodelet::cloudCallback(const sensor_msgs::PointCloud2ConstPtr& cloud) {
  const double t0 = wallNowS();
  std::lock_guard<std::mutex> lock(mutex_);
  frameReceived(cloud->header);
  DepthImage depth;
  Intrinsics K;
  std::string why;
  if (!ros_conv::depthImageFromCloud(*cloud, &depth, &K, &why)) {
    return frameRejected("point cloud", why, &dropped_conversion_);
  }
  processFrame(cloud->header, depth, K, t0);
}

void LocalizationNodelet::imuCallback(const sensor_msgs::ImuConstPtr& imu) {
  double roll, pitch;
  if (!ros_conv::attitudeFromImu(*imu, &roll, &pitch)) {
    NODELET_WARN_THROTTLE(5.0, "gmm_mcl: IMU message without orientation ignored");
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  have_imu_ = true;
  imu_stamp_ = imu->header.stamp;
  imu_roll_rad_ = roll;
  imu_pitch_rad_ = pitch;
}

void LocalizationNodelet::odomCallback(const nav_msgs::OdometryConstPtr& odom) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!odom_history_.empty() && odom->header.stamp < odom_history_.back().header.stamp) {
    odom_history_.clear();  // time went back: the next frame resets the filter
  }
  odom_history_.push_back(*odom);
  while (!odom_history_.empty() &&
         (odom->header.stamp - odom_history_.front().header.stamp).toSec() > kOdomHistoryS) {
    odom_history_.pop_front();
  }
}

bool LocalizationNodelet::lookupExtrinsics(const std::string& camera_frame, const ros::Time& stamp,
                                           Eigen::Isometry3d* T_base_cam) {
  try {
    const geometry_msgs::TransformStamped t =
        tf_buffer_->lookupTransform(opts_.base_frame, camera_frame, ros::Time(0));
    *T_base_cam = ros_conv::isometryFromTransform(t.transform);
    T_base_cam_ = *T_base_cam;
    camera_frame_ = camera_frame;
    have_T_base_cam_ = true;
    return true;
  } catch (const tf2::TransformException& e) {
    // Extrinsics are static: after a tf buffer reset (time jump) the last ones still hold.
    if (have_T_base_cam_ && camera_frame == camera_frame_) {
      *T_base_cam = T_base_cam_;
      return true;
    }
    ++tf_failures_;
    ++dropped_extrinsics_;
    ++frames_rejected_;
    last_problem_ = "no transform " + opts_.base_frame + " -> " + camera_frame + ": " + e.what();
    last_problem_time_ = ros::WallTime::now();
    NODELET_WARN_THROTTLE(2.0, "gmm_mcl: frame at %.3f dropped: %s", stamp.toSec(),
                          last_problem_.c_str());
    return false;
  }
}

bool LocalizationNodelet::odometryAt(const ros::Time& stamp, Eigen::Isometry3d* T_odom_base,
                                     std::string* why) {
  if (opts_.odometry_source == "none") return false;
  if (opts_.odometry_source == "tf") {
    try {
      const geometry_msgs::TransformStamped t = tf_buffer_->lookupTransform(
          opts_.odom_frame, opts_.base_frame, stamp, ros::Duration(opts_.tf_timeout_s));
      *T_odom_base = ros_conv::isometryFromTransform(t.transform);
      return true;
    } catch (const tf2::TransformException& e) {
      *why = std::string("no odometry tf at the frame stamp: ") + e.what();
      return false;
    }
  }
  // Topic: the message nearest to the stamp, within odom_timeout.
  const nav_msgs::Odometry* best = nullptr;
  double best_dt = 1e300;
  for (const auto& o : odom_history_) {
    const double dt = std::abs((o.header.stamp - stamp).toSec());
    if (dt < best_dt) {
      best_dt = dt;
      best = &o;
    }
  }
  if (best == nullptr || best_dt > opts_.odom_timeout_s) {
    std::ostringstream s;
    s << "odometry gap: ";
    if (best == nullptr) s << "no odometry received";
    else s << "nearest odometry is " << best_dt << " s from the frame";
    *why = s.str();
    return false;
  }
  *T_odom_base = ros_conv::isometryFromPose(best->pose.pose);
  return true;
}

void LocalizationNodelet::ensureLocalizer(const Eigen::Isometry3d& T_base_cam) {
  if (localizer_ && localizer_->params().T_base_cam.isApprox(T_base_cam, 1e-9)) return;
  LocalizerParams p = params_;
  p.T_base_cam = T_base_cam;
  const bool had = static_cast<bool>(localizer_);
  PoseEstimate previous;
  if (had) previous = localizer_->filter().estimate();
  localizer_.reset(new Localizer(p, *map_));
  params_ = p;
  if (!localizer_->backendWarning().empty()) {
    NODELET_WARN("gmm_mcl: %s", localizer_->backendWarning().c_str());
  }
  NODELET_INFO("gmm_mcl: localizer ready, %d particles, %s backend", p.filter.num_particles,
               localizer_->backend().name().c_str());
  if (had) {
    // New extrinsics: keep the belief as a Gaussian around the previous estimate.
    const Eigen::Vector4d sigma(std::sqrt(previous.covariance(0, 0)), std::sqrt(previous.covariance(1, 1)),
                                std::sqrt(previous.covariance(2, 2)), std::sqrt(previous.covariance(5, 5)));
    localizer_->resetToPose(previous.mean, sigma.cwiseMax(1e-3));
  }
  if (pending_reset_ == "global") localizer_->reset(localizer_->mapBounds());
  pending_reset_.clear();
  if (pending_pose_) {
    std::string msg;
    pending_pose_ = false;
    applyPoseReset(pending_pose_msg_, &msg);
  }
}

void LocalizationNodelet::processFrame(const std_msgs::Header& header, const DepthImage& depth,
                                       const Intrinsics& K, double t_callback_start_s) {
  const ros::Time stamp = header.stamp;
  std::string warnings;
  if (have_last_frame_ && (stamp - last_frame_stamp_).toSec() < -kTimeJumpToleranceS) {
    // A looped bag or a restarted clock: old transforms and odometry are meaningless now. The
    // core resets the filter itself on the earlier stamp (StepStatus::kTimeJumpBack).
    ++time_jumps_;
    ++resets_;
    NODELET_WARN("gmm_mcl: time jumped back from %.3f to %.3f s: clearing tf and odometry, "
                 "re-initialising the filter", last_frame_stamp_.toSec(), stamp.toSec());
    tf_buffer_->clear();
    // Keep what already belongs to the new timeline (stamped at or before this frame).
    while (!odom_history_.empty() && odom_history_.back().header.stamp > stamp) odom_history_.pop_back();
    while (!odom_history_.empty() && odom_history_.front().header.stamp > stamp) odom_history_.pop_front();
    if (have_imu_ && imu_stamp_ > stamp) have_imu_ = false;
    have_step_odom_ = false;
    have_map_odom_ = false;
    last_tf_stamp_ = ros::Time();
    last_problem_ = "time jumped back";
    last_problem_time_ = ros::WallTime::now();
  }

  Eigen::Isometry3d T_base_cam;
  if (!lookupExtrinsics(header.frame_id, stamp, &T_base_cam)) return;
  ensureLocalizer(T_base_cam);

  StepInput in;
  in.stamp_s = stamp.toSec();
  std::string why;
  in.has_odometry = odometryAt(stamp, &in.T_odom_base, &why);
  if (!in.has_odometry && opts_.odometry_source != "none") {
    ++odom_gaps_;
    warnings += why + "; ";
    last_problem_ = why;
    last_problem_time_ = ros::WallTime::now();
    NODELET_WARN_THROTTLE(2.0, "gmm_mcl: %s (predicting without motion)", why.c_str());
  }
  if (opts_.use_imu) {
    if (have_imu_ && std::abs((imu_stamp_ - stamp).toSec()) <= opts_.imu_timeout_s) {
      in.has_attitude = true;
      in.roll_rad = imu_roll_rad_;
      in.pitch_rad = imu_pitch_rad_;
    } else {
      ++imu_missing_;
      const std::string w = have_imu_ ? "IMU attitude is stale" : "no IMU attitude received";
      warnings += w + " (roll/pitch from odometry); ";
      last_problem_ = w;
      last_problem_time_ = ros::WallTime::now();
      NODELET_WARN_THROTTLE(5.0, "gmm_mcl: %s: roll/pitch from odometry", w.c_str());
    }
  }
  in.depth = &depth;
  in.intrinsics = K;
  const StepResult r = localizer_->step(in);
  ++frames_;
  reinitialised_total_ += r.reinitialised;
  if (r.lost) ++lost_events_total_;
  have_last_frame_ = true;
  last_frame_stamp_ = stamp;
  if (r.status == StepStatus::kTimeJumpBack) {
    // The core saw it too (e.g. a jump smaller than our tolerance); nothing more to do here.
  } else if (r.status != StepStatus::kOk) {
    last_problem_ = std::string(stepStatusName(r.status)) + ": " + r.message;
    last_problem_time_ = ros::WallTime::now();
    NODELET_WARN_THROTTLE(2.0, "gmm_mcl: update %s: %s", stepStatusName(r.status), r.message.c_str());
  }
  if (r.odometry_jump) NODELET_WARN_THROTTLE(2.0, "gmm_mcl: %s", r.message.c_str());

  const Eigen::Isometry3d T_map_base =
      particleToPose(r.estimate.mean, localizer_->rollRad(), localizer_->pitchRad());
  if (opts_.odom_frame.empty() || opts_.odometry_source == "none") {
    T_map_odom_ = T_map_base;  // published as map -> base_frame
    have_map_odom_ = true;
  } else if (in.has_odometry) {
    T_map_odom_ = T_map_base * in.T_odom_base.inverse();
    have_map_odom_ = true;
  }
  if (in.has_odometry) {
    last_step_odom_ = in.T_odom_base;
    have_step_odom_ = true;
  }
  publishOutputs(header, r, depth, K, 1000.0 * (wallNowS() - t_callback_start_s), warnings);
}

// ---- outputs --------------------------------------------------------------------------------

bool LocalizationNodelet::publishTf(const ros::Time& stamp) {
  if (!have_map_odom_) return false;
  // Future-dated by transform_tolerance, from the frame stamp (never now()), and monotonic.
  const ros::Time tf_stamp = stamp + ros::Duration(opts_.transform_tolerance_s);
  if (!last_tf_stamp_.isZero() && tf_stamp <= last_tf_stamp_) return false;
  last_tf_stamp_ = tf_stamp;
  geometry_msgs::TransformStamped t;
  t.header.stamp = tf_stamp;
  t.header.frame_id = opts_.map_frame;
  const bool no_odom = opts_.odom_frame.empty() || opts_.odometry_source == "none";
  t.child_frame_id = no_odom ? opts_.base_frame : opts_.odom_frame;
  t.transform = ros_conv::transformFromIsometry(T_map_odom_);
  tf_broadcaster_->sendTransform(t);
  return true;
}

void LocalizationNodelet::publishOutputs(const std_msgs::Header& header, const StepResult& r,
                                         const DepthImage& depth, const Intrinsics& K,
                                         double callback_ms, const std::string& input_warnings) {
  const double roll = localizer_->rollRad(), pitch = localizer_->pitchRad();
  geometry_msgs::PoseWithCovarianceStamped pose;
  pose.header.stamp = header.stamp;
  pose.header.frame_id = opts_.map_frame;
  pose.pose = ros_conv::poseWithCovarianceFromEstimate(r.estimate, roll, pitch);
  pose_pub_.publish(pose);
  if (!publishTf(header.stamp)) ++tf_skipped_;

  if (particles_pub_.getNumSubscribers() > 0) {
    geometry_msgs::PoseArray particles;
    particles.header = pose.header;
    ros_conv::poseArrayFromParticles(localizer_->filter().particles(), roll, pitch, &particles);
    particles_pub_.publish(particles);
  }

  FilterStatus s;
  s.header = header;
  s.step_status = stepStatusName(r.status);
  s.message = r.message + (input_warnings.empty() ? "" : (r.message.empty() ? "" : "; ") + input_warnings);
  s.backend = localizer_->backend().name();
  s.particles = localizer_->filter().size();
  s.neff = r.neff;
  s.mean_loglik_per_pixel = r.mean_loglik_per_pixel;
  s.best_loglik_per_pixel = r.best_loglik_per_pixel;
  s.floor_hit_fraction = r.floor_hit_fraction;
  s.pixels = r.pixels;
  s.reinitialised = r.reinitialised;
  s.reinitialised_total = reinitialised_total_;
  s.lost = r.lost;
  s.lost_reinitialised = r.lost_reinitialised;
  s.screened_candidates = r.screened_candidates;
  s.reference_loglik_per_pixel = r.reference_loglik_per_pixel;
  s.lost_events_total = lost_events_total_;
  s.resets = resets_;
  s.resampled = r.resampled;
  s.odometry_jump = r.odometry_jump;
  s.predict_ms = r.timings.predict_ms;
  s.frame_prep_ms = r.timings.frame_prep_ms;
  s.projection_membership_ms = r.timings.projection_membership_ms;
  s.likelihood_ms = r.timings.likelihood_ms;
  s.weights_ms = r.timings.weights_ms;
  s.resample_ms = r.timings.resample_ms;
  s.estimate_ms = r.timings.estimate_ms;
  s.total_ms = r.timings.total_ms;
  s.callback_ms = callback_ms;
  s.frames_received = frames_received_;
  s.frames_processed = frames_;
  s.dropped_conversion = dropped_conversion_;
  s.dropped_camera_info = dropped_camera_info_;
  s.dropped_extrinsics = dropped_extrinsics_;
  s.frames_missed_seq = frames_missed_seq_;
  s.odometry_gaps = odom_gaps_;
  s.imu_missing = imu_missing_;
  s.tf_skipped = tf_skipped_;
  s.time_jumps = time_jumps_;
  status_pub_.publish(s);
  last_step_status_ = s.step_status;
  last_neff_ = r.neff;
  last_total_ms_ = r.timings.total_ms;

  // Lazy: only computed while someone listens.
  if (debug_image_pub_.getNumSubscribers() > 0) {
    sensor_msgs::Image img;
    renderDebugImage(depth, K, *map_, localizer_->meanPose() * params_.T_base_cam, params_.frame,
                     params_.measurement, &img);
    img.header = header;
    debug_image_pub_.publish(img);
  }
}

// ---- resets ---------------------------------------------------------------------------------

void LocalizationNodelet::applyPoseReset(const geometry_msgs::PoseWithCovarianceStamped& msg,
                                         std::string* message) {
  if (!msg.header.frame_id.empty() && msg.header.frame_id != opts_.map_frame) {
    NODELET_WARN("gmm_mcl: initial pose in frame '%s', expected '%s'; used as is",
                 msg.header.frame_id.c_str(), opts_.map_frame.c_str());
  }
  Particle p;
  Eigen::Vector4d sigma;
  const Eigen::Vector4d min_sigma(opts_.initial_sigma_xy_m, opts_.initial_sigma_xy_m,
                                  opts_.initial_sigma_z_m, opts_.initial_sigma_yaw_rad);
  if (!ros_conv::particleFromPoseWithCovariance(msg.pose, min_sigma, &p, &sigma)) {
    *message = "initial pose is not finite: ignored";
    NODELET_ERROR("gmm_mcl: %s", message->c_str());
    return;
  }
  if (!localizer_) {
    pending_pose_ = true;
    pending_pose_msg_ = msg;
    *message = "stored until the first depth frame";
    return;
  }
  // A stamp older than the last update: carry the pose forward by the odometry since then.
  std::ostringstream m;
  if (have_last_frame_ && have_step_odom_ && !msg.header.stamp.isZero() &&
      msg.header.stamp < last_frame_stamp_) {
    Eigen::Isometry3d T_odom_base_then;
    std::string why;
    if (odometryAt(msg.header.stamp, &T_odom_base_then, &why)) {
      const Eigen::Isometry3d T_map_base_then = ros_conv::isometryFromPose(msg.pose.pose);
      const Eigen::Isometry3d T_map_base_now =
          T_map_base_then * T_odom_base_then.inverse() * last_step_odom_;
      p = poseToParticle(T_map_base_now);
      m << "carried forward " << (last_frame_stamp_ - msg.header.stamp).toSec()
        << " s by odometry; ";
    } else {
      m << "stale stamp and " << why << ": used as is; ";
      NODELET_WARN("gmm_mcl: initial pose: %s", m.str().c_str());
    }
  }
  localizer_->resetToPose(p, sigma);
  ++resets_;
  m << "reset to (" << p.x_m << ", " << p.y_m << ", " << p.z_m << ", yaw " << p.yaw_rad
    << ") sigma (" << sigma.transpose() << ")";
  *message = m.str();
  NODELET_INFO("gmm_mcl: %s", message->c_str());
}

void LocalizationNodelet::initialPoseCallback(
    const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string message;
  applyPoseReset(*msg, &message);
}

bool LocalizationNodelet::resetToPose(ResetToPose::Request& req, ResetToPose::Response& res) {
  std::lock_guard<std::mutex> lock(mutex_);
  applyPoseReset(req.pose, &res.message);
  res.success = res.message.find("ignored") == std::string::npos;
  return true;
}

bool LocalizationNodelet::globalLocalization(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!localizer_) {
    pending_reset_ = "global";
    NODELET_INFO("gmm_mcl: global localization requested before the first frame");
    return true;
  }
  const InitRegion r = localizer_->mapBounds();
  localizer_->reset(r);
  ++resets_;
  NODELET_INFO("gmm_mcl: global localization: uniform over the map bounds, centre (%.2f %.2f "
               "%.2f), half extent (%.2f %.2f %.2f)", r.centre_m.x(), r.centre_m.y(),
               r.centre_m.z(), r.half_extent_m.x(), r.half_extent_m.y(), r.half_extent_m.z());
  return true;
}

void LocalizationNodelet::reconfigure(LocalizerConfig& c, uint32_t) {
  std::lock_guard<std::mutex> lock(mutex_);
  // A rejected change is reverted in the server too (config is written back to it).
  auto revert = [&]() {
    c.sigma_translation_m = params_.filter.sigma_translation_m;
    c.sigma_yaw_rad = params_.filter.sigma_yaw_rad;
    c.weighting = weightingModeName(params_.filter.weighting);
    c.temperature = params_.filter.temperature;
    c.neff_floor_fraction = params_.filter.neff_floor_fraction;
    c.resample_neff_fraction = params_.filter.resample_neff_fraction;
    c.alpha_slow = params_.filter.alpha_slow;
    c.alpha_fast = params_.filter.alpha_fast;
    c.recovery_threshold = params_.filter.recovery_threshold;
  };
  LocalizerParams p = params_;
  p.filter.sigma_translation_m = c.sigma_translation_m;
  p.filter.sigma_yaw_rad = c.sigma_yaw_rad;
  if (!parseWeightingMode(c.weighting, &p.filter.weighting)) {
    NODELET_ERROR("gmm_mcl: reconfigure: unknown weighting '%s'; ignored", c.weighting.c_str());
    revert();
    return;
  }
  p.filter.temperature = c.temperature;
  p.filter.neff_floor_fraction = c.neff_floor_fraction;
  p.filter.resample_neff_fraction = c.resample_neff_fraction;
  p.filter.alpha_slow = c.alpha_slow;
  p.filter.alpha_fast = c.alpha_fast;
  p.filter.recovery_threshold = c.recovery_threshold;
  const std::string err = p.validate();
  if (!err.empty()) {
    NODELET_ERROR("gmm_mcl: reconfigure rejected (kept the previous values): %s", err.c_str());
    revert();
    return;
  }
  const bool changed = p.filter.sigma_translation_m != params_.filter.sigma_translation_m ||
                       p.filter.sigma_yaw_rad != params_.filter.sigma_yaw_rad ||
                       p.filter.weighting != params_.filter.weighting ||
                       p.filter.temperature != params_.filter.temperature ||
                       p.filter.neff_floor_fraction != params_.filter.neff_floor_fraction ||
                       p.filter.resample_neff_fraction != params_.filter.resample_neff_fraction ||
                       p.filter.alpha_slow != params_.filter.alpha_slow ||
                       p.filter.alpha_fast != params_.filter.alpha_fast ||
                       p.filter.recovery_threshold != params_.filter.recovery_threshold;
  if (!changed) return;
  params_ = p;
  if (localizer_) {
    // The core's parameters are fixed per Localizer: rebuild it, keeping the belief as a
    // Gaussian around the current estimate with its covariance.
    const PoseEstimate e = localizer_->filter().estimate();
    localizer_.reset(new Localizer(p, *map_));
    const Eigen::Vector4d sigma(std::sqrt(e.covariance(0, 0)), std::sqrt(e.covariance(1, 1)),
                                std::sqrt(e.covariance(2, 2)), std::sqrt(e.covariance(5, 5)));
    localizer_->resetToPose(e.mean, sigma.cwiseMax(1e-3));
  }
  NODELET_INFO("gmm_mcl: reconfigured\n  %s", describeParams(params_, opts_).c_str());
}

// ---- diagnostics ----------------------------------------------------------------------------

void LocalizationNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!config_error_.empty()) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "bad configuration: " + config_error_);
    return;
  }
  const bool recent_problem =
      !last_problem_.empty() && (ros::WallTime::now() - last_problem_time_).toSec() < 5.0;
  const double input_age_s =
      last_input_wall_.isZero() ? -1.0 : (ros::WallTime::now() - last_input_wall_).toSec();
  if (input_age_s > 3.0) {
    std::ostringstream s;
    s << "no depth frame for " << input_age_s << " s ("
      << (opts_.depth_input == "image" ? "image with a matching CameraInfo" : "point cloud")
      << "); last problem: " << (last_problem_.empty() ? "none" : last_problem_);
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, s.str());
  } else if (frames_ == 0) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                 recent_problem ? "no frame used yet: " + last_problem_ : "waiting for depth frames");
  } else if (recent_problem) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_problem_);
  } else {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "localizing");
  }
  stat.add("frames used", frames_);
  stat.add("frames rejected", frames_rejected_);
  // Accounting: received == used + the three dropped counters.
  stat.add("frames received", frames_received_);
  stat.add("dropped: conversion", dropped_conversion_);
  stat.add("dropped: camera info", dropped_camera_info_);
  stat.add("dropped: no extrinsics", dropped_extrinsics_);
  stat.add("missed before a callback (seq gaps)", frames_missed_seq_);
  stat.add("tf not published", tf_skipped_);
  stat.add("last step", last_step_status_);
  stat.add("Neff", last_neff_);
  stat.add("update ms", last_total_ms_);
  stat.add("reinitialised particles (total)", reinitialised_total_);
  stat.add("lost events (total)", lost_events_total_);
  stat.add("time jumps back", time_jumps_);
  stat.add("odometry gaps", odom_gaps_);
  stat.add("frames without IMU", imu_missing_);
  stat.add("tf failures", tf_failures_);
  stat.add("last problem", last_problem_);
  stat.add("backend", localizer_ ? localizer_->backend().name() : params_.backend);
}

}  // namespace gmm_mcl

PLUGINLIB_EXPORT_CLASS(gmm_mcl::LocalizationNodelet, nodelet::Nodelet)
