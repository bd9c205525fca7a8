// Deterministic rostests: the test owns /clock (the launch sets use_sim_time) and feeds the
// nodelet one depth frame at a time, waiting for the nodelet's own output for that frame (its
// ~status) before the next; diagnostics are awaited by moving the clock past their period. Wall
// time only bounds how long a wait for something that never comes lasts (a failure), so a
// loaded machine makes the tests slower, not different.
#pragma once

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <topic_tools/shape_shifter.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gmm_mcl/FilterStatus.h"

namespace gmm_mcl {
namespace lockstep {

// Limit of a wait for an output that should come (a failure when reached), wall seconds.
constexpr double kWaitLimitS = 120.0;

// On the first failed wait for the nodelet's output: every thread's stack of the nodelet
// managers on this machine (gdb, when installed), into the test's output, so that a hang shows
// where it hangs.
inline void dumpManagerStacks() {
  static bool done = false;
  if (done) return;
  done = true;
  std::fflush(stdout);
  const int rc = std::system(
      "command -v gdb >/dev/null || { echo 'no gdb: no stacks'; exit 0; }; "
      "for p in $(pgrep -f '^[^ ]*nodelet manager'); do echo \"== stacks of $(cat /proc/$p/cmdline "
      "| "
      "tr '\\0' ' ')\"; timeout 60 gdb -batch -nx -ex 'thread apply all bt' -p $p 2>&1 | "
      "grep -v '^\\[New LWP'; done");
  (void)rc;
}

inline bool waitFor(const std::function<bool()>& done, double limit_s = kWaitLimitS) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(limit_s);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (done()) return true;
    ros::WallDuration(0.002).sleep();
  }
  ros::spinOnce();
  return done();
}

// Nodes per topic as the master lists them: publishers (kPublishers) or subscribers.
enum class Side { kPublishers = 0, kSubscribers = 1 };
inline bool nodesOnMaster(Side side, std::map<std::string, int>* count) {
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", request, response, payload, false)) return false;
  if (payload.getType() != XmlRpc::XmlRpcValue::TypeArray || payload.size() < 2) return false;
  XmlRpc::XmlRpcValue& topics = payload[static_cast<int>(side)];
  for (int i = 0; i < topics.size(); ++i) {
    (*count)[static_cast<std::string>(topics[i][0])] = topics[i][1].size();
  }
  return true;
}
// Registering is not connecting: a message published before the connection is made is lost
// (a loaded machine), and a wait for what it causes fails. These hold once every node the
// master lists on the other side of the topic is connected (this one included).
inline bool connectedToAll(const ros::Publisher& pub) {
  std::map<std::string, int> listed;
  return nodesOnMaster(Side::kSubscribers, &listed) && listed[pub.getTopic()] > 0 &&
         static_cast<int>(pub.getNumSubscribers()) >= listed[pub.getTopic()];
}
inline bool connectedToAll(const ros::Subscriber& sub) {
  std::map<std::string, int> listed;
  return nodesOnMaster(Side::kPublishers, &listed) && listed[sub.getTopic()] > 0 &&
         static_cast<int>(sub.getNumPublishers()) >= listed[sub.getTopic()];
}

// The simulated clock, driven by the test.
class Clock {
 public:
  explicit Clock(ros::NodeHandle& nh) : pub_(nh.advertise<rosgraph_msgs::Clock>("/clock", 10)) {}
  void set(const ros::Time& t) {
    now_ = t;
    rosgraph_msgs::Clock c;
    c.clock = t;
    pub_.publish(c);
  }
  // Only forward (a frame stamp earlier than the clock leaves it).
  void advanceTo(const ros::Time& t) {
    if (t > now_) set(t);
  }
  const ros::Time& now() const { return now_; }
  bool connected() const { return connectedToAll(pub_); }

 private:
  ros::Publisher pub_;
  ros::Time now_;
};

struct Diag {
  std::string name;
  int level = 0;
  std::string message;
  std::map<std::string, std::string> values;
  long long number(const std::string& key) const {
    const auto it = values.find(key);
    return it == values.end() ? -1 : std::atoll(it->second.c_str());
  }
};

