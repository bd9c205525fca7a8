// The nodelet's parameters: the core's LocalizerParams plus the ROS-side options, read from the
// private namespace. Every fault is collected and reported together; a bad config starts nothing.
#pragma once

#include <string>

#include <ros/node_handle.h>

#include "gmm_mcl/filter/params.h"

namespace gmm_mcl {

struct RosOptions {
  std::string map_path;
  std::string map_frame = "map";
  std::string odom_frame = "odom";      // "" = no odometry frame: publish map -> base_frame
  std::string base_frame = "base_link";
  std::string odometry_source = "tf";   // tf (odom_frame -> base_frame), topic (~odom), none
  std::string depth_input = "image";    // image (CameraSubscriber) or cloud (organized PointCloud2)
  // image: raw through image_transport, or compressedDepth (decoded by the nodelet itself).
  std::string image_transport = "raw";
  bool use_imu = true;
  double transform_tolerance_s = 0.1;   // map -> odom is stamped with the frame stamp + this
  double tf_timeout_s = 0.05;           // wait for odometry tf at the frame stamp
  double odom_timeout_s = 0.2;          // odometry older than this (vs the frame) is a gap
  double imu_timeout_s = 0.5;           // attitude older than this is missing
  int queue_size = 1;                   // depth queue: stale frames are dropped
  bool init_from_map_bounds = false;    // initial region = map bounds instead of ~init_*
  double initial_sigma_xy_m = 0.25;     // /initialpose: spread where its covariance is zero
  double initial_sigma_z_m = 0.1;
  double initial_sigma_yaw_rad = 0.2;
  double diagnostics_period_s = 1.0;
};

// Reads ~params into *core and *ros (defaults where absent). Returns "" when valid, else every
// fault (wrong types, unknown enum values, the core's validate()).
std::string loadRosParams(const ros::NodeHandle& pnh, LocalizerParams* core, RosOptions* ros);

// One line per effective parameter, for the log.
std::string describeParams(const LocalizerParams& core, const RosOptions& ros);

}  // namespace gmm_mcl
