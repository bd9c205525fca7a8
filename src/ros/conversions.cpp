#include "gmm_mcl/ros/conversions.h"

#include <sensor_msgs/image_encodings.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {
namespace ros_conv {
namespace {

int fieldOffset(const sensor_msgs::PointCloud2& msg, const std::string& name) {
  for (const auto& f : msg.fields) {
    if (f.name == name && f.datatype == sensor_msgs::PointField::FLOAT32 && f.count >= 1) {
      // An offset beyond int cannot fit any point: the layout check rejects it.
      return f.offset > static_cast<uint32_t>(std::numeric_limits<int>::max())
                 ? std::numeric_limits<int>::max()
                 : static_cast<int>(f.offset);
    }
  }
  return -1;
}

}  // namespace

bool depthImageFromMsg(const sensor_msgs::Image& msg, DepthImage* out, std::string* error) {
  return depthImageFromBuffer(msg.encoding, msg.width, msg.height, msg.step, msg.is_bigendian != 0,
                              msg.data.data(), msg.data.size(), out, error);
}

bool intrinsicsFromCameraInfo(const sensor_msgs::CameraInfo& msg, int expected_width,
                              int expected_height, Intrinsics* out, std::string* error,
                              std::string* note) {
  bool distorted = false;
  for (double d : msg.D) distorted = distorted || d != 0.0;
  const bool has_p = msg.P[0] != 0.0 || msg.P[5] != 0.0;
  if (distorted && !has_p) {
    *error = "CameraInfo has distortion (D non-zero, model '" + msg.distortion_model +
             "') and no projection matrix P: rectify the depth image first";
    return false;
  }
  if (distorted && note) {
    *note =
        "CameraInfo has distortion (D non-zero): the depth image is taken to be the rectified "
        "one (image_rect) and its intrinsics come from P";
  }
  // The rectified image's projection (P, as depth_image_proc uses it), else K; then binning and
  // region of interest, as image_geometry's PinholeCameraModel applies them.
  double K[9] = {msg.K[0], msg.K[1], msg.K[2], msg.K[3], msg.K[4],
                 msg.K[5], msg.K[6], msg.K[7], msg.K[8]};
  if (has_p) {
    const double P[9] = {msg.P[0], msg.P[1], msg.P[2], msg.P[4], msg.P[5], msg.P[6], 0.0, 0.0, 1.0};
    std::copy(P, P + 9, K);
  }
  const uint32_t bx = std::max<uint32_t>(1, msg.binning_x),
                 by = std::max<uint32_t>(1, msg.binning_y);
  const bool roi = msg.roi.width > 0 && msg.roi.height > 0;
  if (roi && (msg.roi.x_offset + msg.roi.width > msg.width ||
              msg.roi.y_offset + msg.roi.height > msg.height)) {
    std::ostringstream s;
    s << "CameraInfo's region of interest (" << msg.roi.width << "x" << msg.roi.height << " at "
      << msg.roi.x_offset << ", " << msg.roi.y_offset << ") exceeds its " << msg.width << "x"
      << msg.height << " image";
    *error = s.str();
    return false;
  }
  K[2] = (K[2] - (roi ? msg.roi.x_offset : 0)) / bx;
  K[5] = (K[5] - (roi ? msg.roi.y_offset : 0)) / by;
  K[0] /= bx;
  K[1] /= bx;
  K[4] /= by;
  const uint32_t width = (roi ? msg.roi.width : msg.width) / bx;
  const uint32_t height = (roi ? msg.roi.height : msg.height) / by;
  return intrinsicsFromCameraMatrix(K, width, height, expected_width, expected_height, out, error);
}

bool depthImageFromCloud(const sensor_msgs::PointCloud2& msg, DepthImage* out, Intrinsics* K,
                         std::string* error) {
  CloudLayout layout;
  layout.width = msg.width;
  layout.height = msg.height;
  layout.point_step = msg.point_step;
  layout.row_step = msg.row_step;
  layout.big_endian = msg.is_bigendian != 0;
  layout.x_offset = fieldOffset(msg, "x");
  layout.y_offset = fieldOffset(msg, "y");
  layout.z_offset = fieldOffset(msg, "z");
  return depthImageFromCloudBuffer(layout, msg.data.data(), msg.data.size(), out, K, error);
}

bool attitudeFromImu(const sensor_msgs::Imu& msg, double* roll_rad, double* pitch_rad) {
  if (msg.orientation_covariance[0] == -1.0) return false;
  const auto& q = msg.orientation;
  const double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (!std::isfinite(n) || n < 1e-6) return false;
  const Eigen::Quaterniond e(q.w / n, q.x / n, q.y / n, q.z / n);
  double yaw;
  rpyFromRotation(e.toRotationMatrix(), roll_rad, pitch_rad, &yaw);
  return true;
}

bool angularVelocityFromImu(const sensor_msgs::Imu& msg, Eigen::Vector3d* omega_rad_s) {
  if (msg.angular_velocity_covariance[0] == -1.0) return false;  // REP 145: none
  const auto& w = msg.angular_velocity;
  const Eigen::Vector3d v(w.x, w.y, w.z);
  // Exactly zero on every axis: a message that carries only an orientation and left the rates
  // unset (a real gyro's noise is never exactly zero).
  if (!v.allFinite() || (v.x() == 0.0 && v.y() == 0.0 && v.z() == 0.0)) return false;
  *omega_rad_s = v;
  return true;
}

namespace {
// An unset (all zero) quaternion is the identity; any other is normalised.
geometry_msgs::Quaternion normalised(const geometry_msgs::Quaternion& q) {
  Eigen::Quaterniond e;
  tf2::fromMsg(q, e);
  return tf2::toMsg(e.norm() > 1e-9 ? e.normalized() : Eigen::Quaterniond::Identity());
}
}  // namespace

Eigen::Isometry3d isometryFromPose(const geometry_msgs::Pose& msg) {
  geometry_msgs::Pose p = msg;
  p.orientation = normalised(msg.orientation);
  Eigen::Isometry3d T;
  tf2::fromMsg(p, T);
  return T;
}

Eigen::Isometry3d isometryFromTransform(const geometry_msgs::Transform& msg) {
  geometry_msgs::Transform t = msg;
  t.rotation = normalised(msg.rotation);
  return tf2::transformToEigen(t);
}

geometry_msgs::Pose poseFromIsometry(const Eigen::Isometry3d& T) {
  geometry_msgs::Pose p = tf2::toMsg(T);
  p.orientation = normalised(p.orientation);
  return p;
}

geometry_msgs::Transform transformFromIsometry(const Eigen::Isometry3d& T) {
  geometry_msgs::Transform t = tf2::eigenToTransform(T).transform;
  t.rotation = normalised(t.rotation);
  return t;
}

geometry_msgs::PoseWithCovariance poseWithCovarianceFromEstimate(const PoseEstimate& estimate,
                                                                 double roll_rad,
                                                                 double pitch_rad) {
  geometry_msgs::PoseWithCovariance out;
  out.pose = poseFromIsometry(particleToPose(estimate.mean, roll_rad, pitch_rad));
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) out.covariance[r * 6 + c] = estimate.covariance(r, c);
  }
  return out;
}

