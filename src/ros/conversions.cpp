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
      return static_cast<int>(f.offset);
    }
  }
  return -1;
}

}  // namespace

bool depthImageFromMsg(const sensor_msgs::Image& msg, DepthImage* out, std::string* error) {
  DepthEncoding enc;
  if (!parseDepthEncoding(msg.encoding, &enc)) {
    *error = "unsupported depth encoding '" + msg.encoding + "' (expected 16UC1, mono16 or 32FC1)";
    return false;
  }
  const size_t sample = enc == DepthEncoding::kMono16Millimetres ? 2 : 4;
  if (msg.width == 0 || msg.height == 0) {
    *error = "empty depth image (" + std::to_string(msg.width) + "x" +
             std::to_string(msg.height) + ")";
    return false;
  }
  if (msg.step < msg.width * sample) {
    std::ostringstream s;
    s << "depth image step " << msg.step << " is shorter than width " << msg.width << " x "
      << sample << " bytes";
    *error = s.str();
    return false;
  }
  if (msg.data.size() < static_cast<size_t>(msg.step) * msg.height) {
    std::ostringstream s;
    s << "depth image data has " << msg.data.size() << " bytes, step x height = "
      << static_cast<size_t>(msg.step) * msg.height;
    *error = s.str();
    return false;
  }
  out->width_px = static_cast<int>(msg.width);
  out->height_px = static_cast<int>(msg.height);
  out->encoding = enc;
  out->row_bytes = msg.step;
  out->data.assign(msg.data.begin(), msg.data.begin() + static_cast<size_t>(msg.step) * msg.height);
  // The core reads little-endian samples; swap when the message's order differs.
  const bool msg_big = msg.is_bigendian != 0;
  if (msg_big) {
    for (size_t r = 0; r < msg.height; ++r) {
      uint8_t* row = out->data.data() + r * msg.step;
      for (size_t c = 0; c < msg.width; ++c) {
        uint8_t* s = row + c * sample;
        for (size_t k = 0; k < sample / 2; ++k) std::swap(s[k], s[sample - 1 - k]);
      }
    }
  }
  const std::string layout = out->checkLayout();
  if (!layout.empty()) {
    *error = layout;
    return false;
  }
  return true;
}

bool intrinsicsFromCameraInfo(const sensor_msgs::CameraInfo& msg, int expected_width,
                              int expected_height, Intrinsics* out, std::string* error) {
  bool all_zero = true;
  for (double k : msg.K) all_zero = all_zero && k == 0.0;
  if (all_zero) {
    *error = "CameraInfo is uncalibrated (K is all zero)";
    return false;
  }
  if (expected_width > 0 && expected_height > 0 &&
      (static_cast<int>(msg.width) != expected_width ||
       static_cast<int>(msg.height) != expected_height)) {
    std::ostringstream s;
    s << "depth image is " << expected_width << "x" << expected_height << " but CameraInfo says "
      << msg.width << "x" << msg.height;
    *error = s.str();
    return false;
  }
  try {
    *out = makeIntrinsics(msg.K.data(), static_cast<int>(msg.width), static_cast<int>(msg.height));
  } catch (const std::exception& e) {
    *error = std::string("CameraInfo: ") + e.what();
    return false;
  }
  return true;
}

bool depthImageFromCloud(const sensor_msgs::PointCloud2& msg, DepthImage* out, Intrinsics* K,
                         std::string* error) {
  if (msg.height <= 1 || msg.width == 0) {
    *error = "point cloud is not organized (height " + std::to_string(msg.height) + ")";
    return false;
  }
  const int ox = fieldOffset(msg, "x"), oy = fieldOffset(msg, "y"), oz = fieldOffset(msg, "z");
  if (ox < 0 || oy < 0 || oz < 0) {
    *error = "point cloud lacks float32 x, y, z fields";
    return false;
  }
  if (msg.is_bigendian) {
    *error = "big-endian point clouds are not supported";
    return false;
  }
  if (msg.point_step < 12 || msg.row_step < msg.width * msg.point_step ||
      msg.data.size() < static_cast<size_t>(msg.row_step) * msg.height) {
    *error = "point cloud data is shorter than its declared layout";
    return false;
  }
  const int w = static_cast<int>(msg.width), h = static_cast<int>(msg.height);
  std::vector<float> depth(static_cast<size_t>(w) * h, std::numeric_limits<float>::quiet_NaN());
  // Normal equations for (fx, cx) from u = fx a + cx with a = x / z, and (fy, cy) likewise.
  double su[5] = {0, 0, 0, 0, 0}, sv[5] = {0, 0, 0, 0, 0};  // n, sum a, sum a^2, sum u, sum a u
  for (int v = 0; v < h; ++v) {
    const uint8_t* row = msg.data.data() + static_cast<size_t>(v) * msg.row_step;
    for (int u = 0; u < w; ++u) {
      const uint8_t* p = row + static_cast<size_t>(u) * msg.point_step;
      float x, y, z;
      std::memcpy(&x, p + ox, 4);
      std::memcpy(&y, p + oy, 4);
      std::memcpy(&z, p + oz, 4);
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) || z <= 0.f) continue;
      depth[static_cast<size_t>(v) * w + u] = z;
      const double a = x / z, b = y / z;
      su[0] += 1; su[1] += a; su[2] += a * a; su[3] += u; su[4] += a * u;
      sv[0] += 1; sv[1] += b; sv[2] += b * b; sv[3] += v; sv[4] += b * v;
    }
  }
  auto fit = [](const double* s, double* f, double* c) {
    const double det = s[0] * s[2] - s[1] * s[1];
    if (!(std::abs(det) > 1e-12)) return false;
    *f = (s[0] * s[4] - s[1] * s[3]) / det;
    *c = (s[3] - *f * s[1]) / s[0];
    return std::isfinite(*f) && *f > 0.0 && std::isfinite(*c);
  };
  double fx, cx, fy, cy;
  if (su[0] < 16 || !fit(su, &fx, &cx) || !fit(sv, &fy, &cy)) {
    *error = "point cloud has too few valid points to recover the camera intrinsics";
    return false;
  }
  *out = DepthImage::fromMetres(w, h, depth);
  K->fx_px = static_cast<float>(fx);
  K->fy_px = static_cast<float>(fy);
  K->cx_px = static_cast<float>(cx);
  K->cy_px = static_cast<float>(cy);
  K->width_px = w;
  K->height_px = h;
  return true;
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
