// rostest node: the nodelet as users run it, in lockstep with a synthetic robot
// (test/ros/synthetic_robot.h) whose clock the test owns. Each case sends frames one at a time
// and waits for the nodelet's own output; none depends on how fast the machine is.
//   FirstFrameWaitsForTf         the first frame arrives before any tf and is used once tf comes
//   DiagnosticsNamedAndOnTime    /diagnostics named after the nodelet, one per period of ROS
//                                time, and still after the clock jumps back
//   MissingCameraInfoIsNamed     images without CameraInfo are reported as such
//   MovingExtrinsicsKeepBelief   a base -> camera tf with 0.01 deg of jitter per frame: the
//                                particles carry over (no rebuild), tracking holds
//   ImuBufferedDuringAnUpdate    IMU messages arriving while an update runs are all kept, and a
//                                frame gets the attitude of its own stamp
//   ReconfigureKeepsParticles    dynamic_reconfigure changes keep the particles; the lost
//                                detector's parameters are reconfigurable
//   UpdateBudgetCutsAndKeepsBelief  a budget no update can meet: stride, refinement, particles
//                                cut to their bounds in that order, still tracking; off: back
//   RequestedPoses               rviz's planar 2D Pose Estimate keeps the height; a pose in the
//                                odom frame is transformed
//   DiagnosticsWarn              not converged (after global localization), lost
//   MarkersAgainAfterAJumpBack   ~gmm_markers republished after a jump back and periodically
//   RefinedPoseAndDebugImage     ~refined_pose of a converged frame; ~debug_image through
//                                image_transport, rendered for the frame that was used
//   JumpBackBeforeTheClock       a frame stamped 10 s back before the clock went back: a jump
//                                back (the filter re-initialises), not a late frame dropped
//   MotionGating, TfBroadcastOff, SavePose, ReloadMap, ReloadMapFromACloud,
//   SinglePoseStartAndCpuFallback
#include <gtest/gtest.h>

#include "nodelet_test_world.h"

namespace gmm_mcl {
namespace lockstep {

World* w = nullptr;

TEST(NodeletTest, FirstFrameWaitsForTf) {
  ASSERT_TRUE(w->robot.waitForNodelet({"/gmm_mcl", "/gmm_mcl_start"}));
  ASSERT_TRUE(w->obs.waitConnected() && w->start_obs.waitConnected());
  // The first frame, before any tf (neither the static extrinsics nor odometry).
  SyntheticRobot::Frame no_tf;
  no_tf.odom_tf = false;
  const ros::Time t = w->robot.stamp(w->step++);
  w->robot.send(t, w->robot.truth(0), no_tf);
  // The nodelet has it (it counts it) before tf comes.
  ASSERT_TRUE(diagUntil([](const Diag& d) { return d.number("frames received") >= 1; }))
      << "the frame never arrived";
  w->robot.publishStaticExtrinsics();
  w->robot.publishOdometry(t, w->robot.truth(0));
  const FilterStatus* s = w->obs.statusAt(t, 30.0);
  ASSERT_NE(s, nullptr) << "the first frame was dropped instead of waiting for tf";
  EXPECT_EQ(s->frames_processed, 1);
  EXPECT_EQ(s->dropped_extrinsics, 0);
}

TEST(NodeletTest, DiagnosticsNamedAndOnTime) {
  Diag d;
  ASSERT_TRUE(w->obs.tickDiagnostics(&w->clock, kDiagPeriodS, &d));
  EXPECT_EQ(d.name, "gmm_mcl: localization") << "named after the manager, not the nodelet";
  // One message per period of ROS time.
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(w->obs.tickDiagnostics(&w->clock, kDiagPeriodS, &d, nullptr, 30.0))
        << "no diagnostics in period " << i;
  }
  // The clock jumps back 30 s (a looped bag): the next period still has its message.
  w->clock.set(w->robot.stamp(w->step) - ros::Duration(30.0));
  EXPECT_TRUE(w->obs.tickDiagnostics(&w->clock, kDiagPeriodS, &d, nullptr, 30.0))
      << "no diagnostics after a jump back";
  w->clock.set(w->robot.stamp(w->step));
}

TEST(NodeletTest, MissingCameraInfoIsNamed) {
  ASSERT_TRUE(ensureTracking());
  SyntheticRobot::Frame no_info;
  no_info.camera_info = false;
  for (int i = 0; i < 12; ++i) {  // 4 s of images without their CameraInfo
    const ros::Time t = w->robot.stamp(w->step);
    w->step += 10;
    w->robot.send(t, w->robot.truth(w->k), no_info);
  }
  Diag d;
  EXPECT_TRUE(diagUntil(
      [](const Diag& d) {
        return d.message.find("but no CameraInfo on /camera/depth/camera_info") !=
               std::string::npos;
      },
      &d))
      << d.message;
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::WARN);
  EXPECT_TRUE(ensureTracking()) << "tracking does not resume with CameraInfo";
}

