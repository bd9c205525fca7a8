// Time-indexed poses (odometry, ground truth) and attitudes (IMU roll and pitch) looked up at a
// frame's stamp: interpolated between the neighbours, or the nearest entry within a tolerance.
// Thread-safe: producers (e.g. ROS callbacks on their own threads) add while a filter update
// reads; the lock is held only to insert or to look up.
#pragma once

#include <Eigen/Geometry>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <string>

namespace gmm_mcl {

class StampedPoseBuffer {
 public:
  // Entries older than the newest by more than max_age_s are dropped; two neighbours more than
  // max_gap_s apart are not interpolated between.
  explicit StampedPoseBuffer(double max_age_s = 10.0, double max_gap_s = 1.0);

  // Inserts in stamp order (a stamp seen before replaces its entry).
  void add(double stamp_s, const Eigen::Isometry3d& pose);
  // Roll and pitch only (an IMU's attitude), as a rotation with zero yaw.
  void addAttitude(double stamp_s, double roll_rad, double pitch_rad);

  // The pose at t: interpolated (slerp, linear) between the neighbours when t lies between two
  // entries at most max_gap_s apart, else the nearest entry when within tolerance_s of t.
  // False, with why, when neither.
  bool at(double t_s, double tolerance_s, Eigen::Isometry3d* out, std::string* why = nullptr) const;
  bool attitudeAt(double t_s, double tolerance_s, double* roll_rad, double* pitch_rad,
                  std::string* why = nullptr) const;

  // Whether an entry stamped at or after t has arrived (a lookup at t no longer has to take the
  // nearest earlier one); waitUntilReaches blocks until it has (woken by add) or until the
  // deadline, and says which.
  bool reaches(double t_s) const;
  bool waitUntilReaches(double t_s, std::chrono::steady_clock::time_point deadline) const;
  // Drops the entries stamped after t (time jumped back: they belong to the old timeline).
  void eraseAfter(double t_s);
  void clear();
  size_t size() const;
  long long added() const;  // entries added since construction
  bool empty() const { return size() == 0; }

 private:
  double max_age_s_, max_gap_s_;
  mutable std::mutex mutex_;
  mutable std::condition_variable added_cv_;  // notified by add
  std::map<double, Eigen::Isometry3d> track_;
  long long added_ = 0;
};

// The heading an IMU's gyro turned (StepInput::gyro_yaw_rad): the angular velocity rotated into
// the gravity-aligned frame by the IMU's roll and pitch, its vertical component (the body's turn
// rate about the vertical, the same for every frame fixed to the body) integrated over the
// samples' stamps by the trapezoidal rule, and looked up at a frame's stamp. A gap between
// samples longer than max_gap_s, or a sample older than the last, starts a new segment: a lookup
// tells which segment it lies in, and headings of different segments are not comparable.
// Thread-safe: samples from a subscription's callback, lookups and a time jump from the frames'
// thread.
class GyroHeading {
 public:
  explicit GyroHeading(double max_age_s = 2.0, double max_gap_s = 0.1);
  void add(double stamp_s, const Eigen::Vector3d& omega_imu_rad_s, double roll_rad,
           double pitch_rad);
  // The heading at t and its segment: interpolated between samples (or a sample's own); after
  // the newest sample, by at most tolerance_s and max_gap_s, extrapolated at its rate. False,
  // with why, otherwise: a heading held beyond the samples would claim that the body did not
  // turn (an IMU whose rates stopped, or a frame before the first sample).
  bool at(double t_s, double tolerance_s, double* heading_rad, long long* segment,
          std::string* why = nullptr) const;
  void eraseAfter(double t_s);  // time went back: the later samples dropped, a new segment
  long long added() const { return track_.added(); }

 private:
  double max_gap_s_;
  StampedPoseBuffer track_;   // heading in translation x, segment in translation y
  mutable std::mutex mutex_;  // the integration's state below, and track_ kept consistent with it
  bool have_ = false;
  double last_stamp_s_ = 0.0, last_rate_rad_s_ = 0.0, heading_rad_ = 0.0;
  long long segment_ = 0;
};

// A step's gyro heading (StepInput::has_gyro_yaw, gyro_yaw_rad, gyro_segment): whether there is
// one at t, the heading (0 where none) and its segment (-1 where none). The localizer compares
// headings of one segment only.
bool gyroHeadingForStep(const GyroHeading& gyro, double t_s, double tolerance_s, long long* segment,
                        double* heading_rad);

}  // namespace gmm_mcl
