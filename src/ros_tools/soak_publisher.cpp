// Soak-test input for the localization nodelet: renders a few hundred frames of the
// built-in box scene once, then publishes them over and over, ping-pong (forward, then
// backward, so that the motion stays continuous), with stamps that keep increasing by a fixed
// period: depth 16UC1 + CameraInfo, IMU attitude, tf odom -> base_link (the nodelet's default
// odometry source), the static base_link -> camera tf and /ground_truth.
//
// Lockstep: frame k+1 is published when the nodelet's ~status for frame k has arrived (matched
// by stamp), or after --timeout seconds without it; such a frame is counted as timed out, not
// waited for. The stamps advance by --period whatever the wall time, so consecutive map -> odom
// stamps must differ by exactly one period when no frame is lost.
//
// Counts on /soak/sent (std_msgs/UInt64, latched) after every frame and /soak/timeouts; when
// all frames are sent, /soak/done (latched) carries the total, then the node lingers briefly.
//
// --write-map FILE [--write-params FILE]: writes the scene's map and an initial-region parameter
// file around the true start instead (no ROS master needed), for the nodelet's configuration.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/UInt64.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros_tools/bag_writer.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {

namespace {

constexpr char kCameraFrame[] = "camera_depth_optical_frame";

struct Options {
  long long frames = 50000;       // frames to send
  int render_frames = 300;        // distinct frames rendered (10 s of the trajectory at 30 Hz)
  int width_px = 160;             // height 3/4 of it
  double period_s = 1.0 / 30.0;   // stamp step
  double timeout_s = 2.0;         // lockstep: wait at most this long for a frame's ~status
  double first_timeout_s = 60.0;  // the first frame builds the localizer
  double linger_s = 5.0;          // stay up after /soak/done so that the monitor reads it
  uint64_t seed = 7;
  bool wait_for_monitor = true;  // start only once something listens to /soak/done
  std::string status_topic = "/gmm_mcl/status";
  std::string write_map, write_params;
  double init_half_extent_m = 0.3, init_yaw_half_range_rad = 0.2;
};

// Parses the command line into *o (exits with status 2 on a malformed one).
void parse(int argc, char** argv, Options* o) {
  const std::string usage =
      std::string(
          "usage: gmm_mcl_soak_publisher [--frames N] [--render-frames F] [--width PX] [--period "
          "S]\n"
          "                              [--timeout S] [--first-timeout S] [--linger S] [--seed "
          "S]\n"
          "                              [--status-topic T] [--no-wait-for-monitor]\n"
          "       gmm_mcl_soak_publisher --write-map FILE.gmm [--write-params FILE.yaml]\n"
          "                              [--init-half-extent M] [--init-yaw-half-range RAD]\n"
          "Publishes /camera/depth/image_raw + camera_info, /imu/data, tf odom -> base_link,\n"
          "/tf_static base_link -> ") +
      kCameraFrame + ", /ground_truth; /soak/sent, /soak/timeouts, /soak/done.\n";
  cli::CommandLine cl("gmm_mcl_soak_publisher", usage);
  // clang-format off
  cl.flags({{"frames", &o->frames}, {"render-frames", &o->render_frames}, {"width", &o->width_px},
           {"period", &o->period_s}, {"timeout", &o->timeout_s},
           {"first-timeout", &o->first_timeout_s}, {"linger", &o->linger_s}, {"seed", &o->seed},
           {"status-topic", &o->status_topic},
           {"no-wait-for-monitor", cli::Clear{&o->wait_for_monitor}}, {"write-map", &o->write_map},
           {"write-params", &o->write_params}, {"init-half-extent", &o->init_half_extent_m},
           {"init-yaw-half-range", &o->init_yaw_half_range_rad}});
  // clang-format on
  cl.parse(argc, argv);
  if (!(o->frames >= 1 && o->render_frames >= 2 && o->width_px >= 64 && o->period_s > 0.0 &&
        o->timeout_s > 0.0 && o->first_timeout_s > 0.0 && o->linger_s >= 0.0)) {
    cl.fail(
        "--frames >= 1, --render-frames >= 2, --width >= 64, --period, --timeout and "
        "--first-timeout > 0, --linger >= 0");
  }
}

// The fixed map -> odom offset that the published odometry carries (the nodelet must find it).
Eigen::Isometry3d mapToOdom() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRpy(0.0, 0.0, 0.15);
  T.translation() = Eigen::Vector3d(0.4, -0.3, 0.0);
  return T;
}

