// What a depth frame's step needs besides the image, at the frame's stamp: the base -> camera
// extrinsics and the odometry from tf (or odometry from the buffered topic), and the IMU's roll
// and pitch from its buffer. IMU and odometry messages are buffered by stamp from any thread
// while an update runs; a frame takes what belongs to its own stamp.
#pragma once

#include <nav_msgs/Odometry.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>

#include <atomic>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/stamped_buffer.h"
#include "gmm_mcl/ros/ros_params.h"

namespace gmm_mcl {

class StepInputs {
 public:
  explicit StepInputs(tf2_ros::Buffer* tf) : tf_(tf) {}
  void setOptions(const RosOptions& opts) { opts_ = opts; }

  // Thread-safe. False: an IMU message without orientation (ignored). Its angular velocity,
  // where it has one, is integrated into the gyro's heading (StepInput::gyro_yaw_rad).
  bool addImu(const sensor_msgs::Imu& imu);
  void addOdometry(const nav_msgs::Odometry& odom);
  long long imuReceived() const { return imu_.added(); }
  long long odometryReceived() const { return odom_.added(); }

  struct Gaps {
    bool odometry = false;  // no odometry at the stamp: the constant-velocity model predicts
    bool imu = false;       // no IMU attitude at the stamp: roll and pitch from odometry
    std::string warnings;   // why, for ~status
  };
  // Whether each source (the IMU, the odometry topic) has a publisher connected now; called from
  // the frame's thread (ros::Subscriber::getNumPublishers). Unset: none.
  void setConnections(std::function<bool()> imu, std::function<bool()> odometry) {
    imu_connected_ = std::move(imu);
    odom_connected_ = std::move(odometry);
  }
  // Whether the IMU sample and the odometry message (odometry_source topic) at the stamp have
  // arrived; sources that are not used, or never delivered and have no publisher, count as
  // arrived (a connected one's first message may be on its way behind the frame). (Odometry
  // from tf is awaited before: DepthInput's tf message filter.)
  bool inputsArrived(const ros::Time& stamp) const;
  // Waits, at most opts.input_wait_s, until inputsArrived(stamp): messages published with a
  // frame travel on other connections and threads and may be handled after it. True when
  // nothing is missing.
  bool waitForInputs(const ros::Time& stamp);
  long long waitsBegun() const { return waits_begun_; }     // frames that had to wait
  long long waitsInVain() const { return waits_in_vain_; }  // of those, timed out
  // Waits for the frame's inputs (waitForInputs), then fills `in` (stamp, extrinsics, odometry,
  // attitude) for it. False, with why, when the
  // camera frame has no extrinsics (and none from an earlier frame of the same camera).
  // first_camera false (a frame set led by another camera of the rig): the header's frame is
  // not the first camera's, whose extrinsics are left to the caller (in->has_T_base_cam and
  // T_base_cam untouched: extrinsicsAt()).
  bool gather(const std_msgs::Header& header, StepInput* in, Gaps* gaps, std::string* why,
              bool first_camera = true);
  // Camera `camera`'s (0: the first) base -> optical frame at the frame's stamp from tf; after a
  // time jump cleared tf, the last ones of the same camera frame. False, with why, otherwise.
  bool extrinsicsAt(const std_msgs::Header& header, size_t camera, Eigen::Isometry3d* T_base_cam,
                    std::string* why);
  // Odometry (odom -> base) at a stamp, from tf or the buffered topic.
  bool odometryAt(const ros::Time& stamp, Eigen::Isometry3d* T_odom_base, std::string* why) const;
  // Time went back (a looped bag): what the buffers hold after the stamp is dropped; tf is
  // cleared after the next gather (which still reads the frame's own transforms).
  void timeJumpedBack(const ros::Time& stamp);
  const Eigen::Isometry3d& extrinsics(size_t camera = 0) const {
    return camera < cameras_.size() ? cameras_[camera].T_base_cam : kIdentity;
  }

 private:
  tf2_ros::Buffer* tf_;
  RosOptions opts_;
  StampedPoseBuffer imu_{2.0}, odom_{10.0};
  GyroHeading gyro_{2.0, 0.1};  // the IMU's angular velocity, integrated
  struct Extrinsics {
    std::string frame;  // the camera frame they belong to ("": none yet)
    Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  };
  std::vector<Extrinsics> cameras_;  // the last ones of each camera
  static const Eigen::Isometry3d kIdentity;
  bool clear_tf_ = false;
  std::atomic<long long> waits_begun_{0}, waits_in_vain_{0};
  std::function<bool()> imu_connected_, odom_connected_;
  // Whether a frame at t waits for the buffer: it has delivered, or a publisher is connected.
  bool awaited(const StampedPoseBuffer& b, const std::function<bool()>& connected) const {
    return b.added() > 0 || (connected && connected());
  }
};

}  // namespace gmm_mcl
