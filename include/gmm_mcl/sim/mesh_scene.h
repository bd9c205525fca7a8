// The built-in synthetic scene as a triangle mesh: a room with box furniture (the box scene's)
// and cylinders (a column, a drum, a stool, a round side table, a ceiling lamp), deliberately
// asymmetric so that the pose is observable. Rendered by the BVH ray caster; its GMM tiles
// every visible surface of the primitives with flat Gaussians whose moments are those of the
// tile (computed by quadrature), plus a normal sigma.
#pragma once

#include <memory>
#include <vector>

#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh.h"
#include "gmm_mcl/sim/mesh_bvh.h"

namespace gmm_mcl {
namespace sim {

// Vertical cylinder (axis along z), closed by caps where they are not on the floor or ceiling.
struct Cylinder {
  Eigen::Vector2d centre_m;
  double radius_m = 0.0;
  double z_min_m = 0.0;
  double z_max_m = 0.0;
};

// The cylinder of radius r (m) about (x, y) from z0 to z1.
inline Cylinder makeCylinder(double x, double y, double r, double z0, double z1) {
  Cylinder c;
  c.centre_m = Eigen::Vector2d(x, y);
  c.radius_m = r;
  c.z_min_m = z0;
  c.z_max_m = z1;
  return c;
}

struct PrimitiveScene {
  Box room;                         // seen from inside
  std::vector<Box> boxes;           // solid, seen from outside
  std::vector<Cylinder> cylinders;  // solid, seen from outside
};

// The box scene's room and ten blocks plus five cylinders (8 m x 6 m x 3 m).
PrimitiveScene makeDefaultPrimitiveScene();

// Triangles of every surface that can be seen (faces lying on the room's walls, floor or
// ceiling are left out); cylinders as `segments`-sided prisms.
Mesh meshFromScene(const PrimitiveScene& scene, int cylinder_segments = 48);

// Tiles the same surfaces with about spacing_m tiles (arcs and rings for cylinders); each tile
// is one Gaussian with the tile's area as weight (normalised), its centroid as mean and its
// second moments plus normal_sigma_m^2 along the surface normal as covariance.
GmmMap tileScene(const PrimitiveScene& scene, double spacing_m, double normal_sigma_m);

// Scenes of many primitives against each other (the building: walls meeting walls, furniture
// against walls and on shelves): like meshFromScene and tileScene, but every box face and every
// face of the room keeps only its part that can be seen, the part where the space in front of it
// lies inside the room and outside every other box (faces touching another box or lying inside
// one are left out, wholly or in part). Faces longer than max_face_m are cut into equal pieces
// first (a flat BVH-friendly mesh). Cylinders are meshed and tiled as by meshFromScene and
// tileScene, less a cap that rests on a box (or hangs from one) over its whole area; other parts
// of cylinders hidden by boxes or by other cylinders are kept.
Mesh visibleMeshFromScene(const PrimitiveScene& scene, int cylinder_segments = 24,
                          double max_face_m = 8.0);
// Tiles the same visible surfaces: each piece of a face on a grid of about spacing_m, each tile's
// Gaussian from the moments of its visible part only (12 x 12 quadrature, plus the variance of a
// quadrature cell so that a whole tile's moments are exact); tiles less than 3 % visible are
// left out. Weights are the visible areas, normalised.
GmmMap tileVisibleScene(const PrimitiveScene& scene, double spacing_m, double normal_sigma_m,
                        double max_face_m = 8.0);

// The default scene ready to render: primitives, mesh, BVH.
struct MeshScene {
  PrimitiveScene primitives;
  Mesh mesh;
  std::shared_ptr<const MeshBvh> bvh;
};
MeshScene makeDefaultMeshScene();

// A pinhole camera with equal focal lengths f_px.
Intrinsics pinholeCamera(int width_px, int height_px, float f_px, float cx_px, float cy_px);

// The synthetic scenes' camera: 7-Scenes-like (f = 585 px at 640x480) scaled to width_px,
// height 3/4 of it, principal point at the image centre.
Intrinsics defaultCamera(int width_px);

// The 7-Scenes Kinect camera: 640x480, f = 585 px, principal point (320, 240).
Intrinsics sevenScenesCamera();

// A per-frame noise seed from a run's seed and the frame index (distinct streams).
uint64_t frameSeed(uint64_t seed, int frame);

}  // namespace sim
}  // namespace gmm_mcl
