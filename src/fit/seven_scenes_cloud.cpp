#include "gmm_mcl/fit/seven_scenes_cloud.h"

#include <Eigen/Core>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/fit_error.h"

namespace gmm_mcl {

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
  // The data-set reader: intrinsics, the poses with their rotations orthonormalised as the
  // replay reads them, depth in millimetres.
  std::unique_ptr<SevenScenesSequence> seq;
  try {
    seq.reset(new SevenScenesSequence(data_dir, params.last_frame + 1));
  } catch (const std::runtime_error& e) {
    throw FitError(std::string("7-Scenes cloud: ") + e.what());
  }
  if (params.last_frame >= seq->size()) {
    throw FitError(data_dir + ": 7-Scenes cloud: frame " + std::to_string(params.last_frame) +
                   " asked for, the sequence has " + std::to_string(seq->size()));
  }
  const Intrinsics& K = seq->intrinsics();
  VoxelAccumulator voxels(params.voxel_m);
  SevenScenesCloudStats s;
  for (int f = params.first_frame; f <= params.last_frame; f += params.frame_step) {
    DepthImage depth;
    try {
      depth = seq->loadDepth(f);
    } catch (const std::exception& e) {
      throw FitError(std::string("7-Scenes cloud: ") + e.what());
    }
    const Eigen::Isometry3d& T_world_cam = seq->T_world_cam(f);
    const Eigen::Matrix3f R = T_world_cam.linear().cast<float>();
    const Eigen::Vector3f t = T_world_cam.translation().cast<float>();
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