TEST(NodeletTest, MovingExtrinsicsKeepBelief) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(w->obs.subscribeParticles());
  // No process noise or recovery: a held robot's particles only get resampled (copies).
  ASSERT_TRUE(reconfigure({{"sigma_translation_m", 0.0},
                           {"sigma_yaw_rad", 0.0},
                           {"alpha_slow", 0.0},
                           {"lost_margin_nats", 0.0}}));
  SyntheticRobot::Frame gimbal;
  gimbal.camera_frame = kGimbalFrame;
  gimbal.dynamic_extrinsics = true;
  gimbal.extrinsics_jitter_deg = 0.01;
  std::vector<geometry_msgs::PoseArray> sets;
  int resets = -1;
  for (int i = 0; i < 6; ++i) {
    ros::Time t;
    const FilterStatus* s = sendFrame(w->k, gimbal, &t);
    ASSERT_NE(s, nullptr) << "frame " << i << " with per-frame extrinsics not used";
    if (resets < 0) resets = s->resets;
    EXPECT_EQ(s->resets, resets);
    const geometry_msgs::PoseArray* p = w->obs.particlesAt(t);
    ASSERT_NE(p, nullptr);
    sets.push_back(*p);
  }
  for (size_t i = 1; i < sets.size(); ++i) {
    const double kept = fractionKept(sets[i], sets[i - 1], 1e-6);
    std::printf(
        "[ measured ] jittered extrinsics, frame %zu: %.0f%% of the particles carried over\n", i,
        100 * kept);
    EXPECT_GE(kept, 0.95) << "the belief was rebuilt at frame " << i;
  }
  restoreDefaults();
  // Moving, with the jitter: tracking holds on every frame.
  double worst = 0.0;
  for (int i = 0; i < 30; ++i) {
    ros::Time t;
    ASSERT_NE(sendFrame(++w->k, gimbal, &t), nullptr);
    worst = std::max(worst, errorOfFrame(t, w->k));
  }
  std::printf("[ measured ] jittered extrinsics while moving: worst error %.3f m over 30 frames\n",
              worst);
  EXPECT_LT(worst, 0.1);
}

TEST(NodeletTest, ImuBufferedDuringAnUpdate) {
  ASSERT_TRUE(ensureTracking());
  const int k = ++w->k;
  // Frame k, then at once (while it is being processed) 200 IMU messages at 600 Hz with a roll
  // offset growing by 1 mrad each; the next frame's stamp is the 20th's.
  const ros::Time t = w->robot.stamp(w->step++);
  w->robot.send(t, w->robot.truth(k));
  double roll, pitch, yaw;
  rpyFromRotation(w->robot.truth(k + 1).linear(), &roll, &pitch, &yaw);
  for (int i = 1; i <= 200; ++i)
    w->robot.publishImu(t + ros::Duration(i / 600.0), roll + 0.001 * i, pitch);
  ASSERT_NE(w->obs.statusAt(t), nullptr);
  // Every IMU message reaches the buffer (none lost to a full queue behind the update).
  const long long sent = w->robot.imuPublished();
  Diag d;
  EXPECT_TRUE(
      diagUntil([&](const Diag& d) { return d.number("IMU messages received") >= sent; }, &d))
      << d.number("IMU messages received") << " of " << sent << " IMU messages kept";
  // Frame k + 1 (without an IMU message of its own) gets the attitude of its stamp.
  SyntheticRobot::Frame no_imu;
  no_imu.imu = false;
  const ros::Time t1 = w->robot.stamp(w->step++);
  ASSERT_NEAR((t1 - t).toSec(), 20 / 600.0, 1e-6);
  w->robot.send(t1, w->robot.truth(++w->k), no_imu);
  const FilterStatus* s = w->obs.statusAt(t1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->message.find("IMU attitude"), std::string::npos) << s->message;
  EXPECT_EQ(s->imu_received, sent);
  const geometry_msgs::PoseWithCovarianceStamped* p = w->obs.poseAt(t1);
  ASSERT_NE(p, nullptr);
  double r, pt, y;
  rpyFromRotation(ros_conv::isometryFromPose(p->pose.pose).linear(), &r, &pt, &y);
  std::printf(
      "[ measured ] roll used %.4f rad, IMU at the frame's stamp %.4f rad, newest IMU %.4f rad\n",
      r, roll + 0.020, roll + 0.200);
  EXPECT_NEAR(r, roll + 0.020, 1e-6) << "the frame did not get the attitude of its own stamp";
}

