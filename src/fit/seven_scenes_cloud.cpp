#include "gmm_mcl/fit/seven_scenes_cloud.h"

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/fit/fit_error.h"
#ifdef GMM_MCL_HAVE_PNG
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace {

// Reads `count` whitespace-separated numbers.
std::vector<double> readNumbers(const std::string& path, size_t count) {
  std::ifstream in(path);
  if (!in) throw FitError(path + ": cannot open");
  std::vector<double> v;
  double x;
  while (v.size() < count && in >> x) v.push_back(x);
  if (v.size() != count) {
    throw FitError(path + ": expected " + std::to_string(count) + " numbers, read " +
                   std::to_string(v.size()));
  }
  for (double d : v) {
    if (!std::isfinite(d)) throw FitError(path + ": non-finite number");
  }
  return v;
}

std::string framePath(const std::string& dir, int frame, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "/frame-%06d.%s", frame, suffix);
  return dir + name;
}

}  // namespace

std::string SevenScenesCloudParams::validate() const {
  std::ostringstream err;
  if (first_frame < 0) err << "first_frame must be >= 0; ";
  if (last_frame < first_frame) err << "last_frame must be >= first_frame; ";
  if (frame_step < 1) err << "frame_step must be >= 1; ";
  if (!(min_depth_m >= 0.f) || !(max_depth_m > min_depth_m)) {
    err << "depth window must satisfy 0 <= min_depth_m < max_depth_m; ";
  }
  if (!(voxel_m > 0.f)) err << "voxel_m must be > 0; ";
  if (pixel_stride < 1) err << "pixel_stride must be >= 1; ";
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

PointCloud buildSevenScenesCloud(const std::string& data_dir, const SevenScenesCloudParams& params,
                                 SevenScenesCloudStats* stats) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("7-Scenes cloud parameters: " + fault);
#ifndef GMM_MCL_HAVE_PNG
  (void)data_dir;
  (void)stats;
  throw FitError("7-Scenes cloud: this build has no libpng (GMM_MCL_HAVE_PNG) to read depth");
#else
  const std::vector<double> k = readNumbers(data_dir + "/camera-intrinsics.txt", 9);
  VoxelAccumulator voxels(params.voxel_m);
  SevenScenesCloudStats s;
  Intrinsics K;
  bool have_k = false;
  for (int f = params.first_frame; f <= params.last_frame; f += params.frame_step) {
    const std::string depth_path = framePath(data_dir, f, "depth.png");
    DepthImage depth;
    try {
      depth = loadDepthPng16(depth_path);
    } catch (const std::exception& e) {
      throw FitError(std::string("7-Scenes cloud: ") + e.what());
    }
    if (!have_k) {
      try {
        K = makeIntrinsics(k.data(), depth.width_px, depth.height_px);
      } catch (const std::exception& e) {
        throw FitError(data_dir + "/camera-intrinsics.txt: " + e.what());
      }
      have_k = true;
    } else if (depth.width_px != K.width_px || depth.height_px != K.height_px) {
      throw FitError(depth_path + ": image size differs from the first frame");
    }
    const std::vector<double> pose = readNumbers(framePath(data_dir, f, "pose.txt"), 16);
    Eigen::Matrix4d T_world_cam;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) T_world_cam(r, c) = pose[4 * r + c];
    }
    // The rotation as gmm_mcl_replay reads it (nearest rotation of the text matrix).
    Eigen::Matrix3d R_world_cam;
    std::string why;
    if (!nearestRotation(T_world_cam.topLeftCorner<3, 3>(), &R_world_cam, &why)) {
      throw FitError(framePath(data_dir, f, "pose.txt") + ": " + why);
    }
    const Eigen::Matrix3f R = R_world_cam.cast<float>();
    const Eigen::Vector3f t = T_world_cam.topRightCorner<3, 1>().cast<float>();
    for (int v = 0; v < depth.height_px; v += params.pixel_stride) {
      for (int u = 0; u < depth.width_px; u += params.pixel_stride) {
        const float z = depth.depthMetres(u, v);
        if (!(z > params.min_depth_m && z <= params.max_depth_m)) continue;  // NaN fails too
        float p_cam[3];
        backProject(K, static_cast<float>(u), static_cast<float>(v), z, p_cam);
        voxels.add(R * Eigen::Vector3f(p_cam[0], p_cam[1], p_cam[2]) + t);
        ++s.points_back_projected;
      }
    }
    ++s.frames;
  }
  PointCloud out = voxels.centroids();
  s.voxels = out.size();
  if (stats) *stats = s;
  return out;
#endif
}

}  // namespace gmm_mcl