void poseArrayFromParticles(const std::vector<Particle>& particles, double roll_rad,
                            double pitch_rad, geometry_msgs::PoseArray* out) {
  out->poses.resize(particles.size());
  for (size_t i = 0; i < particles.size(); ++i) {
    out->poses[i] = poseFromIsometry(particleToPose(particles[i], roll_rad, pitch_rad));
  }
}

geometry_msgs::PoseWithCovarianceStamped poseWithCovarianceStamped(
    const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& covariance,
    const std::string& frame, const ros::Time& stamp) {
  geometry_msgs::PoseWithCovarianceStamped p;
  p.header.stamp = stamp;
  p.header.frame_id = frame;
  p.pose.pose = poseFromIsometry(T);
  for (int k = 0; k < 36; ++k) p.pose.covariance[k] = covariance(k / 6, k % 6);
  return p;
}

geometry_msgs::TransformStamped transformStamped(const Eigen::Isometry3d& T,
                                                 const std::string& parent,
                                                 const std::string& child, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform = transformFromIsometry(T);
  return t;
}

bool poseResetRequestFromMsg(const geometry_msgs::PoseWithCovarianceStamped& msg,
                             const tf2::BufferCore& tf, const std::string& map_frame,
                             PoseResetRequest* out, std::string* why) {
  out->planar =
      isPlanarPose(isometryFromPose(msg.pose.pose), covarianceFromMsg(msg.pose.covariance));
  geometry_msgs::PoseWithCovarianceStamped in_map = msg;
  const std::string& frame = msg.header.frame_id.empty() ? map_frame : msg.header.frame_id;
  if (frame != map_frame) {
    try {
      const ros::Time at =
          tf.canTransform(map_frame, frame, msg.header.stamp) ? msg.header.stamp : ros::Time(0);
      tf2::doTransform(msg, in_map, tf.lookupTransform(map_frame, frame, at));
    } catch (const tf2::TransformException& e) {
      *why = "pose in frame '" + frame + "' not transformed to '" + map_frame + "': " + e.what();
      return false;
    }
  }
  out->T_map_base = isometryFromPose(in_map.pose.pose);
  out->covariance = covarianceFromMsg(in_map.pose.covariance);
  return true;
}

