// Camera paths through the building world (building_scene.h): a drone that flies from room to
// room through doors and along corridors at 1.25-1.75 m, looking along its direction of travel,
// flying through a point in each room it visits, or stopping there to turn where the way on turns
// sharply (and now and then anyway; sometimes looking around first), and sweeping its yaw now and
// then. Planned on a 5 cm grid of the floor plan: A* over the cells at least clearance_m (plus a
// planning margin) from anything that stands below the flying height (walls, furniture; not
// lintels, lamps or beams), costlier near obstacles so that paths keep to the middle of doors and
// corridors; each run of legs smoothed with that clearance kept, then timed with a speed that
// eases in and out of stops and slows in turns. Deterministic for a
// building, a seed and a frame count; the route grows until the frames are used up, so a shorter
// walk of the same seed follows the longer one's route but ends its last leg elsewhere.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/sim/building_scene.h"

namespace gmm_mcl {
namespace sim {

struct BuildingWalkParams {
  uint64_t seed = 1;
  int frames = 900;
  double rate_hz = 30.0;
  double max_speed_mps = 1.0;       // cruise speed; slower in turns and near stops
  double lateral_accel_mps2 = 0.5;  // turns: speed <= sqrt(lateral_accel / curvature)
  double min_height_m = 1.25;
  double max_height_m = 1.75;
  double clearance_m = 0.3;        // of the base, horizontally, from walls and furniture
  double turn_rate_radps = 1.0;    // turning on the spot at a stop
  double sweep_interval_s = 12.0;  // mean time between yaw sweeps
  double sweep_amplitude_rad = 0.8;

  // Empty when valid, else what is wrong (also: the building's doors must clear the flight).
  std::string validate() const;
};

struct BuildingWalk {
  std::vector<double> stamps_s;                 // rate_hz apart, from 0
  std::vector<Eigen::Isometry3d> T_world_base;  // x forward, z up
  std::vector<Eigen::Isometry3d> T_world_cam;   // optical: T_world_base * defaultBaseToCamera()
  std::vector<int> spaces;                      // the spaces flown through, in order
  double length_m = 0.0;                        // path length flown
};

// Throws std::invalid_argument for invalid parameters (or doors lower than the flight needs) and
// std::runtime_error when no room can be reached from the start.
BuildingWalk makeBuildingWalk(const BuildingScene& building, const BuildingWalkParams& params);

}  // namespace sim
}  // namespace gmm_mcl
