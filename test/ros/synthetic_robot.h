// A synthetic robot for the lockstep rostests: the box scene rendered at the poses of
// sim::makeTrajectory (30 Hz), with its tf (odom -> base_link from a T_map_odom offset, the
// base -> camera extrinsics, static or per frame with jitter), IMU attitude and depth image +
// CameraInfo, each frame stamped and sent by the test (which owns the clock).
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/sim/box_scene.h"
#include "lockstep.h"

namespace gmm_mcl {
namespace lockstep {

// What a frame carries (faults for the bad-input cases).
struct RobotFrame {
  bool odom_tf = true;
  bool imu = true;
  bool imu_rates = false;  // the IMU's angular velocity too: the turn since the last frame sent
  bool camera_info = true;
  bool image = true;
  std::string encoding = "16UC1";  // rgb8: a wrong encoding; 32FC1 with nan_depth
  bool nan_depth = false;
  int info_scale = 1;  // CameraInfo for an image this many times larger
  std::string camera_frame = "camera_depth_optical_frame";
  bool dynamic_extrinsics = false;  // base -> camera on /tf at the frame's stamp
  double extrinsics_jitter_deg = 0.0;
  double wall_depth_m = 0.0;  // > 0: a flat wall at this depth instead of the scene
  bool first_camera = true;   // false: no frame of the first camera (a rig's dropout)
  bool more_cameras = true;   // frames of the cameras added with addCamera()
  int more_info_scale = 1;    // their CameraInfo for an image this many times larger
};

class SyntheticRobot {
 public:
  using Frame = RobotFrame;

  SyntheticRobot(ros::NodeHandle& nh, Clock* clock)
      : clock_(clock),
        scene_(sim::makeDefaultScene()),
        truth_(sim::makeTrajectory(600)),
        image_pub_(nh.advertise<sensor_msgs::Image>("/camera/depth/image_raw", 100)),
        info_pub_(nh.advertise<sensor_msgs::CameraInfo>("/camera/depth/camera_info", 100)),
        imu_pub_(nh.advertise<sensor_msgs::Imu>("/imu/data", 2000)),
        tf_pub_(nh.advertise<tf2_msgs::TFMessage>("/tf", 100)),
        t0_(1000.0),
        rng_(7) {
    K_.width_px = 160;
    K_.height_px = 120;
    K_.fx_px = K_.fy_px = 585.f / 4;
    K_.cx_px = 0.5f * (K_.width_px - 1);
    K_.cy_px = 0.5f * (K_.height_px - 1);
    // The odometry frame is offset from the map (as on a robot that started elsewhere).
    T_map_odom_.translation() = Eigen::Vector3d(1.5, -1.0, 0.0);
    T_map_odom_.linear() = rotationFromRpy(0, 0, 0.5);
  }

  const Eigen::Isometry3d& truth(int k) const { return truth_[k % truth_.size()]; }
  ros::Time stamp(double step) const { return t0_ + ros::Duration(step / 30.0); }
  const Eigen::Isometry3d& T_map_odom() const { return T_map_odom_; }
  Eigen::Isometry3d T_odom_base(const Eigen::Isometry3d& T_map_base) const {
    return T_map_odom_.inverse() * T_map_base;
  }
  static Eigen::Isometry3d extrinsics() { return sim::defaultBaseToCamera(); }