TEST(NodeletTest, ReconfigureKeepsParticles) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(w->obs.subscribeParticles());
  ros::Time t0, t1, t2;
  ASSERT_NE(sendFrame(w->k, SyntheticRobot::Frame(), &t0), nullptr);
  const geometry_msgs::PoseArray before = *w->obs.particlesAt(t0);
  // No process noise or recovery from now on: the held robot's particles are only resampled.
  dynamic_reconfigure::Config answer;
  ASSERT_TRUE(reconfigure({{"sigma_translation_m", 0.0},
                           {"sigma_yaw_rad", 0.0},
                           {"alpha_slow", 0.0},
                           {"lost_margin_nats", 0.0}},
                          {{"lost_grace_frames", 7}}, {}, &answer));
  int grace = -1;
  dynamic_reconfigure::ConfigTools::getParameter(answer, "lost_grace_frames", grace);
  EXPECT_EQ(grace, 7) << "the lost detector's parameters are not reconfigurable";
  const FilterStatus* s = sendFrame(w->k, SyntheticRobot::Frame(), &t1);
  ASSERT_NE(s, nullptr);
  const geometry_msgs::PoseArray after = *w->obs.particlesAt(t1);
  const double kept = fractionKept(after, before, 1e-6);
  std::printf("[ measured ] after a reconfigure %.0f%% of the particles carried over\n",
              100 * kept);
  EXPECT_GE(kept, 0.95) << "the reconfigure re-seeded the particles";
  // A smaller particle count: resampled from the same set.
  ASSERT_TRUE(reconfigure({}, {{"num_particles", 300}}));
  ASSERT_NE(sendFrame(w->k, SyntheticRobot::Frame(), &t2), nullptr);
  const geometry_msgs::PoseArray fewer = *w->obs.particlesAt(t2);
  EXPECT_EQ(fewer.poses.size(), 300u);
  EXPECT_GE(fractionKept(fewer, after, 1e-6), 0.95);
  restoreDefaults();
}

// The frame-rate budget made deterministic by a budget that no update can meet (0.001 ms): one
// update over it (budget_over_updates 1) per cut. ~status shows the choice the frame ran with.
TEST(NodeletTest, UpdateBudgetCutsAndKeepsBelief) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(reconfigure(
      {{"max_update_ms", 0.001}},
      {{"budget_max_pixel_stride", 12}, {"budget_min_particles", 150}, {"budget_over_updates", 1}},
      {{"update_budget", true}}));
  const FilterStatus* s = nullptr;
  ros::Time t;
  for (int i = 0; i < 4; ++i) {  // cuts after frames 1 (stride), 2 (refinement), 3 (particles)
    s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->step_status, "ok");
  }
  EXPECT_TRUE(s->budget_enabled);
  EXPECT_NEAR(s->budget_ms, 0.001, 1e-12);
  EXPECT_EQ(s->budget_pixel_stride, 12);
  EXPECT_FALSE(s->budget_refine);
  EXPECT_EQ(s->budget_particle_cap, 150);
  EXPECT_EQ(s->particles, 150);
  EXPECT_GE(s->budget_cuts, 3);
  EXPECT_LT(errorOfFrame(t, w->k), kTrackedM) << "the budget's changes lost the belief";
  // Off: the configured values (nodelet.test: stride 4, 400 particles) at once.
  ASSERT_TRUE(reconfigure(
      {{"max_update_ms", 0.0}},
      {{"budget_max_pixel_stride", 16}, {"budget_min_particles", 100}, {"budget_over_updates", 3}},
      {{"update_budget", false}}));
  s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
  ASSERT_NE(s, nullptr);
  EXPECT_FALSE(s->budget_enabled);
  EXPECT_EQ(s->budget_pixel_stride, 4);
  EXPECT_EQ(s->budget_particle_cap, 400);
  EXPECT_TRUE(s->budget_refine);
  EXPECT_EQ(s->particles, 400);
  EXPECT_LT(errorOfFrame(t, w->k), kTrackedM);
  restoreDefaults();
}

