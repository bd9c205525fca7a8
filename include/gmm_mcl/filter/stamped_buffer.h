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

}  // namespace gmm_mcl
