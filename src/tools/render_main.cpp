// gmm_mcl_render: renders depth from a triangle mesh (the built-in synthetic scene, the
// procedural building world of a seed, or a PLY) along a trajectory (the built-in drone
// trajectory, a walk through the building, a traj.txt of camera-to-world 4x4 rows, or a TUM
// trajectory of the camera) into a TUM RGB-D folder: depth/<t>.png (5000 units per
// metre), depth.txt, groundtruth.txt (t tx ty tz qx qy qz qw, camera optical frame to world),
// intrinsics.txt and gravity-direction.txt (the data-set library's writer, which its TUM reader
// reads back). The structured-light sensor model is on by default, seeded per frame.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/datasets/sequence_base.h"
#include "gmm_mcl/datasets/sequence_writer.h"
#include "gmm_mcl/datasets/tum_sequence.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/sim/building_scene.h"
#include "gmm_mcl/sim/building_walk.h"
#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/mesh_scene.h"
#include "gmm_mcl/sim/trajectory_io.h"

namespace gmm_mcl {

namespace {

const char* kUsage =
    "usage: gmm_mcl_render --out DIR [--mesh FILE.ply | --building SEED [--walk W]]\n"
    "                      [--trajectory FILE] [--camera SPEC]\n"
    "                      [--first I] [--frames N] [--stride K] [--rate HZ] [--start-time S]\n"
    "                      [--seed S] [--no-noise] [--dropout P] [--depth-scale-error E]\n"
    "                      [--max-range M]\n"
    "                      [--down GX,GY,GZ] [--width PX] [--save-map FILE.gmm]\n"
    "                      [--map-spacing M] [--save-mesh FILE.ply]\n"
    "                      [--save-trajectory FILE.txt] [--quiet]\n"
    "  --mesh        a PLY mesh (default: the built-in room with boxes and cylinders)\n"
    "  --building    the procedural building world of this seed (docs/sim.md): 60 x 56 m, 36\n"
    "                rooms, corridors, doors, furniture\n"
    "  --walk W      with --building and no --trajectory: the camera flies walk W (a seed) from\n"
    "                room to room (default 1; 900 frames unless --frames)\n"
    "  --trajectory  camera-to-world poses: 16 numbers a line (row-major 4x4, Replica traj.txt)\n"
    "                or TUM 't tx ty tz qx qy qz qw' (default: the built-in drone trajectory)\n"
    "  --camera      cam_params.json (Replica) or fx,fy,cx,cy,width,height (default: f = 585 px\n"
    "                at 640x480 scaled to --width)\n"
    "  --first I     start at pose I of the trajectory (default 0; stamps keep their place)\n"
    "  --frames N    at most N frames (default: all of a file, 300 of the built-in)\n"
    "  --stride K    every K-th pose of the trajectory (default 1)\n"
    "  --rate HZ     frame rate for trajectories without stamps (default 30)\n"
    "  --no-noise    ideal depth (only the range window of --max-range)\n"
    "  --dropout P   probability that a pixel is missing at random (default 0.005)\n"
    "  --depth-scale-error E  the camera reports (1 + E) times the depth (0.004: 0.4% long)\n"
    "  --down        gravity direction in world coordinates (default 0,0,-1: z up)\n"
    "  --save-map    the built-in scene's or the building's tiled GMM (1.5 cm normal sigma)\n"
    "  --map-spacing its tile size (default 0.4 m for the built-in scene, 0.375 m for the\n"
    "                building: about 100,000 components)\n"
    "  --save-trajectory  the poses rendered, as a TUM trajectory of the camera\n"
    "  Without --out, only the --save-* files are written (nothing is rendered).\n";

// True when the first pose line of a file has 16 numbers (a 4x4 matrix per line).
bool isMatrixTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open trajectory");
  std::string line;
  while (std::getline(in, line)) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ls(line);
    int n = 0;
    std::string tok;
    while (ls >> tok) ++n;
    if (n > 0) return n == 16;
  }
  throw std::runtime_error(path + ": no poses");
}