// Everything the nodelet outputs, kept in arrival order.
class Observer {
 public:
  explicit Observer(ros::NodeHandle& nh, const std::string& ns = "/gmm_mcl") : nh_(nh), ns_(ns) {
    subs_.push_back(nh.subscribe(ns + "/status", 1000, &Observer::onStatus, this));
    subs_.push_back(nh.subscribe(ns + "/pose", 1000, &Observer::onPose, this));
    subs_.push_back(nh.subscribe("/diagnostics", 1000, &Observer::onDiag, this));
    subs_.push_back(nh.subscribe("/tf", 1000, &Observer::onTf, this));
  }
  // Waits until the nodelet's ~status, ~pose and /diagnostics are connected to this observer:
  // one ~status lost before that fails the wait for it (seen once in CI, a loaded machine).
  bool waitConnected() {
    return waitFor([&] {
      for (size_t i = 0; i < 3; ++i) {
        if (!connectedToAll(subs_[i])) return false;
      }
      return true;
    });
  }
  void onStatus(const FilterStatusConstPtr& m) { statuses.push_back(*m); }
  void onPose(const geometry_msgs::PoseWithCovarianceStampedConstPtr& m) { poses.push_back(*m); }
  void onTf(const tf2_msgs::TFMessageConstPtr& m) {
    for (const auto& t : m->transforms) {
      if (t.header.frame_id == "map" && t.child_frame_id == "odom")
        tf_stamps.push_back(t.header.stamp);
    }
  }
  // This nodelet's diagnostics only (named "<nodelet>: localization").
  void onDiag(const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
    for (const auto& s : m->status) {
      const bool mine = s.name == ns_.substr(1) + ": localization" ||
                        (ns_ == "/gmm_mcl" && s.name == "gmm_mcl_manager: localization");
      if (!mine) continue;
      Diag d;
      d.name = s.name;
      d.level = s.level;
      d.message = s.message;
      for (const auto& kv : s.values) d.values[kv.key] = kv.value;
      diags.push_back(d);
    }
  }
  void onMarkers(const visualization_msgs::MarkerArrayConstPtr&) { ++marker_messages; }
  void onParticles(const geometry_msgs::PoseArrayConstPtr& m) { particles.push_back(*m); }
  // Subscriptions of the outputs that are published on demand or latched, once connected.
  bool subscribeMarkers() {
    markers_sub_ = nh_.subscribe(ns_ + "/gmm_markers", 10, &Observer::onMarkers, this);
    return waitFor([&] { return markers_sub_.getNumPublishers() > 0; });
  }
  bool subscribeParticles() {
    particles_sub_ = nh_.subscribe(ns_ + "/particles", 100, &Observer::onParticles, this);
    return waitFor([&] { return particles_sub_.getNumPublishers() > 0; });
  }

  // The ~status of the frame stamped t (among those after index `since`: a looped bag repeats
  // stamps); nullptr when it does not come.
  const FilterStatus* statusAt(const ros::Time& t, double limit_s = kWaitLimitS, size_t since = 0) {
    const FilterStatus* found = nullptr;
    waitFor(
        [&] {
          for (size_t i = statuses.size(); i > since && !found; --i) {
            if (statuses[i - 1].header.stamp == t) found = &statuses[i - 1];
          }
          return found != nullptr;
        },
        limit_s);
    if (!found) dumpManagerStacks();
    return found;
  }
  const geometry_msgs::PoseWithCovarianceStamped* poseAt(const ros::Time& t, size_t since = 0) {
    const geometry_msgs::PoseWithCovarianceStamped* found = nullptr;
    waitFor([&] {
      for (size_t i = poses.size(); i > since && !found; --i) {
        if (poses[i - 1].header.stamp == t) found = &poses[i - 1];
      }
      return found != nullptr;
    });
    return found;
  }
  const geometry_msgs::PoseArray* particlesAt(const ros::Time& t) {
    const geometry_msgs::PoseArray* found = nullptr;
    waitFor([&] {
      for (auto it = particles.rbegin(); it != particles.rend() && !found; ++it) {
        if (it->header.stamp == t) found = &*it;
      }
      return found != nullptr;
    });
    return found;
  }
  // The nodelet's diagnostics that arrive after index `since` and satisfy `ok`.
  bool waitDiag(size_t since, const std::function<bool(const Diag&)>& ok, Diag* out = nullptr,
                double limit_s = kWaitLimitS) {
    return waitFor(
        [&] {
          for (size_t i = since; i < diags.size(); ++i) {
            if (ok(diags[i])) {
              if (out) *out = diags[i];
              return true;
            }
          }
          return false;
        },
        limit_s);
  }
  // Moves the clock on by `period_s` and waits for the next diagnostics message of the nodelet.
  bool tickDiagnostics(Clock* clock, double period_s, Diag* out = nullptr,
                       const std::function<bool(const Diag&)>& ok = nullptr,
                       double limit_s = kWaitLimitS) {
    const size_t since = diags.size();
    clock->set(clock->now() + ros::Duration(period_s));
    return waitDiag(
        since, ok ? ok : [](const Diag&) { return true; }, out, limit_s);
  }
  // What the nodelet said last (for a failure's message).
  std::string describe() const {
    std::string out = std::to_string(statuses.size()) + " statuses";
    if (!statuses.empty()) {
      const FilterStatus& s = statuses.back();
      out += ", the last: frames received " + std::to_string(s.frames_received) + ", processed " +
             std::to_string(s.frames_processed) + ", waiting " + std::to_string(s.frames_waiting) +
             ", dropped " +
             std::to_string(s.dropped_conversion + s.dropped_camera_info + s.dropped_extrinsics);
    }
    if (!diags.empty()) out += "; last diagnostics: " + diags.back().message;
    return out;
  }
  const Diag* lastDiag() const { return diags.empty() ? nullptr : &diags.back(); }

