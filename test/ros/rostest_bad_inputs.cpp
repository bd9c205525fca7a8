// rostest node that feeds the nodelet itself, in lockstep with the clock it owns
// (test/ros/lockstep.h): good frames, then each bad input in turn (wrong encoding, NaN-only
// depth, image size not matching CameraInfo, no CameraInfo, an unknown camera frame, missing
// IMU, an odometry gap); the node must stay up, say what is wrong (status and /diagnostics) and
// recover when good data returns. mode "config": a bad configuration is reported on
// /diagnostics and nothing is subscribed (wall time: nothing runs to wait for).
#include <XmlRpcValue.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/sim/box_scene.h"
#include "synthetic_robot.h"

namespace gmm_mcl {
namespace lockstep {

namespace {

struct ConfigDiag {
  int level;
  std::string message;
};

}  // namespace

// Bad inputs one after another, each awaited (its ~status, or the drop counted on
// /diagnostics, whose period the test's clock steps over): the node stays up, says what is
// wrong, and uses good data again afterwards.
TEST(BadInputsTest, NodeSaysWhatIsWrongAndRecovers) {
  ros::NodeHandle nh;
  Clock clock(nh);
  Observer obs(nh);
  SyntheticRobot robot(nh, &clock);
  ASSERT_TRUE(robot.waitForNodelet());
  ASSERT_TRUE(obs.waitConnected());
  robot.publishStaticExtrinsics();
  double step = 0;
  int k = 0;
  // The next frame's stamp, never behind the clock: the diagnostics ticks move the clock on by as
  // many periods as the nodelet took to say a thing (more on a loaded machine), and a frame
  // stamped in the past would leave the times the checks below depend on (the CameraInfo's age
  // against the last frame's) to that count.
  auto nextStamp = [&] {
    while (robot.stamp(step) < clock.now()) ++step;
    return robot.stamp(step);
  };
  auto send = [&](const SyntheticRobot::Frame& f) {
    const ros::Time t = nextStamp();
    ++step;
    robot.send(t, robot.truth(k++), f);
    return t;
  };
  // Ticks the clock over the diagnostics period until the nodelet's diagnostics satisfy `ok`.
  auto diagUntil = [&](const std::function<bool(const lockstep::Diag&)>& ok) {
    lockstep::Diag d;
    for (int i = 0; i < 10; ++i) {
      if (!obs.tickDiagnostics(&clock, 0.25, &d)) break;
      if (ok(d)) return true;
    }
    std::printf("[ diag ] level %d: %s\n", d.level, d.message.c_str());
    return false;
  };
  auto says = [&](const std::string& text) {
    return diagUntil([&](const lockstep::Diag& d) {
      return d.level >= diagnostic_msgs::DiagnosticStatus::WARN &&
             d.message.find(text) != std::string::npos;
    });
  };
  const SyntheticRobot::Frame good;

  for (int i = 0; i < 5; ++i) {
    const FilterStatus* s = obs.statusAt(send(good));
    ASSERT_NE(s, nullptr) << "good frame " << i << " not used";
    EXPECT_EQ(s->step_status, "ok") << s->message;
  }
  SyntheticRobot::Frame f = good;
  f.encoding = "rgb8";
  send(f);
  EXPECT_TRUE(says("unsupported depth encoding 'rgb8'"));
  EXPECT_EQ(obs.lastDiag()->number("dropped: conversion"), 1);

  f = good;
  f.nan_depth = true;
  const FilterStatus* s = obs.statusAt(send(f));
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->step_status, "no_valid_pixels");

  f = good;
  f.info_scale = 2;
  send(f);
  EXPECT_TRUE(says("but CameraInfo says 320x240"));

  f = good;
  f.camera_info = false;
  for (int i = 0; i < 4; ++i) {
    send(f);
    step += 20;  // 2.7 s of images without CameraInfo
  }
  EXPECT_TRUE(says("but no CameraInfo on /camera/depth/camera_info"));

  // A camera frame that tf does not know: the frame waits for tf, then the next frame takes its
  // place and it is dropped, saying why.
  f = good;
  f.camera_frame = "unknown_camera_frame";
  const long long received = obs.statuses.back().frames_received;
  send(f);
  // It arrived (and waits for tf) before the next frame is sent, which takes its place.
  ASSERT_TRUE(
      diagUntil([&](const lockstep::Diag& d) { return d.number("frames received") > received; }));
  ASSERT_NE(obs.statusAt(send(good)), nullptr);
  EXPECT_TRUE(says("'unknown_camera_frame'"));
  EXPECT_GE(obs.lastDiag()->number("dropped: no extrinsics"), 1);

