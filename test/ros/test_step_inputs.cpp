// A frame's IMU and odometry messages, sent with it but on other connections, may be handled
// after the frame: StepInputs waits for them (at most input_wait) instead of taking the previous
// sample.
// Each case hands the late message over from another thread once the frame has begun waiting
// (StepInputs::waitsBegun), so that nothing depends on wall time. No ROS master.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <tf2_ros/buffer.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <thread>

#include "gmm_mcl/ros/step_inputs.h"

namespace gmm_mcl {
namespace {

constexpr double kWaitLimitS = 60.0;  // never reached when the fix works: a bound, not a window

sensor_msgs::Imu imuAt(double t_s, double roll_rad) {
  sensor_msgs::Imu m;
  m.header.stamp = ros::Time(t_s);
  m.orientation.x = std::sin(0.5 * roll_rad);
  m.orientation.w = std::cos(0.5 * roll_rad);
  return m;
}

geometry_msgs::TransformStamped transformAt(double t_s, const std::string& parent,
                                            const std::string& child) {
  geometry_msgs::TransformStamped ts;
  ts.header.stamp = ros::Time(t_s);
  ts.header.frame_id = parent;
  ts.child_frame_id = child;
  ts.transform.rotation.w = 1.0;
  return ts;
}

nav_msgs::Odometry odometryAt(double t_s, double x_m) {
  nav_msgs::Odometry m;
  m.header.stamp = ros::Time(t_s);
  m.pose.pose.position.x = x_m;
  m.pose.pose.orientation.w = 1.0;
  return m;
}

std_msgs::Header frameHeader(double t_s) {
  std_msgs::Header h;
  h.stamp = ros::Time(t_s);
  h.frame_id = "camera";
  return h;
}

class StepInputsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::Time::init();
    tf_.setTransform(transformAt(0.0, "base_link", "camera"), "test", true);
    opts_.use_imu = true;
    opts_.odometry_source = "none";
    opts_.input_wait_s = kWaitLimitS;
  }
  // gather() for a frame at t_s while `late` runs on another thread once the frame waits.
  StepInput gatherWithLate(double t_s, const std::function<void()>& late) {
    inputs_.setOptions(opts_);
    std::atomic<bool> done{false};
    std::thread sender([&] {
      while (!done && inputs_.waitsBegun() == 0) std::this_thread::yield();
      if (!done) late();
    });
    StepInput in;
    StepInputs::Gaps gaps;
    std::string why;
    EXPECT_TRUE(inputs_.gather(frameHeader(t_s), &in, &gaps, &why)) << why;
    done = true;
    sender.join();
    return in;
  }

  tf2_ros::Buffer tf_;
  RosOptions opts_;
  StepInputs inputs_{&tf_};
};

TEST_F(StepInputsTest, AFrameWaitsForTheImuSampleAtItsStamp) {
  inputs_.setOptions(opts_);
  ASSERT_TRUE(inputs_.addImu(imuAt(1.0, 0.1)));
  const StepInput in = gatherWithLate(1.2, [&] { inputs_.addImu(imuAt(1.2, 0.3)); });
  EXPECT_EQ(inputs_.waitsBegun(), 1);
  EXPECT_EQ(inputs_.waitsInVain(), 0);
  ASSERT_TRUE(in.has_attitude);
  EXPECT_NEAR(in.roll_rad, 0.3, 1e-9) << "the frame took the sample before its own";
}

TEST_F(StepInputsTest, AFrameWaitsForTheOdometryMessageAtItsStamp) {
  opts_.use_imu = false;
  opts_.odometry_source = "topic";
  inputs_.setOptions(opts_);
  inputs_.addOdometry(odometryAt(1.0, 1.0));
  const StepInput in = gatherWithLate(1.2, [&] { inputs_.addOdometry(odometryAt(1.2, 2.0)); });
  EXPECT_EQ(inputs_.waitsBegun(), 1);
  ASSERT_TRUE(in.has_odometry) << "the frame went on without its odometry";
  EXPECT_NEAR(in.T_odom_base.translation().x(), 2.0, 1e-9) << "not the odometry at its stamp";
}

// Without a publisher (no connection: nothing is on its way), a source that never delivered is
// not waited for.
TEST_F(StepInputsTest, ASourceThatNeverDeliveredIsNotWaitedFor) {
  opts_.odometry_source = "topic";
  inputs_.setOptions(opts_);
  StepInput in;
  StepInputs::Gaps gaps;
  std::string why;
  ASSERT_TRUE(inputs_.gather(frameHeader(1.0), &in, &gaps, &why)) << why;
  EXPECT_EQ(inputs_.waitsBegun(), 0);
  EXPECT_FALSE(in.has_attitude);
  EXPECT_FALSE(in.has_odometry);
  EXPECT_TRUE(gaps.imu);
  EXPECT_TRUE(gaps.odometry);
}