  // Until the nodelets (by namespace) are up: their services answer, and they advertise those
  // only once all their subscriptions are made.
  bool waitForNodelet(const std::vector<std::string>& nodelets = {"/gmm_mcl"}) {
    for (const std::string& ns : nodelets) {
      if (!ros::service::waitForService(ns + "/reset_to_pose", ros::Duration(kWaitLimitS)))
        return false;
    }
    // /tf too (odometry at a frame's stamp): a frame whose odometry was lost waits for good.
    return waitFor([&] {
      return connectedToAll(image_pub_) && connectedToAll(info_pub_) && connectedToAll(imu_pub_) &&
             connectedToAll(tf_pub_) && clock_->connected() && moreCamerasConnected();
    });
  }
  // Another depth camera of the rig: 16UC1 images and CameraInfo on NS/image and NS/camera_info,
  // its optical frame `frame_id` at T_base_cam on /tf_static (publishStaticExtrinsics; with
  // publish_tf false never: a camera whose tf never arrives).
  void addCamera(ros::NodeHandle& nh, const std::string& ns, const std::string& frame_id,
                 const Eigen::Isometry3d& T_base_cam, bool publish_tf = true) {
    RigCamera c;
    c.frame_id = frame_id;
    c.T_base_cam = T_base_cam;
    c.publish_tf = publish_tf;
    c.image = nh.advertise<sensor_msgs::Image>(ns + "/image", 100);
    c.info = nh.advertise<sensor_msgs::CameraInfo>(ns + "/camera_info", 100);
    more_.push_back(c);
  }
  bool moreCamerasConnected() const {
    for (const RigCamera& c : more_) {
      if (!connectedToAll(c.image) || !connectedToAll(c.info)) return false;
    }
    return true;
  }
  void publishStaticExtrinsics() {
    if (static_sent_) return;
    static_sent_ = true;
    // One message: the latched /tf_static keeps only this node's last one.
    std::vector<geometry_msgs::TransformStamped> all = {ros_conv::transformStamped(
        extrinsics(), "base_link", "camera_depth_optical_frame", ros::Time(0))};
    for (const RigCamera& c : more_) {
      if (c.publish_tf)
        all.push_back(
            ros_conv::transformStamped(c.T_base_cam, "base_link", c.frame_id, ros::Time(0)));
    }
    static_tf_.sendTransform(all);
  }
  void publishOdometry(const ros::Time& t, const Eigen::Isometry3d& T_map_base) {
    sendTf(ros_conv::transformStamped(T_odom_base(T_map_base), "odom", "base_link", t));
  }
  void publishImu(const ros::Time& t, double roll_rad, double pitch_rad,
                  const Eigen::Vector3d& omega_rad_s = Eigen::Vector3d::Zero()) {
    sensor_msgs::Imu imu;
    imu.header.stamp = t;
    imu.header.frame_id = "base_link";
    imu.orientation =
        ros_conv::poseFromIsometry(particleToPose(Particle(), roll_rad, pitch_rad)).orientation;
    imu.angular_velocity.x = omega_rad_s.x();
    imu.angular_velocity.y = omega_rad_s.y();
    imu.angular_velocity.z = omega_rad_s.z();
    imu_pub_.publish(imu);
    ++imu_published_;
  }
  long long imuPublished() const { return imu_published_; }
  // Sends a frame of the robot at T_map_base stamped t, the clock moved on to t first.
  void send(const ros::Time& t, const Eigen::Isometry3d& T_map_base, const Frame& f = Frame()) {
    clock_->advanceTo(t);
    if (f.odom_tf) publishOdometry(t, T_map_base);
    Eigen::Isometry3d T_base_cam = extrinsics();
    if (f.dynamic_extrinsics) {
      std::normal_distribution<double> g(0.0, 1.0);
      const Eigen::Vector3d axis = Eigen::Vector3d(g(rng_), g(rng_), g(rng_)).normalized();
      T_base_cam.linear() =
          T_base_cam.linear() *
          Eigen::AngleAxisd(f.extrinsics_jitter_deg * M_PI / 180, axis).toRotationMatrix();
      sendTf(ros_conv::transformStamped(T_base_cam, "base_link", f.camera_frame, t));
    }
    if (f.imu) {
      double roll, pitch, yaw;
      rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
      // The body's angular velocity over the interval since the last frame (the IMU is the base).
      Eigen::Vector3d omega = Eigen::Vector3d::Zero();
      if (f.imu_rates && have_last_ && t > last_t_) {
        const Eigen::AngleAxisd turn(last_T_map_base_.linear().transpose() * T_map_base.linear());
        omega = turn.axis() * turn.angle() / (t - last_t_).toSec();
      }
      publishImu(t, roll, pitch, omega);
    }
    have_last_ = true;
    last_t_ = t;
    last_T_map_base_ = T_map_base;
    sensor_msgs::Image img;
    img.header.stamp = t;
    img.header.frame_id = f.camera_frame;
    img.header.seq = seq_++;
    img.width = K_.width_px;
    img.height = K_.height_px;
    if (f.nan_depth || f.wall_depth_m > 0) {
      img.encoding = "32FC1";
      img.step = 4 * img.width;
      std::vector<float> z(img.width * img.height, f.nan_depth
                                                       ? std::numeric_limits<float>::quiet_NaN()
                                                       : static_cast<float>(f.wall_depth_m));
      img.data.resize(img.step * img.height);
      std::memcpy(img.data.data(), z.data(), img.data.size());
    } else if (f.encoding == "rgb8") {
      img.encoding = "rgb8";
      img.step = 3 * img.width;
      img.data.assign(img.step * img.height, 128);
    } else {
      const DepthImage depth = sim::renderDepth(scene_, K_, T_map_base * T_base_cam,
                                                DepthEncoding::kMono16Millimetres, 8.0);
      img.encoding = "16UC1";
      img.step = static_cast<uint32_t>(depth.row_bytes);
      img.data = depth.data;
    }
    const sensor_msgs::CameraInfo info = cameraInfo(img.header, f.info_scale);
    if (f.image && f.first_camera) image_pub_.publish(img);
    if (f.camera_info && f.first_camera) info_pub_.publish(info);
    if (!f.more_cameras) return;
    for (RigCamera& c : more_) {
      const DepthImage depth = sim::renderDepth(scene_, K_, T_map_base * c.T_base_cam,
                                                DepthEncoding::kMono16Millimetres, 8.0);
      sensor_msgs::Image m = img;
      m.header.frame_id = c.frame_id;
      m.header.seq = c.seq++;
      m.encoding = "16UC1";
      m.step = static_cast<uint32_t>(depth.row_bytes);
      m.data = depth.data;
      const sensor_msgs::CameraInfo i = cameraInfo(m.header, f.more_info_scale);
      c.image.publish(m);
      c.info.publish(i);
    }
  }

