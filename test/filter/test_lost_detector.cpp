// The lost detector (gmm_mcl/filter/lost_detector.h) on hand-made score sequences: it waits out
// the grace period, fires after `frames` frames more than the margin below the reference, rises
// with the best score, and sinks with it only down to its floor (the map's predicted level
// minus reference_max_drop_nats), so a filter stuck in a wrong mode is flagged however long it
// stays there.
#include <gtest/gtest.h>

#include "gmm_mcl/filter/lost_detector.h"

namespace gmm_mcl {
namespace {

LostDetectionParams params() {
  LostDetectionParams p;
  p.margin_nats = 3.0;
  p.frames = 10;
  p.grace_frames = 30;
  p.reference_max_drop_nats = 0.5;
  return p;
}

TEST(LostDetectorTest, FiresAfterTheGraceAndTheFrameCount) {
  LostDetector d(params(), -1.0);
  int first = -1;
  for (int f = 0; f < 100 && first < 0; ++f) {
    if (d.update(-5.0)) first = f;  // 4 nats below the reference from the first frame
  }
  // Frames 0..29 are the grace; 10 frames below are counted from the first frame, so the first
  // frame after the grace that has them fires.
  EXPECT_EQ(first, 30);
  // After firing the grace restarts.
  for (int f = 0; f < 30; ++f) EXPECT_FALSE(d.update(-5.0)) << f;
  EXPECT_TRUE(d.update(-5.0));
}

TEST(LostDetectorTest, ReferenceSinksOnlyToItsFloor) {
  LostDetector d(params(), -1.0);
  // A wrong mode scoring 3.6 nats below the predicted level: without the floor the reference
  // would follow it down within the margin after a few hundred frames and never fire again.
  int fired = 0;
  for (int f = 0; f < 3000; ++f) fired += d.update(-4.6) ? 1 : 0;
  EXPECT_DOUBLE_EQ(d.reference(), -1.5);
  EXPECT_GE(fired, 3000 / 41 - 1);  // every grace + 11 frames
  // Rising with the best score (rate up 0.05 per frame).
  LostDetector up(params(), -1.0);
  for (int f = 0; f < 200; ++f) up.update(0.0);
  EXPECT_NEAR(up.reference(), 0.0, 1e-3);
  // Tracking scores within the margin never fire.
  LostDetector ok(params(), -1.0);
  for (int f = 0; f < 1000; ++f) EXPECT_FALSE(ok.update(-1.0 - 2.0 * (f % 7) / 7.0)) << f;
}

TEST(LostDetectorTest, OffAndNonFiniteScores) {
  LostDetectionParams off = params();
  off.margin_nats = 0.0;
  LostDetector d(off, -1.0);
  EXPECT_FALSE(d.enabled());
  for (int f = 0; f < 100; ++f) EXPECT_FALSE(d.update(-50.0));
  LostDetector n(params(), -1.0);
  for (int f = 0; f < 100; ++f) EXPECT_FALSE(n.update(std::nan("")));
  LostDetectionParams bad = params();
  bad.reference_max_drop_nats = -1.0;
  EXPECT_NE(bad.validate().find("reference_max_drop_nats"), std::string::npos);
}

TEST(LostDetectorTest, RestartBeginsTheGraceAgain) {
  LostDetector d(params(), -1.0);
  for (int f = 0; f < 20; ++f) EXPECT_FALSE(d.update(-5.0)) << f;
  EXPECT_EQ(d.framesBelow(), 20);
  // After a re-initialisation of the particles: the whole grace again, and the frames below
  // counted anew, as from construction.
  d.restart();
  EXPECT_EQ(d.framesBelow(), 0);
  int first = -1;
  for (int f = 0; f < 100 && first < 0; ++f) {
    if (d.update(-5.0)) first = f;
  }
  EXPECT_EQ(first, 30);
  // Firing restarts it too: the next report comes a grace period later.
  int next = -1;
  for (int f = 0; f < 100 && next < 0; ++f) {
    if (d.update(-5.0)) next = f;
  }
  EXPECT_EQ(next, 30);
}

TEST(LostDetectorTest, RebaseDropsTheLearnedReferenceToItsFloor) {
  // A rig's camera drops out: the level the remaining cameras score is another one. The
  // reference learned with both (0.0) goes back to the starting floor (-1.5) and the grace
  // restarts, so that a level 4 nats below the learned one is no reason to fire.
  LostDetector d(params(), -1.0);
  for (int f = 0; f < 200; ++f) d.update(0.0);
  ASSERT_NEAR(d.reference(), 0.0, 1e-3);
  LostDetector kept = d;
  d.rebase();
  EXPECT_DOUBLE_EQ(d.reference(), -1.5);
  int fired = 0, fired_kept = 0;
  for (int f = 0; f < 100; ++f) {
    fired += d.update(-4.0) ? 1 : 0;
    fired_kept += kept.update(-4.0) ? 1 : 0;
  }
  EXPECT_EQ(fired, 0);
  EXPECT_GT(fired_kept, 0);  // without the rebase it would have called the filter lost
}

TEST(LostDetectorTest, SetParamsRaisesTheReferenceOnlyToTheNewFloor) {
  LostDetector d(params(), -1.0);
  // A map predicting a higher level: the reference rises to its floor (2.0 - 0.5).
  d.setParams(params(), 2.0);
  EXPECT_DOUBLE_EQ(d.reference(), 1.5);
  // A lower one keeps the learned reference; it may now sink to the new floor (-10.5).
  d.setParams(params(), -10.0);
  EXPECT_DOUBLE_EQ(d.reference(), 1.5);
  for (int f = 0; f < 5000; ++f) d.update(-20.0);
  EXPECT_DOUBLE_EQ(d.reference(), -10.5);
  // Off through new parameters.
  LostDetectionParams off = params();
  off.margin_nats = 0.0;
  d.setParams(off, -10.0);
  EXPECT_FALSE(d.enabled());
  EXPECT_FALSE(d.update(-50.0));
}

}  // namespace
}  // namespace gmm_mcl
