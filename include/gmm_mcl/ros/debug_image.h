// The ~debug_image: the depth frame in grey, each 32x32 patch tinted by its number of relevant
// components, and the 3-sigma ellipses of the projected components, all at one camera pose.
#pragma once

#include <sensor_msgs/Image.h>

#include <Eigen/Geometry>

#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {

// Fills out (rgb8, the image's size; header left to the caller).
void renderDebugImage(const DepthImage& depth, const Intrinsics& K, const GmmMap& map,
                      const Eigen::Isometry3d& T_map_cam, const FrameParams& frame_params,
                      const MeasurementParams& measurement, sensor_msgs::Image* out);

}  // namespace gmm_mcl
