// rostest node: the nodelet (in a manager) localizes on the synthetic bag played with --clock.
// mode "track": final error, map -> odom future-dated and monotonic, covariance consistency,
//   ~global_localization spreads the particles, a stale /initialpose is carried forward.
// mode "looped": the bag loops (time jumps back); the filter resets and re-converges.
#include <cmath>
#include <functional>
#include <iterator>
#include <map>
#include <set>
#include <vector>

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_srvs/Empty.h>
#include <tf2_msgs/TFMessage.h>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"

using namespace gmm_mcl;

namespace {

constexpr double kFinalErrorM = 0.10;        // final translation error
constexpr double kTrackErrorM = 0.15;        // error before global localization
constexpr double kCarriedErrorM = 0.20;      // first estimate after the stale /initialpose
constexpr double kConsistentFraction = 0.8;  // frames with an error component within 3 sigma
constexpr double kTransformTolerance = 0.1;  // the launch's transform_tolerance

struct Pose {
  ros::Time stamp;
  Eigen::Isometry3d T;
  boost::array<double, 36> cov;
};

class Recorder {
 public:
  explicit Recorder(ros::NodeHandle& nh) {
    gt_sub_ = nh.subscribe("/ground_truth", 1000, &Recorder::gt, this);
    pose_sub_ = nh.subscribe("/gmm_mcl/pose", 1000, &Recorder::pose, this);
    tf_sub_ = nh.subscribe("/tf", 1000, &Recorder::tf, this);
    status_sub_ = nh.subscribe("/gmm_mcl/status", 1000, &Recorder::status, this);
  }
  void gt(const geometry_msgs::PoseStampedConstPtr& m) {
    if (t0_.isZero() || m->header.stamp < t0_) t0_ = m->header.stamp;
    truth_[m->header.stamp.toNSec()] = ros_conv::isometryFromPose(m->pose);
  }
  void pose(const geometry_msgs::PoseWithCovarianceStampedConstPtr& m) {
    poses_.push_back(Pose{m->header.stamp, ros_conv::isometryFromPose(m->pose.pose), m->pose.covariance});
  }
  void tf(const tf2_msgs::TFMessageConstPtr& m) {
    for (const auto& t : m->transforms) {
      if (t.header.frame_id == "map" && t.child_frame_id == "odom") tf_stamps_.push_back(t.header.stamp);
    }
  }
  void status(const FilterStatusConstPtr& m) {
    statuses_.push_back(*m);
    resets_[m->header.stamp.toNSec()] = m->resets;
  }
  // Resets the nodelet had applied when it published the pose of this stamp (-1: unknown).
  int resetsAt(const Pose& p) const {
    const auto it = resets_.find(p.stamp.toNSec());
    return it == resets_.end() ? -1 : it->second;
  }
  // The first pose published once `resets` resets were applied.
  bool firstPoseWithResets(int resets, Pose* out) const {
    for (const Pose& p : poses_) {
      if (resetsAt(p) >= resets) {
        *out = p;
        return true;
      }
    }
    return false;
  }

  // Error of a pose against the truth at its stamp; false when no truth has that stamp.
  bool error(const Pose& p, Eigen::Vector4d* e) const {
    const auto it = truth_.find(p.stamp.toNSec());
    if (it == truth_.end()) return false;
    const Eigen::Vector3d d = p.T.translation() - it->second.translation();
    (*e) << d, wrapAngle(yawFromRotation(p.T.linear()) - yawFromRotation(it->second.linear()));
    return true;
  }
  double rel(const ros::Time& t) const { return (t - t0_).toSec(); }

