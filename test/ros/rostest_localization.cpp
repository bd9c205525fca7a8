// rostest node: the nodelet (in a manager) localizes on the synthetic bag, played in lockstep
// (test/ros/lockstep.h): every message in bag order with /clock at its bag time, and after each
// depth frame the test waits for the nodelet's ~status of that frame. No wall-time window.
// mode "track": error after 3.5 s, ~global_localization spreads the particles, a /initialpose
//   stamped 1.5 s before the latest frame is carried forward, final error, map -> odom stamped
//   frame + transform_tolerance and increasing, covariance consistency.
// mode "looped": the first 5 s twice (time jumps back): reported, tf restarts once, the filter
//   re-converges.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <rosgraph_msgs/Log.h>
#include <std_srvs/Empty.h>

#include <cmath>
#include <map>
#include <set>
#include <vector>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "lockstep.h"

namespace gmm_mcl {
namespace lockstep {

namespace {

constexpr double kFinalErrorM = 0.10;        // final translation error
constexpr double kTrackErrorM = 0.15;        // error before global localization
constexpr double kCarriedErrorM = 0.20;      // first estimate after the stale /initialpose
constexpr double kConsistentFraction = 0.8;  // frames with an error component within 3 sigma
constexpr double kTransformTolerance = 0.1;  // the launch's transform_tolerance

// Ground truth of the bag, by stamp.
class Truth {
 public:
  explicit Truth(ros::NodeHandle& nh)
      : sub_(nh.subscribe("/ground_truth", 1000, &Truth::onTruth, this)) {}
  void onTruth(const geometry_msgs::PoseStampedConstPtr& m) {
    truth_[m->header.stamp.toNSec()] = ros_conv::isometryFromPose(m->pose);
  }
  // The truth at t (waits for it: it is published with the frame).
  bool at(const ros::Time& t, Eigen::Isometry3d* T) {
    return waitFor([&] {
      const auto it = truth_.find(t.toNSec());
      if (it != truth_.end()) *T = it->second;
      return it != truth_.end();
    });
  }
  // x, y, z, yaw error of a pose.
  Eigen::Vector4d error(const geometry_msgs::PoseWithCovarianceStamped& p) {
    Eigen::Isometry3d T;
    if (!at(p.header.stamp, &T)) return Eigen::Vector4d::Constant(1e9);
    const Eigen::Isometry3d E = ros_conv::isometryFromPose(p.pose.pose);
    Eigen::Vector4d e;
    e << E.translation() - T.translation(),
        wrapAngle(yawFromRotation(E.linear()) - yawFromRotation(T.linear()));
    return e;
  }
  double translationError(const geometry_msgs::PoseWithCovarianceStamped& p) {
    return error(p).head<3>().norm();
  }

