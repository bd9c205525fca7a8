// gmm_mcl_ground_truth_odometry: turns a ground-truth pose stream into the localizer's odometry
// and attitude inputs while a recorded bag plays (paper D2, voxblox cow_and_lady): noisy
// nav_msgs/Odometry and tf odom -> base, IMU roll/pitch, per the DESIGN.md protocol
// (OdometrySynthesizer, seeded; per-frame sigmas scaled to the stream's interval), the base
// ground truth as PoseStamped for rostests and gmm_mcl_evaluate_pose_bag, and a TUM file of it.
//
// Sources (~source): "topic" (geometry_msgs/TransformStamped on `ground_truth_transform`, e.g.
// /kinect/vrpn_client/estimated_transform), "tf" (~truth_parent_frame -> ~truth_child_frame,
// polled), "tum" (~tum_file, published as the clock passes each stamp). The stream gives the
// marker pose in the world (z up); camera = marker * ~marker_to_camera (the calibration);
// base = camera * ~base_to_camera^-1 (default: camera = base, x forward).
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "gmm_mcl/datasets/tum_sequence.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {

namespace {

// A transform parameter as [x, y, z, qx, qy, qz, qw]; false with why when malformed.
bool transformParam(ros::NodeHandle& pnh, const std::string& name, Eigen::Isometry3d* T,
                    std::string* why) {
  std::vector<double> v;
  if (!pnh.getParam(name, v)) return true;  // keep the default
  if (v.size() != 7) {
    *why = "~" + name + " must be [x, y, z, qx, qy, qz, qw]";
    return false;
  }
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (!std::isfinite(q.norm()) || std::abs(q.norm() - 1.0) > 1e-3) {
    *why = "~" + name + ": quaternion is not of unit length";
    return false;
  }
  *T = Eigen::Isometry3d::Identity();
  T->linear() = q.normalized().toRotationMatrix();
  T->translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return true;
}

class GroundTruthOdometry {
 public:
  GroundTruthOdometry(ros::NodeHandle& nh, ros::NodeHandle& pnh) : T_base_cam_(opticalToBase()) {
    std::string why;
    pnh.param<std::string>("source", source_, "topic");
    pnh.param<std::string>("odom_frame", odom_frame_, "odom");
    pnh.param<std::string>("base_frame", base_frame_, "base_link");
    pnh.param<std::string>("map_frame", map_frame_, "map");
    pnh.param<std::string>("camera_frame", camera_frame_, "camera_rgb_optical_frame");
    pnh.param<bool>("publish_camera_tf", publish_camera_tf_, true);
    pnh.param<double>("reference_rate_hz", reference_rate_hz_, 30.0);
    int seed = 1;
    pnh.param<int>("seed", seed, 1);
    ProtocolNoise noise;
    pnh.param<double>("odom_sigma_m", noise.odom_sigma_m, noise.odom_sigma_m);
    pnh.param<double>("odom_sigma_yaw_rad", noise.odom_sigma_yaw_rad, noise.odom_sigma_yaw_rad);
    pnh.param<double>("attitude_sigma_rad", noise.attitude_sigma_rad, noise.attitude_sigma_rad);
    attitude_sigma_rad_ = noise.attitude_sigma_rad;
    bool ok = transformParam(pnh, "marker_to_camera", &T_marker_cam_, &why) &&
              transformParam(pnh, "base_to_camera", &T_base_cam_, &why);
    if (ok && (source_ != "topic" && source_ != "tf" && source_ != "tum")) {
      why = "~source must be topic, tf or tum, not '" + source_ + "'";
      ok = false;
    }
    if (ok && !(reference_rate_hz_ > 0.0)) {
      why = "~reference_rate_hz must be positive";
      ok = false;
    }
    std::string tum_out;
    pnh.param<std::string>("truth_tum", tum_out, "");
    if (ok && !tum_out.empty()) {
      tum_ = std::make_unique<std::ofstream>(tum_out);
      if (!*tum_) {
        why = "~truth_tum: cannot write " + tum_out;
        ok = false;
      }
    }
    if (ok && source_ == "tum") {
      std::string file;
      pnh.param<std::string>("tum_file", file, "");
      try {
        tum_poses_ = readTumTrajectory(file);
      } catch (const std::exception& e) {
        why = std::string("~tum_file: ") + e.what();
        ok = false;
      }
    }
    if (!ok) {
      ROS_FATAL("ground_truth_odometry: %s; publishing nothing", why.c_str());
      return;
    }
    synth_ = std::make_unique<OdometrySynthesizer>(noise, static_cast<uint64_t>(seed));
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("odom", 50);
    imu_pub_ = nh.advertise<sensor_msgs::Imu>("imu", 50);
    truth_pub_ = nh.advertise<geometry_msgs::PoseStamped>("ground_truth", 50);
    if (publish_camera_tf_) {
      geometry_msgs::TransformStamped t;
      t.header.stamp = ros::Time(0);
      t.header.frame_id = base_frame_;
      t.child_frame_id = camera_frame_;
      t.transform = ros_conv::transformFromIsometry(T_base_cam_);
      static_broadcaster_.sendTransform(t);
    }
    if (source_ == "topic") {
      sub_ = nh.subscribe("ground_truth_transform", 200, &GroundTruthOdometry::onTransform, this);
    } else {
      double poll_hz = 100.0;
      pnh.param<double>("poll_rate_hz", poll_hz, 100.0);
      if (source_ == "tf") {
        pnh.param<std::string>("truth_parent_frame", truth_parent_, "world");
        pnh.param<std::string>("truth_child_frame", truth_child_, "kinect");
        tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
        tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
      }
      timer_ = nh.createTimer(ros::Duration(1.0 / poll_hz), &GroundTruthOdometry::onTimer, this);
    }
    ROS_INFO(
        "ground_truth_odometry: source %s, marker -> camera [%.3f %.3f %.3f], noise %.4f m "
        "/ %.4f rad per frame at %.0f Hz, attitude %.4f rad, seed %d%s%s",
        source_.c_str(), T_marker_cam_.translation().x(), T_marker_cam_.translation().y(),
        T_marker_cam_.translation().z(), noise.odom_sigma_m, noise.odom_sigma_yaw_rad,
        reference_rate_hz_, noise.attitude_sigma_rad, seed, tum_out.empty() ? "" : ", truth to ",
        tum_out.c_str());
  }

