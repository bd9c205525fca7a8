// Writing sensor bags for the nodelet: one place for the message layout that replay.launch
// plays (depth 16UC1 + CameraInfo, organized PointCloud2, IMU attitude, odometry as
// nav_msgs/Odometry and tf, the latched static base -> camera tf, ground truth) and the
// parameter file with the initial region. Used by gmm_mcl_make_bag and gmm_mcl_make_7scenes_bag;
// gmm_mcl_make_sim_bag writes the same layout by hand and can adopt it.
#pragma once

#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <string>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {
namespace ros_bag {

// Topic and frame names; the defaults are replay.launch's (and gmm_mcl_make_sim_bag's).
struct BagLayout {
  std::string depth_topic = "/camera/depth/image_raw";
  std::string camera_info_topic = "/camera/depth/camera_info";
  std::string cloud_topic = "/camera/depth/points";
  std::string imu_topic = "/imu/data";
  std::string odom_topic = "/odom";
  std::string ground_truth_topic = "/ground_truth";  // geometry_msgs/PoseStamped, base in map
  std::string map_frame = "map";
  std::string odom_frame = "odom";
  std::string base_frame = "base_link";
  std::string camera_frame = "camera_depth_optical_frame";
};

// 16UC1 (millimetres) or 32FC1 image (its CameraInfo: ros_conv::cameraInfoFromIntrinsics).
sensor_msgs::Image imageFromDepth(const DepthImage& depth, const ros::Time& stamp,
                                  const std::string& frame_id);
// Organized cloud (float32 x, y, z in the optical frame; NaN where there is no depth).
sensor_msgs::PointCloud2 organizedCloudFromDepth(const DepthImage& depth, const Intrinsics& K,
                                                 const ros::Time& stamp,
                                                 const std::string& frame_id);

class SensorBagWriter {
 public:
  // Opens `path` for writing; throws std::runtime_error naming it.
  SensorBagWriter(const std::string& path, const std::string& caller_id,
                  const BagLayout& layout = BagLayout());

  const BagLayout& layout() const { return layout_; }
  rosbag::Bag& bag() { return bag_; }

  // Latched /tf_static, as a static broadcaster's: rosbag play republishes it latched.
  void writeStaticTransform(const ros::Time& stamp, const std::string& parent,
                            const std::string& child, const Eigen::Isometry3d& T_parent_child);
  // IMU orientation from roll, pitch, yaw with roll/pitch variance sigma^2 (yaw unknown: 1), and
  // the gyro's angular velocity in the IMU (base) frame when given (else marked absent).
  void writeImu(const ros::Time& stamp, const ros::Time& receipt, double roll_rad, double pitch_rad,
                double yaw_rad, double attitude_sigma_rad,
                const Eigen::Vector3d* omega_rad_s = nullptr);
  // nav_msgs/Odometry and tf odom -> base.
  void writeOdometry(const ros::Time& stamp, const ros::Time& receipt,
                     const Eigen::Isometry3d& T_odom_base);
  void writeDepth(const ros::Time& stamp, const DepthImage& depth, const Intrinsics& K);
  void writeCloud(const ros::Time& stamp, const DepthImage& depth, const Intrinsics& K);
  void writeGroundTruth(const ros::Time& stamp, const Eigen::Isometry3d& T_map_base);
  // geometry_msgs/TransformStamped on its own topic (a motion-capture stream).
  void writeTransformStamped(const std::string& topic, const ros::Time& stamp,
                             const std::string& parent, const std::string& child,
                             const Eigen::Isometry3d& T_parent_child);
  void close() { bag_.close(); }

 private:
  BagLayout layout_;
  std::string caller_id_;
  rosbag::Bag bag_;
};

// The localizer's initial-region parameters (init_centre, init_half_extent, init_yaw_centre,
// init_yaw_half_range) around `start`; throws naming the file when it cannot be written.
void writeInitRegionYaml(const std::string& path, const std::string& comment, const Particle& start,
                         double half_extent_m, double yaw_half_range_rad);

// "x,y,z,qx,qy,qz,qw" -> transform; false when malformed or the quaternion is not unit-ish.
bool parseTransform(const std::string& text, Eigen::Isometry3d* out);

}  // namespace ros_bag
}  // namespace gmm_mcl
