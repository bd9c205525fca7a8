#include "gmm_mcl/experiments/figures/scenario.h"

#include <sys/stat.h>

#include <cstdlib>
#include <random>
#include <stdexcept>

#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace figures {
namespace {

bool isFile(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

}  // namespace

Scenario sevenScenesScenario(const std::string& data_dir, int first_frame, int frames) {
  if (first_frame < 0 || frames <= 0) {
    throw std::invalid_argument("7-Scenes scenario: first frame must be >= 0 and frames > 0");
  }
  const SevenScenesSequence seq(data_dir, first_frame + frames);
  if (seq.size() < first_frame + frames) {
    throw std::runtime_error(data_dir + ": has " + std::to_string(seq.size()) +
                             " frames, asked for " + std::to_string(first_frame) + ".." +
                             std::to_string(first_frame + frames - 1));
  }
  Scenario s;
  // The folder's last two path components (e.g. 7scenes_redkitchen/data) name it.
  std::string shortname = data_dir;
  while (shortname.size() > 1 && shortname.back() == '/') shortname.pop_back();
  const size_t last = shortname.rfind('/');
  const size_t prev =
      last == std::string::npos || last == 0 ? std::string::npos : shortname.rfind('/', last - 1);
  if (prev != std::string::npos) shortname = shortname.substr(prev + 1);
  s.name = "7-Scenes " + shortname + " frames " + std::to_string(first_frame) + "-" +
           std::to_string(first_frame + frames - 1);
  s.dataset_dir = data_dir;
  s.intrinsics = seq.intrinsics();
  s.T_base_cam = opticalToBase();
  s.max_range_m = 4.0f;
  s.frame_rate_hz = 30.0;
  s.R_map_world = seq.R_aligned_world();
  Eigen::Isometry3d T_map_world = Eigen::Isometry3d::Identity();
  T_map_world.linear() = s.R_map_world;
  for (int f = first_frame; f < first_frame + frames; ++f) {
    s.T_map_base.push_back(T_map_world * seq.T_world_cam(f) * s.T_base_cam.inverse());
    s.depth.push_back(seq.loadDepth(f));
  }
  return s;
}

Scenario syntheticScenario(int first_frame, int frames, int width_px, uint64_t noise_seed) {
  if (first_frame < 0 || frames <= 0 || width_px < 32) {
    throw std::invalid_argument(
        "synthetic scenario: first frame must be >= 0, frames > 0 and width >= 32 px");
  }
  Scenario s;
  s.name = "synthetic box scene frames " + std::to_string(first_frame) + "-" +
           std::to_string(first_frame + frames - 1);
  s.intrinsics = sim::defaultCamera(width_px);
  s.T_base_cam = sim::defaultBaseToCamera();
  s.max_range_m = 6.0f;  // as the demo: the room is 8 m long
  const std::vector<Eigen::Isometry3d> traj = sim::makeTrajectory(first_frame + frames);
  s.T_map_base.assign(traj.begin() + first_frame, traj.end());
  const sim::BoxScene scene = sim::makeDefaultScene();
  const sim::DepthNoise noise{0.0015, 0.02};  // the demo's sensor
  std::mt19937_64 rng(noise_seed);
  for (const Eigen::Isometry3d& T : s.T_map_base) {
    s.depth.push_back(sim::renderDepth(scene, s.intrinsics, T * s.T_base_cam,
                                       DepthEncoding::kMono16Millimetres, 8.0, noise, &rng));
  }
  return s;
}

GmmMap syntheticTiledMap(double spacing_m, double normal_sigma_m) {
  return sim::tileScene(sim::makeDefaultScene(), spacing_m, normal_sigma_m);
}

std::string findSevenScenes(const std::string& exe_dir) {
  std::vector<std::string> roots;
  const char* env = std::getenv("GMM_MCL_DATASETS");
  if (env && *env) {
    roots.push_back(env);
  } else {
    roots.push_back("../shared/datasets");
    if (!exe_dir.empty()) {
      // build/<dir>/tool or build/test/devel/lib/gmm_mcl/tool: try the package's sibling.
      for (const char* up : {"/../..", "/../../..", "/../../../../.."}) {
        roots.push_back(exe_dir + up + "/../shared/datasets");
      }
    }
  }
  for (const std::string& r : roots) {
    const std::string dir = r + "/7scenes_redkitchen/data";
    if (isFile(dir + "/camera-intrinsics.txt")) return dir;
  }
  return "";
}

SensorInputs synthesiseInputs(const Scenario& scenario, const SensorNoise& noise, uint64_t seed) {
  std::mt19937_64 rng(seed * 7919 + 17);
  std::normal_distribution<double> g(0.0, 1.0);
  SensorInputs in;
  const int n = scenario.size();
  Eigen::Isometry3d odom = n > 0 ? scenario.T_map_base[0] : Eigen::Isometry3d::Identity();
  for (int f = 0; f < n; ++f) {
    const Eigen::Isometry3d& T = scenario.T_map_base[f];
    if (f > 0) {
      Eigen::Isometry3d delta = scenario.T_map_base[f - 1].inverse() * T;
      delta.translation() += noise.odom_sigma_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
      delta.linear() = delta.linear() * Eigen::AngleAxisd(noise.odom_sigma_yaw_rad * g(rng),
                                                          Eigen::Vector3d::UnitZ())
                                            .toRotationMatrix();
      odom = odom * delta;
    }
    in.T_odom_base.push_back(odom);
    double roll, pitch, yaw;
    rpyFromRotation(T.linear(), &roll, &pitch, &yaw);
    in.roll_rad.push_back(roll + noise.attitude_sigma_rad * g(rng));
    in.pitch_rad.push_back(pitch + noise.attitude_sigma_rad * g(rng));
  }
  return in;
}

}  // namespace figures
}  // namespace gmm_mcl
