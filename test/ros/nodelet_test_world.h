// The world of the nodelet rostest (rostest_nodelet.cpp): the synthetic robot, its clock and
// the observer of the nodelet's output, and the steps its cases share (send a frame and wait for
// its status, reset to the truth and track, reconfigure, tick the diagnostics).
#pragma once

#include <dynamic_reconfigure/Reconfigure.h>
#include <dynamic_reconfigure/config_tools.h>
#include <image_transport/image_transport.h>
#include <std_srvs/Empty.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <string>

#include "gmm_mcl/LoadMap.h"
#include "gmm_mcl/ResetToPose.h"
#include "synthetic_robot.h"

namespace gmm_mcl {
namespace lockstep {

constexpr double kTrackedM = 0.05;    // converged: position error below this
constexpr double kDiagPeriodS = 1.0;  // the launch's diagnostics_period
const std::string kGimbalFrame = "gimbal_camera_optical_frame";

struct World {
  ros::NodeHandle nh;
  Clock clock{nh};
  Observer obs{nh};
  Observer start_obs{nh, "/gmm_mcl_start"};
  SyntheticRobot robot{nh, &clock};
  ros::Publisher initialpose =
      nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("/initialpose", 1, true);
  double step = 0;  // stamp of the next frame: robot.stamp(step)
  int k = 0;        // pose index of the robot
};
// The running node's world (main owns it).
extern World* w;

inline double positionError(const geometry_msgs::PoseWithCovarianceStamped& p,
                            const Eigen::Isometry3d& truth) {
  return (ros_conv::isometryFromPose(p.pose.pose).translation() - truth.translation()).norm();
}

// Sends the robot's frame at pose index k with the next stamp and waits for its ~status.
inline const FilterStatus* sendFrame(int k,
                                     const SyntheticRobot::Frame& f = SyntheticRobot::Frame(),
                                     ros::Time* stamp = nullptr) {
  const ros::Time t = w->robot.stamp(w->step++);
  if (stamp) *stamp = t;
  w->robot.send(t, w->robot.truth(k), f);
  return w->obs.statusAt(t);
}
inline double errorOfFrame(const ros::Time& t, int k) {
  const auto* p = w->obs.poseAt(t);
  return p ? positionError(*p, w->robot.truth(k)) : 1e9;
}

// Calls a service of the nodelet. A call that fails in transport (the client's connection to the
// manager, which a loaded machine can drop: seen once in CI, 6 ms into a case, between two calls
// that worked) is tried again, up to three times, each failure printed; a service that answers
// false fails at once.
template <typename Service>
inline bool callService(const std::string& name, Service* srv) {
  for (int attempt = 1; attempt <= 3; ++attempt) {
    if (!ros::service::waitForService(name, 60000)) {
      std::printf("[ service ] %s not advertised within 60 s\n", name.c_str());
      return false;
    }
    ros::ServiceClient client = ros::NodeHandle().serviceClient<Service>(name);
    if (client.call(*srv)) return true;
    if (client.isValid() && client.exists()) {
      std::printf("[ service ] %s: call %d failed\n", name.c_str(), attempt);
    } else {
      std::printf("[ service ] %s: call %d failed, the service gone\n", name.c_str(), attempt);
    }
    ros::WallDuration(0.1).sleep();
  }
  return false;
}

// Resets the filter to the robot's true pose (the service answers once it is applied) and
// tracks a few frames: the precondition of most cases. Says which step failed.
inline bool ensureTracking() {
  if (!w->robot.waitForNodelet() || !w->obs.waitConnected()) {
    std::printf("[ tracking ] the nodelet or its outputs not connected\n");
    return false;
  }
  w->robot.publishStaticExtrinsics();  // latched; the first case sends its first frame without
  ResetToPose srv;
  srv.request.pose.header.frame_id = "map";
  srv.request.pose.pose.pose = ros_conv::poseFromIsometry(w->robot.truth(w->k));
  for (int i : {0, 7, 14, 35}) srv.request.pose.pose.covariance[i] = 0.02 * 0.02;
  if (!callService("/gmm_mcl/reset_to_pose", &srv)) return false;
  if (!srv.response.success) {  // the frames below show whether it tracks anyway
    std::printf("[ tracking ] reset refused: %s\n", srv.response.message.c_str());
  }
  double err = 1e9;
  for (int i = 0; i < 8; ++i) {
    ros::Time t;
    if (!sendFrame(++w->k, SyntheticRobot::Frame(), &t)) {
      std::printf("[ tracking ] no status for frame %d\n", w->k);
      return false;
    }
    err = errorOfFrame(t, w->k);
  }
  std::printf("[ tracking ] error %.3f m at pose %d\n", err, w->k);
  return err < kTrackedM;
}

// dynamic_reconfigure request; *out: the configuration the server answers with.
inline bool reconfigure(const std::map<std::string, double>& doubles,
                        const std::map<std::string, int>& ints = {},
                        const std::map<std::string, bool>& bools = {},
                        dynamic_reconfigure::Config* out = nullptr) {
  dynamic_reconfigure::Reconfigure srv;
  for (const auto& kv : doubles)
    dynamic_reconfigure::ConfigTools::appendParameter(srv.request.config, kv.first, kv.second);
  for (const auto& kv : ints)
    dynamic_reconfigure::ConfigTools::appendParameter(srv.request.config, kv.first, kv.second);
  for (const auto& kv : bools)
    dynamic_reconfigure::ConfigTools::appendParameter(srv.request.config, kv.first, kv.second);
  if (!callService("/gmm_mcl/set_parameters", &srv)) return false;
  if (out) *out = srv.response.config;
  return true;
}
inline void restoreDefaults() {
  reconfigure({{"sigma_translation_m", 0.02},
               {"sigma_yaw_rad", 0.01},
               {"alpha_slow", 0.001},
               {"lost_margin_nats", 3.0},
               {"update_min_d", 0.0},
               {"update_min_a", 0.0}},
              {{"num_particles", 400}, {"lost_grace_frames", 30}, {"lost_frames", 10}},
              {{"tf_broadcast", true}});
}

// Fraction of `later`'s particles that are one of `earlier`'s (position and yaw within tol).
inline double fractionKept(const geometry_msgs::PoseArray& later,
                           const geometry_msgs::PoseArray& earlier, double tol) {
  int kept = 0;
  for (const auto& a : later.poses) {
    const Eigen::Isometry3d A = ros_conv::isometryFromPose(a);
    for (const auto& b : earlier.poses) {
      const Eigen::Isometry3d B = ros_conv::isometryFromPose(b);
      if ((A.translation() - B.translation()).norm() < tol &&
          std::abs(wrapAngle(yawFromRotation(A.linear()) - yawFromRotation(B.linear()))) < tol) {
        ++kept;
        break;
      }
    }
  }
  return later.poses.empty() ? 0.0 : static_cast<double>(kept) / later.poses.size();
}

// Ticks the clock by the diagnostics period until a diagnostics message satisfies `ok`: at most
// `ticks` periods when given (what the nodelet already knows shows in the next messages), else
// until the wait limit (what depends on messages the nodelet has yet to take from its queue, as
// far as the clock must go for that: never a fixed count, which would be a bet on the machine's
// speed).
inline bool diagUntil(const std::function<bool(const Diag&)>& ok, Diag* out = nullptr,
                      int ticks = 0) {
  Diag d;
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(kWaitLimitS);
  for (int i = 0; ticks > 0 ? i < ticks : ros::WallTime::now() < end; ++i) {
    if (!w->obs.tickDiagnostics(&w->clock, kDiagPeriodS, &d, nullptr)) {
      std::printf("[ diag ] none after moving the clock to %.3f (ros::ok %d, %zu so far)\n",
                  w->clock.now().toSec(), ros::ok(), w->obs.diags.size());
      return false;
    }
    std::printf("[ diag ] %d: %s\n", d.level, d.message.c_str());
    if (ok(d)) {
      if (out) *out = d;
      return true;
    }
  }
  std::printf("[ diag ] last: level %d: %s\n", d.level, d.message.c_str());
  if (out) *out = d;
  return false;
}

}  // namespace lockstep
}  // namespace gmm_mcl