TEST(NodeletTest, RequestedPoses) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(waitFor([&] { return w->initialpose.getNumSubscribers() > 0; }));
  // rviz's 2D Pose Estimate: z = 0, yaw only, x/y variance 0.25, yaw 0.0685.
  const Particle truth = poseToParticle(w->robot.truth(w->k));
  geometry_msgs::PoseWithCovarianceStamped planar;
  planar.header.frame_id = "map";
  planar.header.stamp = w->robot.stamp(w->step - 1);
  planar.pose.pose = ros_conv::poseFromIsometry(
      particleToPose(Particle{truth.x_m, truth.y_m, 0.0, truth.yaw_rad}, 0, 0));
  planar.pose.covariance[0] = planar.pose.covariance[7] = 0.25;
  planar.pose.covariance[35] = 0.0685;
  const int resets = w->obs.statuses.back().resets;
  w->initialpose.publish(planar);
  const FilterStatus* s = nullptr;
  ros::Time t;
  for (int i = 0; i < 10 && !(s && s->resets > resets); ++i)
    s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
  ASSERT_TRUE(s && s->resets > resets) << "the planar pose was not applied";
  const auto* p = w->obs.poseAt(t);
  const double z = p->pose.pose.position.z, z_true = w->robot.truth(w->k).translation().z();
  std::printf("[ measured ] after a planar pose: z %.3f m, true %.3f m\n", z, z_true);
  EXPECT_NEAR(z, z_true, 0.15) << "the drone was put on the floor";

  // A pose given in the odom frame (offset from the map by 1.8 m and 0.5 rad): transformed.
  ASSERT_TRUE(ensureTracking());
  geometry_msgs::PoseWithCovarianceStamped in_odom;
  in_odom.header.frame_id = "odom";
  in_odom.header.stamp = w->robot.stamp(w->step - 1);
  in_odom.pose.pose = ros_conv::poseFromIsometry(w->robot.T_odom_base(w->robot.truth(w->k)));
  for (int i : {0, 7, 14, 35}) in_odom.pose.covariance[i] = 0.05 * 0.05;
  const int resets2 = w->obs.statuses.back().resets;
  w->initialpose.publish(in_odom);
  s = nullptr;
  for (int i = 0; i < 10 && !(s && s->resets > resets2); ++i)
    s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
  ASSERT_TRUE(s && s->resets > resets2) << "the odom-frame pose was not applied";
  const double err = errorOfFrame(t, w->k);
  std::printf("[ measured ] after a pose in the odom frame: error %.3f m\n", err);
  EXPECT_LT(err, 0.2) << "a pose in another frame was used as if in the map frame";
}

