// 16-bit grayscale PNG depth images (7-Scenes, TUM, Replica; ROS compressedDepth) via libpng;
// built when libpng is found (GMM_MCL_HAVE_PNG).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

// Reads a 16-bit single-channel PNG as raw uint16 values into a kMono16Millimetres image.
// The caller rescales when the data set's unit is not millimetres. Throws std::runtime_error
// naming the file and the fault.
DepthImage loadDepthPng16(const std::string& path);

// Writes a kMono16Millimetres image as a 16-bit PNG; throws std::runtime_error on failure.
void saveDepthPng16(const DepthImage& image, const std::string& path);

// 16-bit grey PNG in memory -> row-major values. Throws std::runtime_error with the fault: not a
// PNG, not 16-bit grey, truncated or corrupt, or a size that `size` compressed bytes cannot hold
// (deflate expands at most 1032:1), which would otherwise allocate up to 2 TB.
void decodePng16(const uint8_t* data, size_t size, int* width, int* height,
                 std::vector<uint16_t>* values);
// Row-major values -> 16-bit grey PNG appended to *out (zlib level 1); throws on failure.
void encodePng16(int width, int height, const std::vector<uint16_t>& values,
                 std::vector<uint8_t>* out);

// compressed_depth_image_transport's format ("16UC1; compressedDepth[ png]" or "32FC1; ..."): a
// 12-byte header (int32 format, float depth quantisation A, B) then a 16-bit grey PNG of the raw
// millimetres (16UC1) or of the quantised inverse depth (32FC1: z = A / (q - B), q = 0 none).
// ROS-free: the nodelet's conversion (ros_conv::depthImageFromCompressedDepth) calls these.
// False with *error saying why.
bool decodeCompressedDepth(const std::string& format, const uint8_t* data, size_t size,
                           DepthImage* out, std::string* error);
// The inverse, with the transport's default quantisation (depth_quantization 100, depth_max
// 10 m) for 32FC1.
bool encodeCompressedDepth(const DepthImage& image, std::string* format, std::vector<uint8_t>* data,
                           std::string* error);

}  // namespace gmm_mcl