// The first frame after start: its IMU message was published just before it but is handled on
// another connection's thread after it. With a publisher on the topic, the frame waits for that
// first sample instead of going on without an attitude (which set the nodelet's no-odometry
// runs on a loaded machine apart: rostest no_odometry.test).
TEST_F(StepInputsTest, TheFirstFrameWaitsForTheFirstSampleOfAConnectedSource) {
  inputs_.setConnections([] { return true; }, [] { return false; });
  const StepInput in = gatherWithLate(1.0, [&] { inputs_.addImu(imuAt(1.0, 0.2)); });
  EXPECT_EQ(inputs_.waitsBegun(), 1);
  EXPECT_EQ(inputs_.waitsInVain(), 0);
  ASSERT_TRUE(in.has_attitude) << "the first frame went on without its IMU sample";
  EXPECT_NEAR(in.roll_rad, 0.2, 1e-9);
}

TEST_F(StepInputsTest, ASourceThatStopsIsAGapAfterTheWait) {
  opts_.input_wait_s = 0.01;
  inputs_.setOptions(opts_);
  ASSERT_TRUE(inputs_.addImu(imuAt(1.0, 0.1)));
  StepInput in;
  StepInputs::Gaps gaps;
  std::string why;
  ASSERT_TRUE(inputs_.gather(frameHeader(5.0), &in, &gaps, &why)) << why;
  EXPECT_EQ(inputs_.waitsBegun(), 1);
  EXPECT_EQ(inputs_.waitsInVain(), 1);
  EXPECT_FALSE(in.has_attitude);
  EXPECT_TRUE(gaps.imu);
  // input_wait 0: never waits.
  opts_.input_wait_s = 0.0;
  inputs_.setOptions(opts_);
  ASSERT_TRUE(inputs_.gather(frameHeader(6.0), &in, &gaps, &why)) << why;
  EXPECT_EQ(inputs_.waitsBegun(), 1);
}

// The IMU's angular velocity becomes the gyro's heading at each frame's stamp, with the run of
// samples it belongs to (the localizer compares headings within one run). An IMU message whose
// rates are unset (all zero, or covariance -1) gives no heading.
TEST_F(StepInputsTest, TheImuRatesGiveTheGyroHeadingAtEachFrame) {
  opts_.input_wait_s = 0.0;
  inputs_.setOptions(opts_);
  for (int k = 0; k <= 100; ++k) {
    sensor_msgs::Imu m = imuAt(1.0 + 0.005 * k, 0.0);
    m.angular_velocity.z = 1.2;
    ASSERT_TRUE(inputs_.addImu(m));
  }
  StepInput a, b;
  StepInputs::Gaps gaps;
  std::string why;
  ASSERT_TRUE(inputs_.gather(frameHeader(1.1), &a, &gaps, &why)) << why;
  ASSERT_TRUE(inputs_.gather(frameHeader(1.2), &b, &gaps, &why)) << why;
  ASSERT_TRUE(a.has_gyro_yaw);
  ASSERT_TRUE(b.has_gyro_yaw);
  EXPECT_EQ(a.gyro_segment, b.gyro_segment);
  EXPECT_NEAR(b.gyro_yaw_rad - a.gyro_yaw_rad, 1.2 * 0.1, 1e-9);
  // Orientation only (rates left at zero), then rates marked absent: no heading.
  for (const bool absent : {false, true}) {
    StepInputs plain(&tf_);
    plain.setOptions(opts_);
    for (int k = 0; k <= 100; ++k) {
      sensor_msgs::Imu m = imuAt(1.0 + 0.005 * k, 0.0);
      if (absent) {
        m.angular_velocity.z = 1.2;
        m.angular_velocity_covariance[0] = -1.0;
      }
      ASSERT_TRUE(plain.addImu(m));
    }
    ASSERT_TRUE(plain.gather(frameHeader(1.1), &a, &gaps, &why)) << why;
    ASSERT_TRUE(plain.gather(frameHeader(1.2), &b, &gaps, &why)) << why;
    EXPECT_TRUE(b.has_attitude);
    EXPECT_FALSE(b.has_gyro_yaw) << (absent ? "covariance -1" : "rates all zero");
  }
}

}  // namespace
}  // namespace gmm_mcl