 private:
  ros::Subscriber sub_;
  std::map<uint64_t, Eigen::Isometry3d> truth_;
};

std::string bagPath() {
  std::string bag;
  ros::param::param<std::string>("~bag", bag, "");
  return bag;
}

}  // namespace

TEST(LocalizationBagTest, TracksResetsAndPublishesTf) {
  ros::NodeHandle nh;
  Observer obs(nh);
  Truth truth(nh);
  Clock clock(nh);
  BagPlayer player(nh, bagPath(), "/camera/depth/image_raw", &clock);
  ASSERT_TRUE(player.waitForSubscribers()) << "the nodelet does not subscribe the depth image";
  ASSERT_TRUE(obs.waitConnected()) << "the nodelet's outputs do not connect";
  ros::Publisher init_pub =
      nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("/initialpose", 1, true);
  // The nodelet's log: a /initialpose is applied in its own callback, logged as "reset to".
  int resets_logged = 0;
  ros::Subscriber rosout =
      nh.subscribe<rosgraph_msgs::Log>("/rosout", 1000, [&](const rosgraph_msgs::LogConstPtr& m) {
        resets_logged += m->msg.find("reset to") != std::string::npos ? 1 : 0;
      });
  ASSERT_TRUE(waitFor([&] { return connectedToAll(rosout); })) << "/rosout does not connect";
  const ros::Time t0 = player.frameStamp(0);
  auto rel = [&](const ros::Time& t) { return (t - t0).toSec(); };

  enum Phase { kTracking, kGlobal, kInitialPose, kToTheEnd } phase = kTracking;
  ros::Time t_global, t_stale,
      t_carried;  // frames: after the global reset, the stale pose's, after it
  int resets = 0;
  std::vector<geometry_msgs::PoseWithCovarianceStamped> poses;
  for (int i = 0; i < player.frames(); ++i) {
    player.publishFrame(i);
    const ros::Time t = player.frameStamp(i);
    const FilterStatus* s = obs.statusAt(t);
    ASSERT_NE(s, nullptr) << "no ~status for frame " << i << " at " << rel(t) << " s; "
                          << obs.describe();
    EXPECT_NE(s->step_status, "bad_frame") << s->message;
    const geometry_msgs::PoseWithCovarianceStamped* p = obs.poseAt(t);
    ASSERT_NE(p, nullptr);
    poses.push_back(*p);
    if (phase == kTracking && rel(t) >= 3.5) {
      // 1. Tracking from the initial region, then global localization: uniform over the map.
      const double err = truth.translationError(*p);
      std::printf("[ measured ] error after %.2f s of tracking: %.3f m\n", rel(t), err);
      EXPECT_LT(err, kTrackErrorM);
      std_srvs::Empty srv;
      ASSERT_TRUE(ros::service::call("/gmm_mcl/global_localization", srv));
      resets = s->resets;
      phase = kGlobal;
    } else if (phase == kGlobal) {
      // The first frame after the reset: spread over the map.
      EXPECT_EQ(s->resets, resets + 1);
      t_global = t;
      std::printf("[ measured ] sigma x, y after global localization: %.2f, %.2f m\n",
                  std::sqrt(p->pose.covariance[0]), std::sqrt(p->pose.covariance[7]));
      EXPECT_GT(std::sqrt(p->pose.covariance[0]), 1.0) << "particles not spread over the map";
      EXPECT_GT(std::sqrt(p->pose.covariance[7]), 1.0);
      phase = kInitialPose;
    } else if (phase == kInitialPose && (t - t_global).toSec() >= 0.5) {
      // 2. A /initialpose stamped 1.5 s (45 frames) before this frame, the true pose then:
      // carried forward by odometry to the latest frame.
      Eigen::Isometry3d T_then, T_now;
      ASSERT_TRUE(truth.at(player.frameStamp(i - 45), &T_then));
      t_stale = player.frameStamp(i - 45);
      ASSERT_TRUE(truth.at(t, &T_now));
      const double moved_m = (T_now.translation() - T_then.translation()).norm();
      std::printf("[ measured ] the robot moved %.2f m since the stale initial pose's stamp\n",
                  moved_m);
      ASSERT_GT(moved_m, 2.0 * kCarriedErrorM) << "the stale-stamp check would not discriminate";
      geometry_msgs::PoseWithCovarianceStamped init;
      init.header.frame_id = "map";
      init.header.stamp = t_stale;
      init.pose.pose = ros_conv::poseFromIsometry(T_then);
      init.pose.covariance[0] = init.pose.covariance[7] = init.pose.covariance[14] = 0.05 * 0.05;
      init.pose.covariance[35] = 0.05 * 0.05;
      ASSERT_TRUE(waitFor([&] { return init_pub.getNumSubscribers() > 0; }));
      const int logged_before = resets_logged;
      init_pub.publish(init);
      // Applied before the next frame goes out: carried forward to this frame's stamp, not to a
      // later frame's that a loaded machine might process first.
      ASSERT_TRUE(waitFor([&] { return resets_logged > logged_before; }))
          << "the /initialpose was not applied (no \"reset to\" in the nodelet's log)";
      resets = s->resets;
      phase = kToTheEnd;
    } else if (phase == kToTheEnd && t_carried.isZero() && s->resets > resets) {
      // The first estimate after the reset was applied.
      t_carried = t;
      const double err = truth.translationError(*p);
      std::printf("[ measured ] error right after the stale initial pose: %.3f m\n", err);
      EXPECT_LT(err, kCarriedErrorM);
    }
  }
  ASSERT_FALSE(t_carried.isZero()) << "the initial pose was never applied";
  const double err_final = truth.translationError(poses.back());
  std::printf("[ measured ] final error %.3f m at %.2f s (%zu poses)\n", err_final,
              rel(poses.back().header.stamp), poses.size());
  EXPECT_LT(err_final, kFinalErrorM);

  // map -> odom: future-dated by transform_tolerance from a frame stamp, strictly increasing.
  ASSERT_TRUE(waitFor([&] { return obs.tf_stamps.size() >= poses.size() - 2; }));
  std::set<uint64_t> stamps;
  for (const auto& p : poses) stamps.insert(p.header.stamp.toNSec());
  int dated = 0;
  for (size_t i = 0; i < obs.tf_stamps.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(obs.tf_stamps[i], obs.tf_stamps[i - 1]) << "tf " << i << " not monotonic";
    }
    const uint64_t frame = (obs.tf_stamps[i] - ros::Duration(kTransformTolerance)).toNSec();
    bool match = false;
    for (uint64_t s : {frame - 1, frame, frame + 1}) match = match || stamps.count(s);
    dated += match;
  }
  EXPECT_EQ(dated, static_cast<int>(obs.tf_stamps.size()))
      << "map -> odom stamps are not the frame stamps + transform_tolerance";

