#include "gmm_mcl/experiments/figures/map_series.h"

#include <cmath>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/seven_scenes_cloud.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace figures {

PointCloud scenarioCloud(const Scenario& scenario) {
  if (!scenario.dataset_dir.empty()) {
    SevenScenesCloudParams cp;  // frames 0..990 every 10th, (0.1, 4] m, 2 cm: the protocol map
    return buildSevenScenesCloud(scenario.dataset_dir, cp);
  }
  // Synthetic: one loop of the trajectory (0.25 rad/s: 25 s), every 15th frame.
  const sim::BoxScene scene = sim::makeDefaultScene();
  const Intrinsics K = sim::defaultCamera(320);
  const std::vector<Eigen::Isometry3d> traj = sim::makeTrajectory(760);
  const Eigen::Isometry3d T_base_cam = sim::defaultBaseToCamera();
  VoxelAccumulator voxels(0.02f);
  for (size_t f = 0; f < traj.size(); f += 15) {
    const Eigen::Isometry3d T_map_cam = traj[f] * T_base_cam;
    const DepthImage img =
        sim::renderDepth(scene, K, T_map_cam, DepthEncoding::kFloat32Metres, 6.0);
    for (int v = 0; v < img.height_px; ++v) {
      for (int u = 0; u < img.width_px; ++u) {
        const float z = img.depthMetres(u, v);
        if (!(z > 0.1f && z <= 6.0f)) continue;
        float p[3];
        backProject(K, static_cast<float>(u), static_cast<float>(v), z, p);
        const Eigen::Vector3d pw = T_map_cam * Eigen::Vector3d(p[0], p[1], p[2]);
        voxels.add(pw.cast<float>());
      }
    }
  }
  return voxels.centroids();
}

GmmMap fitScenarioMap(const Scenario& scenario, const PointCloud& cloud_world, int components,
                      EmParams params) {
  params.components = components;
  const EmResult fit = fitGmm(cloud_world, params);
  const std::string source = "fit M=" + std::to_string(components);
  const GmmMap world = makeStorableMap(fit.components, params.reg_covar_m2, source);
  if (scenario.R_map_world.isIdentity(0.0)) return world;
  return rotateMap(world, scenario.R_map_world, source + " (map frame)");
}

}  // namespace figures
}  // namespace gmm_mcl
