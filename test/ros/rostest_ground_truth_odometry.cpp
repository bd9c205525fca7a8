// rostest node: a bag laid out as cow_and_lady (organized cloud, motion-capture
// TransformStamped of the marker) plays in lockstep (test/ros/lockstep.h: the test owns /clock
// and waits for the nodelet's ~status of each cloud); gmm_mcl_ground_truth_odometry makes
// odometry, IMU and ground truth from it (with the marker -> camera calibration); the nodelet
// localizes on the cloud. Checks convergence against the ground truth, the odometry's drift and the
// IMU's attitude against the truth, and the TUM file of the ground truth.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "lockstep.h"

namespace gmm_mcl {

namespace {

constexpr double kTrackErrorM = 0.15;                     // 3 s into the bag
constexpr double kFinalErrorM = 0.10;                     // last pose
constexpr double kAttitudeErrorRad = 3.0 * M_PI / 180.0;  // 6 sigma of the 0.5 deg noise
constexpr double kMaxOdomDriftM = 0.5;   // drifting odometry over the bag, vs truth motion
constexpr double kMinOdomDriftM = 1e-4;  // it is noisy at all

struct Stamped {
  ros::Time stamp;
  Eigen::Isometry3d T;
};

class Recorder {
 public:
  explicit Recorder(ros::NodeHandle& nh) {
    subs_.push_back(nh.subscribe("/ground_truth", 1000, &Recorder::gt, this));
    subs_.push_back(nh.subscribe("/gmm_mcl/pose", 1000, &Recorder::pose, this));
    subs_.push_back(nh.subscribe("/odom", 1000, &Recorder::odom, this));
    subs_.push_back(nh.subscribe("/imu/data", 1000, &Recorder::imu, this));
  }
  void gt(const geometry_msgs::PoseStampedConstPtr& m) {
    if (t0_.isZero()) t0_ = m->header.stamp;
    truth_[m->header.stamp.toNSec()] = ros_conv::isometryFromPose(m->pose);
  }
  void pose(const geometry_msgs::PoseWithCovarianceStampedConstPtr& m) {
    poses_.push_back(Stamped{m->header.stamp, ros_conv::isometryFromPose(m->pose.pose)});
  }
  void odom(const nav_msgs::OdometryConstPtr& m) {
    odom_.push_back(Stamped{m->header.stamp, ros_conv::isometryFromPose(m->pose.pose)});
  }
  void imu(const sensor_msgs::ImuConstPtr& m) {
    double r, p;
    if (ros_conv::attitudeFromImu(*m, &r, &p))
      imu_[m->header.stamp.toNSec()] = Eigen::Vector2d(r, p);
  }
  double error(const Stamped& p) const {
    const auto it = truth_.find(p.stamp.toNSec());
    return it == truth_.end() ? 1e9 : (p.T.translation() - it->second.translation()).norm();
  }
  double rel(const ros::Time& t) const { return (t - t0_).toSec(); }

