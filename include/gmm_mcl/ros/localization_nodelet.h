// ROS 1 nodelet around the core Localizer: converts messages, calls Localizer::step(), converts
// back. The policy (predict / update / resample / recover / reset, time jump back, odometry
// jumps) lives in the core; this class only gathers inputs (depth + CameraInfo or an organized
// cloud, IMU attitude, odometry from a topic or tf, extrinsics from tf) and publishes outputs.
#pragma once

#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include <boost/thread/recursive_mutex.hpp>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <image_transport/camera_common.h>
#include <image_transport/image_transport.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <sensor_msgs/CompressedImage.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "gmm_mcl/LocalizerConfig.h"
#include "gmm_mcl/ResetToPose.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/ros/ros_params.h"

namespace gmm_mcl {

class LocalizationNodelet : public nodelet::Nodelet {
 public:
  LocalizationNodelet();
  ~LocalizationNodelet() override;

 private:
  void onInit() override;

  // Inputs.
  void depthCallback(const sensor_msgs::ImageConstPtr& image,
                     const sensor_msgs::CameraInfoConstPtr& info);
  void compressedDepthCallback(const sensor_msgs::CompressedImageConstPtr& image,
                               const sensor_msgs::CameraInfoConstPtr& info);
  void cloudCallback(const sensor_msgs::PointCloud2ConstPtr& cloud);
  void imuCallback(const sensor_msgs::ImuConstPtr& imu);
  void odomCallback(const nav_msgs::OdometryConstPtr& odom);
  void initialPoseCallback(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg);
  bool globalLocalization(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);
  bool resetToPose(ResetToPose::Request& req, ResetToPose::Response& res);
  void reconfigure(LocalizerConfig& config, uint32_t level);

  // Common path of both depth inputs (mutex held).
  void processFrame(const std_msgs::Header& header, const DepthImage& depth, const Intrinsics& K,
                    double t_callback_start_s);
  bool lookupExtrinsics(const std::string& camera_frame, const ros::Time& stamp,
                        Eigen::Isometry3d* T_base_cam);
  bool odometryAt(const ros::Time& stamp, Eigen::Isometry3d* T_odom_base, std::string* why);
  void ensureLocalizer(const Eigen::Isometry3d& T_base_cam);
  void applyPoseReset(const geometry_msgs::PoseWithCovarianceStamped& msg, std::string* message);
  void publishOutputs(const std_msgs::Header& header, const StepResult& result,
                      const DepthImage& depth, const Intrinsics& K, double callback_ms,
                      const std::string& input_warnings);
  // False when no transform was sent (no estimate in the odometry frame yet, or a stamp not
  // after the last one).
  bool publishTf(const ros::Time& stamp);
  // A depth input was delivered to a callback: counts it and the frames that header.seq says
  // went missing before it.
  void frameReceived(const std_msgs::Header& header);
  // Drops the frame: counts it under *reason (one of the dropped_* counters) and says why.
  void frameRejected(const std::string& what, const std::string& why, long long* reason);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  std::mutex mutex_;
  RosOptions opts_;
  LocalizerParams params_;
  std::unique_ptr<GmmMap> map_;
  std::unique_ptr<Localizer> localizer_;
  bool configured_ = false;
  std::string config_error_;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<image_transport::ImageTransport> it_;
  image_transport::CameraSubscriber camera_sub_;
  // compressedDepth, decoded here (Debian has no compressed_depth_image_transport plugin).
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::CompressedImage>> compressed_sub_;
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::CameraInfo>> info_sub_;
  std::unique_ptr<message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>> compressed_sync_;
  ros::Subscriber cloud_sub_, imu_sub_, odom_sub_, initialpose_sub_;
  ros::Publisher pose_pub_, particles_pub_, status_pub_, markers_pub_, debug_image_pub_;
  ros::ServiceServer global_srv_, reset_srv_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Timer diagnostics_timer_;
  std::unique_ptr<dynamic_reconfigure::Server<LocalizerConfig>> reconfigure_server_;
  boost::recursive_mutex reconfigure_mutex_;

  // Input state.
  bool have_imu_ = false;
  ros::Time imu_stamp_;
  double imu_roll_rad_ = 0.0, imu_pitch_rad_ = 0.0;
  std::deque<nav_msgs::Odometry> odom_history_;
  bool have_T_base_cam_ = false;
  std::string camera_frame_;
  Eigen::Isometry3d T_base_cam_ = Eigen::Isometry3d::Identity();
  bool have_last_frame_ = false;
  ros::Time last_frame_stamp_;
  bool have_step_odom_ = false;
  Eigen::Isometry3d last_step_odom_ = Eigen::Isometry3d::Identity();  // odometry of the last step
  bool have_map_odom_ = false;
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  ros::Time last_tf_stamp_;
  std::string pending_reset_;  // reset requested before the first frame: "global" or ""
  bool pending_pose_ = false;
  geometry_msgs::PoseWithCovarianceStamped pending_pose_msg_;

  // Diagnostics.
  long long frames_ = 0, frames_rejected_ = 0, time_jumps_ = 0, odom_gaps_ = 0, imu_missing_ = 0,
            tf_failures_ = 0, reinitialised_total_ = 0, lost_events_total_ = 0;
  // Frame accounting: frames_received_ == frames_ (processed: a core step ran) + the dropped_*
  // counters (frames_rejected_ is their sum). frames_missed_seq_ counts frames that never reached
  // a callback (subscriber queue, image/CameraInfo synchronizer), from gaps in header.seq.
  long long frames_received_ = 0, dropped_conversion_ = 0, dropped_camera_info_ = 0,
            dropped_extrinsics_ = 0, frames_missed_seq_ = 0, tf_skipped_ = 0;
  bool have_last_seq_ = false;
  uint32_t last_seq_ = 0;
  int resets_ = 0;
  std::string last_problem_;
  ros::WallTime last_problem_time_;
  ros::WallTime last_input_wall_;  // last depth input delivered (used or rejected)
  std::string last_step_status_ = "waiting for the first frame";
  double last_neff_ = 0.0, last_total_ms_ = 0.0;
};

}  // namespace gmm_mcl