TEST(NodeletTest, DiagnosticsWarn) {
  ASSERT_TRUE(ensureTracking());
  // Global localization: the estimate is metres wide, not "OK".
  std_srvs::Empty srv;
  ASSERT_TRUE(ros::service::call("/gmm_mcl/global_localization", srv));
  ASSERT_NE(sendFrame(++w->k), nullptr);
  Diag d;
  EXPECT_TRUE(diagUntil(
      [](const Diag& d) { return d.message.find("not converged") != std::string::npos; }, &d, 3))
      << d.message;
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::WARN);
  // Lost: frames of a wall that is not in the map score far below the reference.
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(reconfigure({}, {{"lost_grace_frames", 0}, {"lost_frames", 2}}));
  SyntheticRobot::Frame wall;
  wall.wall_depth_m = 0.6;
  for (int i = 0; i < 3; ++i) ASSERT_NE(sendFrame(w->k, wall), nullptr);
  EXPECT_TRUE(
      diagUntil([](const Diag& d) { return d.message.find("lost") != std::string::npos; }, &d, 3))
      << d.message;
  restoreDefaults();
}

TEST(NodeletTest, MarkersAgainAfterAJumpBack) {
  ASSERT_TRUE(w->obs.subscribeMarkers());
  ASSERT_TRUE(waitFor([&] { return w->obs.marker_messages >= 1; }))
      << "the latched markers never came";
  ASSERT_TRUE(ensureTracking());
  // A frame stamped 10 s earlier (a looped bag): rviz clears its displays; the markers come again.
  const int before = w->obs.marker_messages;
  const ros::Time back = w->robot.stamp(w->step - 1) - ros::Duration(10.0);
  w->clock.set(back);
  w->robot.send(back, w->robot.truth(w->k));
  const FilterStatus* s = w->obs.statusAt(back);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->step_status, "time_jump_back");
  EXPECT_TRUE(waitFor([&] { return w->obs.marker_messages > before; }, 30.0))
      << "no markers after the jump back";
  // And periodically while subscribed (rviz's Reset drops them too): markers_period 5 s.
  const int after_jump = w->obs.marker_messages;
  EXPECT_TRUE(diagUntil([&](const Diag&) { return w->obs.marker_messages > after_jump; }));
  w->clock.set(w->robot.stamp(w->step));
  ASSERT_TRUE(ensureTracking());
}

// A looped bag's first frame taken before the nodelet has the clock's jump back (/clock comes on
// another connection): a jump back as well, not a frame whose tf came late.
TEST(NodeletTest, JumpBackBeforeTheClock) {
  ASSERT_TRUE(ensureTracking());
  const ros::Time back = w->robot.stamp(w->step - 1) - ros::Duration(10.0);
  w->robot.send(back, w->robot.truth(w->k));  // the clock stays where it is
  const FilterStatus* s = w->obs.statusAt(back);
  ASSERT_NE(s, nullptr) << "the frame was dropped; " << w->obs.describe();
  EXPECT_EQ(s->step_status, "time_jump_back");
  ASSERT_TRUE(ensureTracking());
}

TEST(NodeletTest, MotionGating) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(reconfigure({{"update_min_d", 0.3}, {"update_min_a", 0.3}}));
  // Hovering: the first frame after the change updates (the gate starts from it), then none.
  ros::Time t;
  sendFrame(w->k);
  const FilterStatus* s = sendFrame(w->k, SyntheticRobot::Frame(), &t);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->step_status, "no_motion");
  const long long gated = s->frames_gated;
  EXPECT_GE(gated, 1);
  EXPECT_LT(errorOfFrame(t, w->k), kTrackedM) << "the gated pose does not follow odometry";
  // Moving on: about 2 cm per frame, so every 15th frame or so updates.
  int updated = 0, skipped = 0;
  for (int i = 0; i < 40; ++i) {
    s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
    ASSERT_NE(s, nullptr);
    (s->step_status == "no_motion" ? skipped : updated)++;
    EXPECT_LT(errorOfFrame(t, w->k), 0.1);
  }
  std::printf("[ measured ] update_min_d 0.3 m: %d of 40 moving frames updated\n", updated);
  EXPECT_GE(updated, 1);
  EXPECT_GE(skipped, 20);
  restoreDefaults();
}

