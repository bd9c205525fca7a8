#include "gmm_mcl/ros/step_inputs.h"

#include <chrono>

#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {

bool StepInputs::addImu(const sensor_msgs::Imu& imu) {
  double roll, pitch;
  if (!ros_conv::attitudeFromImu(imu, &roll, &pitch)) return false;
  // The gyro's sample first: a frame waiting for this message wakes on the attitude's
  // (waitForInputs) and must find both.
  Eigen::Vector3d omega;
  if (ros_conv::angularVelocityFromImu(imu, &omega)) {
    gyro_.add(imu.header.stamp.toSec(), omega, roll, pitch);
  }
  imu_.addAttitude(imu.header.stamp.toSec(), roll, pitch);
  return true;
}

void StepInputs::addOdometry(const nav_msgs::Odometry& odom) {
  odom_.add(odom.header.stamp.toSec(), ros_conv::isometryFromPose(odom.pose.pose));
}

bool StepInputs::odometryAt(const ros::Time& stamp, Eigen::Isometry3d* T_odom_base,
                            std::string* why) const {
  if (opts_.odometry_source == "none") return false;
  if (opts_.odometry_source == "topic") {
    if (odom_.at(stamp.toSec(), opts_.odom_timeout_s, T_odom_base, why)) return true;
    *why = "no odometry at the frame's stamp: " + *why;
    return false;
  }
  try {
    *T_odom_base = ros_conv::isometryFromTransform(
        tf_->lookupTransform(opts_.odom_frame, opts_.base_frame, stamp).transform);
    return true;
  } catch (const tf2::TransformException& e) {
    *why = std::string("no odometry tf at the frame's stamp: ") + e.what();
    return false;
  }
}

bool StepInputs::inputsArrived(const ros::Time& stamp) const {
  const double t = stamp.toSec();
  if (opts_.use_imu && awaited(imu_, imu_connected_) && !imu_.reaches(t)) return false;
  if (opts_.odometry_source == "topic" && awaited(odom_, odom_connected_) && !odom_.reaches(t)) {
    return false;
  }
  return true;
}

bool StepInputs::waitForInputs(const ros::Time& stamp) {
  if (opts_.input_wait_s <= 0.0 || inputsArrived(stamp)) return true;
  ++waits_begun_;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(opts_.input_wait_s));
  // Each buffer wakes its waiter when a message is added (StampedPoseBuffer::waitUntilReaches).
  const double t = stamp.toSec();
  const bool imu =
      !opts_.use_imu || !awaited(imu_, imu_connected_) || imu_.waitUntilReaches(t, deadline);
  const bool odom = opts_.odometry_source != "topic" || !awaited(odom_, odom_connected_) ||
                    odom_.waitUntilReaches(t, deadline);
  if (imu && odom) return true;
  ++waits_in_vain_;
  return false;
}

const Eigen::Isometry3d StepInputs::kIdentity = Eigen::Isometry3d::Identity();

bool StepInputs::extrinsicsAt(const std_msgs::Header& header, size_t camera,
                              Eigen::Isometry3d* T_base_cam, std::string* why) {
  if (cameras_.size() <= camera) cameras_.resize(camera + 1);
  Extrinsics& e = cameras_[camera];
  try {  // per frame, at its stamp: a gimbal or a moving joint
    e.T_base_cam = ros_conv::isometryFromTransform(
        tf_->lookupTransform(opts_.base_frame, header.frame_id, header.stamp).transform);
    e.frame = header.frame_id;
  } catch (const tf2::TransformException& ex) {
    // After a time jump cleared tf, the last extrinsics of the same camera still hold.
    if (e.frame != header.frame_id) {
      *why = "no transform " + opts_.base_frame + " <- " + header.frame_id + ": " + ex.what();
      return false;
    }
  }
  *T_base_cam = e.T_base_cam;
  return true;
}

bool StepInputs::gather(const std_msgs::Header& header, StepInput* in, Gaps* gaps, std::string* why,
                        bool first_camera) {
  // The IMU and odometry topics sent with the frame first (the frame's own connection may be
  // faster; odometry from tf was awaited by DepthInput's tf message filter); whatever is still
  // missing after the wait is a gap, reported below.
  waitForInputs(header.stamp);
  in->stamp_s = header.stamp.toSec();
  if (first_camera) {
    in->has_T_base_cam = true;
    if (!extrinsicsAt(header, 0, &in->T_base_cam, why)) return false;
  }
  std::string gap;
  in->has_odometry = odometryAt(header.stamp, &in->T_odom_base, &gap);
  if (clear_tf_) tf_->clear();
  clear_tf_ = false;
  gaps->odometry = !in->has_odometry && opts_.odometry_source != "none";
  if (gaps->odometry) gaps->warnings += gap + " (predicting with the constant-velocity model); ";
  if (opts_.use_imu) {
    in->has_attitude =
        imu_.attitudeAt(in->stamp_s, opts_.imu_timeout_s, &in->roll_rad, &in->pitch_rad, &gap);
    gaps->imu = !in->has_attitude;
    if (gaps->imu) gaps->warnings += "IMU attitude: " + gap + " (roll/pitch from odometry); ";
    // The gyro's heading, for a step without odometry (the localizer compares headings only
    // within one segment of gap-free samples).
    in->has_gyro_yaw = gyroHeadingForStep(gyro_, in->stamp_s, opts_.imu_timeout_s,
                                          &in->gyro_segment, &in->gyro_yaw_rad);
  }
  return true;
}

void StepInputs::timeJumpedBack(const ros::Time& stamp) {
  imu_.eraseAfter(stamp.toSec());
  gyro_.eraseAfter(stamp.toSec());
  odom_.eraseAfter(stamp.toSec());
  clear_tf_ = true;
}

}  // namespace gmm_mcl
