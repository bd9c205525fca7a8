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

}  // namespace
}  // namespace gmm_mcl