  f = good;
  f.imu = false;
  step += 30;  // the last IMU message is a second older than this frame
  s = obs.statusAt(send(f));
  ASSERT_NE(s, nullptr);
  EXPECT_NE(s->message.find("IMU attitude"), std::string::npos) << s->message;

  // No odometry tf at a frame's stamp: it waits; the next stamp's odometry brackets it and it is
  // used (odometry interpolated at the stamp, as amcl does), then the next frame. One frame in
  // flight at a time: had the next image come before its odometry, it would have taken the
  // waiting frame's place (queue_size 1), which is what happens on a loaded machine.
  f = good;
  f.odom_tf = false;
  const long long received_before_gap = obs.statuses.back().frames_received;
  const ros::Time t_gap = send(f);
  ASSERT_TRUE(diagUntil(
      [&](const lockstep::Diag& d) { return d.number("frames received") > received_before_gap; }));
  const ros::Time t_next = nextStamp();
  robot.publishOdometry(t_next, robot.truth(k));
  s = obs.statusAt(t_gap);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->message.find("odometry"), std::string::npos) << s->message;
  SyntheticRobot::Frame next = good;
  next.odom_tf = false;  // its odometry is out already
  ASSERT_EQ(send(next), t_next);
  ASSERT_NE(obs.statusAt(t_next), nullptr);

  // Good data again: used, and once the problems are 5 s old the diagnostics return to OK.
  lockstep::Diag d;
  d.level = -1;
  for (int i = 0; i < 40 && d.level != diagnostic_msgs::DiagnosticStatus::OK; ++i) {
    ASSERT_NE(obs.statusAt(send(good)), nullptr);
    ASSERT_TRUE(obs.tickDiagnostics(&clock, 0.25, &d));
  }
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::OK) << d.message;
  EXPECT_EQ(d.message, "localizing");
  // Every frame accounted for: received = used + dropped + waiting.
  const FilterStatus& last = obs.statuses.back();
  EXPECT_EQ(last.frames_received, last.frames_processed + last.frames_gated +
                                      last.dropped_conversion + last.dropped_camera_info +
                                      last.dropped_extrinsics + last.frames_waiting);
}

TEST(BadConfigTest, ReportedAndNothingSubscribed) {
  ros::NodeHandle nh;
  std::vector<ConfigDiag> diags;
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
        for (const auto& s : m->status) diags.push_back(ConfigDiag{s.level, s.message});
      });
  ASSERT_TRUE(waitFor([&] { return diags.size() >= 2; }, 30.0)) << "no diagnostics from the node";
  const ConfigDiag d = diags.back();
  std::printf("[ diag ] level %d: %s\n", d.level, d.message.c_str());
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::ERROR);
  EXPECT_NE(d.message.find("bad configuration"), std::string::npos);
  // What the message must name: ~expect, '|'-separated (bad_cloud_map.test), else the faults
  // of bad_config.test.
  std::string expect = "num_particles|weighting 'bogus'";
  ros::param::get("~expect", expect);
  std::istringstream parts(expect);
  for (std::string part; std::getline(parts, part, '|');) {
    EXPECT_NE(d.message.find(part), std::string::npos) << "no '" << part << "' in the message";
  }
  // Still up: diagnostics keep coming.
  const size_t n = diags.size();
  EXPECT_TRUE(waitFor([&] { return diags.size() > n; }, 10.0));
  // No subscriptions: nobody listens to the depth topic.
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  ASSERT_TRUE(ros::master::execute("getSystemState", args, result, payload, true));
  const XmlRpc::XmlRpcValue& subs = payload[1];
  for (int i = 0; i < subs.size(); ++i) {
    const std::string topic = subs[i][0];
    EXPECT_TRUE(topic.find("/camera") != 0 && topic != "/imu/data") << topic << " is subscribed";
  }
}

}  // namespace lockstep
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  return gmm_mcl::lockstep::runTestNode(
      argc, argv, "rostest_bad_inputs", "inputs", [](const std::string& mode) {
        return std::string(mode == "config" ? "BadConfigTest.*" : "BadInputsTest.*");
      });
}
