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

// Bounds on pinhole intrinsics accepted from a sensor (px). Real depth cameras have focal
// lengths of 10^2 to 10^3 px; the bounds only keep every value a float32 can hold and every
// back-projected point finite (|u - cx| z / f for any int pixel and z up to 1e20 m).
constexpr double kMinFocalLengthPx = 1e-3;
constexpr double kMaxIntrinsicsPx = 1e9;

// Pinhole camera from a 3x3 K (row-major) and the image size; throws std::invalid_argument
// naming the fault for non-finite or non-positive focal lengths or sizes, and for focal lengths
// or principal points outside the bounds above.
Intrinsics makeIntrinsics(const double K[9], int width_px, int height_px);

// ---- sensor buffers -> core types: the byte-level checks of the ROS conversions, ROS-free so
// that they are unit-tested and fuzzed without ROS (test/fuzz). Each returns false with *error
// saying why; *out is unspecified then.

// A sensor_msgs/Image's fields: encoding 16UC1/mono16 (millimetres) or 32FC1 (metres), size,
// row step in bytes, byte order and `size` bytes of data (at least step x height).
bool depthImageFromBuffer(const std::string& encoding, uint32_t width, uint32_t height,
                          uint32_t step, bool big_endian, const uint8_t* data, size_t size,
                          DepthImage* out, std::string* error);

// A sensor_msgs/CameraInfo's K (row-major) and size; expected_width/height (> 0) are the depth
// image's size that the CameraInfo must match. Rejects an all-zero K as uncalibrated, then what
// makeIntrinsics rejects.
bool intrinsicsFromCameraMatrix(const double K[9], uint32_t width, uint32_t height,
                                int expected_width, int expected_height, Intrinsics* out,
                                std::string* error);

// An organized sensor_msgs/PointCloud2: `height` rows of `row_step` bytes, `width` points of
// `point_step` bytes each, float32 x, y, z at the given byte offsets (-1: the field is missing).
struct CloudLayout {
  uint32_t width = 0;
  uint32_t height = 0;
  uint32_t point_step = 0;
  uint32_t row_step = 0;
  bool big_endian = false;
  int x_offset = -1;
  int y_offset = -1;
  int z_offset = -1;
};

// Organized cloud in the camera optical frame -> 32FC1 depth image (z per pixel, NaN where
// missing) and pinhole intrinsics fitted to the points by least squares (u = fx x / z + cx,
// v = fy y / z + cy), checked as makeIntrinsics does.
bool depthImageFromCloudBuffer(const CloudLayout& layout, const uint8_t* data, size_t size,
                               DepthImage* out, Intrinsics* K, std::string* error);

}  // namespace gmm_mcl
