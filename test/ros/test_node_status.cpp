// The nodelet's bookkeeping without a master: frame accounting, ~status filling, and what
// /diagnostics says in each situation.
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <gtest/gtest.h>

#include "gmm_mcl/ros/node_status.h"

namespace gmm_mcl {
using S = diagnostic_msgs::DiagnosticStatus;

namespace {

std::string value(const Diagnosis& d, const std::string& key) {
  for (const auto& kv : d.values) {
    if (kv.first == key) return kv.second;
  }
  return "(absent)";
}

StepResult converged() {
  StepResult r;
  r.estimate.covariance.diagonal().setConstant(1e-4);  // 1 cm, 0.01 rad
  r.best_loglik_per_pixel = -1.0;
  r.reference_loglik_per_pixel = -1.2;
  return r;
}

// A node that has used frames until now_s and is healthy.
NodeHealth tracking(double now_s) {
  NodeHealth h;
  h.now_s = now_s;
  h.depth_topic = "/camera/depth/image_raw";
  h.camera_info_topic = "/camera/depth/camera_info";
  h.backend = "cpu";
  FilterStatus s;
  for (int i = 0; i < 10; ++i) {
    h.counters.arrived(i);
    h.counters.camera_info_received++;
    recordFrame(converged(), false, true, now_s, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  }
  h.last_arrival_s = h.last_camera_info_s = now_s;
  return h;
}

}  // namespace

TEST(NodeStatusTest, AccountingIdentityAndSeqGaps) {
  FrameCounters c;
  c.arrived(10);
  c.arrived(11);
  c.arrived(15);  // 12, 13, 14 never arrived
  c.arrived(3);   // a restarted publisher: not a gap
  EXPECT_EQ(c.received, 4);
  EXPECT_EQ(c.missed_seq, 3);
  c.drop(FrameDrop::kCameraInfo);
  c.drop(FrameDrop::kExtrinsics);
  NodeHealth h;
  h.counters = c;
  FilterStatus s;
  recordFrame(converged(), false, true, 1.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  EXPECT_EQ(s.frames_received, 4);
  EXPECT_EQ(s.frames_processed, 1);
  EXPECT_EQ(s.dropped_camera_info, 1);
  EXPECT_EQ(s.dropped_extrinsics, 1);
  EXPECT_EQ(s.frames_waiting, 1);  // 4 = 1 processed + 2 dropped + 1 waiting
  recordFrame(converged(), true, false, 1.1, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  EXPECT_EQ(s.step_status, "no_motion");
  EXPECT_EQ(s.frames_gated, 1);
  EXPECT_EQ(s.frames_waiting, 0);
  EXPECT_EQ(s.tf_skipped, 1);
}

TEST(NodeStatusTest, HealthyIsOk) {
  const Diagnosis d = diagnose(tracking(100.0));
  EXPECT_EQ(d.level, S::OK) << d.message;
  EXPECT_EQ(d.message, "localizing");
  EXPECT_EQ(value(d, "frames used"), "10");
}

// Images arrive but no CameraInfo: said so, not "waiting for depth frames".
TEST(NodeStatusTest, MissingCameraInfoIsNamed) {
  NodeHealth h;
  h.now_s = 50.0;
  h.depth_topic = "/camera/depth/image_raw";
  h.camera_info_topic = "/camera/depth/camera_info";
  for (int i = 0; i < 45; ++i) h.counters.arrived(i);
  h.last_arrival_s = 49.9;
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("45 so far) but no CameraInfo on /camera/depth/camera_info"),
            std::string::npos)
      << d.message;
  // After frames were used: a CameraInfo that stopped for more than 3 s.
  NodeHealth later = tracking(100.0);
  later.now_s = 104.0;
  later.last_arrival_s = 103.9;
  const Diagnosis d2 = diagnose(later);
  EXPECT_NE(d2.message.find("no CameraInfo on /camera/depth/camera_info for more than 3 s"),
            std::string::npos)
      << d2.message;
  // Nothing at all.
  NodeHealth none;
  none.depth_topic = "/d";
  EXPECT_NE(diagnose(none).message.find("no depth frame received on /d"), std::string::npos);
}

// After global localization the estimate is metres wide: not "OK".
TEST(NodeStatusTest, LargeCovarianceWarns) {
  NodeHealth h = tracking(10.0);
  StepResult wide = converged();
  wide.estimate.covariance(0, 0) = 4.0;
  FilterStatus s;
  recordFrame(wide, false, true, 10.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("not converged: sigma x/y 2 m"), std::string::npos) << d.message;
}

// A depth-scale estimate held at its bound: warned with the value and the parameter to look at;
// back inside, OK again.
TEST(NodeStatusTest, DepthScaleAtItsBoundWarns) {
  NodeHealth h = tracking(10.0);
  StepResult bound = converged();
  bound.depth_scale = 0.95;
  bound.depth_scale_at_bound = true;
  FilterStatus s;
  recordFrame(bound, false, true, 10.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("depth scale 0.95 held at its bound (refine_depth_scale_max_error)"),
            std::string::npos)
      << d.message;
  EXPECT_EQ(value(d, "depth scale"), "0.95");
  StepResult inside = converged();
  inside.depth_scale = 0.97;
  recordFrame(inside, false, true, 10.1, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  EXPECT_EQ(diagnose(h).level, S::OK) << diagnose(h).message;
}

// A rig: each camera's depth-scale estimate in /diagnostics and ~status, and a camera's held at
// its bound warned by its name.
TEST(NodeStatusTest, EachCamerasDepthScaleIsReported) {
  NodeHealth h = tracking(10.0);
  h.cameras.resize(2);
  h.cameras[0].name = "depth";
  h.cameras[1].name = "down";
  for (CameraHealth& cam : h.cameras) {  // both in use
    cam.sets.frames = cam.sets.used = 10;
    cam.sets.last_stamp_s = cam.sets.last_used_s = 9.9;
    cam.used_last = cam.in_last_set = true;
  }
  h.cameras[0].depth_scale = 0.996;
  h.cameras[1].depth_scale = 1.05;
  h.cameras[1].depth_scale_at_bound = true;
  FilterStatus s;
  recordFrame(converged(), false, true, 10.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("depth scale 1.05 of camera 'down' held at its bound"),
            std::string::npos)
      << d.message;
  EXPECT_EQ(value(d, "camera depth: depth scale"), "0.996");
  EXPECT_EQ(value(d, "camera down: depth scale"), "1.05");
  fillCameraStatus(h, 10.0, &s);
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_EQ(s.cameras[0].depth_scale, 0.996);
  EXPECT_EQ(s.cameras[1].depth_scale, 1.05);
  h.cameras[1].depth_scale = 1.04;
  h.cameras[1].depth_scale_at_bound = false;
  EXPECT_EQ(diagnose(h).level, S::OK) << diagnose(h).message;
}

// What predicted the step, by name: the gyro's turn named apart from the model's own yaw rate.
TEST(NodeStatusTest, TheStepsMotionIsNamed) {
  StepResult r;
  FilterStatus s;
  fillStatus(r, FrameCounters(), "cpu", "", 1.0, "", &s);
  EXPECT_EQ(s.motion, "odometry");
  r.motion = MotionSource::kConstantVelocity;
  fillStatus(r, FrameCounters(), "cpu", "", 1.0, "", &s);
  EXPECT_EQ(s.motion, "constant_velocity");
  r.gyro_yaw = true;
  fillStatus(r, FrameCounters(), "cpu", "", 1.0, "", &s);
  EXPECT_EQ(s.motion, "constant_velocity_gyro");
  r.motion = MotionSource::kStatic;
  r.gyro_yaw = false;
  fillStatus(r, FrameCounters(), "cpu", "", 1.0, "", &s);
  EXPECT_EQ(s.motion, "static");
}

// The best particle below the lost detector's line, and a lost event: warned.
TEST(NodeStatusTest, LostDetectorWarns) {
  NodeHealth h = tracking(10.0);
  StepResult below = converged();
  below.best_loglik_per_pixel = -6.0;  // reference -1.2, margin 3
  FilterStatus s;
  recordFrame(below, false, true, 10.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("lost"), std::string::npos) << d.message;
  // A lost event keeps warning for the next frames although they score well again.
  StepResult fired = converged();
  fired.lost = true;
  recordFrame(fired, false, true, 10.1, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  recordFrame(converged(), false, true, 10.2, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  d = diagnose(h);
  EXPECT_NE(d.message.find("1 lost events"), std::string::npos) << d.message;
  for (int i = 0; i < 30; ++i)
    recordFrame(converged(), false, true, 11.0, LostDetectionParams(), "cpu", "", 1.0, "", &h, &s);
  EXPECT_EQ(diagnose(h).level, S::OK) << diagnose(h).message;
}

// The core's backend warning (e.g. CUDA asked for but not built) and a backend error.
TEST(NodeStatusTest, BackendWarningAndErrorShown) {
  NodeHealth h = tracking(10.0);
  h.backend_warning = "CUDA asked for but not built: CPU backend";
  Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("CUDA asked for but not built"), std::string::npos) << d.message;
  StepResult failed = converged();
  failed.status = StepStatus::kBackendError;
  failed.message = "likelihood backend: out of memory";
  FilterStatus s;
  recordFrame(failed, false, true, 10.0, LostDetectionParams(), "cpu", h.backend_warning, 1.0, "",
              &h, &s);
  EXPECT_EQ(s.step_status, "backend_error");
  EXPECT_EQ(s.backend_warning, "CUDA asked for but not built: CPU backend");
  d = diagnose(h);
  EXPECT_EQ(d.level, S::ERROR);
  EXPECT_NE(d.message.find("out of memory"), std::string::npos) << d.message;
}

// The CUDA backend fails at run time and the core falls back to the CPU: ~status marks the
// frame, and /diagnostics shows the backend now running and why from then on.
TEST(NodeStatusTest, RunTimeFallbackShown) {
  NodeHealth h = tracking(10.0);
  h.backend = "cuda";
  StepResult failed = converged();
  failed.status = StepStatus::kBackendError;
  failed.backend_fallback = true;
  failed.message = "likelihood backend: an illegal memory access; fell back to the CPU backend";
  const std::string why =
      "the cuda backend failed (an illegal memory access): fell back to the CPU backend, particles "
      "kept";
  FilterStatus s;
  recordFrame(failed, false, true, 10.0, LostDetectionParams(), "cpu", why, 1.0, "", &h, &s);
  EXPECT_TRUE(s.backend_fallback);
  EXPECT_EQ(s.backend, "cpu");
  recordFrame(converged(), false, true, 10.1, LostDetectionParams(), "cpu", why, 1.0, "", &h, &s);
  EXPECT_FALSE(s.backend_fallback);
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN) << d.message;
  EXPECT_NE(d.message.find("fell back to the CPU backend"), std::string::npos) << d.message;
  EXPECT_EQ(value(d, "backend"), "cpu");
}

TEST(NodeStatusTest, BadConfigurationIsAnError) {
  NodeHealth h;
  h.config_error = "~num_particles must be in [1, 1e+07] (got -5)";
  const Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::ERROR);
  EXPECT_EQ(d.message, "bad configuration: ~num_particles must be in [1, 1e+07] (got -5)");
}

TEST(NodeStatusTest, PeriodicScheduleFollowsRosTimeAndSurvivesAJumpBack) {
  PeriodicSchedule s{1.0};
  EXPECT_TRUE(s.due(1000.0));
  EXPECT_FALSE(s.due(1000.5));
  EXPECT_TRUE(s.due(1001.0));
  EXPECT_FALSE(s.due(1001.99));
  EXPECT_TRUE(s.due(1002.5));
  EXPECT_TRUE(s.due(970.0));  // the clock went back 32 s: due at once, not in 32 s
  EXPECT_FALSE(s.due(970.5));
  EXPECT_TRUE(s.due(971.0));
}

// The latest distinct problems of the last 5 s are all named, the latest first.
TEST(NodeStatusTest, RecentProblemsAreAllNamed) {
  NodeHealth h = tracking(10.0);
  h.problem("depth frame dropped: no transform base_link <- 'unknown'", 9.0);
  h.problem("depth frame dropped: no CameraInfo with the image's stamp", 9.5);
  h.problem("depth frame dropped: no CameraInfo with the image's stamp", 9.6);  // again: once
  Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_EQ(d.message,
            "depth frame dropped: no CameraInfo with the image's stamp; depth frame dropped: no "
            "transform "
            "base_link <- 'unknown'");
  h.now_s = 14.2;  // the first is older than 5 s now
  h.last_arrival_s = h.last_used_s = 14.2;
  d = diagnose(h);
  EXPECT_EQ(d.message, "depth frame dropped: no CameraInfo with the image's stamp");
  for (int i = 0; i < 6; ++i) h.problem("p" + std::to_string(i), 14.0);
  EXPECT_EQ(h.problems.size(), NodeHealth::kRecentProblems);
  EXPECT_EQ(h.problems.back().first, "p5");
}

TEST(NodeStatusTest, UpdateBudgetReportedAndWarnsOnlyAtItsLimit) {
  // Updates of 100 ms against 30 Hz frames: the budget cuts to its coarsest setting.
  UpdateBudgetParams params;
  params.max_pixel_stride = 12;
  params.min_particles = 200;
  LocalizerParams configured;
  configured.filter.num_particles = 1000;
  configured.frame.pixel_stride = 4;
  UpdateBudget budget(params, configured);
  for (int i = 0; i < 10; ++i) budget.frameArrived(i / 30.0, i, i / 30.0, i / 30.0);
  NodeHealth h = tracking(10.0);
  h.budget = budget.state();
  Diagnosis d = diagnose(h);
  EXPECT_EQ(d.level, S::OK) << d.message;
  EXPECT_EQ(value(d, "pixel stride"), "4");
  EXPECT_EQ(value(d, "particle cap"), "1000");
  EXPECT_NE(value(d, "budget").find("33.3"), std::string::npos) << value(d, "budget");

  for (int i = 0; i < 3; ++i) budget.updateTook(100.0, 1000);  // a first cut: the stride
  h.budget = budget.state();
  d = diagnose(h);
  EXPECT_EQ(d.level, S::OK) << d.message;  // adapting, not at its limit: no warning
  EXPECT_NE(value(d, "pixel stride"), "4");
  FilterStatus s;
  fillBudgetStatus(budget.state(), &s);
  EXPECT_TRUE(s.budget_enabled);
  EXPECT_NEAR(s.budget_ms, 1000.0 / 30.0, 1e-6);
  EXPECT_EQ(s.budget_pixel_stride, budget.state().pixel_stride);
  EXPECT_EQ(s.budget_particle_cap, 1000);
  EXPECT_EQ(s.budget_cuts, 1);

  for (int i = 0; i < 60; ++i) budget.updateTook(100.0, budget.state().particle_cap);
  h.budget = budget.state();
  d = diagnose(h);
  EXPECT_EQ(d.level, S::WARN);
  EXPECT_NE(d.message.find("over the budget"), std::string::npos) << d.message;
  EXPECT_EQ(value(d, "pixel stride"), "12");
  EXPECT_EQ(value(d, "particle cap"), "200");
  EXPECT_EQ(value(d, "refinement"), "off (budget)");

  UpdateBudgetParams off = params;
  off.enabled = false;
  budget.configure(off, configured);
  h.budget = budget.state();
  d = diagnose(h);
  EXPECT_EQ(d.level, S::OK) << d.message;
  EXPECT_EQ(value(d, "budget"), "off");
  EXPECT_EQ(value(d, "pixel stride"), "4");
}

}  // namespace gmm_mcl
