// rostest node that feeds the nodelet itself (wall time): good frames, then each bad input in
// turn (wrong encoding, NaN-only depth, image size not matching CameraInfo, no CameraInfo,
// missing tf, missing IMU, odometry gap); the node must stay up, say what is wrong (status and
// /diagnostics) and recover when good data returns. mode "config": a bad configuration is
// reported on /diagnostics and nothing is subscribed.
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <XmlRpcValue.h>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/sim/box_scene.h"

using namespace gmm_mcl;

namespace {

bool spinUntil(const std::function<bool()>& done, double wall_timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(wall_timeout_s);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (done()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return false;
}

struct Diag {
  int level;
  std::string message;
};

class Harness {
 public:
  Harness() {
    image_pub_ = nh_.advertise<sensor_msgs::Image>("/camera/depth/image_raw", 5);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("/camera/depth/camera_info", 5);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>("/imu/data", 5);
    status_sub_ = nh_.subscribe("/gmm_mcl/status", 100, &Harness::status, this);
    diag_sub_ = nh_.subscribe("/diagnostics", 100, &Harness::diag, this);
    scene_ = sim::makeDefaultScene();
    truth_ = sim::makeTrajectory(400);
    K_.width_px = 160;
    K_.height_px = 120;
    K_.fx_px = K_.fy_px = 585.f / 4;
    K_.cx_px = 0.5f * (K_.width_px - 1);
    K_.cy_px = 0.5f * (K_.height_px - 1);
    geometry_msgs::TransformStamped st;
    st.header.stamp = ros::Time::now();
    st.header.frame_id = "base_link";
    st.child_frame_id = "camera_depth_optical_frame";
    st.transform = ros_conv::transformFromIsometry(sim::defaultBaseToCamera());
    static_tf_.sendTransform(st);
  }
  void status(const FilterStatusConstPtr& m) { statuses_.push_back(*m); }
  void diag(const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
    for (const auto& s : m->status) {
      if (s.name.find("localization") != std::string::npos) diags_.push_back(Diag{s.level, s.message});
    }
  }

  enum Fault { kNone, kEncoding, kNanDepth, kSizeMismatch, kNoInfo, kNoTf, kNoImu, kNoOdom };
  // Sends frame f with the fault; 15 Hz.
  void send(Fault fault) {
    const int f = frame_++;
    const ros::Time stamp = ros::Time::now();
    const Eigen::Isometry3d T = truth_[f % truth_.size()];
    if (fault != kNoOdom) {
      geometry_msgs::TransformStamped odom;
      odom.header.stamp = stamp;
      odom.header.frame_id = "odom";
      odom.child_frame_id = "base_link";
      odom.transform = ros_conv::transformFromIsometry(T);  // perfect odometry from the map origin
      tf_.sendTransform(odom);
    }
    if (fault != kNoImu) {
      sensor_msgs::Imu imu;
      imu.header.stamp = stamp;
      imu.orientation = ros_conv::poseFromIsometry(T).orientation;
      imu_pub_.publish(imu);
    }
    ros::WallDuration(0.01).sleep();  // tf before the frame
    const DepthImage depth = sim::renderDepth(scene_, K_, T * sim::defaultBaseToCamera(),
                                              DepthEncoding::kMono16Millimetres, 8.0);
    sensor_msgs::Image img;
    img.header.stamp = stamp;
    img.header.frame_id = fault == kNoTf ? "unknown_camera_frame" : "camera_depth_optical_frame";
    img.width = depth.width_px;
    img.height = depth.height_px;
    img.encoding = "16UC1";
    img.step = static_cast<uint32_t>(depth.row_bytes);
    img.data = depth.data;
    if (fault == kEncoding) {
      img.encoding = "rgb8";
      img.step = 3 * img.width;
      img.data.assign(img.step * img.height, 128);
    } else if (fault == kNanDepth) {
      img.encoding = "32FC1";
      img.step = 4 * img.width;
      std::vector<float> nan(img.width * img.height, std::numeric_limits<float>::quiet_NaN());
      img.data.resize(img.step * img.height);
      std::memcpy(img.data.data(), nan.data(), img.data.size());
    }
    sensor_msgs::CameraInfo info;
    info.header = img.header;
    const int scale = fault == kSizeMismatch ? 2 : 1;
    info.width = K_.width_px * scale;
    info.height = K_.height_px * scale;
    info.K = {K_.fx_px * scale, 0, K_.cx_px * scale, 0, K_.fy_px * scale, K_.cy_px * scale, 0, 0, 1};
    image_pub_.publish(img);
    if (fault != kNoInfo) info_pub_.publish(info);
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(1.0 / 15);
    while (ros::WallTime::now() < until) {
      ros::spinOnce();
      ros::WallDuration(0.005).sleep();
    }
  }
  // Sends n frames with the fault; true once a diagnostics message since the start contains
  // `expected` (empty: no check).
  bool sendUntilDiag(Fault fault, int n, const std::string& expected, int min_level) {
    const size_t d0 = diags_.size();
    bool seen = expected.empty();
    for (int i = 0; i < n; ++i) {
      send(fault);
      for (size_t k = d0; k < diags_.size() && !seen; ++k) {
        seen = diags_[k].level >= min_level && diags_[k].message.find(expected) != std::string::npos;
      }
    }
    return seen;
  }
  int statusesSince(size_t s0, const std::string& step_status) const {
    int n = 0;
    for (size_t i = s0; i < statuses_.size(); ++i) n += statuses_[i].step_status == step_status;
    return n;
  }

  ros::NodeHandle nh_;
  ros::Publisher image_pub_, info_pub_, imu_pub_;
  ros::Subscriber status_sub_, diag_sub_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  sim::BoxScene scene_;
  std::vector<Eigen::Isometry3d> truth_;
  Intrinsics K_;
  int frame_ = 0;
  std::vector<FilterStatus> statuses_;
  std::vector<Diag> diags_;
};

void lastDiag(const Harness& h) {
  if (!h.diags_.empty()) {
    std::printf("[ diag ] level %d: %s\n", h.diags_.back().level, h.diags_.back().message.c_str());
  }
}

}  // namespace

TEST(BadInputs, NodeSaysWhatIsWrongAndRecovers) {
  Harness h;
  ASSERT_TRUE(spinUntil([&] { return h.image_pub_.getNumSubscribers() > 0 && h.info_pub_.getNumSubscribers() > 0; }, 20.0));
  const int warn = diagnostic_msgs::DiagnosticStatus::WARN;

  size_t s0 = h.statuses_.size();
  h.sendUntilDiag(Harness::kNone, 15, "", 0);
  EXPECT_GE(h.statusesSince(s0, "ok"), 5) << "good frames are not used";

  s0 = h.statuses_.size();
  EXPECT_TRUE(h.sendUntilDiag(Harness::kEncoding, 25, "unsupported depth encoding 'rgb8'", warn));
  lastDiag(h);
  EXPECT_EQ(h.statuses_.size(), s0) << "a frame with a wrong encoding was used";

  s0 = h.statuses_.size();
  h.sendUntilDiag(Harness::kNanDepth, 10, "", 0);
  EXPECT_GE(h.statusesSince(s0, "no_valid_pixels"), 3) << "NaN-only frames not reported";
  EXPECT_EQ(h.statusesSince(s0, "ok"), 0);

  s0 = h.statuses_.size();
  EXPECT_TRUE(h.sendUntilDiag(Harness::kSizeMismatch, 25, "but CameraInfo says 320x240", warn));
  lastDiag(h);
  EXPECT_EQ(h.statuses_.size(), s0) << "a frame not matching its CameraInfo was used";

  EXPECT_TRUE(h.sendUntilDiag(Harness::kNoInfo, 90, "no depth frame for", warn));
  lastDiag(h);

  s0 = h.statuses_.size();
  EXPECT_TRUE(h.sendUntilDiag(Harness::kNoTf, 25, "no transform base_link -> unknown_camera_frame", warn));
  lastDiag(h);
  EXPECT_EQ(h.statuses_.size(), s0) << "a frame without extrinsics was used";

  s0 = h.statuses_.size();
  h.sendUntilDiag(Harness::kNoImu, 20, "", 0);
  ASSERT_GT(h.statuses_.size(), s0);
  EXPECT_NE(h.statuses_.back().message.find("IMU attitude is stale"), std::string::npos)
      << h.statuses_.back().message;

  s0 = h.statuses_.size();
  h.sendUntilDiag(Harness::kNoOdom, 10, "", 0);
  ASSERT_GT(h.statuses_.size(), s0);
  EXPECT_NE(h.statuses_.back().message.find("no odometry tf"), std::string::npos)
      << h.statuses_.back().message;

  // Good data again: frames are used, and the diagnostics return to OK.
  s0 = h.statuses_.size();
  EXPECT_TRUE(h.sendUntilDiag(Harness::kNone, 150, "localizing", diagnostic_msgs::DiagnosticStatus::OK));
  lastDiag(h);
  EXPECT_GE(h.statusesSince(s0, "ok"), 20);
}

TEST(BadConfig, ReportedAndNothingSubscribed) {
  ros::NodeHandle nh;
  std::vector<Diag> diags;
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
        for (const auto& s : m->status) diags.push_back(Diag{s.level, s.message});
      });
  ASSERT_TRUE(spinUntil([&] { return diags.size() >= 2; }, 30.0)) << "no diagnostics from the node";
  const Diag d = diags.back();
  std::printf("[ diag ] level %d: %s\n", d.level, d.message.c_str());
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::ERROR);
  EXPECT_NE(d.message.find("bad configuration"), std::string::npos);
  EXPECT_NE(d.message.find("num_particles"), std::string::npos);
  EXPECT_NE(d.message.find("weighting 'bogus'"), std::string::npos);
  // Still up: diagnostics keep coming.
  const size_t n = diags.size();
  EXPECT_TRUE(spinUntil([&] { return diags.size() > n; }, 10.0));
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

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "rostest_bad_inputs");
  ros::NodeHandle nh;
  std::string mode;
  ros::param::param<std::string>("~mode", mode, "inputs");
  testing::GTEST_FLAG(filter) = mode == "config" ? "BadConfig.*" : "BadInputs.*";
  return RUN_ALL_TESTS();
}
