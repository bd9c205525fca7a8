#include "gmm_mcl/ros_tools/bag_writer.h"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {
namespace ros_bag {

sensor_msgs::Image imageFromDepth(const DepthImage& depth, const ros::Time& stamp,
                                  const std::string& frame_id) {
  sensor_msgs::Image img;
  img.header.stamp = stamp;
  img.header.frame_id = frame_id;
  img.width = depth.width_px;
  img.height = depth.height_px;
  img.encoding = depth.encoding == DepthEncoding::kMono16Millimetres ? "16UC1" : "32FC1";
  img.is_bigendian = 0;
  img.step = static_cast<uint32_t>(depth.row_bytes);
  img.data = depth.data;
  return img;
}

sensor_msgs::PointCloud2 organizedCloudFromDepth(const DepthImage& depth, const Intrinsics& K,
                                                 const ros::Time& stamp,
                                                 const std::string& frame_id) {
  sensor_msgs::PointCloud2 pc;
  sensor_msgs::PointCloud2Modifier mod(pc);
  mod.setPointCloud2FieldsByString(1, "xyz");
  mod.resize(static_cast<size_t>(depth.width_px) * depth.height_px);
  pc.header.stamp = stamp;
  pc.header.frame_id = frame_id;
  pc.width = depth.width_px;
  pc.height = depth.height_px;
  pc.row_step = pc.width * pc.point_step;
  pc.is_dense = false;
  sensor_msgs::PointCloud2Iterator<float> x(pc, "x"), y(pc, "y"), z(pc, "z");
  for (int v = 0; v < depth.height_px; ++v) {
    for (int u = 0; u < depth.width_px; ++u, ++x, ++y, ++z) {
      const float d = depth.depthMetres(u, v);
      float p[3] = {NAN, NAN, NAN};
      if (std::isfinite(d) && d > 0.f) {
        backProject(K, static_cast<float>(u), static_cast<float>(v), d, p);
      }
      *x = p[0];
      *y = p[1];
      *z = p[2];
    }
  }
  return pc;
}

SensorBagWriter::SensorBagWriter(const std::string& path, const std::string& caller_id,
                                 const BagLayout& layout)
    : layout_(layout), caller_id_(caller_id) {
  try {
    bag_.open(path, rosbag::bagmode::Write);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot write the bag: " + e.what());
  }
}

void SensorBagWriter::writeStaticTransform(const ros::Time& stamp, const std::string& parent,
                                           const std::string& child,
                                           const Eigen::Isometry3d& T_parent_child) {
  tf2_msgs::TFMessage st;
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform = ros_conv::transformFromIsometry(T_parent_child);
  st.transforms.push_back(t);
  auto header = boost::make_shared<ros::M_string>();
  (*header)["latching"] = "1";
  (*header)["callerid"] = caller_id_;
  (*header)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
  (*header)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
  (*header)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();
  bag_.write("/tf_static", stamp, st, header);
}

void SensorBagWriter::writeImu(const ros::Time& stamp, const ros::Time& receipt, double roll_rad,
                               double pitch_rad, double yaw_rad, double attitude_sigma_rad,
                               const Eigen::Vector3d* omega_rad_s) {
  sensor_msgs::Imu imu =
      ros_conv::imuFromAttitude(stamp, layout_.base_frame, roll_rad, pitch_rad, yaw_rad,
                                attitude_sigma_rad * attitude_sigma_rad, omega_rad_s == nullptr);
  if (omega_rad_s != nullptr) {
    imu.angular_velocity.x = omega_rad_s->x();
    imu.angular_velocity.y = omega_rad_s->y();
    imu.angular_velocity.z = omega_rad_s->z();
    imu.linear_acceleration_covariance[0] = -1.0;  // no accelerometer
  }
  bag_.write(layout_.imu_topic, receipt, imu);
}

void SensorBagWriter::writeOdometry(const ros::Time& stamp, const ros::Time& receipt,
                                    const Eigen::Isometry3d& T_odom_base) {
  nav_msgs::Odometry od;
  od.header.stamp = stamp;
  od.header.frame_id = layout_.odom_frame;
  od.child_frame_id = layout_.base_frame;
  od.pose.pose = ros_conv::poseFromIsometry(T_odom_base);
  bag_.write(layout_.odom_topic, receipt, od);
  tf2_msgs::TFMessage tf;
  geometry_msgs::TransformStamped ts;
  ts.header = od.header;
  ts.child_frame_id = layout_.base_frame;
  ts.transform = ros_conv::transformFromIsometry(T_odom_base);
  tf.transforms.push_back(ts);
  bag_.write("/tf", receipt, tf);
}

void SensorBagWriter::writeDepth(const ros::Time& stamp, const DepthImage& depth,
                                 const Intrinsics& K) {
  bag_.write(layout_.depth_topic, stamp, imageFromDepth(depth, stamp, layout_.camera_frame));
  bag_.write(layout_.camera_info_topic, stamp,
             ros_conv::cameraInfoFromIntrinsics(K, stamp, layout_.camera_frame));
}

void SensorBagWriter::writeCloud(const ros::Time& stamp, const DepthImage& depth,
                                 const Intrinsics& K) {
  bag_.write(layout_.cloud_topic, stamp,
             organizedCloudFromDepth(depth, K, stamp, layout_.camera_frame));
}

void SensorBagWriter::writeGroundTruth(const ros::Time& stamp,
                                       const Eigen::Isometry3d& T_map_base) {
  geometry_msgs::PoseStamped gt;
  gt.header.stamp = stamp;
  gt.header.frame_id = layout_.map_frame;
  gt.pose = ros_conv::poseFromIsometry(T_map_base);
  bag_.write(layout_.ground_truth_topic, stamp, gt);
}

void SensorBagWriter::writeTransformStamped(const std::string& topic, const ros::Time& stamp,
                                            const std::string& parent, const std::string& child,
                                            const Eigen::Isometry3d& T_parent_child) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform = ros_conv::transformFromIsometry(T_parent_child);
  bag_.write(topic, stamp, t);
}

void writeInitRegionYaml(const std::string& path, const std::string& comment, const Particle& start,
                         double half_extent_m, double yaw_half_range_rad) {
  std::ofstream y(path);
  y.precision(9);
  y << "# " << comment << "\n"
    << "init_centre: [" << start.x_m << ", " << start.y_m << ", " << start.z_m << "]\n"
    << "init_half_extent: [" << half_extent_m << ", " << half_extent_m << ", " << half_extent_m
    << "]\n"
    << "init_yaw_centre: " << start.yaw_rad << "\n"
    << "init_yaw_half_range: " << yaw_half_range_rad << "\n";
  if (!y) throw std::runtime_error(path + ": cannot write");
}

bool parseTransform(const std::string& text, Eigen::Isometry3d* out) {
  const std::vector<double> v = parseNumberList(text);
  if (v.size() != 7) return false;
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (std::abs(q.norm() - 1.0) > 1e-3) return false;
  *out = Eigen::Isometry3d::Identity();
  out->linear() = q.normalized().toRotationMatrix();
  out->translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return true;
}

}  // namespace ros_bag
}  // namespace gmm_mcl