 private:
  // What tf2_ros::TransformBroadcaster does, with a publisher whose connections can be checked.
  void sendTf(const geometry_msgs::TransformStamped& t) {
    tf2_msgs::TFMessage m;
    m.transforms.push_back(t);
    tf_pub_.publish(m);
  }

  // The camera's CameraInfo for an image `scale` times larger than the rendered one.
  sensor_msgs::CameraInfo cameraInfo(const std_msgs::Header& header, int scale) const {
    sensor_msgs::CameraInfo info;
    info.header = header;
    const double s = scale;
    info.width = K_.width_px * scale;
    info.height = K_.height_px * scale;
    info.K = {K_.fx_px * s, 0, K_.cx_px * s, 0, K_.fy_px * s, K_.cy_px * s, 0, 0, 1};
    info.P = {K_.fx_px * s, 0, K_.cx_px * s, 0, 0, K_.fy_px * s, K_.cy_px * s, 0, 0, 0, 1, 0};
    return info;
  }

  struct RigCamera {
    std::string frame_id;
    bool publish_tf = true;
    Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
    ros::Publisher image, info;
    uint32_t seq = 0;
  };

  Clock* clock_;
  std::vector<RigCamera> more_;
  sim::BoxScene scene_;
  std::vector<Eigen::Isometry3d> truth_;
  Intrinsics K_;
  ros::Publisher image_pub_, info_pub_, imu_pub_, tf_pub_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  ros::Time t0_;
  std::mt19937_64 rng_;
  uint32_t seq_ = 0;
  long long imu_published_ = 0;
  bool have_last_ = false;  // the last frame sent (the IMU's rates)
  ros::Time last_t_;
  Eigen::Isometry3d last_T_map_base_ = Eigen::Isometry3d::Identity();
  bool static_sent_ = false;
};

}  // namespace lockstep
}  // namespace gmm_mcl
