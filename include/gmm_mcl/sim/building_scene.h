// The building test world (DESIGN.md "Building scale"): a procedural, seeded floor plan of
// rooms of different size, shape and content joined by doors and corridors, as primitives (the
// outer shell seen from inside, walls, lintels and furniture as boxes, columns, drums and round
// tables as cylinders), its mesh for the renderer and an analytic GMM tiling its visible
// surfaces. Deterministic for a seed (its own uniform draws from std::mt19937_64, no
// implementation-defined distributions). The plan: corridors first (one along the longer side,
// one across each half, mostly a third through the largest block), the blocks between them split
// into rooms, some pairs of rooms merged into one (an L-shape, or a room split by a partial
// wall), every room joined to the rest by one door plus a number of extra doors, then furniture
// per room of one of several kinds with its own sizes and counts, kept out of the doors' way.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/sim/mesh.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace sim {

// The tile spacing and normal sigma of the building's analytic GMM: about 100,000 components
// for the default building (103,409 for seed 1; docs/sim.md).
constexpr double kBuildingMapSpacingM = 0.375;
constexpr double kBuildingMapNormalSigmaM = 0.015;

struct BuildingParams {
  uint64_t seed = 1;
  double width_m = 60.0;   // along x
  double length_m = 56.0;  // along y
  double height_m = 3.0;   // floor to ceiling
  int room_count = 36;     // rooms (corridors not counted)
  int merged_rooms = 6;    // of which made of two plan cells (L-shapes, partial walls)
  int extra_doors = 12;    // doors beyond the one that joins each room to the rest
  double wall_thickness_m = 0.15;
  double door_min_width_m = 1.0;
  double door_max_width_m = 1.3;
  double door_height_m = 2.1;
  double corridor_min_width_m = 1.9;
  double corridor_max_width_m = 2.6;
  double min_room_side_m = 3.5;  // between wall centre lines

  // Empty when valid, else what is wrong.
  std::string validate() const;
};

// An axis-aligned rectangle of the floor plan (m).
struct PlanRect {
  Eigen::Vector2d lo_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d hi_m = Eigen::Vector2d::Zero();

  double area_m2() const { return (hi_m - lo_m).prod(); }
  bool contains(const Eigen::Vector2d& p_m) const {
    return (p_m.array() >= lo_m.array()).all() && (p_m.array() <= hi_m.array()).all();
  }
};

// A room, or the corridor network (one space of several strips).
struct BuildingSpace {
  std::string kind;  // "corridor", "office", "storage", ...
  bool corridor = false;
  std::vector<PlanRect> cells;  // between wall centre lines; two for merged rooms
};

// A door: a gap in the wall between two spaces, with a lintel above it.
struct BuildingDoor {
  int space_a = -1, space_b = -1;  // indices into BuildingScene::spaces
  int normal_axis = 0;             // 0: the wall runs along y (x = plane_m), 1: along x
  double plane_m = 0.0;            // the wall's centre line
  double centre_m = 0.0;           // the door's centre along the wall
  double width_m = 0.0;
  double height_m = 0.0;

  // The door's centre on the floor plan.
  Eigen::Vector2d centre2d() const;
};

struct BuildingScene {
  BuildingParams params;
  // room: the outer shell (seen from inside); boxes: [0, wall_box_count) walls, partial walls and
  // lintels, then furniture; cylinders: furniture.
  PrimitiveScene primitives;
  size_t wall_box_count = 0;
  std::vector<BuildingSpace> spaces;  // rooms and the corridor network
  std::vector<BuildingDoor> doors;

  int roomCount() const;  // spaces that are not corridors
  const Box& bounds() const { return primitives.room; }
  // The space whose cell holds p (wall centre lines split them), -1 outside every cell.
  int spaceAt(const Eigen::Vector2d& p_m) const;
};

// Throws std::invalid_argument for invalid parameters, std::runtime_error when no plan with the
// requested rooms and doors was found (too many rooms for the area).
BuildingScene makeBuilding(const BuildingParams& params);

// The building's triangles (visibleMeshFromScene: hidden faces left out; cylinders 24-sided).
Mesh meshFromBuilding(const BuildingScene& building);
// The building's analytic GMM (tileVisibleScene).
GmmMap tileBuilding(const BuildingScene& building, double spacing_m = kBuildingMapSpacingM,
                    double normal_sigma_m = kBuildingMapNormalSigmaM);

// True when p lies inside a box or cylinder of the scene grown by margin_m, or closer than
// margin_m to the shell (or outside it).
bool insideSolid(const PrimitiveScene& scene, const Eigen::Vector3d& p_m, double margin_m);

}  // namespace sim
}  // namespace gmm_mcl
