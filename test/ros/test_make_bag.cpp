// The bag converters without a master: gmm_mcl_make_bag on TUM and Stanford fixtures written
// from the synthetic scene, on the shared 7-Scenes data (skipped without), the cow_and_lady
// layout; message counts, content against the sequence, the protocol's noise, seeding; and
// gmm_mcl_replay_bag on converted bags.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/sim_sequence.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros_tools/bag_writer.h"
#include "gmm_mcl/ros_tools/sequence_bag.h"
#include "test_utils/synthetic_fixtures.h"
#include "test_utils/temp_dir.h"

namespace gmm_mcl {
namespace {

using test::TempDir;

constexpr double kPoseTolM = 1e-6;
constexpr double kReplayFinalErrorM = 0.05;

SimSequence sim(int frames, int width = 64, uint64_t seed = 1) {
  SimSequenceParams p;
  p.frames = frames;
  p.width_px = width;
  p.seed = seed;
  p.start_s = 1305031102.175304;
  return SimSequence(p);
}

int run(const std::string& cmd) {
  std::printf("$ %s\n", cmd.c_str());
  std::fflush(stdout);
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

struct BagContents {
  std::map<std::string, int> count;
  std::vector<sensor_msgs::Image> images;
  std::vector<sensor_msgs::CameraInfo> infos;
  std::vector<nav_msgs::Odometry> odom;
  std::vector<sensor_msgs::Imu> imu;
  std::vector<geometry_msgs::PoseStamped> truth;
  std::vector<geometry_msgs::TransformStamped> mocap;
  std::vector<sensor_msgs::PointCloud2> clouds;
  bool static_latched = false;
};

BagContents readBag(const std::string& path) {
  BagContents c;
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    ++c.count[m.getTopic()];
    if (auto x = m.instantiate<sensor_msgs::Image>()) c.images.push_back(*x);
    if (auto x = m.instantiate<sensor_msgs::CameraInfo>()) c.infos.push_back(*x);
    if (auto x = m.instantiate<nav_msgs::Odometry>()) c.odom.push_back(*x);
    if (auto x = m.instantiate<sensor_msgs::Imu>()) c.imu.push_back(*x);
    if (auto x = m.instantiate<geometry_msgs::PoseStamped>()) c.truth.push_back(*x);
    if (auto x = m.instantiate<geometry_msgs::TransformStamped>()) c.mocap.push_back(*x);
    if (auto x = m.instantiate<sensor_msgs::PointCloud2>()) c.clouds.push_back(*x);
    if (m.getTopic() == "/tf_static") {
      const auto h = m.getConnectionHeader();
      c.static_latched = h && h->count("latching") && h->at("latching") == "1";
    }
  }
  return c;
}

// The image layout: one of each per frame, content equal to the sequence.
void checkImageLayout(const BagContents& c, const Sequence& seq, int n) {
  EXPECT_EQ(c.count.at("/camera/depth/image_raw"), n);
  EXPECT_EQ(c.count.at("/camera/depth/camera_info"), n);
  EXPECT_EQ(c.count.at("/imu/data"), n);
  EXPECT_EQ(c.count.at("/odom"), n);
  EXPECT_EQ(c.count.at("/tf"), n);
  EXPECT_EQ(c.count.at("/ground_truth"), n);
  EXPECT_EQ(c.count.at("/tf_static"), 1);
  EXPECT_TRUE(c.static_latched);
  const std::vector<Eigen::Isometry3d> truth = alignedBaseTrajectory(seq, n);
  std::vector<double> gyro_errors;
  for (int f = 0; f < n; ++f) {
    const sensor_msgs::Image& img = c.images[f];
    EXPECT_EQ(img.encoding, "16UC1");
    EXPECT_EQ(img.header.frame_id, "camera_depth_optical_frame");
    EXPECT_NEAR((img.header.stamp - c.images[0].header.stamp).toSec(),
                seq.stampS(f) - seq.stampS(0), 2e-6);
    if (f % 5 == 0) {
      EXPECT_EQ(img.data, seq.loadDepth(f).data) << "frame " << f;
    }
    EXPECT_FLOAT_EQ(c.infos[f].K[0], seq.intrinsics().fx_px);
    EXPECT_FLOAT_EQ(c.infos[f].K[5], seq.intrinsics().cy_px);
    EXPECT_EQ(c.truth[f].header.stamp, img.header.stamp);
    EXPECT_LT(
        (ros_conv::isometryFromPose(c.truth[f].pose).translation() - truth[f].translation()).norm(),
        kPoseTolM);
    // The gyro: the true body rate over the interval ending at the frame (the first frame's over
    // the next one), plus a bias and white noise (ProtocolNoise): within 5 sigma of each.
    Eigen::Vector3d omega;
    ASSERT_TRUE(ros_conv::angularVelocityFromImu(c.imu[f], &omega)) << "frame " << f;
    const int a = f > 0 ? f - 1 : 0, b = f > 0 ? f : 1;
    const double dt = seq.stampS(b) - seq.stampS(a);
    const Eigen::AngleAxisd turn(truth[a].linear().transpose() * truth[b].linear());
    const Eigen::Vector3d error = omega - turn.angle() / dt * turn.axis();
    const ProtocolNoise noise;
    const double bound = 5.0 * (noise.gyro_bias_sigma_rad_s +
                                noise.gyro_noise_density_rad_s_sqrt_hz / std::sqrt(dt));
    EXPECT_LT(error.cwiseAbs().maxCoeff(), bound) << "frame " << f;
    gyro_errors.push_back(error.x());
  }
  // White noise: the samples' errors differ from frame to frame (a bias alone would not).
  const auto range = std::minmax_element(gyro_errors.begin(), gyro_errors.end());
  EXPECT_GT(*range.second - *range.first, 1e-4) << "the IMU's rates carry no noise";
}

// Odometry increments minus true increments: per-frame sigma about 0.005 m per axis.
double odometryNoiseSigma(const BagContents& c) {
  double s = 0;
  int n = 0;
  for (size_t f = 1; f < c.odom.size(); ++f) {
    const Eigen::Isometry3d o = ros_conv::isometryFromPose(c.odom[f - 1].pose.pose).inverse() *
                                ros_conv::isometryFromPose(c.odom[f].pose.pose);
    const Eigen::Isometry3d t = ros_conv::isometryFromPose(c.truth[f - 1].pose).inverse() *
                                ros_conv::isometryFromPose(c.truth[f].pose);
    s += (o.translation() - t.translation()).squaredNorm();
    n += 3;
  }
  return std::sqrt(s / n);
}

TEST(MakeBagTest, TumFolderThroughTheTool) {
  const int n = 40;
  const SimSequence s = sim(n);
  TempDir dir("make_bag_tum");
  writeTumFolder(s, dir / "tum");
  ASSERT_EQ(run(std::string(GMM_MCL_MAKE_BAG) + " --format tum " + (dir / "tum") + " " +
                (dir / "out.bag") + " --seed 3 --quiet"),
            0);
  const std::unique_ptr<Sequence> seq = openSequence("tum", dir / "tum");
  const BagContents c = readBag(dir / "out.bag");
  checkImageLayout(c, *seq, n);
  const double sigma = odometryNoiseSigma(c);
  std::printf("[ measured ] odometry noise per frame and axis: %.4f m (protocol 0.005)\n", sigma);
  EXPECT_GT(sigma, 0.0035);  // 117 samples: sample sigma within about +-30%
  EXPECT_LT(sigma, 0.0065);
  // IMU roll/pitch = truth + N(0, 0.5 deg).
  double s2 = 0;
  for (int f = 0; f < n; ++f) {
    double r, p, rt, pt, yt;
    ASSERT_TRUE(ros_conv::attitudeFromImu(c.imu[f], &r, &p));
    rpyFromRotation(ros_conv::isometryFromPose(c.truth[f].pose).linear(), &rt, &pt, &yt);
    s2 += (r - rt) * (r - rt) + (p - pt) * (p - pt);
  }
  const double att = std::sqrt(s2 / (2 * n)) * 180 / M_PI;
  std::printf("[ measured ] IMU attitude noise: %.3f deg (protocol 0.5)\n", att);
  EXPECT_GT(att, 0.3);
  EXPECT_LT(att, 0.7);
  // The initial region file around the true start.
  const std::string init = test::readText(dir / "out_init.yaml");
  EXPECT_NE(init.find("init_half_extent: [2, 2, 2]"), std::string::npos) << init;
}

TEST(MakeBagTest, SeededNoise) {
  const SimSequence s = sim(10);
  TempDir dir("make_bag_seed");
  ros_bag::SequenceBagOptions o;
  o.seed = 5;
  ros_bag::writeSequenceBag(s, nullptr, dir / "a.bag", o);
  ros_bag::writeSequenceBag(s, nullptr, dir / "b.bag", o);
  o.seed = 6;
  ros_bag::writeSequenceBag(s, nullptr, dir / "c.bag", o);
  const BagContents a = readBag(dir / "a.bag"), b = readBag(dir / "b.bag"),
                    c = readBag(dir / "c.bag");
  EXPECT_EQ(a.odom.back().pose.pose.position.x, b.odom.back().pose.pose.position.x);
  EXPECT_EQ(a.imu.back().orientation.x, b.imu.back().orientation.x);
  EXPECT_NE(a.odom.back().pose.pose.position.x, c.odom.back().pose.pose.position.x);
}

TEST(MakeBagTest, StanfordFolderThroughTheTool) {
  const int n = 12;
  const SimSequence s = sim(n);
  TempDir dir("make_bag_stanford");
  writeStanfordFolder(s, dir / "st");
  saveMap(s.map(), dir / "world.gmm");
  ASSERT_EQ(run(std::string(GMM_MCL_MAKE_BAG) + " --format stanford " + (dir / "st") + " " +
                (dir / "out.bag") + " --map " + (dir / "world.gmm") + " --quiet"),
            0);
  const std::unique_ptr<Sequence> seq = openSequence("stanford", dir / "st");
  checkImageLayout(readBag(dir / "out.bag"), *seq, n);
  EXPECT_EQ(loadMap(dir / "out.gmm").size(), s.map().size());
  // Bad input: the tool fails with the reader's message.
  std::remove((dir / "st/trajectory.log").c_str());
  EXPECT_EQ(run(std::string(GMM_MCL_MAKE_BAG) + " --format stanford " + (dir / "st") + " " +
                (dir / "bad.bag") + " --quiet"),
            1);
}

TEST(MakeBagTest, SevenScenesSharedData) {
  const std::string root = test::datasetsRoot();
  if (root.empty()) {
    std::printf("[  SKIPPED ] ../shared/datasets not found: 7-Scenes conversion not checked\n");
    return;
  }
  TempDir dir("make_bag_7s");
  const std::string data = root + "/7scenes_redkitchen/data";
  ASSERT_EQ(run(std::string(GMM_MCL_MAKE_BAG) + " --format 7scenes " + data + " " +
                (dir / "7s.bag") + " --frames 6 --quiet"),
            0);
  SequenceOptions o;
  o.max_frames = 6;
  const std::unique_ptr<Sequence> seq = openSequence("7scenes", data, o);
  const BagContents c = readBag(dir / "7s.bag");
  checkImageLayout(c, *seq, 6);
  EXPECT_EQ(c.images[0].width, 640u);
  // Ground truth is gravity-aligned: the data set's gravity direction becomes -z.
  std::ifstream g(data + "/gravity-direction.txt");
  Eigen::Vector3d down;
  ASSERT_TRUE(static_cast<bool>(g >> down.x() >> down.y() >> down.z()));
  EXPECT_LT((seq->R_aligned_world() * down.normalized() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-9);
}

TEST(MakeBagTest, CowAndLadyLayout) {
  const int n = 10;
  const SimSequence s = sim(n);
  TempDir dir("make_bag_cow");
  ros_bag::SequenceBagOptions o;
  o.layout = "cow_and_lady";
  ASSERT_TRUE(ros_bag::parseTransform("0.1,-0.05,0.12,0,0,0.0998334,0.9950042", &o.T_marker_cam));
  ros_bag::writeSequenceBag(s, nullptr, dir / "cow.bag", o);
  const BagContents c = readBag(dir / "cow.bag");
  EXPECT_EQ(c.count.at(ros_bag::kCowCloudTopic), n);
  EXPECT_EQ(c.count.at(ros_bag::kCowTruthTopic), n);
  EXPECT_EQ(c.count.count("/odom"), 0u);
  EXPECT_EQ(c.count.count("/tf"), 0u);
  for (int f = 0; f < n; ++f) {
    EXPECT_EQ(c.clouds[f].height, 48u);  // organized
    EXPECT_EQ(c.clouds[f].header.frame_id, ros_bag::kCowCameraFrame);
    EXPECT_EQ(c.mocap[f].header.frame_id, ros_bag::kCowWorldFrame);
    // marker * calibration = camera pose (world z up, as the sim).
    const Eigen::Isometry3d cam =
        ros_conv::isometryFromTransform(c.mocap[f].transform) * o.T_marker_cam;
    EXPECT_LT((cam.translation() - s.T_world_cam(f).translation()).norm(), kPoseTolM);
    // The cloud's depth equals the sequence's.
    DepthImage d;
    Intrinsics K;
    std::string why;
    ASSERT_TRUE(ros_conv::depthImageFromCloud(c.clouds[f], &d, &K, &why)) << why;
    EXPECT_NEAR(K.fx_px, s.intrinsics().fx_px, 1e-2);
    const DepthImage ref = s.loadDepth(f);
    EXPECT_NEAR(d.depthMetres(30, 20), ref.depthMetres(30, 20), 1e-6);
  }
  Eigen::Isometry3d T;
  EXPECT_FALSE(ros_bag::parseTransform("1,2,3", &T));
  EXPECT_FALSE(ros_bag::parseTransform("0,0,0,0,0,0,2", &T));
  o.layout = "bogus";
  EXPECT_THROW(ros_bag::writeSequenceBag(s, nullptr, dir / "x.bag", o), std::runtime_error);
}

// Last data row's error column of a frames.csv (empty when unknown).
double lastError(const std::string& csv_path, int* rows) {
  std::ifstream in(csv_path);
  std::string line, last;
  *rows = -1;
  while (std::getline(in, line)) {
    last = line;
    ++*rows;
  }
  const size_t a = last.find(','), b = last.find(',', a + 1);
  return a == std::string::npos ? NAN : std::atof(last.substr(a + 1, b - a - 1).c_str());
}

TEST(ReplayBagTest, ImageAndCowAndLadyBagsWithoutAMaster) {
  const int n = 90;
  const SimSequence s = sim(n, 160, 4);
  TempDir dir("replay_bag");
  saveMap(s.map(), dir / "map.gmm");
  ros_bag::SequenceBagOptions o;
  ros_bag::writeSequenceBag(s, nullptr, dir / "img.bag", o);
  o.layout = "cow_and_lady";
  ASSERT_TRUE(ros_bag::parseTransform("0.1,-0.05,0.12,0,0,0.0998334,0.9950042", &o.T_marker_cam));
  ros_bag::writeSequenceBag(s, nullptr, dir / "cow.bag", o);
  const std::string common = " --map " + (dir / "map.gmm") +
                             " --num-particles 300 --init-half-extent 0.5 --init-yaw-half-range 0.3"
                             " --max-range 8 --quiet";
  run(std::string(GMM_MCL_REPLAY_BAG) + " " + (dir / "img.bag") + common + " --out " +
      (dir / "img"));
  int rows = 0;
  double err = lastError(dir / "img/frames.csv", &rows);
  std::printf("[ measured ] image bag: final error %.3f m over %d frames\n", err, rows);
  EXPECT_EQ(rows, n);
  EXPECT_LT(err, kReplayFinalErrorM);
  EXPECT_EQ(test::readText(dir / "img/estimate.tum").size() > 0, true);

  // Without odometry (docs/no_odometry.md): the constant-velocity model turned by the gyro's
  // heading (the bag's IMU carries the body rates with a gyro's bias and noise), every frame
  // used.
  run(std::string(GMM_MCL_REPLAY_BAG) + " " + (dir / "img.bag") + common +
      " --odometry none --out " + (dir / "none"));
  err = lastError(dir / "none/frames.csv", &rows);
  std::printf("[ measured ] image bag without odometry: final error %.3f m over %d frames\n", err,
              rows);
  EXPECT_EQ(rows, n);
  EXPECT_LT(err, kReplayFinalErrorM);

  run(std::string(GMM_MCL_REPLAY_BAG) + " " + (dir / "cow.bag") + common +
      " --cow-and-lady --marker-to-camera 0.1,-0.05,0.12,0,0,0.0998334,0.9950042 --out " +
      (dir / "cow"));
  err = lastError(dir / "cow/frames.csv", &rows);
  std::printf("[ measured ] cow_and_lady bag: final error %.3f m over %d frames\n", err, rows);
  EXPECT_EQ(rows, n);
  EXPECT_LT(err, kReplayFinalErrorM);
}

}  // namespace
}  // namespace gmm_mcl