Eigen::Matrix<double, 6, 6> covarianceFromMsg(const boost::array<double, 36>& c) {
  Eigen::Matrix<double, 6, 6> m;
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) m(r, k) = c[6 * r + k];
  }
  return m;
}

void markersFromMap(const GmmMap& map, const std::string& frame_id,
                    visualization_msgs::MarkerArray* out, const std::vector<int>* only) {
  out->markers.clear();
  out->markers.reserve((only ? only->size() : map.size()) + 1);
  if (only) {
    visualization_msgs::Marker clear;
    clear.header.frame_id = frame_id;
    clear.ns = "gmm";
    clear.action = visualization_msgs::Marker::DELETEALL;
    out->markers.push_back(clear);
  }
  const double z_lo = map.minBound().z(), z_span = std::max(1e-6, map.maxBound().z() - z_lo);
  const size_t count = only ? only->size() : map.size();
  for (size_t k = 0; k < count; ++k) {
    const size_t i = only ? static_cast<size_t>((*only)[k]) : k;
    const GaussianComponent& c = map.components()[i];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(c.cov_m2);
    Eigen::Matrix3d R = es.eigenvectors();
    if (R.determinant() < 0) R.col(2) = -R.col(2);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = c.mean_m;
    visualization_msgs::Marker m;
    m.header.frame_id = frame_id;
    m.ns = "gmm";
    m.id = static_cast<int>(i);
    m.type = visualization_msgs::Marker::SPHERE;
    m.action = visualization_msgs::Marker::ADD;
    m.pose = poseFromIsometry(T);
    const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);
    m.scale.x = std::max(1e-3, 6.0 * std::sqrt(ev[0]));
    m.scale.y = std::max(1e-3, 6.0 * std::sqrt(ev[1]));
    m.scale.z = std::max(1e-3, 6.0 * std::sqrt(ev[2]));
    const double h = (c.mean_m.z() - z_lo) / z_span;  // blue (low) -> red (high)
    m.color.r = static_cast<float>(h);
    m.color.g = static_cast<float>(0.4 + 0.4 * (1.0 - std::abs(2.0 * h - 1.0)));
    m.color.b = static_cast<float>(1.0 - h);
    m.color.a = 0.35f;
    m.frame_locked = false;
    out->markers.push_back(m);
  }
}

sensor_msgs::Imu imuFromAttitude(const ros::Time& stamp, const std::string& frame_id,
                                 double roll_rad, double pitch_rad, double yaw_rad,
                                 double attitude_variance_rad2, bool rates_absent) {
  sensor_msgs::Imu imu;
  imu.header.stamp = stamp;
  imu.header.frame_id = frame_id;
  const Eigen::Quaterniond q(rotationFromRpy(roll_rad, pitch_rad, yaw_rad));
  imu.orientation.w = q.w();
  imu.orientation.x = q.x();
  imu.orientation.y = q.y();
  imu.orientation.z = q.z();
  imu.orientation_covariance[0] = imu.orientation_covariance[4] = attitude_variance_rad2;
  imu.orientation_covariance[8] = 1.0;
  if (rates_absent) {
    imu.angular_velocity_covariance[0] = -1.0;
    imu.linear_acceleration_covariance[0] = -1.0;
  }
  return imu;
}

sensor_msgs::CameraInfo cameraInfoFromIntrinsics(const Intrinsics& K, const ros::Time& stamp,
                                                 const std::string& frame_id) {
  sensor_msgs::CameraInfo info;
  info.distortion_model = "plumb_bob";
  info.width = K.width_px;
  info.height = K.height_px;
  info.header.stamp = stamp;
  info.header.frame_id = frame_id;
  info.D.assign(5, 0.0);
  info.K = {K.fx_px, 0, K.cx_px, 0, K.fy_px, K.cy_px, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {K.fx_px, 0, K.cx_px, 0, 0, K.fy_px, K.cy_px, 0, 0, 0, 1, 0};
  return info;
}

}  // namespace ros_conv
}  // namespace gmm_mcl
