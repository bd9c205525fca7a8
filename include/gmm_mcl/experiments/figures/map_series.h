// Maps of several component counts for the component sweep, fitted in-process with the map
// builder (gmm_mcl_fit) to the scenario's point cloud.
#pragma once

#include <cstdint>

#include "gmm_mcl/experiments/figures/scenario.h"
#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/point_cloud.h"

namespace gmm_mcl {
namespace figures {

// The cloud the scenario's maps are fitted to, in the data set's world frame:
// 7-Scenes: the protocol cloud (frames 0, 10, ..., 990, depth in (0.1, 4] m, 2 cm voxels, as
// scripts/build_map_7scenes.sh); synthetic: noise-free depth rendered every 15th frame over one
// loop of the trajectory (320x240), depth up to 6 m, 2 cm voxels.
PointCloud scenarioCloud(const Scenario& scenario);

// Fits `components` components (params' other settings, e.g. seed and max_iterations) and
// returns the map rotated into the scenario's map frame.
GmmMap fitScenarioMap(const Scenario& scenario, const PointCloud& cloud_world, int components,
                      EmParams params);

}  // namespace figures
}  // namespace gmm_mcl