 private:
  void onTransform(const geometry_msgs::TransformStampedConstPtr& msg) {
    process(msg->header.stamp, ros_conv::isometryFromTransform(msg->transform));
  }

  void onTimer(const ros::TimerEvent&) {
    if (source_ == "tum") {
      const double now = ros::Time::now().toSec();
      if (!last_stamp_.isZero() && now < last_stamp_.toSec()) next_tum_ = 0;  // clock went back
      while (next_tum_ < tum_poses_.size() && tum_poses_[next_tum_].stamp_s <= now) {
        const StampedPose& p = tum_poses_[next_tum_++];
        process(ros::Time(p.stamp_s), p.T);
      }
      return;
    }
    try {
      const geometry_msgs::TransformStamped t =
          tf_buffer_->lookupTransform(truth_parent_, truth_child_, ros::Time(0));
      if (t.header.stamp != last_stamp_)
        process(t.header.stamp, ros_conv::isometryFromTransform(t.transform));
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(5.0, "ground_truth_odometry: %s", e.what());
    }
  }

  void process(const ros::Time& stamp, const Eigen::Isometry3d& T_world_marker) {
    double frames = 1.0;
    if (!last_stamp_.isZero()) {
      if (stamp < last_stamp_) {
        ROS_WARN("ground_truth_odometry: time went back %.3f s (bag looped?): odometry restarts",
                 (last_stamp_ - stamp).toSec());
        synth_->restart();
      } else if (stamp == last_stamp_) {
        return;
      } else {
        frames = (stamp - last_stamp_).toSec() * reference_rate_hz_;
      }
    }
    last_stamp_ = stamp;
    const Eigen::Isometry3d T_world_base = T_world_marker * T_marker_cam_ * T_base_cam_.inverse();
    const Eigen::Isometry3d T_odom_base = synth_->next(T_world_base, frames);
    double roll, pitch;
    synth_->attitude(T_world_base, &roll, &pitch);

    nav_msgs::Odometry od;
    od.header.stamp = stamp;
    od.header.frame_id = odom_frame_;
    od.child_frame_id = base_frame_;
    od.pose.pose = ros_conv::poseFromIsometry(T_odom_base);
    odom_pub_.publish(od);
    geometry_msgs::TransformStamped ts;
    ts.header = od.header;
    ts.child_frame_id = base_frame_;
    ts.transform = ros_conv::transformFromIsometry(T_odom_base);
    broadcaster_.sendTransform(ts);

    imu_pub_.publish(ros_conv::imuFromAttitude(stamp, base_frame_, roll, pitch,
                                               yawFromRotation(T_world_base.linear()),
                                               attitude_sigma_rad_ * attitude_sigma_rad_));

    geometry_msgs::PoseStamped gt;
    gt.header.stamp = stamp;
    gt.header.frame_id = map_frame_;
    gt.pose = ros_conv::poseFromIsometry(T_world_base);
    truth_pub_.publish(gt);
    if (tum_) {
      const Eigen::Quaterniond qt(T_world_base.linear());
      char line[256];
      std::snprintf(line, sizeof(line), "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", stamp.toSec(),
                    T_world_base.translation().x(), T_world_base.translation().y(),
                    T_world_base.translation().z(), qt.x(), qt.y(), qt.z(), qt.w());
      *tum_ << line << std::flush;
    }
  }

  std::string source_, odom_frame_, base_frame_, map_frame_, camera_frame_;
  std::string truth_parent_, truth_child_;
  bool publish_camera_tf_ = true;
  double reference_rate_hz_ = 30.0;
  double attitude_sigma_rad_ = 0.0;
  Eigen::Isometry3d T_marker_cam_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_cam_;
  std::unique_ptr<OdometrySynthesizer> synth_;
  std::unique_ptr<std::ofstream> tum_;
  std::vector<StampedPose> tum_poses_;
  size_t next_tum_ = 0;
  ros::Time last_stamp_;
  ros::Publisher odom_pub_, imu_pub_, truth_pub_;
  ros::Subscriber sub_;
  ros::Timer timer_;
  tf2_ros::TransformBroadcaster broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
};

}  // namespace

int run(int argc, char** argv) {
  ros::init(argc, argv, "ground_truth_odometry");
  ros::NodeHandle nh, pnh("~");
  GroundTruthOdometry node(nh, pnh);
  ros::spin();
  return 0;
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
