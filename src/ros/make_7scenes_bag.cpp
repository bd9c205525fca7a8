// Converts a 7-Scenes sequence into a bag for the nodelet (DESIGN.md accuracy protocol): depth
// PNGs as 16UC1 + CameraInfo, IMU roll/pitch = truth + N(0, 0.5 deg), odometry = truth motion
// plus drifting noise (0.005 m, 0.002 rad per frame) as /odom and tf odom -> base_link, the
// static base_link -> camera tf, /ground_truth; the map rotated into the gravity-aligned frame;
// and a parameter file with the initial region around the true start.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/replay/seven_scenes_sequence.h"
#include "gmm_mcl/ros/conversions.h"

using namespace gmm_mcl;

int main(int argc, char** argv) {
  std::string data_dir, map_in, bag_path;
  int frames = -1;
  uint64_t seed = 1;
  double start_s = 1000.0, init_half_extent_m = 2.0, init_yaw_half_range_rad = 0.5 * M_PI;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "missing value after %s\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--map") map_in = next();
    else if (a == "--bag") bag_path = next();
    else if (a == "--frames") frames = std::atoi(next());
    else if (a == "--seed") seed = std::strtoull(next(), nullptr, 10);
    else if (a == "--init-half-extent") init_half_extent_m = std::atof(next());
    else if (a == "--init-yaw-half-range") init_yaw_half_range_rad = std::atof(next());
    else if (a[0] != '-' && data_dir.empty()) data_dir = a;
    else {
      std::printf(
          "usage: make_7scenes_bag DATA_DIR --map WORLD_MAP.gmm --bag OUT.bag [--frames N] [--seed S]\n"
          "                        [--init-half-extent M (2)] [--init-yaw-half-range RAD (pi/2)]\n"
          "Writes OUT.bag, OUT.gmm (the map in the gravity-aligned frame) and OUT_init.yaml.\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (data_dir.empty() || map_in.empty() || bag_path.empty()) {
    std::fprintf(stderr, "need DATA_DIR, --map and --bag (see --help)\n");
    return 2;
  }
  const std::string stem = bag_path.substr(0, bag_path.rfind('.'));
  try {
    const SevenScenesSequence seq(data_dir, frames);
    const GmmMap map = rotateMap(loadMap(map_in), seq.R_aligned_world(), map_in + " (gravity-aligned)");
    saveMap(map, stem + ".gmm");
    const Eigen::Isometry3d T_base_cam = opticalToBase();
    Eigen::Isometry3d T_aligned_world = Eigen::Isometry3d::Identity();
    T_aligned_world.linear() = seq.R_aligned_world();
    const int n = seq.size();
    std::vector<Eigen::Isometry3d> truth(n);
    for (int f = 0; f < n; ++f) truth[f] = T_aligned_world * seq.T_world_cam(f) * T_base_cam.inverse();
    const Particle start = poseToParticle(truth[0]);
    {
      std::ofstream y(stem + "_init.yaml");
      y << "# Initial region around the true start of " << bag_path << " (paper: 4 m cube, pi yaw)\n"
        << "init_centre: [" << start.x_m << ", " << start.y_m << ", " << start.z_m << "]\n"
        << "init_half_extent: [" << init_half_extent_m << ", " << init_half_extent_m << ", "
        << init_half_extent_m << "]\n"
        << "init_yaw_centre: " << start.yaw_rad << "\n"
        << "init_yaw_half_range: " << init_yaw_half_range_rad << "\n";
    }
    rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
    const std::string cam_frame = "camera_depth_optical_frame";
    const ros::Time t0(start_s);
    {
      tf2_msgs::TFMessage st;
      geometry_msgs::TransformStamped t;
      t.header.stamp = t0;
      t.header.frame_id = "base_link";
      t.child_frame_id = cam_frame;
      t.transform = ros_conv::transformFromIsometry(T_base_cam);
      st.transforms.push_back(t);
      auto header = boost::make_shared<ros::M_string>();
      (*header)["latching"] = "1";
      (*header)["callerid"] = "/make_7scenes_bag";
      (*header)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
      (*header)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
      (*header)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();
      bag.write("/tf_static", t0, st, header);
    }
    std::mt19937_64 rng(seed * 7919 + 17);
    std::normal_distribution<double> g(0.0, 1.0);
    const double att_sigma = 0.5 * M_PI / 180.0;
    const Intrinsics& K = seq.intrinsics();
    Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
    for (int f = 0; f < n; ++f) {
      if (f > 0) {
        Eigen::Isometry3d delta = truth[f - 1].inverse() * truth[f];
        delta.translation() += 0.005 * Eigen::Vector3d(g(rng), g(rng), g(rng));
        delta.linear() = delta.linear() *
                         Eigen::AngleAxisd(0.002 * g(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
        odom = odom * delta;
      }
      const ros::Time t = t0 + ros::Duration(f / seq.frameRateHz());
      const ros::Time t_before = t - ros::Duration(0.002);
      double roll, pitch, yaw;
      rpyFromRotation(truth[f].linear(), &roll, &pitch, &yaw);
      sensor_msgs::Imu imu;
      imu.header.stamp = t;
      imu.header.frame_id = "base_link";
      const Eigen::Quaterniond q(rotationFromRpy(roll + att_sigma * g(rng), pitch + att_sigma * g(rng), yaw));
      imu.orientation.w = q.w();
      imu.orientation.x = q.x();
      imu.orientation.y = q.y();
      imu.orientation.z = q.z();
      bag.write("/imu/data", t_before, imu);
      nav_msgs::Odometry od;
      od.header.stamp = t;
      od.header.frame_id = "odom";
      od.child_frame_id = "base_link";
      od.pose.pose = ros_conv::poseFromIsometry(odom);
      bag.write("/odom", t_before, od);
      tf2_msgs::TFMessage tf;
      geometry_msgs::TransformStamped ts;
      ts.header = od.header;
      ts.child_frame_id = "base_link";
      ts.transform = ros_conv::transformFromIsometry(odom);
      tf.transforms.push_back(ts);
      bag.write("/tf", t_before, tf);

      const DepthImage depth = seq.loadDepth(f);
      sensor_msgs::Image img;
      img.header.stamp = t;
      img.header.frame_id = cam_frame;
      img.width = depth.width_px;
      img.height = depth.height_px;
      img.encoding = depth.encoding == DepthEncoding::kMono16Millimetres ? "16UC1" : "32FC1";
      img.step = static_cast<uint32_t>(depth.row_bytes);
      img.data = depth.data;
      sensor_msgs::CameraInfo info;
      info.header = img.header;
      info.width = K.width_px;
      info.height = K.height_px;
      info.distortion_model = "plumb_bob";
      info.D.assign(5, 0.0);
      info.K = {K.fx_px, 0, K.cx_px, 0, K.fy_px, K.cy_px, 0, 0, 1};
      info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
      info.P = {K.fx_px, 0, K.cx_px, 0, 0, K.fy_px, K.cy_px, 0, 0, 0, 1, 0};
      bag.write("/camera/depth/image_raw", t, img);
      bag.write("/camera/depth/camera_info", t, info);
      geometry_msgs::PoseStamped gt;
      gt.header.stamp = t;
      gt.header.frame_id = "map";
      gt.pose = ros_conv::poseFromIsometry(truth[f]);
      bag.write("/ground_truth", t, gt);
    }
    bag.close();
    std::printf("wrote %s (%d frames, %.1f s), %s.gmm (%zu components, gravity-aligned), %s_init.yaml\n",
                bag_path.c_str(), n, n / seq.frameRateHz(), stem.c_str(), map.size(), stem.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_7scenes_bag: %s\n", e.what());
    return 1;
  }
  return 0;
}
