// Writes the built-in synthetic scene (gmm_mcl::sim) as a bag for the nodelet, the rostests and
// the demo: depth (16UC1 mm or 32FC1 m) + CameraInfo, IMU attitude, drifting odometry (as
// nav_msgs/Odometry and as tf odom -> base_link), the static base -> camera tf, ground truth,
// plus the map file and a parameter file with the initial region around the true start. --rig:
// the camera rig's corridor instead (docs/multi_camera.md), a forward camera on /camera/depth/*
// and a downward one on /down/depth/*, the initial region anywhere along 8 m of the corridor.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/time.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros_tools/bag_writer.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace {

const char* kUsage =
    "usage: gmm_mcl_make_sim_bag --bag FILE [--map FILE] [--params FILE] [--frames N]\n"
    "                            [--width PX] [--seed S] [--encoding 16UC1|32FC1]\n"
    "                            [--start-time S] [--init-half-extent M]\n"
    "                            [--init-yaw-half-range RAD] [--compressed] [--cloud]\n"
    "                            [--save-mesh FILE.ply] [--rig] [--quiet]\n"
    "Topics: /camera/depth/image_raw, /camera/depth/camera_info, /imu/data, /odom, /tf,\n"
    "/tf_static, /ground_truth (base pose in map); --rig: the corridor with a downward camera\n"
    "on /down/depth/image_raw, /down/depth/camera_info too; --compressed adds\n"
    "/camera/depth/image_raw/compressedDepth, --cloud /camera/depth/points (organized).\n"
    "Frames map, odom, base_link,\n"
    "camera_depth_optical_frame; 30 Hz.\n";

struct Options {
  int frames = 240, width_px = 320;
  uint64_t seed = 1;
  double start_s = 1000.0, init_half_extent_m = 0.5, init_yaw_half_range_rad = 0.3;
  std::string bag_path, map_path, params_path, encoding = "16UC1";
  std::string mesh_path;  // the scene as a triangle mesh (a map given as a mesh: cloud_map.test)
  bool quiet = false, compressed = false, cloud = false, rig = false;
};

// The command line, checked: a usage error exits with status 2.
Options parseOptions(int argc, char** argv) {
  Options o;
  cli::CommandLine cl("gmm_mcl_make_sim_bag", kUsage);
  // clang-format off
  cl.flags({{"bag", &o.bag_path}, {"map", &o.map_path}, {"params", &o.params_path},
            {"frames", &o.frames}, {"width", &o.width_px}, {"seed", &o.seed},
            {"encoding", &o.encoding}, {"start-time", &o.start_s},
            {"init-half-extent", &o.init_half_extent_m},
            {"init-yaw-half-range", &o.init_yaw_half_range_rad}, {"quiet", &o.quiet},
            {"compressed", &o.compressed}, {"cloud", &o.cloud}, {"save-mesh", &o.mesh_path},
            {"rig", &o.rig}});
  // clang-format on
  cl.parse(argc, argv);
  if (o.bag_path.empty()) cl.fail("--bag is needed");
  if (o.frames < 2 || o.width_px < 64 || (o.encoding != "16UC1" && o.encoding != "32FC1")) {
    cl.fail("--frames >= 2, --width >= 64, --encoding 16UC1 or 32FC1");
  }
  if (o.params_path.empty()) {
    o.params_path = o.bag_path.substr(0, o.bag_path.rfind('.')) + "_init.yaml";
  }
  if (o.map_path.empty()) o.map_path = o.bag_path.substr(0, o.bag_path.rfind('.')) + ".gmm";
  return o;
}

// The latched base -> camera transform on /tf_static, as a static broadcaster's would be:
// rosbag play republishes it latched.
void writeStaticTransform(rosbag::Bag* bag, const ros::Time& t0,
                          const Eigen::Isometry3d& T_base_cam, const std::string& cam_frame) {
  tf2_msgs::TFMessage st;
  geometry_msgs::TransformStamped t;
  t.header.stamp = t0;
  t.header.frame_id = "base_link";
  t.child_frame_id = cam_frame;
  t.transform = ros_conv::transformFromIsometry(T_base_cam);
  st.transforms.push_back(t);
  auto header = boost::make_shared<ros::M_string>();
  (*header)["latching"] = "1";
  (*header)["callerid"] = "/make_sim_bag";
  (*header)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
  (*header)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
  (*header)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();
  bag->write("/tf_static", t0, st, header);
}