// Frames rendered on demand (the writer asks for each once), seeded per frame.
class RenderedSequence : public Sequence {
 public:
  RenderedSequence(std::shared_ptr<const sim::MeshBvh> bvh, const Intrinsics& K,
                   std::vector<double> stamps, std::vector<Eigen::Isometry3d> poses,
                   const Eigen::Matrix3d& R_aligned_world, double max_range_m, bool noise,
                   const sim::SensorNoiseParams& sensor, uint64_t seed, std::string source,
                   bool quiet)
      : Sequence("render", std::move(source)),
        bvh_(std::move(bvh)),
        max_range_m_(max_range_m),
        noise_(noise),
        seed_(seed),
        quiet_(quiet),
        sensor_(sensor) {
    intrinsics_ = K;
    stamps_s_ = std::move(stamps);
    T_world_cam_ = std::move(poses);
    for (int i = 0; i < size(); ++i) depth_paths_.push_back("rendered frame " + std::to_string(i));
    R_aligned_world_ = R_aligned_world;
    gravity_source_ = "--down";
  }

  DepthImage loadDepth(int i) const override {
    const auto t0 = std::chrono::steady_clock::now();
    const DepthImage img =
        sim::renderDepth(*bvh_, intrinsics_, T_world_cam_[i], DepthEncoding::kMono16Millimetres,
                         max_range_m_, noise_ ? &sensor_ : nullptr, sim::frameSeed(seed_, i));
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    total_ms_ += ms;
    ++rendered_;
    if (!quiet_ && (i % 50 == 0 || i + 1 == size())) {
      std::printf("frame %d / %d  %.1f ms\n", i + 1, size(), ms);
    }
    return img;
  }
  double meanRenderMs() const { return rendered_ ? total_ms_ / rendered_ : 0.0; }

 private:
  std::shared_ptr<const sim::MeshBvh> bvh_;
  double max_range_m_;
  bool noise_;
  uint64_t seed_;
  bool quiet_;
  sim::SensorNoiseParams sensor_;
  mutable double total_ms_ = 0.0;
  mutable int rendered_ = 0;
};

// --camera: a Replica camera JSON, or fx,fy,cx,cy,width,height; empty: the default camera at
// width_px.
Intrinsics cameraFromFlag(const std::string& camera, int width_px) {
  Intrinsics K = sim::defaultCamera(width_px);
  if (camera.empty()) return K;
  if (camera.size() > 5 && camera.substr(camera.size() - 5) == ".json") {
    double units;
    sim::readReplicaCamera(camera, &K, &units);
    return K;
  }
  const std::vector<double> v = parseNumberList(camera);
  if (v.size() != 6) throw std::runtime_error("--camera: expected fx,fy,cx,cy,width,height");
  const double Km[9] = {v[0], 0, v[2], 0, v[1], v[3], 0, 0, 1};
  return makeIntrinsics(Km, static_cast<int>(v[4]), static_cast<int>(v[5]));
}

