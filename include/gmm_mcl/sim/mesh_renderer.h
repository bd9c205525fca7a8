// Depth images of a triangle mesh by ray casting (MeshBvh): z-depth in the optical frame
// (x right, y down, z forward), pixel centres at integer (u, v), OpenMP over rows.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/sim/mesh_bvh.h"
#include "gmm_mcl/sim/sensor_noise.h"

namespace gmm_mcl {
namespace sim {

// Ideal z-depth up to max_depth_m (NaN beyond or where nothing is hit), incidence cosines and,
// when projector_baseline_m is not 0, the projector-shadow mask (a shadow ray from each hit
// point to the projector at T_map_cam * (baseline, 0, 0)).
IdealDepth renderIdealDepth(const MeshBvh& bvh, const Intrinsics& K,
                            const Eigen::Isometry3d& T_map_cam, double max_depth_m,
                            double projector_baseline_m = 0.0);

// Metres (NaN = missing) to a DepthImage: 16UC1 millimetres (rounded, 0 = missing) or 32FC1.
DepthImage toDepthImage(int width_px, int height_px, const std::vector<float>& z_m,
                        DepthEncoding encoding);

// Renders a depth image like the box scene's renderDepth: without noise, every hit with
// z-depth up to max_range_m; with noise, the sensor model (its own range window, further
// limited by max_range_m) with the given seed.
DepthImage renderDepth(const MeshBvh& bvh, const Intrinsics& K, const Eigen::Isometry3d& T_map_cam,
                       DepthEncoding encoding, double max_range_m,
                       const SensorNoiseParams* noise = nullptr, uint64_t seed = 0);

}  // namespace sim
}  // namespace gmm_mcl