// The IMU attitude (truth plus noise from rng), the odometry (Odometry and tf) 2 ms before the
// frame's stamp t (g: the bag's one normal distribution, whose cached draws keep the sequence).
void writeImuAndOdometry(rosbag::Bag* bag, const ros::Time& t, const Eigen::Isometry3d& truth,
                         const Eigen::Isometry3d& odom, double att_sigma, std::mt19937_64* rng,
                         std::normal_distribution<double>* g) {
  const ros::Time t_before = t - ros::Duration(0.002);
  double roll, pitch, yaw;
  rpyFromRotation(truth.linear(), &roll, &pitch, &yaw);
  sensor_msgs::Imu imu;
  imu.header.stamp = t;
  imu.header.frame_id = "base_link";
  const Eigen::Quaterniond q(
      rotationFromRpy(roll + att_sigma * (*g)(*rng), pitch + att_sigma * (*g)(*rng), yaw));
  imu.orientation.w = q.w();
  imu.orientation.x = q.x();
  imu.orientation.y = q.y();
  imu.orientation.z = q.z();
  imu.orientation_covariance[0] = imu.orientation_covariance[4] = att_sigma * att_sigma;
  imu.orientation_covariance[8] = 1.0;
  bag->write("/imu/data", t_before, imu);

  nav_msgs::Odometry od;
  od.header.stamp = t;
  od.header.frame_id = "odom";
  od.child_frame_id = "base_link";
  od.pose.pose = ros_conv::poseFromIsometry(odom);
  bag->write("/odom", t_before, od);
  tf2_msgs::TFMessage tf;
  geometry_msgs::TransformStamped ts;
  ts.header = od.header;
  ts.child_frame_id = "base_link";
  ts.transform = ros_conv::transformFromIsometry(odom);
  tf.transforms.push_back(ts);
  bag->write("/tf", t_before, tf);
}

// The depth image, its CameraInfo, optionally the organized cloud and the compressedDepth
// image; false (said on stderr) when compressedDepth cannot encode it.
bool writeDepth(rosbag::Bag* bag, const ros::Time& t, const DepthImage& depth, const Intrinsics& K,
                const std::string& cam_frame, const Options& o,
                const std::string& ns = "/camera/depth") {
  const sensor_msgs::Image img = ros_bag::imageFromDepth(depth, t, cam_frame);
  bag->write(ns + "/image_raw", t, img);
  bag->write(ns + "/camera_info", t, ros_conv::cameraInfoFromIntrinsics(K, t, cam_frame));
  if (o.cloud) {
    bag->write(ns + "/points", t, ros_bag::organizedCloudFromDepth(depth, K, t, cam_frame));
  }
  if (o.compressed) {
    sensor_msgs::CompressedImage c;
    std::string why;
    if (!ros_conv::compressedDepthFromImage(depth, &c, &why)) {
      std::fprintf(stderr, "compressedDepth: %s\n", why.c_str());
      return false;
    }
    c.header = img.header;
    bag->write(ns + "/image_raw/compressedDepth", t, c);
  }
  return true;
}

// The rig's parameters: the corridor's initial region (anywhere along 8 m of it) and the
// forward camera's 3 m range (it sees only the blank walls); the downward camera is the
// launch's to add (more_cameras), so that the same bag runs with the forward camera alone.
void writeRigYaml(const std::string& path, const std::string& bag_path) {
  std::ofstream y(path);
  y << "# The camera rig's corridor of " << bag_path
    << " (gmm_mcl_make_sim_bag --rig, docs/multi_camera.md)\n"
    << "init_centre: [13.0, 1.0, 1.5]\n"
    << "init_half_extent: [4.0, 0.3, 0.05]\n"
    << "init_yaw_centre: 0.0\n"
    << "init_yaw_half_range: 0.3\n"
    << "max_range_m: 3.0\n"
    << "# The downward camera: more_cameras: [down] (replay.launch more_cameras:=[down]\n"
    << "# second_camera:=down), its images on /down/depth/image_raw.\n";
  if (!y) throw std::runtime_error(path + ": cannot write");
}

