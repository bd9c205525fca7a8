// Offline demo: the localizer on the built-in synthetic scene (no ROS, no data files).
// Renders depth along a smooth trajectory (default: the mesh scene with boxes and cylinders,
// ray cast through the BVH, with the structured-light sensor model; --scene box: the analytic
// box scene with its simple noise; --scene corridor: the camera rig's corridor, where a forward
// camera alone cannot tell where it is and --down-camera adds the downward one,
// docs/multi_camera.md), feeds drifting odometry and noisy attitude (the protocol's
// OdometrySynthesizer), starts from a uniform 4 m cube / pi yaw range (the corridor: 8 m of it)
// and prints the error.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/replay/odometry_synthesizer.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/mesh_scene.h"
#include "gmm_mcl/sim/step_input.h"

namespace gmm_mcl {

namespace {

const char* kUsage =
    "usage: gmm_mcl_sim_demo [--frames N] [--num-particles N (1068)] [--seed S]\n"
    "                        [--pixel-stride PX (8)]\n"
    "                        [--weighting paper|tempered] [--temperature T] [--backend cpu|cuda]\n"
    "                        [--width PX] [--map-spacing M] [--map-normal-sigma M]\n"
    "                        [--scene mesh|box|corridor] [--down-camera]\n"
    "                        [--no-sensor-noise] [--save-map FILE]\n"
    "                        [--save-mesh FILE.ply] [--quiet]\n"
    "Filter parameters: every one as --name-with-dashes (the list under --help).\n";

}  // namespace

int run(int argc, char** argv) {
  int frames = 300;
  double spacing_m = 0.4, normal_sigma_m = 0.015;
  int width_px = 640;
  uint64_t seed = 1;
  std::string backend = "cpu", save_map, save_mesh, scene_name = "mesh";
  bool quiet = false, sensor_noise = true, down_camera = false;
  LocalizerParams params;
  cli::CommandLine cl("gmm_mcl_sim_demo", kUsage);
  // clang-format off
  cl.flags({{"frames", &frames}, {"seed", &seed},
           {"map-spacing", &spacing_m}, {"map-normal-sigma", &normal_sigma_m}, {"width", &width_px},
           {"backend", &backend}, {"save-map", &save_map}, {"scene", &scene_name},
           {"no-sensor-noise", cli::Clear{&sensor_noise}}, {"save-mesh", &save_mesh},
           {"down-camera", &down_camera},
           {"quiet", &quiet}});
  // clang-format on
  params.frame.pixel_stride = 8;
  cl.addLocalizerParams(&params, {"seed", "backend", "init_centre", "init_yaw_centre"});
  cl.alias("stride", "pixel-stride");
  cl.alias("particles", "num-particles");
  cl.parse(argc, argv);

  if (scene_name != "mesh" && scene_name != "box" && scene_name != "corridor") {
    std::fprintf(stderr, "unknown scene '%s' (mesh, box, corridor)\n", scene_name.c_str());
    return 2;
  }
  const bool corridor = scene_name == "corridor";
  if (down_camera && !corridor) {
    std::fprintf(stderr, "--down-camera: only with --scene corridor\n");
    return 2;
  }
  const bool mesh_scene = scene_name == "mesh";
  const sim::BoxScene box_scene = corridor ? sim::makeCorridorScene() : sim::makeDefaultScene();
  sim::MeshScene scene;
  if (mesh_scene) scene = sim::makeDefaultMeshScene();
  GmmMap map = mesh_scene ? sim::tileScene(scene.primitives, spacing_m, normal_sigma_m)
                          : sim::tileScene(box_scene, spacing_m, normal_sigma_m);
  if (!save_map.empty()) saveMap(map, save_map);
  if (!save_mesh.empty()) {
    sim::PrimitiveScene boxes_only;
    boxes_only.room = box_scene.room;
    boxes_only.boxes = box_scene.blocks;
    sim::savePlyMesh(mesh_scene ? scene.mesh : sim::meshFromScene(boxes_only), save_mesh);
  }
  const std::vector<Eigen::Isometry3d> truth =
      corridor ? sim::corridorTrajectory(frames) : sim::makeTrajectory(frames);
  const Eigen::Isometry3d T_base_cam =
      corridor ? sim::corridorForwardCamera() : sim::defaultBaseToCamera();
  const Intrinsics K = sim::defaultCamera(width_px);

  params.filter.seed = seed;
  // The corridor's forward camera ranges 3 m: it sees only the blank walls.
  if (!cl.given("max-range-m")) params.frame.max_range_m = corridor ? 3.0f : 6.0f;
  params.T_base_cam = T_base_cam;
  params.backend = backend;
  const Particle start = poseToParticle(truth[0]);
  params.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  params.init.yaw_centre_rad = start.yaw_rad;
  if (corridor) {  // anywhere along 8 m of the corridor, 60 cm across
    params.init.centre_m = Eigen::Vector3d(13.0, 1.0, 1.5);
    if (!cl.given("init-half-extent")) params.init.half_extent_m = Eigen::Vector3d(4.0, 0.3, 0.05);
  }
  CameraInput down;  // the corridor's downward camera, with the first camera's parameters
  down.name = "down";
  down.T_base_cam = sim::corridorDownCamera();
  down.frame = params.frame;
  down.measurement = params.measurement;
  down.intrinsics = K;
  Localizer localizer(params, map);
  if (!localizer.backendWarning().empty()) {
    std::fprintf(stderr, "warning: %s\n", localizer.backendWarning().c_str());
  }
  std::printf(
      "gmm_mcl demo: synthetic %s scene, %zu components, %d particles, %dx%d depth%s, stride %d, "
      "%s weighting, %s backend, seed %llu\n",
      mesh_scene ? "mesh (boxes and cylinders)"
      : corridor ? "corridor"
                 : "box",
      map.size(), params.filter.num_particles, K.width_px, K.height_px,
      down_camera ? " (forward and down cameras)" : "", params.frame.pixel_stride,
      weightingModeName(params.filter.weighting), localizer.backend().name().c_str(),
      static_cast<unsigned long long>(seed));

  // Odometry and attitude noise per the DESIGN.md protocol; depth noise seeded per frame.
  OdometrySynthesizer motion(ProtocolNoise(), seed + 1000);
  std::mt19937_64 rng(seed + 1000);
  const sim::DepthNoise box_noise{0.0015, 0.02};
  const sim::SensorNoiseParams sensor;  // Kinect v1 class defaults (docs/sim.md)
  double sum_sq = 0.0, total_ms = 0.0;
  int counted = 0;
  double err_t = 0.0, err_yaw = 0.0;
  for (int f = 0; f < frames; ++f) {
    const Eigen::Isometry3d odom = motion.next(truth[f]);
    double roll, pitch;
    motion.attitude(truth[f], &roll, &pitch);
    const Eigen::Isometry3d T_map_cam = truth[f] * T_base_cam;
    const DepthImage depth =
        mesh_scene
            ? sim::renderDepth(*scene.bvh, K, T_map_cam, DepthEncoding::kMono16Millimetres, 8.0,
                               sensor_noise ? &sensor : nullptr, sim::frameSeed(seed, f))
            : sim::renderDepth(box_scene, K, T_map_cam, DepthEncoding::kMono16Millimetres, 8.0,
                               sensor_noise ? box_noise : sim::DepthNoise(), &rng);
    StepInput in = sim::frameInput(f / 30.0, odom, roll, pitch, depth, K);
    DepthImage down_depth;
    if (down_camera) {
      down_depth = sim::renderDepth(box_scene, K, truth[f] * down.T_base_cam,
                                    DepthEncoding::kMono16Millimetres, 8.0,
                                    sensor_noise ? box_noise : sim::DepthNoise(), &rng);
      down.depth = &down_depth;
      in.more_cameras.push_back(down);
    }
    const StepResult r = localizer.step(in);
    total_ms += r.timings.total_ms;
    const Particle est = r.estimate.mean;
    const Particle gt = poseToParticle(truth[f]);
    err_t = std::sqrt(std::pow(est.x_m - gt.x_m, 2) + std::pow(est.y_m - gt.y_m, 2) +
                      std::pow(est.z_m - gt.z_m, 2));
    err_yaw = std::abs(wrapAngle(est.yaw_rad - gt.yaw_rad));
    if (f >= frames / 2) {
      sum_sq += err_t * err_t;
      ++counted;
    }
    if (!quiet && (f % 10 == 0 || f == frames - 1)) {
      // The likelihood at the true pose tells a hard view from a lost filter.
      LikelihoodScratch scratch;
      const DepthFrame frame = prepareFrame(depth, K, params.frame);
      const double truth_ll =
          poseLogLikelihood(map.packed(), frame, toRigidF(truth[f] * T_base_cam),
                            params.measurement, &scratch)
              .log_likelihood /
          std::max<size_t>(1, frame.size());
      std::printf(
          "frame %4d  error %7.3f m %6.2f deg  Neff %7.1f  loglik/px best %6.2f truth %6.2f"
          "  beta %.3f  reinit %3d  %6.1f ms  %s\n",
          f, err_t, err_yaw * 180.0 / M_PI, r.neff, r.best_loglik_per_pixel, truth_ll,
          r.beta_fraction, r.reinitialised, r.timings.total_ms, stepStatusName(r.status));
    }
  }
  std::printf(
      "final error: %.3f m translation, %.2f deg yaw; RMSE over the second half: %.3f m; "
      "mean step %.1f ms\n",
      err_t, err_yaw * 180.0 / M_PI, std::sqrt(sum_sq / std::max(1, counted)), total_ms / frames);
  return 0;
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