  std::vector<ros::Subscriber> subs_;
  ros::Time t0_;
  std::map<uint64_t, Eigen::Isometry3d> truth_;
  std::map<uint64_t, Eigen::Vector2d> imu_;
  std::vector<Stamped> poses_, odom_;
};

double errorOf(const Recorder& rec, const Stamped& p) {
  double e = 1e9;
  lockstep::waitFor([&] { return (e = rec.error(p)) < 1e9; });  // its truth comes from the node
  return e;
}

}  // namespace

TEST(GroundTruthOdometryTest, LocalizerConvergesOnACowAndLadyLayoutBag) {
  ros::NodeHandle nh;
  Recorder rec(nh);
  lockstep::Clock clock(nh);
  lockstep::Observer obs(nh);
  std::string bag, truth_tum, cloud_topic;
  ros::param::param<std::string>("~bag", bag, "");
  ros::param::param<std::string>("~truth_tum", truth_tum, "");
  ros::param::param<std::string>("~cloud_topic", cloud_topic, "/camera/depth_registered/points");
  lockstep::BagPlayer player(nh, bag, cloud_topic, &clock);
  ASSERT_TRUE(player.waitForSubscribers()) << "the nodelet does not subscribe " << cloud_topic;
  ASSERT_TRUE(
      lockstep::waitFor([&] { return ros::service::exists("/gmm_mcl/reset_to_pose", false); }));
  ASSERT_TRUE(obs.waitConnected());
  ASSERT_TRUE(lockstep::waitFor([&] { return rec.subs_[1].getNumPublishers() > 0; }))
      << "the nodelet's ~pose does not connect";
  const ros::Time t0 = player.frameStamp(0);
  bool tracked = false;
  for (int i = 0; i < player.frames(); ++i) {
    player.publishFrame(i);
    const ros::Time t = player.frameStamp(i);
    ASSERT_NE(obs.statusAt(t), nullptr) << "no ~status for cloud " << i << "; " << obs.describe();
    ASSERT_TRUE(
        lockstep::waitFor([&] { return !rec.poses_.empty() && rec.poses_.back().stamp == t; }));
    if (!tracked && (t - t0).toSec() >= 3.0) {
      tracked = true;
      const double err_track = errorOf(rec, rec.poses_.back());
      std::printf("[ measured ] error 3 s into the bag: %.3f m\n", err_track);
      EXPECT_LT(err_track, kTrackErrorM);
    }
  }
  ASSERT_TRUE(tracked);
  const double err_final = errorOf(rec, rec.poses_.back());
  std::printf("[ measured ] final error %.3f m at %.2f s (%zu poses, %zu truths, %zu odometry)\n",
              err_final, rec.rel(rec.poses_.back().stamp), rec.poses_.size(), rec.truth_.size(),
              rec.odom_.size());
  EXPECT_LT(err_final, kFinalErrorM);

  // Odometry: one per ground-truth pose, drifting away from the true motion, but not far.
  ASSERT_FALSE(rec.odom_.empty());
  ASSERT_GE(rec.odom_.size(), rec.truth_.size() * 9 / 10);
  const Stamped& o0 = rec.odom_.front();
  const Stamped& o1 = rec.odom_.back();
  const auto g0 = rec.truth_.find(o0.stamp.toNSec()), g1 = rec.truth_.find(o1.stamp.toNSec());
  ASSERT_TRUE(g0 != rec.truth_.end() && g1 != rec.truth_.end());
  const Eigen::Isometry3d d_odom = o0.T.inverse() * o1.T;
  const Eigen::Isometry3d d_true = g0->second.inverse() * g1->second;
  const double drift = (d_odom.translation() - d_true.translation()).norm();
  std::printf("[ measured ] odometry drift over %.1f s: %.3f m (true motion %.2f m)\n",
              (o1.stamp - o0.stamp).toSec(), drift, d_true.translation().norm());
  EXPECT_LT(drift, kMaxOdomDriftM);
  EXPECT_GT(drift, kMinOdomDriftM);

  // IMU attitude = truth + 0.5 deg noise.
  int checked = 0;
  for (const auto& a : rec.imu_) {
    const auto g = rec.truth_.find(a.first);
    if (g == rec.truth_.end()) continue;
    double r, p, y;
    rpyFromRotation(g->second.linear(), &r, &p, &y);
    EXPECT_LT(std::abs(a.second.x() - r), kAttitudeErrorRad);
    EXPECT_LT(std::abs(a.second.y() - p), kAttitudeErrorRad);
    ++checked;
  }
  EXPECT_GT(checked, 10);

  // The TUM file: one line per ground-truth pose, the same positions.
  if (!truth_tum.empty()) {
    std::ifstream in(truth_tum);
    ASSERT_TRUE(in.good()) << truth_tum;
    int lines = 0, matched = 0;
    double t, x, y, z, qx, qy, qz, qw;
    while (in >> t >> x >> y >> z >> qx >> qy >> qz >> qw) {
      ++lines;
      const auto g = rec.truth_.lower_bound(static_cast<uint64_t>(std::llround((t - 5e-7) * 1e9)));
      if (g != rec.truth_.end() &&
          (g->second.translation() - Eigen::Vector3d(x, y, z)).norm() < 1e-5) {
        ++matched;
      }
    }
    std::printf("[ measured ] %s: %d poses, %d match /ground_truth\n", truth_tum.c_str(), lines,
                matched);
    EXPECT_GE(lines, static_cast<int>(rec.truth_.size()));
    EXPECT_GE(matched, static_cast<int>(rec.truth_.size()) * 9 / 10);
  }
}

}  // namespace gmm_mcl

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "rostest_ground_truth_odometry");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