  // Covariance consistency: each component within 3 sigma for most converged frames.
  int n = 0, within[4] = {0, 0, 0, 0};
  const int diag[4] = {0, 7, 14, 35};
  for (const auto& p : poses) {
    const double t = rel(p.header.stamp);
    const bool converged =
        (t >= 1.5 && p.header.stamp < t_global) || (p.header.stamp - t_carried).toSec() >= 1.0;
    if (!converged) continue;
    const Eigen::Vector4d e = truth.error(p);
    ++n;
    for (int k = 0; k < 4; ++k)
      within[k] += std::abs(e[k]) <= 3.0 * std::sqrt(p.pose.covariance[diag[k]]);
  }
  ASSERT_GE(n, 10);
  for (int k = 0; k < 4; ++k) {
    std::printf("[ measured ] component %d within 3 sigma in %d of %d frames\n", k, within[k], n);
    EXPECT_GE(within[k], kConsistentFraction * n) << "component " << k;
  }
}

TEST(LocalizationBagTest, LoopedBagResets) {
  ros::NodeHandle nh;
  Observer obs(nh);
  Truth truth(nh);
  Clock clock(nh);
  BagPlayer player(nh, bagPath(), "/camera/depth/image_raw", &clock);
  ASSERT_TRUE(player.waitForSubscribers());
  ASSERT_TRUE(obs.waitConnected());
  double loop_s = 5.0;
  ros::param::param("~loop_duration", loop_s, 5.0);
  const ros::Time t0 = player.frameStamp(0);
  int frames = 0;
  while (frames < player.frames() && (player.frameStamp(frames) - t0).toSec() < loop_s) ++frames;
  geometry_msgs::PoseWithCovarianceStamped last;
  for (int loop = 0; loop < 2; ++loop) {
    if (loop == 1) player.rewind();
    for (int i = 0; i < frames; ++i) {
      const size_t since = obs.statuses.size(), since_pose = obs.poses.size();
      player.publishFrame(i);
      const ros::Time t = player.frameStamp(i);
      const FilterStatus* s = obs.statusAt(t, kWaitLimitS, since);
      ASSERT_NE(s, nullptr) << "no ~status for frame " << i << " of loop " << loop << "; "
                            << obs.describe();
      if (loop == 1 && i == 0) {
        EXPECT_EQ(s->step_status, "time_jump_back") << s->message;
        EXPECT_EQ(s->time_jumps, 1);
        std::printf("[ measured ] error before the loop: %.3f m\n", truth.translationError(last));
      }
      last = *obs.poseAt(t, since_pose);
      if (loop == 1 && i % 20 == 0) {
        std::printf("  second loop: pose at %.3f s: error %.3f m, sigma x %.3f m\n",
                    (t - t0).toSec(), truth.translationError(last),
                    std::sqrt(last.pose.covariance[0]));
      }
    }
  }
  const double err_after = truth.translationError(last);
  std::printf("[ measured ] error at %.2f s of the second loop: %.3f m\n",
              (last.header.stamp - t0).toSec(), err_after);
  EXPECT_LT(err_after, kTrackErrorM);
  // tf: one step back at the loop, strictly increasing on either side.
  EXPECT_TRUE(waitFor([&] { return obs.tf_stamps.size() >= 2u * frames; }))
      << obs.tf_stamps.size() << " map -> odom transforms for " << 2 * frames << " frames";
  int backs = 0;
  for (size_t i = 1; i < obs.tf_stamps.size(); ++i)
    backs += obs.tf_stamps[i] <= obs.tf_stamps[i - 1];
  EXPECT_EQ(backs, 1) << "map -> odom should restart once at the loop and increase otherwise";
}

}  // namespace lockstep
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  return gmm_mcl::lockstep::runTestNode(
      argc, argv, "rostest_localization", "track", [](const std::string& mode) {
        return std::string(mode == "looped" ? "LocalizationBagTest.Looped*"
                                            : "LocalizationBagTest.Tracks*");
      });
}
