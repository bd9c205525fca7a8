// ROS 1 nodelet around the core Localizer: converts messages, calls Localizer::step(), publishes.
// The policy (predict / update / resample / recover / reset, time jump back, odometry jumps,
// pose resets, parameter changes keeping the belief) lives in the core; the bookkeeping (frame
// accounting, status, diagnostics) in node_status.h; the depth input in depth_input.h.
//
// Threads: depth frames, the tf listener, /initialpose, the services and dynamic_reconfigure run
// on the nodelet's single-threaded queue, one at a time (so nothing else touches the filter
// during an update; and tf2's message filter, which registers a frame's transform request
// before it queues the frame, never meets a transform inserted by another thread in between,
// which would complete a request it cannot find yet and leave the frame waiting for good);
// IMU, odometry and the poll timer (diagnostics, markers, the saved pose) run on its
// multi-threaded queue and never wait for an
// update (they only take the buffers' and the health snapshot's own locks).
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <boost/thread/recursive_mutex.hpp>
#include <memory>
#include <mutex>
#include <string>

#include "gmm_mcl/LoadMap.h"
#include "gmm_mcl/LocalizerConfig.h"
#include "gmm_mcl/ResetToPose.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/pose_reset.h"
#include "gmm_mcl/ros/depth_input.h"
#include "gmm_mcl/ros/frame_outputs.h"
#include "gmm_mcl/ros/frame_sets.h"
#include "gmm_mcl/ros/map_markers.h"
#include "gmm_mcl/ros/node_status.h"
#include "gmm_mcl/ros/ros_params.h"
#include "gmm_mcl/ros/step_inputs.h"

namespace gmm_mcl {

class LocalizationNodelet : public nodelet::Nodelet {
 public:
  LocalizationNodelet();
  ~LocalizationNodelet() override;

 private:
  void onInit() override;
  bool configure(std::vector<std::string>* unknown);
  void advertise();

  // Single-threaded queue.
  // One update: a frame of the one camera, or a frame set of a rig (set; header, depth and K
  // are then its lead frame's).
  void onFrame(const std_msgs::Header& header, const DepthImage& depth, const Intrinsics& K,
               const FrameSet* set = nullptr);
  // Several cameras: camera i's frame to the frame sets; the completed sets updated, the wait
  // of a pending one armed (a one-shot wall timer on the same queue: nothing blocks it).
  void onCameraFrame(size_t camera, const std_msgs::Header& header, const DepthImage& depth,
                     const Intrinsics& K);
  void drainSets();
  // The StepInput's cameras of a set (extrinsics from tf); *problems: per camera, why not.
  void fillCameras(const FrameSet& set, StepInput* in, std::vector<std::string>* problems);
  void recordCameras(const FrameSet& set, const StepResult& r,
                     const std::vector<std::string>& problems);
  void onDrop(FrameDrop reason, const std::string& why);
  void onInitialPose(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg);
  bool onGlobalLocalization(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);
  bool onResetToPose(ResetToPose::Request& req, ResetToPose::Response& res);
  bool onLoadMap(LoadMap::Request& req, LoadMap::Response& res);
  void onReconfigure(LocalizerConfig& config, uint32_t level);
  // Multi-threaded queue.
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  void jumpedBack(const ros::Time& stamp);
  bool applyPose(const geometry_msgs::PoseWithCovarianceStamped& msg, std::string* message);
  bool resetTo(const PoseResetRequest& request, const std::string& note, std::string* message);
  // Logs the changes between predicting with odometry and without it.
  void logMotionSource(bool has_odometry);
  void publish(const std_msgs::Header& header, const StepResult& r,
               const Eigen::Isometry3d& T_map_base, const DepthImage& depth, const Intrinsics& K,
               double callback_ms, const std::string& warnings, bool gated,
               const FrameSet* set = nullptr);
  void problem(const std::string& what, bool warn = true);
  // The frame-rate budget: a frame's stamp for the period, an update's duration for the choice,
  // which goes to the localizer (keeping the particles) when it changes.
  void budgetUpdate(const StepResult& r, double callback_ms);
  void applyBudget();   // the budget's choice to the localizer (the particles kept)
  void applyOptions();  // the run-time options, at start and on dynamic_reconfigure

  RosOptions opts_;
  LocalizerParams params_;
  std::unique_ptr<Localizer> localizer_;
  MotionGate gate_;
  UpdateBudget budget_;  // params_ are the configured values; the localizer gets budget_.apply()

  std::unique_ptr<tf2_ros::Buffer> tf_;
  std::unique_ptr<StepInputs> inputs_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<image_transport::ImageTransport> it_;
  std::unique_ptr<DepthInput> input_;
  // Several cameras (~more_cameras): the others' parameters and inputs, the frame sets.
  std::vector<RigCameraParams> rig_;
  std::vector<std::unique_ptr<DepthInput>> more_inputs_;
  std::unique_ptr<FrameSets> sets_;
  ros::WallTimer set_timer_;  // the pending set's wait
  unsigned long armed_generation_ = 0;
  long long first_dropped_in_sets_ = 0;  // the first camera's frames dropped by the sets, counted
  int last_lead_ = 0;
  ros::Subscriber imu_sub_, odom_sub_, initialpose_sub_;
  FrameOutputs outputs_;  // ~pose, ~refined_pose, tf, ~particles, ~status, ~debug_image
  MapMarkers markers_;
  ros::ServiceServer global_srv_, reset_srv_, map_srv_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  // Polled on wall time, due on ROS time (PeriodicSchedule): diagnostics and the markers.
  ros::WallTimer poll_timer_;
  PeriodicSchedule diagnostics_due_;
  boost::recursive_mutex reconfigure_mutex_;  // outlives the server, which locks it when it goes
  std::unique_ptr<dynamic_reconfigure::Server<LocalizerConfig>> reconfigure_server_;

  // The last update (single-threaded queue only).
  bool have_step_ = false;
  int frames_without_odometry_ = 0;  // consecutive updates without odometry (logged on change)
  ros::Time last_stamp_;
  StepResult last_result_;
  bool have_map_odom_ = false;
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  bool have_step_odom_ = false;
  Eigen::Isometry3d T_odom_base_last_ = Eigen::Isometry3d::Identity();

  PoseSaver pose_saver_;  // offered on the update thread, written by the poll timer
  HealthMonitor health_;  // counters and the /diagnostics snapshot
};

}  // namespace gmm_mcl
