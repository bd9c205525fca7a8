// Named depth-noise models of common depth cameras (docs/measurement_model.md "Sensor
// presets", with each one's source): the parameter depth_noise_preset fills the model's a, b and
// z0 (DepthNoiseModel, sigma(z) = a + b (z - z0)^2) by name. "custom" (the default) keeps the
// three numbers as they are given. Stereo cameras (RealSense D400) depend on the depth
// resolution through the focal length, so they have one preset per common resolution; for
// another one, give b = subpixel / (f baseline) (the preset's subpixel, f from the CameraInfo)
// as depth_noise_b_per_m.
#pragma once

#include <string>
#include <vector>

#include "gmm_mcl/measurement/measurement_params.h"

namespace gmm_mcl {

// The name that keeps depth_noise_a_m, depth_noise_b_per_m and depth_noise_z0_m as given.
constexpr const char* kCustomDepthNoisePreset = "custom";

struct DepthNoisePreset {
  std::string name;        // e.g. "realsense_d435_848x480"
  std::string camera;      // e.g. "Intel RealSense D435 / D435i"
  std::string resolution;  // depth resolution the numbers hold for, e.g. "848x480"
  DepthNoiseModel model;
  double min_range_m = 0.0;  // working range over which the model holds
  double max_range_m = 0.0;
};

// Every preset, in the order of the parameter's choices (custom not included).
const std::vector<DepthNoisePreset>& depthNoisePresets();
// The preset called `name`; nullptr for "custom" or an unknown name.
const DepthNoisePreset* findDepthNoisePreset(const std::string& name);
// "custom" followed by every preset's name: the parameter's choices.
std::vector<std::string> depthNoisePresetChoices();
// Writes the preset's a, b and z0 into *model ("custom": *model unchanged). Returns "" when the
// name is known, else why, naming every valid one (*model unchanged).
std::string applyDepthNoisePreset(const std::string& name, DepthNoiseModel* model);

}  // namespace gmm_mcl
