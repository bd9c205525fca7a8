// FrameSets (frame_sets.h): which frames of a rig go into one update, by their stamps alone.
#include <gtest/gtest.h>

#include "gmm_mcl/ros/frame_sets.h"

namespace gmm_mcl {
namespace {

constexpr double kPeriodS = 1.0 / 30;

CameraFrame frameAt(double t_s) {
  CameraFrame f;
  f.header.stamp.fromSec(100.0 + t_s);
  return f;
}
double stampOf(const FrameSet& s) { return s.header.stamp.toSec() - 100.0; }

TEST(FrameSetsTest, OneSetPerLeadFrameWithTheOthersInTheWindow) {
  FrameSets sets(2, FrameSetParams());
  FrameSet s;
  sets.add(0, frameAt(0));  // the second camera never delivered: not waited for
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_FALSE(sets.pending());
  EXPECT_EQ(s.lead, 0);
  EXPECT_FALSE(s.frames[1]);
  sets.add(1, frameAt(0.005));  // stored for the next set (a second camera before the first)
  sets.add(1, frameAt(kPeriodS + 0.005));
  sets.add(0, frameAt(kPeriodS));
  ASSERT_TRUE(sets.takeReady(&s));
  ASSERT_TRUE(s.frames[1]);
  EXPECT_NEAR(s.frames[1]->header.stamp.toSec() - 100.0, kPeriodS + 0.005, 1e-9);
  EXPECT_EQ(sets.stats(1).dropped, 1);  // the older one
  EXPECT_EQ(sets.stats(1).used, 1);
  // Now it delivers: the next set waits for it.
  sets.add(0, frameAt(2 * kPeriodS));
  EXPECT_TRUE(sets.pending());
  EXPECT_FALSE(sets.takeReady(&s));
  sets.add(1, frameAt(2 * kPeriodS - 0.01));
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_TRUE(s.frames[1]);
  EXPECT_FALSE(s.waited_in_vain);
}

TEST(FrameSetsTest, ASlowerCameraIsAwaitedOnlyForTheSetsItsFramesFallIn) {
  // The second camera at 15 Hz beside a 30 Hz first one, each of its frames handed in after
  // the first camera's of the same stamp (another connection): once its period is known, the
  // sets its frames fall in wait for them and the others do not.
  FrameSets sets(2, FrameSetParams());
  FrameSet s;
  int used = 0, in_vain = 0;
  for (int k = 0; k < 20; ++k) {
    sets.add(0, frameAt(k * kPeriodS));
    if (k % 2 == 0) sets.add(1, frameAt(k * kPeriodS));
    if (sets.pending()) sets.expire(sets.generation());  // the caller's timer
    ASSERT_TRUE(sets.takeReady(&s)) << k;
    in_vain += s.waited_in_vain ? 1 : 0;
    used += s.frames[1] ? 1 : 0;
    if (k >= 4) {
      EXPECT_EQ(static_cast<bool>(s.frames[1]), k % 2 == 0) << k;
    }
  }
  EXPECT_EQ(used, 8);     // from its third frame on (its period known from the second)
  EXPECT_EQ(in_vain, 1);  // the set after its first frame, which it was in
  EXPECT_FALSE(sets.stats(1).dropped_out);
}

TEST(FrameSetsTest, DropoutWaitsOnceThenNotReportedAndBack) {
  FrameSets sets(2, FrameSetParams());
  FrameSet s;
  int k = 0;
  for (; k < 3; ++k) {
    sets.add(1, frameAt(k * kPeriodS));
    sets.add(0, frameAt(k * kPeriodS));
    ASSERT_TRUE(sets.takeReady(&s));
    EXPECT_TRUE(s.frames[1]);
  }
  // The second camera stops: the first set waits for it (until the caller's timer), the
  // following ones do not.
  sets.add(0, frameAt(k++ * kPeriodS));
  ASSERT_TRUE(sets.pending());
  sets.expire(sets.generation());
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_TRUE(s.waited_in_vain);
  bool dropped_out = false;
  for (int i = 0; i < 20; ++i, ++k) {
    sets.add(0, frameAt(k * kPeriodS));
    ASSERT_TRUE(sets.takeReady(&s)) << i;
    EXPECT_FALSE(s.frames[1]);
    for (const CameraTransition& t : sets.takeTransitions()) {
      EXPECT_TRUE(t.dropped_out && t.camera == 1 && t.gap_s > 0.5);
      dropped_out = true;
    }
  }
  EXPECT_TRUE(dropped_out);
  EXPECT_TRUE(sets.stats(1).dropped_out);
  EXPECT_EQ(sets.stats(1).missing, 21);
  // Back: its frame joins the set and it is reported back once.
  sets.add(1, frameAt(k * kPeriodS));
  sets.add(0, frameAt(k * kPeriodS));
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_TRUE(s.frames[1]);
  const auto back = sets.takeTransitions();
  ASSERT_EQ(back.size(), 1u);
  EXPECT_FALSE(back[0].dropped_out);
  EXPECT_FALSE(sets.stats(1).dropped_out);
}

// Frames of both cameras at t_s, `first` handed in first, and the set they made.
bool addBoth(FrameSets* sets, double t_s, int first, FrameSet* s) {
  sets->add(first, frameAt(t_s));
  sets->add(1 - first, frameAt(t_s));
  return sets->takeReady(s);
}

TEST(FrameSetsTest, AnotherCameraLeadsAfterTheFirstTimesOut) {
  FrameSets sets(2, FrameSetParams());
  FrameSet s;
  ASSERT_TRUE(addBoth(&sets, 0, 0, &s));
  int k = 1;
  // The first camera stops: the second one's frames wait (the first still leads) ...
  for (; k * kPeriodS <= 0.5; ++k) {
    sets.add(1, frameAt(k * kPeriodS));
    EXPECT_FALSE(sets.takeReady(&s)) << k;
  }
  // ... until it has been silent for camera_timeout: then they lead, not waiting for it.
  sets.add(1, frameAt(k * kPeriodS));
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_EQ(s.lead, 1);
  EXPECT_FALSE(s.frames[0]);
  EXPECT_GT(sets.stats(1).dropped, 10);  // those that waited
  ++k;
  // The first camera back, its frame after the second's at the same stamp: that set is updated
  // already (led by the second); the next one is the first's again.
  sets.add(1, frameAt(k * kPeriodS));
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_EQ(s.lead, 1);
  sets.add(0, frameAt(k * kPeriodS));
  EXPECT_FALSE(sets.takeReady(&s));
  ++k;
  sets.add(0, frameAt(k * kPeriodS));
  EXPECT_TRUE(sets.pending());  // waits for the second camera, which delivered
  sets.add(1, frameAt(k * kPeriodS));
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_EQ(s.lead, 0);
  EXPECT_TRUE(s.frames[1]);
  EXPECT_EQ(sets.stats(0).dropped, 1);  // the late one
}

TEST(FrameSetsTest, JumpBackStartsAfresh) {
  FrameSets sets(2, FrameSetParams());
  FrameSet s;
  ASSERT_TRUE(addBoth(&sets, 10, 1, &s));
  sets.add(0, frameAt(0));  // a looped bag: nobody is waited for until it delivers again
  ASSERT_TRUE(sets.takeReady(&s));
  EXPECT_NEAR(stampOf(s), 0.0, 1e-9);
}

}  // namespace
}  // namespace gmm_mcl
