// Offline replay over a folder format: the synthetic scene written as a Stanford folder, read
// back and replayed through the localizer; it must converge and track. (The TUM format runs
// the same way through the gmm_mcl_replay tool: test_replay_tool_tum.) The writers' handling
// of frames without ground truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/replay/replay.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

constexpr int kFrames = 90;            // 3 s at 30 Hz
constexpr double kAteLimitM = 0.05;    // over the converged frames
constexpr double kFinalLimitM = 0.05;  // last frame

ReplayParams smallReplay() {
  ReplayParams rp;
  rp.localizer.filter.num_particles = 300;
  rp.localizer.frame.pixel_stride = 4;
  rp.localizer.frame.max_range_m = 8.0f;
  rp.init_half_extent_m = 0.5;  // CI-sized start region (the paper's 4 m cube needs ~1000)
  rp.init_yaw_half_range_rad = 0.3;
  rp.evaluation.hold_frames = 15;
  rp.evaluation.tail_frames = 30;
  return rp;
}

void replayFolder(const std::string& format, const Sequence& seq, const GmmMap& map_world) {
  std::vector<DepthImage> depth(seq.size());
  for (int f = 0; f < seq.size(); ++f) depth[f] = seq.loadDepth(f);
  const GmmMap map = rotateMap(map_world, seq.R_aligned_world(), "aligned");
  const TrialResult r = runTrial(
      seq, [&depth](int f) -> const DepthImage& { return depth[f]; }, map, smallReplay(), 1);
  const TrialMetrics& m = r.metrics;
  std::printf(
      "[ measured ] %s: converged %d at %.2f s, ATE %.2f cm / %.2f deg, final %.2f cm, "
      "%.0f ms per step\n",
      format.c_str(), m.converged, m.converge_time_s, 100 * m.ate_translation_m,
      m.ate_yaw_rad * 180 / M_PI, 100 * r.frames.back().error.translation_m, r.mean_step_ms);
  ASSERT_EQ(static_cast<int>(r.frames.size()), kFrames);
  ASSERT_TRUE(m.converged) << format;
  EXPECT_LT(m.ate_translation_m, kAteLimitM) << format;
  EXPECT_LT(r.frames.back().error.translation_m, kFinalLimitM) << format;
  EXPECT_TRUE(m.success) << format;
  // Stamps are the folder's own (TUM: epoch seconds).
  EXPECT_DOUBLE_EQ(r.frames.front().stamp_s, seq.stampS(0));
}

SimSequence sim() {
  SimSequenceParams p;
  p.frames = kFrames;
  p.width_px = 160;
  p.seed = 5;
  p.start_s = 1305031102.175304;
  return SimSequence(p);
}

TEST(ReplayFormatsTest, StanfordFolderConvergesAndTracks) {
  const SimSequence s = sim();
  test::TempDir dir("replay_stanford");
  writeStanfordFolder(s, dir.path());
  const std::unique_ptr<Sequence> seq = openSequence("stanford", dir.path());
  replayFolder("stanford", *seq, s.map());
}

TEST(ReplayFormatsTest, WritersKeepUnknownTruthEmpty) {
  TrialResult r;
  StepResult step;
  step.estimate.mean.x_m = 1.0;
  Particle truth;
  r.frames.push_back(makeReplayFrame(1.5, step, &truth));
  r.frames.push_back(makeReplayFrame(1305031102.25, step, nullptr));
  finishTrial(EvaluationParams(), &r);
  EXPECT_EQ(r.metrics.frames, 1);  // only the frame with truth is evaluated
  test::TempDir dir("writers");
  writeTum(r, false, dir / "est.tum");
  writeTum(r, true, dir / "truth.tum");
  writeFrameCsv(r, dir / "f.csv");
  const std::string est = test::readText(dir / "est.tum");
  EXPECT_NE(est.find("1305031102.250000 1 0 0"), std::string::npos) << est;
  EXPECT_EQ(std::count(est.begin(), est.end(), '\n'), 2);
  const std::string tr = test::readText(dir / "truth.tum");
  EXPECT_EQ(std::count(tr.begin(), tr.end(), '\n'), 1);
  const std::string csv = test::readText(dir / "f.csv");
  EXPECT_NE(csv.find("\n1.500000,1,0,1,0,0,0,0,0,0,0,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\n1305031102.250000,,,1,0,0,0,,,,,"), std::string::npos) << csv;
}

}  // namespace
}  // namespace gmm_mcl