int run(int argc, char** argv) {
  std::string out, mesh_path, traj_path, camera, save_map, save_mesh, save_traj, down = "0,0,-1";
  int first = 0, frames = -1, stride = 1, width_px = 640, building_seed = -1;
  uint64_t walk_seed = 1;
  double map_spacing_m = 0.0;     // 0: the scene's default
  sim::SensorNoiseParams sensor;  // Kinect v1 class defaults (docs/sim.md)
  double rate_hz = 30.0, start_s = 0.0, max_range_m = 10.0;
  uint64_t seed = 1;
  bool noise = true, quiet = false;
  cli::CommandLine cl("gmm_mcl_render", kUsage);
  // clang-format off
  cl.flags({{"out", &out}, {"mesh", &mesh_path}, {"trajectory", &traj_path}, {"camera", &camera},
           {"first", &first}, {"frames", &frames}, {"stride", &stride}, {"rate", &rate_hz},
           {"start-time", &start_s}, {"seed", &seed}, {"no-noise", cli::Clear{&noise}},
           {"dropout", &sensor.random_dropout}, {"depth-scale-error", &sensor.depth_scale_error},
           {"max-range", &max_range_m}, {"down", &down},
           {"width", &width_px}, {"save-map", &save_map}, {"save-mesh", &save_mesh},
           {"building", &building_seed}, {"walk", &walk_seed}, {"map-spacing", &map_spacing_m},
           {"save-trajectory", &save_traj}, {"quiet", &quiet}});
  // clang-format on
  cl.parse(argc, argv);
  const std::string sensor_err = sensor.validate();
  if (!sensor_err.empty()) throw std::runtime_error("sensor model: " + sensor_err);
  const bool save_only = out.empty();
  if (save_only && save_map.empty() && save_mesh.empty() && save_traj.empty()) {
    cl.fail("--out is needed (or at least one of --save-map, --save-mesh, --save-trajectory)");
  }
  if (building_seed >= 0 && !mesh_path.empty()) cl.fail("--building and --mesh exclude each other");
  if (map_spacing_m < 0.0) cl.fail("--map-spacing must be positive");
  if (stride < 1 || first < 0 || !(rate_hz > 0.0) || !(max_range_m > 0.0) || width_px < 16) {
    cl.fail("--stride >= 1, --first >= 0, --rate > 0, --max-range > 0 and --width >= 16");
  }

  // Mesh.
  std::shared_ptr<const sim::MeshBvh> bvh;
  std::string source;
  const bool builtin = mesh_path.empty() && building_seed < 0;
  std::unique_ptr<sim::BuildingScene> building;
  if (building_seed >= 0) {
    using Clock = std::chrono::steady_clock;
    auto msSince = [](Clock::time_point t) {
      return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
    };
    sim::BuildingParams params;
    params.seed = static_cast<uint64_t>(building_seed);
    auto t0 = Clock::now();
    building.reset(new sim::BuildingScene(sim::makeBuilding(params)));
    const double plan_ms = msSince(t0);
    t0 = Clock::now();
    const sim::Mesh mesh = sim::meshFromBuilding(*building);
    const double mesh_ms = msSince(t0);
    t0 = Clock::now();
    bvh = std::make_shared<const sim::MeshBvh>(mesh);
    const double bvh_ms = msSince(t0);
    const Eigen::Vector3d size = building->bounds().max_m - building->bounds().min_m;
    if (!quiet) {
      std::printf(
          "building seed %d: %.1f x %.1f x %.1f m (%.0f m^2), %d rooms + corridors, %zu doors, "
          "%zu boxes (%zu walls and lintels), %zu cylinders, %zu triangles, %.1f m^2 of surface; "
          "plan and furniture %.0f ms, mesh %.0f ms, BVH %.0f ms\n",
          building_seed, size.x(), size.y(), size.z(), size.x() * size.y(), building->roomCount(),
          building->doors.size(), building->primitives.boxes.size(), building->wall_box_count,
          building->primitives.cylinders.size(), mesh.triangles.size(), mesh.area_m2(), plan_ms,
          mesh_ms, bvh_ms);
    }
    source = "gmm_mcl building world, seed " + std::to_string(building_seed);
    if (!save_mesh.empty()) sim::savePlyMesh(mesh, save_mesh, {}, source);
    if (!save_map.empty()) {
      const double spacing = map_spacing_m > 0.0 ? map_spacing_m : sim::kBuildingMapSpacingM;
      t0 = Clock::now();
      const GmmMap map = sim::tileBuilding(*building, spacing, sim::kBuildingMapNormalSigmaM);
      const double tile_ms = msSince(t0);
      saveMap(map, save_map);
      if (!quiet) {
        std::printf("%s: %zu components (%.3f m tiles), %.0f ms\n", save_map.c_str(), map.size(),
                    spacing, tile_ms);
      }
    }
  } else if (builtin) {
    const sim::MeshScene scene = sim::makeDefaultMeshScene();
    bvh = scene.bvh;
    source = "gmm_mcl built-in mesh scene";
    if (!save_mesh.empty()) sim::savePlyMesh(scene.mesh, save_mesh);
    if (!save_map.empty()) {
      saveMap(sim::tileScene(scene.primitives, map_spacing_m > 0.0 ? map_spacing_m : 0.4, 0.015),
              save_map);
    }
  } else {
    const auto t0 = std::chrono::steady_clock::now();
    const sim::Mesh mesh = sim::loadPlyMesh(mesh_path);
    bvh = std::make_shared<const sim::MeshBvh>(mesh);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (!quiet) {
      std::printf("%s: %zu vertices, %zu triangles, BVH %zu nodes (depth %d), %.0f ms\n",
                  mesh_path.c_str(), mesh.vertices_m.size(), mesh.triangles.size(),
                  bvh->nodeCount(), bvh->depth(), ms);
    }
    source = mesh_path;
    if (!save_mesh.empty()) sim::savePlyMesh(mesh, save_mesh);
    if (!save_map.empty()) {
      throw std::runtime_error("--save-map is for the built-in scene and the building only");
    }
  }

  if (save_only && save_traj.empty()) return 0;  // only the mesh or the map
  const Intrinsics K = cameraFromFlag(camera, width_px);

  // Trajectory (camera-to-world, optical frame) and stamps.
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> stamps;
  if (traj_path.empty() && building) {
    sim::BuildingWalkParams wp;
    wp.seed = walk_seed;
    wp.frames = first + (frames > 0 ? frames : 900) * stride;
    wp.rate_hz = rate_hz;
    const auto t0 = std::chrono::steady_clock::now();
    const sim::BuildingWalk walk = sim::makeBuildingWalk(*building, wp);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    poses = walk.T_world_cam;
    if (!quiet) {
      int rooms = 0;
      for (int s : walk.spaces) rooms += building->spaces[s].corridor ? 0 : 1;
      std::printf(
          "walk %llu: %zu poses, %.1f m flown, %zu spaces in turn (%d room visits), %.0f ms\n",
          static_cast<unsigned long long>(walk_seed), poses.size(), walk.length_m,
          walk.spaces.size(), rooms, ms);
    }
  } else if (traj_path.empty()) {
    const int n = frames > 0 ? frames * stride : 300 * stride;
    const std::vector<Eigen::Isometry3d> base = sim::makeTrajectory(n);
    for (const auto& T : base) poses.push_back(T * sim::defaultBaseToCamera());
    if (!builtin && !quiet) {
      std::printf(
          "note: the built-in trajectory is made for the built-in scene's 8 x 6 x 3 m room\n");
    }
  } else if (isMatrixTrajectory(traj_path)) {
    poses = sim::readMatrixTrajectory(traj_path);
  } else {
    for (const StampedPose& p : readTumTrajectory(traj_path)) {
      poses.push_back(p.T);
      stamps.push_back(p.stamp_s);
    }
  }
  std::vector<Eigen::Isometry3d> kept_poses;
  std::vector<double> kept_stamps;
  for (size_t i = first; i < poses.size(); i += stride) {
    if (frames > 0 && static_cast<int>(kept_poses.size()) >= frames) break;
    kept_poses.push_back(poses[i]);
    kept_stamps.push_back(stamps.empty() ? start_s + i / rate_hz : stamps[i]);
  }
  for (size_t i = 1; i < kept_stamps.size(); ++i) {
    if (!(kept_stamps[i] > kept_stamps[i - 1])) {
      throw std::runtime_error(traj_path + ": stamps must increase (pose " + std::to_string(i) +
                               ")");
    }
  }

  const std::vector<double> g = parseNumberList(down);
  if (g.size() != 3 || Eigen::Vector3d(g[0], g[1], g[2]).norm() < 1e-9) {
    throw std::runtime_error("--down: expected a non-zero gx,gy,gz");
  }
  const Eigen::Matrix3d R_aligned_world = gravityAlignment(Eigen::Vector3d(g[0], g[1], g[2]));

  if (kept_poses.empty()) {
    throw std::runtime_error("no poses from --first " + std::to_string(first) + " on");
  }
  if (!save_traj.empty()) {
    sim::writeTumTrajectory(save_traj, kept_stamps, kept_poses,
                            "camera (optical frame) to world, from " + source);
  }
  if (save_only) return 0;
  RenderedSequence seq(bvh, K, kept_stamps, kept_poses, R_aligned_world, max_range_m, noise, sensor,
                       seed, source, quiet);
  TumWriteOptions options;
  options.truth_offset_s = 0.0;  // rendered: ground truth at exactly the depth stamps
  options.truth_per_frame = 1;
  const auto t0 = std::chrono::steady_clock::now();
  writeTumFolder(seq, out, options);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("wrote %s: %d frames %dx%d, %s, seed %llu; render %.1f ms/frame, total %.1f s\n",
              out.c_str(), seq.size(), K.width_px, K.height_px,
              noise ? "sensor noise on" : "no noise", static_cast<unsigned long long>(seed),
              seq.meanRenderMs(), s);
  return 0;
}

}  // namespace

int toolMain(int argc, char** argv) {
  return cli::reportErrors("gmm_mcl_render", [&] { return run(argc, argv); });
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::toolMain(argc, argv); }
