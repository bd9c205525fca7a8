#include "gmm_mcl/filter/stamped_buffer.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <sstream>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {

StampedPoseBuffer::StampedPoseBuffer(double max_age_s, double max_gap_s)
    : max_age_s_(max_age_s), max_gap_s_(max_gap_s) {}

void StampedPoseBuffer::add(double stamp_s, const Eigen::Isometry3d& pose) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    track_[stamp_s] = pose;
    ++added_;
    const double oldest = track_.rbegin()->first - max_age_s_;
    while (!track_.empty() && track_.begin()->first < oldest) track_.erase(track_.begin());
  }
  added_cv_.notify_all();
}

void StampedPoseBuffer::addAttitude(double stamp_s, double roll_rad, double pitch_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(roll_rad, pitch_rad, 0.0);
  add(stamp_s, T);
}

bool StampedPoseBuffer::at(double t, double tolerance_s, Eigen::Isometry3d* out,
                           std::string* why) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::ostringstream msg;
  if (track_.empty()) {
    if (why) *why = "none received";
    return false;
  }
  const auto hi = track_.lower_bound(t);
  if (hi != track_.end() && hi->first == t) {
    *out = hi->second;
    return true;
  }
  if (hi != track_.end() && hi != track_.begin()) {
    const auto lo = std::prev(hi);
    if (hi->first - lo->first <= max_gap_s_) {
      const double a = (t - lo->first) / (hi->first - lo->first);
      *out = Eigen::Isometry3d::Identity();
      out->linear() = Eigen::Quaterniond(lo->second.linear())
                          .slerp(a, Eigen::Quaterniond(hi->second.linear()))
                          .toRotationMatrix();
      out->translation() = (1 - a) * lo->second.translation() + a * hi->second.translation();
      return true;
    }
  }
  // The nearest neighbour.
  auto nearest = hi == track_.end() ? std::prev(hi) : hi;
  if (hi != track_.end() && hi != track_.begin() && t - std::prev(hi)->first < hi->first - t) {
    nearest = std::prev(hi);
  }
  const double dt = std::abs(nearest->first - t);
  if (dt <= tolerance_s) {
    *out = nearest->second;
    return true;
  }
  if (why) {
    msg << "nearest is " << dt << " s " << (nearest->first < t ? "before" : "after")
        << " the stamp (tolerance " << tolerance_s << " s)";
    *why = msg.str();
  }
  return false;
}

bool StampedPoseBuffer::attitudeAt(double t_s, double tolerance_s, double* roll_rad,
                                   double* pitch_rad, std::string* why) const {
  Eigen::Isometry3d T;
  if (!at(t_s, tolerance_s, &T, why)) return false;
  double yaw;
  rpyFromRotation(T.linear(), roll_rad, pitch_rad, &yaw);
  return true;
}

void StampedPoseBuffer::eraseAfter(double t_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  track_.erase(track_.upper_bound(t_s), track_.end());
}

void StampedPoseBuffer::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  track_.clear();
}

bool StampedPoseBuffer::reaches(double t_s) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return !track_.empty() && track_.rbegin()->first >= t_s;
}

bool StampedPoseBuffer::waitUntilReaches(double t_s,
                                         std::chrono::steady_clock::time_point deadline) const {
  std::unique_lock<std::mutex> lock(mutex_);
  return added_cv_.wait_until(lock, deadline,
                              [&] { return !track_.empty() && track_.rbegin()->first >= t_s; });
}

size_t StampedPoseBuffer::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return track_.size();
}

long long StampedPoseBuffer::added() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return added_;
}

GyroHeading::GyroHeading(double max_age_s, double max_gap_s)
    : max_gap_s_(max_gap_s), track_(max_age_s, max_gap_s) {}

void GyroHeading::add(double stamp_s, const Eigen::Vector3d& omega_imu_rad_s, double roll_rad,
                      double pitch_rad) {
  const double rate = (rotationFromRpy(roll_rad, pitch_rad, 0.0) * omega_imu_rad_s).z();
  if (!std::isfinite(rate) || !std::isfinite(stamp_s)) return;
  std::lock_guard<std::mutex> lock(mutex_);
  const double dt = stamp_s - last_stamp_s_;
  if (have_ && dt > 0.0 && dt <= max_gap_s_) {
    heading_rad_ += 0.5 * (last_rate_rad_s_ + rate) * dt;
  } else if (!have_ || dt != 0.0) {  // the first sample, a gap or a sample out of order
    if (have_) ++segment_;
    heading_rad_ = 0.0;
  }
  have_ = true;
  last_stamp_s_ = stamp_s;
  last_rate_rad_s_ = rate;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(heading_rad_, static_cast<double>(segment_), 0.0);
  track_.add(stamp_s, T);
}

bool GyroHeading::at(double t_s, double tolerance_s, double* heading_rad, long long* segment,
                     std::string* why) const {
  // One lock over both looks (add() takes the same one around its track_.add): no sample can
  // arrive between them.
  std::lock_guard<std::mutex> lock(mutex_);
  Eigen::Isometry3d T;
  if (track_.at(t_s, 0.0, &T)) {  // between two samples of a segment, or at one
    *heading_rad = T.translation().x();
    *segment = std::llround(T.translation().y());
    return true;
  }
  const double ahead_s = t_s - last_stamp_s_;
  if (have_ && ahead_s > 0.0 && ahead_s <= std::min(tolerance_s, max_gap_s_)) {
    *heading_rad = heading_rad_ + last_rate_rad_s_ * ahead_s;
    *segment = segment_;
    return true;
  }
  if (why) {
    std::ostringstream msg;
    msg << "no gyro samples around " << t_s << " s (the heading is extrapolated at most "
        << std::min(tolerance_s, max_gap_s_) << " s past the newest)";
    *why = msg.str();
  }
  return false;
}

void GyroHeading::eraseAfter(double t_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  track_.eraseAfter(t_s);
  have_ = false;
  ++segment_;
}

bool gyroHeadingForStep(const GyroHeading& gyro, double t_s, double tolerance_s, long long* segment,
                        double* heading_rad) {
  const bool found = gyro.at(t_s, tolerance_s, heading_rad, segment);
  if (!found) {
    *heading_rad = 0.0;
    *segment = -1;
  }
  return found;
}

}  // namespace gmm_mcl