int run(int argc, char** argv) {
  const Options o = parseOptions(argc, argv);
  const sim::BoxScene scene = o.rig ? sim::makeCorridorScene() : sim::makeDefaultScene();
  const GmmMap map = sim::tileScene(scene, o.rig ? 0.25 : 0.4, 0.015);
  saveMap(map, o.map_path);
  if (!o.mesh_path.empty()) {
    sim::PrimitiveScene boxes;
    boxes.room = scene.room;
    boxes.boxes = scene.blocks;
    sim::savePlyMesh(sim::meshFromScene(boxes), o.mesh_path);
  }
  const std::vector<Eigen::Isometry3d> truth =
      o.rig ? sim::corridorTrajectory(o.frames) : sim::makeTrajectory(o.frames);
  const Eigen::Isometry3d T_base_cam =
      o.rig ? sim::corridorForwardCamera() : sim::defaultBaseToCamera();
  const Intrinsics K = sim::defaultCamera(o.width_px);

  const Particle start = poseToParticle(truth[0]);
  try {
    if (o.rig) {
      writeRigYaml(o.params_path, o.bag_path);
    } else {
      ros_bag::writeInitRegionYaml(
          o.params_path,
          "Initial region around the true start of " + o.bag_path + " (gmm_mcl_make_sim_bag)",
          start, o.init_half_extent_m, o.init_yaw_half_range_rad);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }

  rosbag::Bag bag;
  try {
    bag.open(o.bag_path, rosbag::bagmode::Write);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cannot write %s: %s\n", o.bag_path.c_str(), e.what());
    return 1;
  }
  const std::string cam_frame = "camera_depth_optical_frame";
  const ros::Time t0(o.start_s);
  writeStaticTransform(&bag, t0, T_base_cam, cam_frame);
  const std::string down_frame = "down_depth_optical_frame";
  if (o.rig) writeStaticTransform(&bag, t0, sim::corridorDownCamera(), down_frame);

  std::mt19937_64 rng(o.seed + 1000);
  std::normal_distribution<double> g(0.0, 1.0);
  const sim::DepthNoise noise{0.0015, 0.02};
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  const double att_sigma = 0.5 * M_PI / 180.0;
  const DepthEncoding enc =
      o.encoding == "16UC1" ? DepthEncoding::kMono16Millimetres : DepthEncoding::kFloat32Metres;
  for (int f = 0; f < o.frames; ++f) {
    if (f > 0) {
      Eigen::Isometry3d delta = truth[f - 1].inverse() * truth[f];
      delta.translation() += 0.005 * Eigen::Vector3d(g(rng), g(rng), g(rng));
      delta.linear() =
          delta.linear() *
          Eigen::AngleAxisd(0.002 * g(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      odom = odom * delta;
    }
    const ros::Time t = t0 + ros::Duration(f / 30.0);
    writeImuAndOdometry(&bag, t, truth[f], odom, att_sigma, &rng, &g);
    const DepthImage depth =
        sim::renderDepth(scene, K, truth[f] * T_base_cam, enc, 8.0, noise, &rng);
    if (!writeDepth(&bag, t, depth, K, cam_frame, o)) return 1;
    if (o.rig) {
      const DepthImage down =
          sim::renderDepth(scene, K, truth[f] * sim::corridorDownCamera(), enc, 8.0, noise, &rng);
      if (!writeDepth(&bag, t, down, K, down_frame, o, "/down/depth")) return 1;
    }

    geometry_msgs::PoseStamped gt;
    gt.header.stamp = t;
    gt.header.frame_id = "map";
    gt.pose = ros_conv::poseFromIsometry(truth[f]);
    bag.write("/ground_truth", t, gt);
    if (!o.quiet && f % 30 == 0) std::printf("frame %d / %d\n", f, o.frames);
  }
  bag.close();
  std::printf("wrote %s (%d frames %dx%d %s, %.1f s), map %s (%zu components), params %s\n",
              o.bag_path.c_str(), o.frames, K.width_px, K.height_px, o.encoding.c_str(),
              o.frames / 30.0, o.map_path.c_str(), map.size(), o.params_path.c_str());
  return 0;
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