int writeMapAndParams(const Options& o) {
  const sim::BoxScene scene = sim::makeDefaultScene();
  saveMap(sim::tileScene(scene, 0.4, 0.015), o.write_map);
  if (o.write_params.empty()) return 0;
  const Particle start = poseToParticle(sim::makeTrajectory(2)[0]);
  try {
    ros_bag::writeInitRegionYaml(
        o.write_params,
        "Initial region around the soak trajectory's true start (gmm_mcl_soak_publisher)", start,
        o.init_half_extent_m, o.init_yaw_half_range_rad);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}

// One rendered frame, kept as the messages' payload.
struct Frame {
  Eigen::Isometry3d T_map_base;
  std::vector<uint8_t> depth;  // 16UC1 millimetres
  uint32_t step_bytes = 0;
};

class SoakPublisher {
 public:
  explicit SoakPublisher(const Options& o) : o_(o), K_(sim::defaultCamera(o.width_px)) {
    image_pub_ = nh_.advertise<sensor_msgs::Image>("/camera/depth/image_raw", 2);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("/camera/depth/camera_info", 2);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>("/imu/data", 10);
    truth_pub_ = nh_.advertise<geometry_msgs::PoseStamped>("/ground_truth", 10);
    sent_pub_ = nh_.advertise<std_msgs::UInt64>("/soak/sent", 1, true);
    timeouts_pub_ = nh_.advertise<std_msgs::UInt64>("/soak/timeouts", 1, true);
    done_pub_ = nh_.advertise<std_msgs::UInt64>("/soak/done", 1, true);
    status_sub_ = nh_.subscribe(o_.status_topic, 10, &SoakPublisher::status, this);
  }

  void render() {
    const ros::WallTime t0 = ros::WallTime::now();
    const sim::BoxScene scene = sim::makeDefaultScene();
    const std::vector<Eigen::Isometry3d> truth = sim::makeTrajectory(o_.render_frames);
    const Eigen::Isometry3d T_base_cam = sim::defaultBaseToCamera();
    std::mt19937_64 rng(o_.seed);
    const sim::DepthNoise noise{0.0015, 0.02};
    frames_.resize(truth.size());
    for (size_t f = 0; f < truth.size(); ++f) {
      const DepthImage d = sim::renderDepth(scene, K_, truth[f] * T_base_cam,
                                            DepthEncoding::kMono16Millimetres, 8.0, noise, &rng);
      frames_[f].T_map_base = truth[f];
      frames_[f].depth = d.data;
      frames_[f].step_bytes = static_cast<uint32_t>(d.row_bytes);
    }
    std::printf("soak_publisher: rendered %zu frames %dx%d in %.2f s\n", frames_.size(),
                K_.width_px, K_.height_px, (ros::WallTime::now() - t0).toSec());
    std::fflush(stdout);
  }

  // Waits until the nodelet listens to the depth image and CameraInfo and publishes ~status,
  // and the monitor listens.
  bool waitForNodelet(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::ok() && ros::WallTime::now() < end) {
      ros::spinOnce();
      // The monitor subscribes to /soak/done after its other topics.
      if (image_pub_.getNumSubscribers() > 0 && info_pub_.getNumSubscribers() > 0 &&
          imu_pub_.getNumSubscribers() > 0 && status_sub_.getNumPublishers() > 0 &&
          (!o_.wait_for_monitor || done_pub_.getNumSubscribers() > 0)) {
        ros::WallDuration(1.0).sleep();  // let every connection finish its handshake
        return true;
      }
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }

  int run() {
    geometry_msgs::TransformStamped st;
    st.header.stamp = ros::Time::now();
    st.header.frame_id = "base_link";
    st.child_frame_id = kCameraFrame;
    st.transform = ros_conv::transformFromIsometry(sim::defaultBaseToCamera());
    static_tf_.sendTransform(st);

    if (!waitForNodelet(120.0)) {
      std::fprintf(stderr,
                   "soak_publisher: the nodelet (or the monitor) did not subscribe within 120 s\n");
      return 1;
    }
    t0_ = ros::Time::now();
    sendOdometry(0);
    const ros::WallTime start = ros::WallTime::now();
    ros::WallTime last_report = start;
    long long last_report_sent = 0;
    for (long long k = 0; k < o_.frames && ros::ok(); ++k) {
      sendOdometry(k + 1);  // one frame ahead: the nodelet's tf lookup at t_k never waits
      sendFrame(k);
      ++sent_;
      std_msgs::UInt64 n;
      n.data = static_cast<uint64_t>(sent_);
      sent_pub_.publish(n);
      if (!waitForStatus(stampOf(k), k == 0 ? o_.first_timeout_s : o_.timeout_s)) {
        ++timeouts_;
        n.data = static_cast<uint64_t>(timeouts_);
        timeouts_pub_.publish(n);
        ROS_WARN("soak_publisher: no ~status for frame %lld within the timeout", k);
      }
      const ros::WallTime now = ros::WallTime::now();
      if ((now - last_report).toSec() >= 30.0) {
        std::printf("soak_publisher: %lld / %lld frames sent, %.1f frames/s, %lld timeouts\n",
                    sent_, o_.frames, (sent_ - last_report_sent) / (now - last_report).toSec(),
                    timeouts_);
        std::fflush(stdout);
        last_report = now;
        last_report_sent = sent_;
      }
    }
    const double wall_s = (ros::WallTime::now() - start).toSec();
    std_msgs::UInt64 done;
    done.data = static_cast<uint64_t>(sent_);
    done_pub_.publish(done);
    std::printf(
        "soak_publisher: sent %lld frames in %.1f s (%.1f frames/s), %lld lockstep "
        "timeouts\n",
        sent_, wall_s, sent_ / std::max(wall_s, 1e-9), timeouts_);
    std::fflush(stdout);
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(o_.linger_s);
    while (ros::ok() && ros::WallTime::now() < end) {
      ros::spinOnce();
      ros::WallDuration(0.05).sleep();
    }
    return sent_ == o_.frames ? 0 : 1;
  }

 private:
  ros::Time stampOf(long long k) const {
    return t0_ + ros::Duration(o_.period_s * static_cast<double>(k));
  }

  // Ping-pong over the rendered frames: 0, 1, ..., F-1, F-2, ..., 1, 0, 1, ...
  const Frame& frameOf(long long k) const {
    const long long F = static_cast<long long>(frames_.size());
    const long long i = k % (2 * F - 2);
    return frames_[static_cast<size_t>(i < F ? i : 2 * F - 2 - i)];
  }

  void sendOdometry(long long k) {
    geometry_msgs::TransformStamped t;
    t.header.stamp = stampOf(k);
    t.header.frame_id = "odom";
    t.child_frame_id = "base_link";
    t.transform = ros_conv::transformFromIsometry(mapToOdom().inverse() * frameOf(k).T_map_base);
    tf_.sendTransform(t);
  }

  void sendFrame(long long k) {
    const Frame& f = frameOf(k);
    const ros::Time stamp = stampOf(k);
    double roll, pitch, yaw;
    rpyFromRotation(f.T_map_base.linear(), &roll, &pitch, &yaw);
    imu_pub_.publish(ros_conv::imuFromAttitude(stamp, "base_link", roll, pitch, yaw, 1e-4, false));

    geometry_msgs::PoseStamped gt;
    gt.header.stamp = stamp;
    gt.header.frame_id = "map";
    gt.pose = ros_conv::poseFromIsometry(f.T_map_base);
    truth_pub_.publish(gt);

    sensor_msgs::CameraInfo info = ros_conv::cameraInfoFromIntrinsics(K_, stamp, kCameraFrame);
    info.header.seq = static_cast<uint32_t>(k);
    sensor_msgs::Image img;
    img.header = info.header;
    img.width = info.width;
    img.height = info.height;
    img.encoding = "16UC1";
    img.is_bigendian = 0;
    img.step = f.step_bytes;
    img.data = f.depth;
    info_pub_.publish(info);
    image_pub_.publish(img);
  }

  void status(const FilterStatusConstPtr& s) { last_status_stamp_ = s->header.stamp; }

  bool waitForStatus(const ros::Time& stamp, double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    ros::CallbackQueue* queue = ros::getGlobalCallbackQueue();
    while (ros::ok()) {
      if (last_status_stamp_ == stamp) return true;
      const double left_s = (end - ros::WallTime::now()).toSec();
      if (left_s <= 0.0) return false;
      // Blocks until a callback is ready (no busy wait on a shared machine).
      queue->callAvailable(ros::WallDuration(std::min(left_s, 0.05)));
    }
    return false;
  }

  Options o_;
  Intrinsics K_;
  ros::NodeHandle nh_;
  ros::Publisher image_pub_, info_pub_, imu_pub_, truth_pub_, sent_pub_, timeouts_pub_, done_pub_;
  ros::Subscriber status_sub_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  std::vector<Frame> frames_;
  ros::Time t0_, last_status_stamp_;
  long long sent_ = 0, timeouts_ = 0;
};

}  // namespace

int run(int argc, char** argv) {
  ros::init(argc, argv, "soak_publisher");  // strips remappings and __name before parsing
  Options o;
  parse(argc, argv, &o);
  if (!o.write_map.empty()) return writeMapAndParams(o);
  SoakPublisher pub(o);
  pub.render();
  return pub.run();
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
