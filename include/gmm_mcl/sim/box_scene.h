// A small analytic indoor scene (a room with box furniture) for tests and the offline demo:
// exact ray casting for depth, a GMM made by tiling every surface with flat Gaussians, a smooth
// drone-like trajectory. Deliberately asymmetric so that the pose is observable.
#pragma once

#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace sim {

struct Box {
  Eigen::Vector3d min_m;
  Eigen::Vector3d max_m;
};

// The box with corners (x0, y0, z0) and (x1, y1, z1) (m).
inline Box makeBox(double x0, double y0, double z0, double x1, double y1, double z1) {
  return Box{Eigen::Vector3d(x0, y0, z0), Eigen::Vector3d(x1, y1, z1)};
}

struct BoxScene {
  Box room;                 // seen from inside
  std::vector<Box> blocks;  // solid furniture, seen from outside
};

// 8 m x 6 m x 3 m room with ten blocks of different sizes, none symmetric to another.
BoxScene makeDefaultScene();

// A camera rig's ambiguous case (docs/multi_camera.md): a 30 m x 2 m x 3 m corridor with blank
// walls and flat boxes (20 cm high) of different sizes at irregular places on its floor. A level
// forward camera ranging 3 m from 1.5 m height sees only the blank side walls, so its position
// along the corridor is unobservable; a downward camera sees the boxes.
BoxScene makeCorridorScene();

// The corridor's rig: a level forward camera 10 cm ahead of the base and a downward one 10 cm
// below it (its wider image axis along base x).
Eigen::Isometry3d corridorForwardCamera();
Eigen::Isometry3d corridorDownCamera();
// The drone along the corridor at 1.5 m height and 0.6 m/s from x = 11 m, with a slight weave in
// y and yaw: n base poses at 30 Hz.
std::vector<Eigen::Isometry3d> corridorTrajectory(int n);

// The optical frame (z along the view, x along image right) of a camera at position_m in the
// base frame looking along `view` with image right along `right` (base axes, orthogonal).
Eigen::Isometry3d baseToCamera(const Eigen::Vector3d& position_m, const Eigen::Vector3d& view,
                               const Eigen::Vector3d& right);

// Distance along a unit ray to the first surface; +inf when nothing is hit.
double castRay(const BoxScene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir);

struct DepthNoise {
  double sigma_at_1m_m = 0.0;  // axial noise sigma = sigma_at_1m * z^2 (structured-light-like)
  double dropout = 0.0;        // probability that a pixel is missing
};

// Renders z-depth (optical frame, pixel centres at integer coordinates) as 16UC1 millimetres
// (0 = no return) or 32FC1 metres (NaN = no return). Returns beyond max_range_m are missing.
DepthImage renderDepth(const BoxScene& scene, const Intrinsics& K,
                       const Eigen::Isometry3d& T_map_cam, DepthEncoding encoding,
                       double max_range_m, const DepthNoise& noise = DepthNoise(),
                       std::mt19937_64* rng = nullptr);

// Tiles every visible face with flat Gaussians on a grid of about spacing_m (in-plane sigma
// 0.3 x the cell size, about what EM fits to a uniform tile, normal sigma normal_sigma_m), weights
// proportional to cell area.
GmmMap tileScene(const BoxScene& scene, double spacing_m, double normal_sigma_m);

// A smooth 6-DoF trajectory of the base through the room (x forward, z up; small roll/pitch),
// n poses at 30 Hz, starting near `start`.
std::vector<Eigen::Isometry3d> makeTrajectory(int n);

// Fixed base -> camera optical frame: camera looking along base x, slightly down.
Eigen::Isometry3d defaultBaseToCamera();

}  // namespace sim
}  // namespace gmm_mcl