TEST(NodeletTest, TfBroadcastOff) {
  ASSERT_TRUE(ensureTracking());
  ASSERT_TRUE(reconfigure({}, {}, {{"tf_broadcast", false}}));
  ros::Time t;
  ASSERT_NE(sendFrame(++w->k, SyntheticRobot::Frame(), &t), nullptr);
  ASSERT_NE(sendFrame(++w->k, SyntheticRobot::Frame(), &t), nullptr);
  const size_t n = w->obs.tf_stamps.size();
  for (int i = 0; i < 5; ++i) ASSERT_NE(sendFrame(++w->k, SyntheticRobot::Frame(), &t), nullptr);
  ASSERT_NE(w->obs.poseAt(t), nullptr) << "the pose is still published";
  EXPECT_EQ(w->obs.tf_stamps.size(), n) << "map -> odom published with tf_broadcast false";
  restoreDefaults();
  ASSERT_NE(sendFrame(++w->k, SyntheticRobot::Frame(), &t), nullptr);
  EXPECT_TRUE(waitFor([&] { return w->obs.tf_stamps.size() > n; }));
}

TEST(NodeletTest, SavePose) {
  ASSERT_TRUE(ensureTracking());
  ros::Time t;
  for (int i = 0; i < 70; ++i)
    ASSERT_NE(sendFrame(++w->k, SyntheticRobot::Frame(), &t), nullptr);  // > 2 s
  // save_pose_rate 0.5 Hz: the estimate of a frame of the last 2 s reaches the parameter server
  // (written by the nodelet's timer, off the update thread: waited for).
  double x = NAN, y = NAN, z = NAN, cov_xx = NAN, best = 1e9;
  waitFor([&] {
    if (!(ros::param::get("/gmm_mcl/initial_pose_x", x) &&
          ros::param::get("/gmm_mcl/initial_pose_y", y) &&
          ros::param::get("/gmm_mcl/initial_pose_z", z) &&
          ros::param::get("/gmm_mcl/initial_cov_xx", cov_xx)))
      return false;
    const Eigen::Vector3d saved(x, y, z);
    best = 1e9;
    for (int i = 0; i <= 62; ++i)
      best = std::min(best, (saved - w->robot.truth(w->k - i).translation()).norm());
    return best < kTrackedM;
  });
  std::printf("[ measured ] saved pose within %.3f m of the true pose of the last 2 s\n", best);
  EXPECT_LT(best, kTrackedM);
  EXPECT_GT(cov_xx, 0.0);
}

