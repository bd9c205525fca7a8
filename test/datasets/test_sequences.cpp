// The data-set readers on fixtures written from the synthetic scene (TUM, Stanford), their
// error messages on bad input, and the 7-Scenes reader on the shared data (skipped without).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/datasets/stanford_sequence.h"
#include "gmm_mcl/datasets/tum_sequence.h"
#include "test_utils/synthetic_fixtures.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

using test::readText;
using test::TempDir;
using test::writeText;

constexpr double kPoseTolM = 1e-6;  // text round trip of poses (9+ significant digits)
constexpr double kPoseTolRad = 1e-6;

SimSequence smallSim(int frames = 12, double start_s = 0.0) {
  SimSequenceParams p;
  p.frames = frames;
  p.width_px = 64;
  p.start_s = start_s;
  return SimSequence(p);
}

void expectSamePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, int frame) {
  EXPECT_LT((a.translation() - b.translation()).norm(), kPoseTolM) << "frame " << frame;
  EXPECT_LT(Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle(), kPoseTolRad)
      << "frame " << frame;
}

void expectSameDepth(const DepthImage& a, const DepthImage& b, int frame) {
  ASSERT_EQ(a.width_px, b.width_px);
  ASSERT_EQ(a.height_px, b.height_px);
  int differ = 0;
  for (int v = 0; v < a.height_px; ++v) {
    for (int u = 0; u < a.width_px; ++u) {
      const float x = a.depthMetres(u, v), y = b.depthMetres(u, v);
      if (std::isnan(x) != std::isnan(y) || (!std::isnan(x) && x != y)) ++differ;
    }
  }
  EXPECT_EQ(differ, 0) << "frame " << frame;
}

// Runs fn, expects a std::runtime_error whose message holds every fragment.
void expectError(const std::function<void()>& fn, const std::vector<std::string>& fragments) {
  try {
    fn();
    ADD_FAILURE() << "no error; expected one mentioning " << fragments.front();
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    for (const std::string& f : fragments) {
      EXPECT_NE(what.find(f), std::string::npos) << "'" << what << "' lacks '" << f << "'";
    }
  }
}

void replaceInFile(const std::string& path, const std::string& from, const std::string& to) {
  std::string s = readText(path);
  const size_t pos = s.find(from);
  ASSERT_NE(pos, std::string::npos) << from << " not in " << path;
  s.replace(pos, from.size(), to);
  writeText(path, s);
}

