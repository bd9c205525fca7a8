// Stamped poses and attitudes looked up at a frame's stamp; concurrent producers and readers.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/stamped_buffer.h"

namespace gmm_mcl {
namespace {

Eigen::Isometry3d pose(double x, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, 2 * x, 0.5);
  T.linear() = rotationFromRpy(0, 0, yaw);
  return T;
}

TEST(StampedPoseBufferTest, InterpolatesBetweenNeighboursAndTakesTheNearestWithinTolerance) {
  StampedPoseBuffer b(10.0, 1.0);
  Eigen::Isometry3d T;
  std::string why;
  EXPECT_FALSE(b.at(1.0, 0.1, &T, &why));
  EXPECT_EQ(why, "none received");
  b.add(1.0, pose(0.0, 0.0));
  b.add(2.0, pose(1.0, 0.4));
  b.add(1.5, pose(0.5, 0.2));  // out of order: inserted in place
  ASSERT_TRUE(b.at(1.25, 0.0, &T));
  EXPECT_NEAR(T.translation().x(), 0.25, 1e-12);
  EXPECT_NEAR(yawFromRotation(T.linear()), 0.1, 1e-12);
  ASSERT_TRUE(b.at(2.0, 0.0, &T));  // exact
  EXPECT_NEAR(T.translation().x(), 1.0, 1e-12);
  ASSERT_TRUE(b.at(2.05, 0.1, &T));  // after the newest, within tolerance
  EXPECT_NEAR(T.translation().x(), 1.0, 1e-12);
  EXPECT_FALSE(b.at(2.3, 0.1, &T, &why));
  EXPECT_NE(why.find("0.3 s before the stamp"), std::string::npos) << why;
  EXPECT_FALSE(b.at(0.5, 0.1, &T, &why));
  EXPECT_NE(why.find("after the stamp"), std::string::npos) << why;
  // A gap longer than max_gap: no interpolation across it, the nearest within tolerance only.
  b.add(5.0, pose(3.0, 0.0));
  EXPECT_FALSE(b.at(3.5, 0.1, &T));
  ASSERT_TRUE(b.at(4.95, 0.1, &T));
  EXPECT_NEAR(T.translation().x(), 3.0, 1e-12);
  // A time jump back: what came after is dropped.
  b.eraseAfter(1.5);
  EXPECT_EQ(b.size(), 2u);
  EXPECT_EQ(b.added(), 4);
  // Entries older than max_age behind the newest are dropped.
  b.add(30.0, pose(0, 0));
  EXPECT_EQ(b.size(), 1u);
}

TEST(StampedPoseBufferTest, AttitudeRoundTrip) {
  StampedPoseBuffer b;
  b.addAttitude(1.0, 0.1, -0.05);
  b.addAttitude(1.1, 0.2, -0.15);
  double roll, pitch;
  ASSERT_TRUE(b.attitudeAt(1.05, 0.0, &roll, &pitch));
  EXPECT_NEAR(roll, 0.15, 2e-3);
  EXPECT_NEAR(pitch, -0.10, 2e-3);
  ASSERT_TRUE(b.attitudeAt(1.1, 0.0, &roll, &pitch));
  EXPECT_NEAR(roll, 0.2, 1e-12);
}

// Producers add while a reader looks up: every entry arrives, no lookup fails in between.
TEST(StampedPoseBufferTest, ConcurrentProducersAndReader) {
  StampedPoseBuffer b(1e9, 1.0);
  b.add(0.0, pose(0, 0));
  std::atomic<bool> done(false);
  std::thread reader([&] {
    Eigen::Isometry3d T;
    while (!done) EXPECT_TRUE(b.at(0.0, 0.0, &T));
  });
  std::thread a([&] {
    for (int i = 1; i <= 20000; i += 2) b.add(i * 1e-3, pose(i, 0));
  });
  std::thread c([&] {
    for (int i = 2; i <= 20000; i += 2) b.add(i * 1e-3, pose(i, 0));
  });
  a.join();
  c.join();
  done = true;
  reader.join();
  EXPECT_EQ(b.size(), 20001u);
  EXPECT_EQ(b.added(), 20001);
}

// A waiter for an entry at t is woken by the add that brings it; without one it gives up at the
// deadline (a deadline already past: it only looks).
TEST(StampedPoseBufferTest, WaitUntilReachesWakesOnAdd) {
  StampedPoseBuffer b;
  b.add(1.0, pose(1, 0));
  const auto now = std::chrono::steady_clock::now();
  EXPECT_TRUE(b.waitUntilReaches(1.0, now));
  EXPECT_FALSE(b.waitUntilReaches(2.0, now));
  std::atomic<bool> waiting{false};
  std::thread producer([&] {
    while (!waiting) std::this_thread::yield();
    b.add(2.0, pose(2, 0));
  });
  waiting = true;  // the add may come before or during the wait: both must return true
  EXPECT_TRUE(b.waitUntilReaches(2.0, now + std::chrono::seconds(60)));
  producer.join();
}

// A level IMU turning at 0.5 rad/s: samples at 100 Hz from t0_s, the last at t0_s + samples / 100.
void turnLevel(GyroHeading* gyro, double t0_s, int samples) {
  for (int k = 0; k <= samples; ++k) gyro->add(t0_s + 0.01 * k, Eigen::Vector3d(0, 0, 0.5), 0, 0);
}

// The gyro's heading: the vertical component of the angular velocity, integrated; a gap starts a
// new segment.
TEST(GyroHeadingTest, IntegratesTheTurnAboutTheVerticalAndSplitsAtGaps) {
  GyroHeading gyro(2.0, 0.1);
  turnLevel(&gyro, 10.0, 50);  // level, turning at 0.5 rad/s, 100 Hz, from t = 10 s
  double h0, h1;
  long long s0, s1;
  ASSERT_TRUE(gyro.at(10.1, 0.05, &h0, &s0));
  ASSERT_TRUE(gyro.at(10.333, 0.05, &h1, &s1));  // interpolated between samples
  EXPECT_EQ(s0, s1);
  EXPECT_NEAR(h1 - h0, 0.5 * 0.233, 1e-9);
  // Rolled by 90 deg: the IMU's y axis points up, so its y rate is the turn about the vertical.
  GyroHeading rolled(2.0, 0.1);
  for (int k = 0; k <= 10; ++k) {
    rolled.add(0.01 * k, Eigen::Vector3d(0.3, -0.4, 0.2), 0.5 * M_PI, 0.0);
  }
  ASSERT_TRUE(rolled.at(0.1, 0.05, &h1, &s1));
  ASSERT_TRUE(rolled.at(0.0, 0.05, &h0, &s0));
  EXPECT_NEAR(h1 - h0, -0.4 * 0.1, 1e-9);
  // A gap of 0.5 s: a new segment, whose headings are not comparable with the old one's.
  turnLevel(&gyro, 11.0, 10);
  ASSERT_TRUE(gyro.at(11.05, 0.05, &h1, &s1));
  EXPECT_NE(s1, s0);
  // Time going back: the later samples dropped, a new segment again.
  gyro.eraseAfter(10.2);
  gyro.add(10.21, Eigen::Vector3d(0, 0, 0.5), 0.0, 0.0);
  long long s2;
  ASSERT_TRUE(gyro.at(10.21, 0.005, &h1, &s2));
  EXPECT_NE(s2, s1);
}

// Past the newest sample the heading goes on at its rate for at most the gap that would end the
// segment; held there, it would claim that the body stopped turning (an IMU whose rates stopped).
TEST(GyroHeadingTest, PastTheNewestSampleTheHeadingGoesOnAtItsRateForAGapAtMost) {
  GyroHeading gyro(2.0, 0.1);
  turnLevel(&gyro, 10.0, 50);
  double h_end, h;
  long long s_end, s;
  ASSERT_TRUE(gyro.at(10.5, 0.5, &h_end, &s_end));
  ASSERT_TRUE(gyro.at(10.56, 0.5, &h, &s));
  EXPECT_EQ(s, s_end);
  EXPECT_NEAR(h - h_end, 0.5 * 0.06, 1e-9);
  std::string why;
  EXPECT_FALSE(gyro.at(10.65, 0.5, &h, &s, &why)) << "0.15 s past the newest sample";
  EXPECT_NE(why.find("no gyro samples"), std::string::npos) << why;
  EXPECT_FALSE(gyro.at(10.55, 0.02, &h, &s)) << "beyond the caller's tolerance";
  EXPECT_FALSE(gyro.at(9.99, 0.5, &h, &s)) << "before the first sample";
}

TEST(GyroHeadingTest, AStepsHeadingNamesItsSegment) {
  GyroHeading gyro(2.0, 0.1);
  turnLevel(&gyro, 10.0, 50);
  long long s0 = -2, s1 = -2;
  double h0 = -1.0, h1 = -1.0;
  ASSERT_TRUE(gyroHeadingForStep(gyro, 10.1, 0.05, &s0, &h0));
  EXPECT_GE(s0, 0);
  ASSERT_TRUE(gyroHeadingForStep(gyro, 10.2, 0.05, &s1, &h1));
  EXPECT_EQ(s1, s0);
  EXPECT_NEAR(h1 - h0, 0.05, 1e-9);
  // No sample near the stamp: none, heading 0, segment -1.
  EXPECT_FALSE(gyroHeadingForStep(gyro, 20.0, 0.05, &s1, &h1));
  EXPECT_EQ(h1, 0.0);
  EXPECT_EQ(s1, -1);
  // A gap: a new segment, whose headings are not comparable with the old one's.
  turnLevel(&gyro, 11.0, 10);
  ASSERT_TRUE(gyroHeadingForStep(gyro, 11.05, 0.05, &s1, &h1));
  EXPECT_GT(s1, s0);
}

}  // namespace
}  // namespace gmm_mcl
