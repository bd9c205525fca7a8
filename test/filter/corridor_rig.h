// The camera rig's corridor (docs/multi_camera.md): a forward and a downward camera on a drone
// flying along sim::makeCorridorScene(), where the forward camera alone cannot tell where it is
// along the corridor. Shared by the CPU and CUDA localizer tests.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/sim/box_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace test {

constexpr double kCorridorDt = 1.0 / 30.0;

// Forward (level, looking along base x) and downward cameras, 10 cm apart.
inline Eigen::Isometry3d forwardCamera() { return sim::corridorForwardCamera(); }
inline Eigen::Isometry3d downCamera() { return sim::corridorDownCamera(); }

struct Corridor {
  sim::BoxScene scene;
  GmmMap map;
};
inline const Corridor& corridor() {
  static const Corridor c = [] {
    sim::BoxScene scene = sim::makeCorridorScene();
    GmmMap map = sim::tileScene(scene, 0.25, 0.015);
    return Corridor{scene, map};
  }();
  return c;
}

// The drone along the corridor at 1.5 m, 0.6 m/s, with a slight weave in y and yaw.
inline Eigen::Isometry3d corridorPose(int frame) {
  return sim::corridorTrajectory(frame + 1)[frame];
}

inline LocalizerParams corridorParams() {
  LocalizerParams p;
  p.filter.num_particles = 1500;
  p.frame.pixel_stride = 8;
  p.frame.max_range_m = 3.f;
  p.T_base_cam = forwardCamera();
  // Anywhere along 8 m of the corridor, 60 cm across, 0.6 rad of yaw.
  p.init.centre_m = Eigen::Vector3d(13.0, 1.0, 1.5);
  p.init.half_extent_m = Eigen::Vector3d(4.0, 0.3, 0.05);
  p.init.yaw_centre_rad = 0.0;
  p.init.yaw_half_range_rad = 0.3;
  return p;
}

struct CorridorRun {
  double final_error_m = 0.0;       // of the refined pose, else the mean, at the last frame
  double worst_last_error_m = 0.0;  // the worst of the last 10 steps
  double last_step_ms = 0.0;        // their mean Localizer::step time
  double final_sigma_x_m = 0.0;     // the belief's spread along the corridor at the last frame
  int two_camera_updates = 0;       // steps whose update used both cameras
};

inline CorridorRun runCorridor(bool with_down_camera, int frames,
                               const std::string& backend = "cpu") {
  const Corridor& c = corridor();
  const Intrinsics K = smallCamera();
  LocalizerParams params = corridorParams();
  params.backend = backend;
  Localizer loc(params, c.map);
  std::mt19937_64 rng(11);
  CorridorRun run;
  StepResult res;
  for (int f = 0; f < frames; f += 3) {
    const Eigen::Isometry3d T = corridorPose(f);
    const DepthImage forward =
        sim::renderDepth(c.scene, K, T * forwardCamera(), DepthEncoding::kMono16Millimetres, 4.0,
                         sim::DepthNoise{0.0015, 0.02}, &rng);
    const DepthImage down =
        sim::renderDepth(c.scene, K, T * downCamera(), DepthEncoding::kMono16Millimetres, 4.0,
                         sim::DepthNoise{0.0015, 0.02}, &rng);
    StepInput in;
    in.stamp_s = 50.0 + f * kCorridorDt;
    in.depth = &forward;
    in.intrinsics = K;
    in.has_odometry = true;
    in.T_odom_base = T;
    in.has_attitude = true;
    if (with_down_camera) {
      CameraInput cam;
      cam.name = "down";
      cam.depth = &down;
      cam.intrinsics = K;
      cam.T_base_cam = downCamera();
      cam.frame = params.frame;
      cam.measurement = params.measurement;
      in.more_cameras.push_back(cam);
    }
    res = loc.step(in);
    EXPECT_EQ(res.status, StepStatus::kOk) << res.message;
    if (f >= frames - 30) {
      run.last_step_ms += res.timings.total_ms / 10.0;
      const Particle g = poseToParticle(T);
      const Particle& e = res.refinement.pose;
      run.worst_last_error_m =
          std::max(run.worst_last_error_m,
                   std::hypot(std::hypot(e.x_m - g.x_m, e.y_m - g.y_m), e.z_m - g.z_m));
    }
    if (res.cameras.size() == 2 && res.cameras[0].used && res.cameras[1].used) {
      ++run.two_camera_updates;
    }
  }
  const Particle gt = poseToParticle(corridorPose(frames - 1 - (frames - 1) % 3));
  const Particle& est = res.refinement.pose;
  run.final_error_m = std::hypot(std::hypot(est.x_m - gt.x_m, est.y_m - gt.y_m), est.z_m - gt.z_m);
  run.final_sigma_x_m = std::sqrt(res.estimate.covariance(0, 0));
  return run;
}

}  // namespace test
}  // namespace gmm_mcl
