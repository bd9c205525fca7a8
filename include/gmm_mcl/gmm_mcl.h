// The localizer's API in one include (docs/architecture.md "API"): link gmm_mcl_core and compile
// with EIGEN_MAX_STATIC_ALIGN_BYTES=0 (the core's layout of fixed-size Eigen members).
//   GmmMap map = loadMap("map.gmm");                      // map/gmm_map_io.h
//   LocalizerParams params;                                // filter/params.h, the parameter table
//   params.T_base_cam = ...;                               // the camera's optical frame in base
//   Localizer localizer(params, std::move(map));           // filter/localizer.h
//   StepInput in; in.depth = &image; in.intrinsics = K;    // camera/depth_image.h
//   StepResult r = localizer.step(in);                     // the pose, its covariance, status
// Every header under gmm_mcl/{map,camera,measurement,backend,filter,common} is API as well (the
// stages' own types and functions); gmm_mcl/internal/ is not installed.
#pragma once

#include "gmm_mcl/backend/backend_params.h"
#include "gmm_mcl/backend/likelihood_backend_base.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/common/types.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/parameter_table.h"
#include "gmm_mcl/filter/params.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/pose_reset.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/measurement_params.h"