  std::vector<FilterStatus> statuses;
  std::vector<geometry_msgs::PoseWithCovarianceStamped> poses;
  std::vector<Diag> diags;
  std::vector<ros::Time> tf_stamps;
  std::vector<geometry_msgs::PoseArray> particles;
  int marker_messages = 0;

 private:
  ros::NodeHandle nh_;
  std::string ns_;
  std::vector<ros::Subscriber> subs_;
  ros::Subscriber markers_sub_, particles_sub_;
};

// Plays a bag in lockstep with the nodelet: every message in bag order with the clock at its
// bag time (as rosbag play --clock), and after each depth frame (the image and its CameraInfo,
// or a cloud) waits for the nodelet's ~status of that frame.
class BagPlayer {
 public:
  BagPlayer(ros::NodeHandle& nh, const std::string& path, const std::string& frame_topic,
            Clock* clock)
      : nh_(nh), clock_(clock), frame_topic_(frame_topic) {
    bag_.open(path, rosbag::bagmode::Read);
    view_.reset(new rosbag::View(bag_));
    for (const rosbag::MessageInstance& m : *view_) {
      messages_.push_back(m);
      if (m.getTopic() == frame_topic) frames_.push_back(messages_.size() - 1);
    }
    for (const rosbag::ConnectionInfo* c : view_->getConnections()) {
      if (publishers_.count(c->topic)) continue;
      ros::AdvertiseOptions opts(c->topic, 100, c->md5sum, c->datatype, c->msg_def);
      opts.latch = c->topic == "/tf_static";
      publishers_[c->topic] = nh_.advertise(opts);
    }
  }
  int frames() const { return static_cast<int>(frames_.size()); }
  // The frame's header stamp.
  ros::Time frameStamp(int i) const { return frameHeaderStamp(messages_[frames_[i]]); }
  // Waits until the nodelet listens to the frame topic and every node the master lists as
  // subscribing one of the bag's topics is connected to its publisher: /tf is not latched, so a
  // frame's odometry sent before the nodelet's tf listener connected (a loaded machine) never
  // arrives and the frame waits for it for good.
  bool waitForSubscribers() {
    return waitFor([&] {
      if (publishers_[frame_topic_].getNumSubscribers() == 0) return false;
      std::map<std::string, int> listed;
      if (!nodesOnMaster(Side::kSubscribers, &listed)) return false;
      for (auto& p : publishers_) {
        if (static_cast<int>(p.second.getNumSubscribers()) < listed[p.first]) return false;
      }
      return true;
    });
  }
  // Publishes the messages after the previous frame up to frame i, and those recorded at the
  // frame's bag time after it (its CameraInfo).
  void publishFrame(int i) {
    const size_t frame = frames_[i];
    while (next_ <= frame) publish(messages_[next_++]);
    while (next_ < messages_.size() && messages_[next_].getTopic() != frame_topic_ &&
           messages_[next_].getTime() == messages_[frame].getTime()) {
      publish(messages_[next_++]);
    }
  }
  // The bag from the start again (a loop: the clock and the stamps jump back).
  void rewind() {
    next_ = 0;
    rewound_ = true;
  }

 private:
  static ros::Time frameHeaderStamp(const rosbag::MessageInstance& m) {
    if (auto image = m.instantiate<sensor_msgs::Image>()) return image->header.stamp;
    if (auto cloud = m.instantiate<sensor_msgs::PointCloud2>()) return cloud->header.stamp;
    if (auto compressed = m.instantiate<sensor_msgs::CompressedImage>())
      return compressed->header.stamp;
    return ros::Time();
  }
  void publish(const rosbag::MessageInstance& m) {
    if (rewound_) clock_->set(m.getTime());
    rewound_ = false;
    clock_->advanceTo(m.getTime());
    publishers_[m.getTopic()].publish(m.instantiate<topic_tools::ShapeShifter>());
  }

  ros::NodeHandle nh_;
  Clock* clock_;
  std::string frame_topic_;
  rosbag::Bag bag_;
  std::unique_ptr<rosbag::View> view_;
  std::vector<rosbag::MessageInstance> messages_;
  std::vector<size_t> frames_;
  std::map<std::string, ros::Publisher> publishers_;
  size_t next_ = 0;
  bool rewound_ = false;
};

// main() of a test node whose launch file picks its cases with the private parameter ~mode:
// gtest and ROS initialised, the cases filterForMode(mode) names run.
inline int runTestNode(int argc, char** argv, const std::string& node,
                       const std::string& default_mode,
                       const std::function<std::string(const std::string&)>& filterForMode) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node);
  ros::NodeHandle nh;
  std::string mode;
  ros::param::param<std::string>("~mode", mode, default_mode);
  testing::GTEST_FLAG(filter) = filterForMode(mode);
  return RUN_ALL_TESTS();
}

}  // namespace lockstep
}  // namespace gmm_mcl
