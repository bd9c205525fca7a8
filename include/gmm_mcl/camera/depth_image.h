// A depth image as it arrives from a sensor, in one of the two ROS depth encodings.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

enum class DepthEncoding {
  kMono16Millimetres,  // sensor_msgs "16UC1"/"mono16": uint16 millimetres; 0 and 65535 = none
  kFloat32Metres,      // sensor_msgs "32FC1": float metres; 0, NaN, Inf = none
};

// Parses a sensor_msgs encoding string; returns false for anything but 16UC1, mono16, 32FC1.
bool parseDepthEncoding(const std::string& encoding, DepthEncoding* out);
const char* depthEncodingName(DepthEncoding encoding);

// Owning depth image. `data` holds height rows of `row_bytes` bytes, little-endian samples.
struct DepthImage {
  int width_px = 0;
  int height_px = 0;
  DepthEncoding encoding = DepthEncoding::kMono16Millimetres;
  size_t row_bytes = 0;
  std::vector<uint8_t> data;

  static DepthImage fromMillimetres(int width, int height, const std::vector<uint16_t>& mm);
  static DepthImage fromMetres(int width, int height, const std::vector<float>& m);

  // Depth of pixel (u, v) in metres; NaN when the pixel holds no measurement.
  float depthMetres(int u, int v) const;
  // Empty string when the layout is consistent, otherwise what is wrong.
  std::string checkLayout() const;
};

// Pinhole camera from a 3x3 K (row-major) and the image size; throws std::invalid_argument
// naming the fault for non-finite or non-positive focal lengths or sizes.
Intrinsics makeIntrinsics(const double K[9], int width_px, int height_px);

}  // namespace gmm_mcl
