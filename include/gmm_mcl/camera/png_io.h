// 16-bit grayscale PNG depth images (7-Scenes, TUM, Replica) via libpng; built when libpng is
// found (GMM_MCL_HAVE_PNG).
#pragma once

#include <string>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

// Reads a 16-bit single-channel PNG as raw uint16 values into a kMono16Millimetres image.
// The caller rescales when the data set's unit is not millimetres. Throws std::runtime_error
// naming the file and the fault.
DepthImage loadDepthPng16(const std::string& path);

// Writes a kMono16Millimetres image as a 16-bit PNG; throws std::runtime_error on failure.
void saveDepthPng16(const DepthImage& image, const std::string& path);

}  // namespace gmm_mcl
