#include "gmm_mcl/ros/conversions.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <sensor_msgs/image_encodings.h>

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
                              int expected_height, Intrinsics* out, std::string* error) {
  return intrinsicsFromCameraMatrix(msg.K.data(), msg.width, msg.height, expected_width,
                                    expected_height, out, error);
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

Eigen::Isometry3d isometryFromPose(const geometry_msgs::Pose& msg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Quaterniond q(msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z);
  if (q.norm() > 1e-9) q.normalize();
  else q = Eigen::Quaterniond::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(msg.position.x, msg.position.y, msg.position.z);
  return T;
}

Eigen::Isometry3d isometryFromTransform(const geometry_msgs::Transform& msg) {
  geometry_msgs::Pose p;
  p.position.x = msg.translation.x;
  p.position.y = msg.translation.y;
  p.position.z = msg.translation.z;
  p.orientation = msg.rotation;
  return isometryFromPose(p);
}

geometry_msgs::Pose poseFromIsometry(const Eigen::Isometry3d& T) {
  geometry_msgs::Pose p;
  p.position.x = T.translation().x();
  p.position.y = T.translation().y();
  p.position.z = T.translation().z();
  Eigen::Quaterniond q(T.linear());
  q.normalize();
  p.orientation.w = q.w();
  p.orientation.x = q.x();
  p.orientation.y = q.y();
  p.orientation.z = q.z();
  return p;
}

geometry_msgs::Transform transformFromIsometry(const Eigen::Isometry3d& T) {
  const geometry_msgs::Pose p = poseFromIsometry(T);
  geometry_msgs::Transform t;
  t.translation.x = p.position.x;
  t.translation.y = p.position.y;
  t.translation.z = p.position.z;
  t.rotation = p.orientation;
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

bool particleFromPoseWithCovariance(const geometry_msgs::PoseWithCovariance& msg,
                                    const Eigen::Vector4d& min_sigma, Particle* pose,
                                    Eigen::Vector4d* sigma) {
  const auto& p = msg.pose.position;
  const auto& q = msg.pose.orientation;
  if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(q.x) &&
        std::isfinite(q.y) && std::isfinite(q.z) && std::isfinite(q.w))) {
    return false;
  }
  *pose = poseToParticle(isometryFromPose(msg.pose));
  const int diag[4] = {0, 7, 14, 35};
  for (int k = 0; k < 4; ++k) {
    const double var = msg.covariance[diag[k]];
    (*sigma)[k] = (std::isfinite(var) && var > 0.0) ? std::sqrt(var) : min_sigma[k];
  }
  return true;
}

void markersFromMap(const GmmMap& map, const std::string& frame_id,
                    visualization_msgs::MarkerArray* out) {
  out->markers.clear();
  out->markers.reserve(map.size());
  const double z_lo = map.minBound().z(), z_span = std::max(1e-6, map.maxBound().z() - z_lo);
  for (size_t i = 0; i < map.size(); ++i) {
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

}  // namespace ros_conv
}  // namespace gmm_mcl