TEST(NodeletTest, ReloadMap) {
  ASSERT_TRUE(ensureTracking());
  LoadMap srv;
  srv.request.path = "/nonexistent/map.gmm";
  ASSERT_TRUE(ros::service::call("/gmm_mcl/reload_map", srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_NE(srv.response.message.find("previous one is kept"), std::string::npos)
      << srv.response.message;
  srv.request.path = "";
  ASSERT_TRUE(ros::service::call("/gmm_mcl/reload_map", srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_GT(srv.response.components, 100);
  ros::Time t;
  const FilterStatus* s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->step_status, "ok");
  EXPECT_LT(errorOfFrame(t, w->k), kTrackedM) << "the particles were not kept across the reload";
}

// ~reload_map with a point cloud of the scene (sim_scene.pcd, written at test-data time): fitted
// on load (or taken from its cache beside it), tracking goes on; then the map file again.
TEST(NodeletTest, ReloadMapFromACloud) {
  ASSERT_TRUE(ensureTracking());
  std::string cloud, map;
  ASSERT_TRUE(ros::param::get("~cloud_map", cloud) && ros::param::get("~map", map));
  LoadMap srv;
  srv.request.path = cloud;
  ASSERT_TRUE(ros::service::call("/gmm_mcl/reload_map", srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_EQ(srv.response.components, 600) << "map_fit_components of nodelet.test";
  EXPECT_TRUE(srv.response.message.find("fitted") != std::string::npos ||
              srv.response.message.find("cached fit") != std::string::npos)
      << srv.response.message;
  std::printf("[ reload ] %s\n", srv.response.message.c_str());
  ros::Time t;
  for (int i = 0; i < 3; ++i) {
    const FilterStatus* s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->step_status, "ok");
  }
  EXPECT_LT(errorOfFrame(t, w->k), kTrackedM) << "not tracking on the fitted map";
  // Again: the cache this time.
  ASSERT_TRUE(ros::service::call("/gmm_mcl/reload_map", srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_NE(srv.response.message.find("cached fit"), std::string::npos) << srv.response.message;
  srv.request.path = map;
  ASSERT_TRUE(ros::service::call("/gmm_mcl/reload_map", srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
}

TEST(NodeletTest, RefinedPoseAndDebugImage) {
  ASSERT_TRUE(ensureTracking());
  std::vector<geometry_msgs::PoseWithCovarianceStamped> refined;
  std::vector<sensor_msgs::Image> debug;
  ros::Subscriber refined_sub = w->nh.subscribe<geometry_msgs::PoseWithCovarianceStamped>(
      "/gmm_mcl/refined_pose", 100,
      [&](const geometry_msgs::PoseWithCovarianceStampedConstPtr& m) { refined.push_back(*m); });
  image_transport::ImageTransport it(w->nh);
  image_transport::Subscriber debug_sub = it.subscribe(
      "/gmm_mcl/debug_image", 10, [&](const sensor_msgs::ImageConstPtr& m) { debug.push_back(*m); },
      ros::VoidPtr(), image_transport::TransportHints("raw"));
  ASSERT_TRUE(waitFor(
      [&] { return refined_sub.getNumPublishers() > 0 && debug_sub.getNumPublishers() > 0; }));
  ros::Time t;
  const FilterStatus* s = sendFrame(++w->k, SyntheticRobot::Frame(), &t);
  ASSERT_NE(s, nullptr);
  ASSERT_EQ(s->step_status, "ok");
  EXPECT_TRUE(s->refined) << "converged, yet not refined: " << s->refine_why;
  EXPECT_GE(s->refine_ms, 0.0);
  ASSERT_TRUE(waitFor([&] { return !refined.empty() && refined.back().header.stamp == t; }))
      << "no ~refined_pose of the frame";
  const double err = positionError(refined.back(), w->robot.truth(w->k));
  std::printf("[ measured ] refined pose error %.4f m, particle mean %.4f m\n", err,
              errorOfFrame(t, w->k));
  EXPECT_LT(err, kTrackedM);
  EXPECT_EQ(refined.back().header.frame_id, "map");
  ASSERT_TRUE(waitFor([&] { return !debug.empty() && debug.back().header.stamp == t; }))
      << "no ~debug_image of the frame";
  EXPECT_EQ(debug.back().width, 160u);
  EXPECT_EQ(debug.back().height, 120u);
}

// A second nodelet in the same manager starts from ~initial_pose_* (far from its initial
// region) and asks for the CUDA backend: without CUDA in the build or a usable device the CPU
// runs, and says so; with both (scripts/gpu_ros_check.sh on a GPU machine) CUDA runs, silently.
TEST(NodeletTest, SinglePoseStartAndCpuFallback) {
  const FilterStatus* first = nullptr;
  ASSERT_TRUE(waitFor([&] { return !w->start_obs.statuses.empty(); }))
      << "the second nodelet never updated";
  first = &w->start_obs.statuses.front();
  const auto* p = w->start_obs.poseAt(first->header.stamp);
  ASSERT_NE(p, nullptr);
  const double err = positionError(*p, w->robot.truth(0));
  std::printf("[ measured ] single-pose start: first error %.3f m\n", err);
  EXPECT_LT(err, 0.2);
  if (first->backend == "cuda") {
    EXPECT_EQ(first->backend_warning, "");
    return;
  }
  EXPECT_EQ(first->backend, "cpu");
  EXPECT_NE(first->backend_warning.find("CUDA"), std::string::npos) << first->backend_warning;
  Diag d;
  EXPECT_TRUE(w->start_obs.waitDiag(
      0,
      [](const Diag& d) {
        return d.name == "gmm_mcl_start: localization" &&
               d.message.find("CUDA") != std::string::npos;
      },
      &d, 30.0))
      << d.message;
}

}  // namespace lockstep
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "rostest_nodelet");
  gmm_mcl::lockstep::World world;
  gmm_mcl::lockstep::w = &world;
  const std::string filter = ros::param::param<std::string>("~filter", "");
  if (!filter.empty()) testing::GTEST_FLAG(filter) = filter;
  world.robot.waitForNodelet();  // every case starts with the nodelet up (a failure shows there)
  return RUN_ALL_TESTS();
}