TEST(TumSequenceTest, RoundTripOfTheSyntheticScene) {
  const SimSequence sim = smallSim(12, 1305031102.175304);
  TempDir dir("tum");
  writeTumFolder(sim, dir.path());
  const TumSequence tum(dir.path());
  ASSERT_EQ(tum.size(), sim.size());
  EXPECT_EQ(tum.unassociatedFrames(), 0);
  EXPECT_STREQ(tum.format(), "tum");
  EXPECT_EQ(tum.intrinsics().width_px, 64);
  EXPECT_NEAR(tum.intrinsics().fx_px, sim.intrinsics().fx_px, 1e-4);
  EXPECT_NEAR(tum.intrinsics().cy_px, sim.intrinsics().cy_px, 1e-4);
  EXPECT_NE(tum.gravitySource().find("gravity-direction.txt"), std::string::npos);
  EXPECT_LT((tum.R_aligned_world() - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  for (int i = 0; i < tum.size(); ++i) {
    EXPECT_NEAR(tum.stampS(i), sim.stampS(i), 2e-6);
    expectSamePose(tum.T_world_cam(i), sim.T_world_cam(i), i);
    expectSameDepth(tum.loadDepth(i), sim.loadDepth(i), i);  // 5000 units/m -> mm is exact
  }
  // max_frames, and a folder with neither intrinsics.txt nor gravity-direction.txt.
  std::remove((dir / "gravity-direction.txt").c_str());
  SequenceOptions o;
  o.max_frames = 5;
  o.intrinsics = "fr3";
  const TumSequence five(dir.path(), o);
  EXPECT_EQ(five.size(), 5);
  // The format's convention is used and said to be an assumption, with the options to change it.
  EXPECT_EQ(five.gravitySource().rfind("z-up (assumed: no gravity-direction.txt", 0), 0u)
      << five.gravitySource();
  EXPECT_NE(five.gravitySource().find("--gravity"), std::string::npos);
  // Up axes of the world frame: y-up turns world +y into +z.
  o.gravity = "y-up";
  const TumSequence yup(dir.path(), o);
  EXPECT_EQ(yup.gravitySource(), "y-up");
  EXPECT_LT((yup.R_aligned_world() * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(),
            1e-12);
  o.gravity = "z-down";
  EXPECT_LT((TumSequence(dir.path(), o).R_aligned_world() * Eigen::Vector3d::UnitZ() +
             Eigen::Vector3d::UnitZ())
                .norm(),
            1e-12);
  o.gravity = "w-up";
  EXPECT_THROW(TumSequence(dir.path(), o), std::runtime_error);
  EXPECT_FLOAT_EQ(five.intrinsics().fx_px, 535.4f);
  EXPECT_FLOAT_EQ(five.intrinsics().cy_px, 247.6f);
}

TEST(TumSequenceTest, AssociatesByNearestStampWithinTolerance) {
  std::vector<StampedPose> gt(3);
  gt[0].stamp_s = 10.00;
  gt[1].stamp_s = 10.01;
  gt[2].stamp_s = 10.05;
  EXPECT_EQ(nearestPose(gt, 10.004, 0.02), 0);
  EXPECT_EQ(nearestPose(gt, 10.006, 0.02), 1);
  EXPECT_EQ(nearestPose(gt, 10.029, 0.02), 1);
  EXPECT_EQ(nearestPose(gt, 10.031, 0.02), 2);
  EXPECT_EQ(nearestPose(gt, 10.08, 0.02), -1);
  EXPECT_EQ(nearestPose(gt, 9.97, 0.02), -1);

  // Frames whose nearest ground truth is too far are dropped and counted.
  const SimSequence sim = smallSim(10);
  TempDir dir("tum_assoc");
  TumWriteOptions w;
  w.truth_per_frame = 1;
  writeTumFolder(sim, dir.path(), w);
  // Remove the ground truth of frames 3 and 4 (lines 3 + 4 and 3 + 5 after 3 comment lines).
  std::string gt_text = readText(dir / "groundtruth.txt");
  std::vector<std::string> lines;
  size_t pos = 0;
  while (pos < gt_text.size()) {
    const size_t end = gt_text.find('\n', pos);
    lines.push_back(gt_text.substr(pos, end - pos + 1));
    pos = end + 1;
  }
  std::string kept;
  for (size_t i = 0; i < lines.size(); ++i) {
    if (i != 6 && i != 7) kept += lines[i];
  }
  writeText(dir / "groundtruth.txt", kept);
  const TumSequence tum(dir.path());
  EXPECT_EQ(tum.unassociatedFrames(), 2);
  ASSERT_EQ(tum.size(), 8);
  expectSamePose(tum.T_world_cam(3), sim.T_world_cam(5), 5);
  // A tolerance below the 4 ms offset of the fixture's ground truth associates nothing.
  SequenceOptions o;
  o.association_tolerance_s = 0.002;
  expectError([&] { TumSequence(dir.path(), o); },
              {"depth.txt", "no depth frame has a ground-truth pose within 0.002"});
}

TEST(TumSequenceTest, BadInputNamesTheFileAndTheFault) {
  const SimSequence sim = smallSim(4);
  TempDir dir("tum_bad");
  writeTumFolder(sim, dir.path());
  const std::string gt = dir / "groundtruth.txt", list = dir / "depth.txt";
  const std::string gt_good = readText(gt), list_good = readText(list);
  auto open = [&] { TumSequence s(dir.path()); };

  // Line 4 is the first pose.
  std::string bad = gt_good;
  bad.insert(bad.find('\n', bad.find("# timestamp")) + 1, "1.0 2.0 3.0\n");
  writeText(gt, bad);
  expectError(open, {"groundtruth.txt:4", "expected 8 fields"});
  bad = gt_good;
  bad.insert(bad.find('\n', bad.find("# timestamp")) + 1, "0.0 1 2 nan 0 0 0 1\n");
  writeText(gt, bad);
  expectError(open, {"groundtruth.txt:4", "'nan' is not a finite number"});
  bad = gt_good;
  bad.insert(bad.find('\n', bad.find("# timestamp")) + 1, "0.0 1 2 3 0 0 0 0\n");
  writeText(gt, bad);
  expectError(open, {"groundtruth.txt:4", "quaternion"});
  writeText(gt, gt_good + "0.001 1 2 3 0 0 0 1\n");
  expectError(open, {"groundtruth.txt", "timestamp goes backwards"});
  writeText(gt, "# nothing\n");
  expectError(open, {"groundtruth.txt", "no poses"});
  writeText(gt, gt_good);

  writeText(list, list_good + "1.5\n");
  expectError(open, {"depth.txt:8", "expected 'timestamp filename'"});
  writeText(list, list_good + "0.01 depth/x.png\n");
  expectError(open, {"depth.txt:8", "timestamp not increasing"});
  writeText(list, list_good);
  std::remove((dir / "intrinsics.txt").c_str());
  expectError(open, {dir.path(), "no intrinsics"});
  SequenceOptions o;
  o.intrinsics = "500,500,30";
  expectError([&] { TumSequence(dir.path(), o); }, {"fx,fy,cx,cy"});
  o.intrinsics = "fr9";
  expectError([&] { TumSequence(dir.path(), o); }, {"'fr9' is neither a preset"});
  o.intrinsics = "-500,500,30,20";
  expectError([&] { TumSequence(dir.path(), o); }, {"non-positive focal length"});
  writeText(dir / "intrinsics.txt", "500 500 31.5\n");
  expectError(open, {"intrinsics.txt", "found 3 numbers"});
  writeText(dir / "intrinsics.txt", "500 500 31.5 23.5\n");
  writeText(dir / "gravity-direction.txt", "0 0\n");
  expectError(open, {"gravity-direction.txt", "expected 3 numbers"});
  writeText(dir / "gravity-direction.txt", "0 0 -1\n");
  EXPECT_NO_THROW(open());
  // A listed depth image that is missing, or not a 16-bit PNG.
  const size_t at = list_good.find("depth/");
  const std::string first_png =
      dir.path() + "/" + list_good.substr(at, list_good.find('\n', at) - at);
  writeText(first_png, "not a png");
  expectError(open, {first_png});
  std::remove(first_png.c_str());
  expectError(open, {first_png, "cannot open"});
  std::remove(list.c_str());
  expectError(open, {"depth.txt", "missing: not a TUM RGB-D folder"});
  expectError([&] { openSequence("tum", dir / "nope"); }, {"nope", "not a folder"});
  expectError([&] { openSequence("kitti", dir.path()); }, {"unknown data-set format 'kitti'"});
}

TEST(TumSequenceTest, IclNuimDepthScaleAndPresets) {
  // ICL-NUIM in TUM format: 5000 units per metre as TUM, intrinsics preset "icl".
  const SimSequence sim = smallSim(3);
  TempDir dir("icl");
  writeTumFolder(sim, dir.path());
  SequenceOptions o;
  o.intrinsics = "icl";
  const TumSequence icl(dir.path(), o);
  EXPECT_FLOAT_EQ(icl.intrinsics().fx_px, 481.2f);
  EXPECT_FLOAT_EQ(icl.intrinsics().fy_px, 480.0f);
  // Read at 1000 units per metre instead, every depth is 5 times as far.
  o.depth_units_per_m = 1000.0;
  const TumSequence mm(dir.path(), o);
  const DepthImage a = sim.loadDepth(0), b = mm.loadDepth(0);
  int checked = 0;
  for (int v = 0; v < a.height_px; v += 7) {
    for (int u = 0; u < a.width_px; u += 7) {
      const float x = a.depthMetres(u, v), y = b.depthMetres(u, v);
      if (std::isnan(x) || x * 5 > 65.0f) continue;
      EXPECT_NEAR(y, 5 * x, 1e-3);
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
}

TEST(StanfordSequenceTest, RoundTripAndGravityFromTheFirstCamera) {
  const SimSequence sim = smallSim(8);
  TempDir dir("stanford");
  writeStanfordFolder(sim, dir.path());
  const StanfordSequence st(dir.path());
  ASSERT_EQ(st.size(), sim.size());
  EXPECT_EQ(st.trajectoryPath(), dir / "trajectory.log");
  for (int i = 0; i < st.size(); ++i) {
    EXPECT_NEAR(st.stampS(i), i / 30.0, 1e-12);
    expectSamePose(st.T_world_cam(i), sim.T_world_cam(i), i);
    expectSameDepth(st.loadDepth(i), sim.loadDepth(i), i);
  }
  EXPECT_LT((st.R_aligned_world() - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  // Without gravity-direction.txt: the first camera's +y (image down) is taken as down.
  std::remove((dir / "gravity-direction.txt").c_str());
  std::remove((dir / "intrinsics.txt").c_str());
  const StanfordSequence level(dir.path());
  EXPECT_EQ(level.gravitySource().rfind("first-camera (assumed", 0), 0u) << level.gravitySource();
  const Eigen::Vector3d down_first = level.T_world_cam(0).linear() * Eigen::Vector3d::UnitY();
  EXPECT_LT((level.R_aligned_world() * down_first - Eigen::Vector3d(0, 0, -1)).norm(), 1e-9);
  EXPECT_FLOAT_EQ(level.intrinsics().fx_px, 525.f);  // the Stanford default
  EXPECT_FLOAT_EQ(level.intrinsics().cx_px, 319.5f);
}

TEST(StanfordSequenceTest, BadInputNamesTheFileAndTheFault) {
  const SimSequence sim = smallSim(3);
  TempDir dir("stanford_bad");
  writeStanfordFolder(sim, dir.path());
  const std::string log = dir / "trajectory.log";
  const std::string good = readText(log);
  auto open = [&] { StanfordSequence s(dir.path()); };

  replaceInFile(log, "1 1 2\n", "1 2\n");
  expectError(open, {"trajectory.log:6", "expected a header 'id id frame_index'"});
  // Each faulty trajectory file and what its error names.
  const std::vector<std::pair<std::string, std::vector<std::string>>> faults = {
      {good.substr(0, good.rfind('\n', good.size() - 2) + 1),
       {"trajectory.log", "ends inside the matrix of frame 3"}},
      {good + "3 3 4\n1 0 0 0\n0 1 0 0\n0 0 1\n0 0 0 1\n",
       {"trajectory.log:19", "matrix row of 4 numbers"}},
      {good + "3 3 4\n2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
       {"trajectory.log:20", "not a rotation"}},
      {good + "3 3 4\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n",
       {"trajectory.log:20", "last matrix row"}},
      {good + "3 3 4\n1 0 0 0\n0 1 0 x\n0 0 1 0\n0 0 0 1\n",
       {"trajectory.log:18", "'x' is not a finite number"}},
      {good + "3 3 2\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
       {"trajectory.log:16", "frame index 2 not increasing"}},
      {good + "3 3 7\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
       {"trajectory.log", "frame index 7 has no depth image"}},
  };
  for (const auto& fault : faults) {
    writeText(log, fault.first);
    expectError(open, fault.second);
  }
  writeText(log, good);
  writeText(dir / "other.log", good);
  expectError(open, {dir.path(), "more than one *.log"});
  SequenceOptions o;
  o.trajectory = log;
  EXPECT_EQ(StanfordSequence(dir.path(), o).size(), 3);
  std::remove((dir / "other.log").c_str());
  std::remove(log.c_str());
  expectError(open, {dir.path(), "no *.log trajectory"});
}

TEST(SevenScenesSequenceTest, SharedDataThroughTheCommonInterface) {
  const std::string root = test::datasetsRoot();
  if (root.empty()) {
    std::printf("[  SKIPPED ] ../shared/datasets not found: 7-Scenes reader not checked\n");
    return;
  }
  SequenceOptions o;
  o.max_frames = 3;
  const std::unique_ptr<Sequence> seq =
      openSequence("7scenes", root + "/7scenes_redkitchen/data", o);
  ASSERT_EQ(seq->size(), 3);
  EXPECT_FLOAT_EQ(seq->intrinsics().fx_px, 585.f);
  EXPECT_NE(seq->gravitySource().find("gravity-direction.txt"), std::string::npos);
  EXPECT_NEAR(seq->stampS(2), 2 / 30.0, 1e-12);
  const DepthImage d = seq->loadDepth(0);
  EXPECT_EQ(d.width_px, 640);
  // The camera moves at most 3.6 cm per frame (SOURCES.md).
  EXPECT_LT((seq->T_world_cam(1).translation() - seq->T_world_cam(0).translation()).norm(), 0.036);
}

}  // namespace
}  // namespace gmm_mcl