  ros::Subscriber gt_sub_, pose_sub_, tf_sub_, status_sub_;
  ros::Time t0_;
  std::map<uint64_t, Eigen::Isometry3d> truth_;
  std::vector<Pose> poses_;
  std::vector<ros::Time> tf_stamps_;
  std::vector<FilterStatus> statuses_;
  std::map<uint64_t, int> resets_;
};

bool spinUntil(const std::function<bool()>& done, double wall_timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(wall_timeout_s);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (done()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return false;
}

double translationError(const Recorder& r, const Pose& p) {
  Eigen::Vector4d e;
  return r.error(p, &e) ? e.head<3>().norm() : 1e9;
}

}  // namespace

TEST(LocalizationBag, TracksResetsAndPublishesTf) {
  ros::NodeHandle nh;
  Recorder rec(nh);
  double bag_duration_s = 8.0;
  ros::param::param("~bag_duration", bag_duration_s, 8.0);

  // 1. Tracking from the initial region.
  ASSERT_TRUE(spinUntil([&] { return !rec.poses_.empty() && rec.rel(rec.poses_.back().stamp) >= 3.5; }, 120.0))
      << "no pose 3.5 s into the bag (" << rec.poses_.size() << " poses)";
  const double err_tracking = translationError(rec, rec.poses_.back());
  std::printf("[ measured ] error after 3.5 s of tracking: %.3f m\n", err_tracking);
  EXPECT_LT(err_tracking, kTrackErrorM);

  // 2. Global localization: uniform over the map bounds.
  std_srvs::Empty srv;
  ASSERT_TRUE(ros::service::waitForService("/gmm_mcl/global_localization", 5000));
  ASSERT_TRUE(ros::service::call("/gmm_mcl/global_localization", srv));
  // The first pose computed after the reset (status.resets counts the resets applied).
  const int resets0 = rec.statuses_.back().resets;
  Pose after_global;
  ASSERT_TRUE(spinUntil([&] { return rec.firstPoseWithResets(resets0 + 1, &after_global); }, 30.0));
  const ros::Time t_global = after_global.stamp;
  std::printf("[ measured ] sigma x, y after global localization: %.2f, %.2f m\n",
              std::sqrt(after_global.cov[0]), std::sqrt(after_global.cov[7]));
  EXPECT_GT(std::sqrt(after_global.cov[0]), 1.0) << "particles not spread over the map";
  EXPECT_GT(std::sqrt(after_global.cov[7]), 1.0);

  // 3. A stale /initialpose (the true pose 1.5 s before the latest frame) is carried forward.
  ASSERT_TRUE(spinUntil([&] { return (rec.poses_.back().stamp - t_global).toSec() >= 0.5; }, 30.0));
  const ros::Time t_latest = ros::Time::now();
  const ros::Time t_stale = t_latest - ros::Duration(1.5);
  auto stale = rec.truth_.lower_bound(t_stale.toNSec());
  ASSERT_NE(stale, rec.truth_.end());
  const auto now_truth = std::prev(rec.truth_.end());  // the latest truth received
  const double moved_m = (now_truth->second.translation() - stale->second.translation()).norm();
  std::printf("[ measured ] the robot moved %.2f m since the stale initial pose's stamp\n", moved_m);
  ASSERT_GT(moved_m, 2.0 * kCarriedErrorM) << "the stale-stamp check would not discriminate";
  ros::Publisher init_pub = nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("/initialpose", 1, true);
  geometry_msgs::PoseWithCovarianceStamped init;
  init.header.frame_id = "map";
  init.header.stamp.fromNSec(stale->first);
  init.pose.pose = ros_conv::poseFromIsometry(stale->second);
  init.pose.covariance[0] = init.pose.covariance[7] = init.pose.covariance[14] = 0.05 * 0.05;
  init.pose.covariance[35] = 0.05 * 0.05;
  ASSERT_TRUE(spinUntil([&] { return init_pub.getNumSubscribers() > 0; }, 5.0));
  init_pub.publish(init);
  // The first estimate after the reset was applied.
  Pose first_after;
  ASSERT_TRUE(spinUntil([&] { return rec.firstPoseWithResets(resets0 + 2, &first_after); }, 30.0));
  const double err_carried = translationError(rec, first_after);
  std::printf("[ measured ] error right after the stale initial pose: %.3f m\n", err_carried);
  EXPECT_LT(err_carried, kCarriedErrorM);

  // 4. To the end of the bag.
  spinUntil([&] { return rec.rel(rec.poses_.back().stamp) >= bag_duration_s - 0.3; }, 120.0);
  ros::WallDuration(1.0).sleep();
  ros::spinOnce();
  for (const Pose& p : rec.poses_) {
    const double t = rec.rel(p.stamp);
    if (t > rec.rel(t_global) - 0.2 && t < rec.rel(first_after.stamp) + 0.5) {
      std::printf("  pose at %.3f s: error %.3f m, sigma x %.3f m\n", t, translationError(rec, p), std::sqrt(p.cov[0]));
    }
  }
  const double err_final = translationError(rec, rec.poses_.back());
  std::printf("[ measured ] final error %.3f m at %.2f s (%zu poses)\n", err_final,
              rec.rel(rec.poses_.back().stamp), rec.poses_.size());
  EXPECT_LT(err_final, kFinalErrorM);

  // map -> odom: future-dated by transform_tolerance from a frame stamp, strictly increasing.
  ASSERT_GE(rec.tf_stamps_.size(), 10u);
  std::set<uint64_t> pose_stamps;
  for (const Pose& p : rec.poses_) pose_stamps.insert(p.stamp.toNSec());
  int dated = 0;
  for (size_t i = 0; i < rec.tf_stamps_.size(); ++i) {
    if (i > 0) EXPECT_GT(rec.tf_stamps_[i], rec.tf_stamps_[i - 1]) << "tf " << i << " not monotonic";
    const uint64_t frame = (rec.tf_stamps_[i] - ros::Duration(kTransformTolerance)).toNSec();
    bool match = false;
    for (uint64_t s : {frame - 1, frame, frame + 1}) match = match || pose_stamps.count(s);
    dated += match;
  }
  EXPECT_EQ(dated, static_cast<int>(rec.tf_stamps_.size()))
      << "map -> odom stamps are not the frame stamps + transform_tolerance";

  // Covariance consistency: each component within 3 sigma for most converged frames.
  int n = 0, within[4] = {0, 0, 0, 0};
  const int diag[4] = {0, 7, 14, 35};
  for (const Pose& p : rec.poses_) {
    const double t = rec.rel(p.stamp);
    const bool converged = (t >= 1.5 && p.stamp < t_global) || (p.stamp - first_after.stamp).toSec() >= 1.0;
    Eigen::Vector4d e;
    if (!converged || !rec.error(p, &e)) continue;
    ++n;
    for (int k = 0; k < 4; ++k) within[k] += std::abs(e[k]) <= 3.0 * std::sqrt(p.cov[diag[k]]);
  }
  ASSERT_GE(n, 10);
  for (int k = 0; k < 4; ++k) {
    std::printf("[ measured ] component %d within 3 sigma in %d of %d frames\n", k, within[k], n);
    EXPECT_GE(within[k], kConsistentFraction * n) << "component " << k;
  }
  for (const FilterStatus& s : rec.statuses_) EXPECT_NE(s.step_status, "bad_frame") << s.message;
}

TEST(LocalizationBag, LoopedBagResets) {
  ros::NodeHandle nh;
  Recorder rec(nh);
  double loop_s = 4.0;
  ros::param::param("~loop_duration", loop_s, 4.0);
  size_t i_jump = 0;
  auto find_jump = [&] {
    for (size_t i = 1; i < rec.poses_.size(); ++i) {
      if (rec.poses_[i].stamp < rec.poses_[i - 1].stamp) {
        i_jump = i;
        return true;
      }
    }
    return false;
  };
  ASSERT_TRUE(spinUntil(find_jump, 150.0)) << "no jump back in time seen (" << rec.poses_.size() << " poses)";
  const double err_before = translationError(rec, rec.poses_[i_jump - 1]);
  std::printf("[ measured ] error before the loop: %.3f m; jump from %.2f to %.2f s\n", err_before,
              rec.rel(rec.poses_[i_jump - 1].stamp), rec.rel(rec.poses_[i_jump].stamp));
  ASSERT_TRUE(spinUntil([&] { return rec.rel(rec.poses_.back().stamp) >= loop_s - 0.5 &&
                                     rec.poses_.size() > i_jump + 5; }, 120.0));
  for (size_t i = i_jump; i < rec.poses_.size(); i += 4) {
    std::printf("  second loop: pose at %.3f s: error %.3f m, sigma x %.3f m\n", rec.rel(rec.poses_[i].stamp),
                translationError(rec, rec.poses_[i]), std::sqrt(rec.poses_[i].cov[0]));
  }
  const double err_after = translationError(rec, rec.poses_.back());
  std::printf("[ measured ] error at %.2f s of the second loop: %.3f m\n", rec.rel(rec.poses_.back().stamp), err_after);
  EXPECT_LT(err_after, kTrackErrorM);
  bool reported = false;
  for (const FilterStatus& s : rec.statuses_) reported = reported || s.step_status == "time_jump_back";
  EXPECT_TRUE(reported) << "no status reported time_jump_back";
  // tf: one step back at the loop, strictly increasing on either side.
  int backs = 0;
  for (size_t i = 1; i < rec.tf_stamps_.size(); ++i) backs += rec.tf_stamps_[i] <= rec.tf_stamps_[i - 1];
  EXPECT_EQ(backs, 1) << "map -> odom should restart once at the loop and increase otherwise";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "rostest_localization");
  ros::NodeHandle nh;
  std::string mode;
  ros::param::param<std::string>("~mode", mode, "track");
  if (mode == "looped") {
    testing::GTEST_FLAG(filter) = "LocalizationBag.Looped*";
  } else {
    testing::GTEST_FLAG(filter) = "LocalizationBag.Tracks*";
  }
  return RUN_ALL_TESTS();
}
