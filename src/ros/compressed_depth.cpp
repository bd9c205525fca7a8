// compressedDepth (compressed_depth_image_transport's PNG format) <-> DepthImage. The transport
// plugin is not packaged for Debian; the nodelet decodes the format itself, with the ROS-free
// core functions in gmm_mcl/camera/png_io.h (fuzzed in test/fuzz).
#include "gmm_mcl/ros/conversions.h"

#ifdef GMM_MCL_HAVE_PNG
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace ros_conv {

#ifdef GMM_MCL_HAVE_PNG

bool depthImageFromCompressedDepth(const sensor_msgs::CompressedImage& msg, DepthImage* out,
                                   std::string* error) {
  return decodeCompressedDepth(msg.format, msg.data.data(), msg.data.size(), out, error);
}

bool compressedDepthFromImage(const DepthImage& image, sensor_msgs::CompressedImage* out,
                              std::string* error) {
  return encodeCompressedDepth(image, &out->format, &out->data, error);
}

#else  // a build without libpng: both directions say so

namespace {

bool withoutPng(std::string* error) {
  *error = "compressedDepth needs libpng, which this build lacks";
  return false;
}

}  // namespace

bool depthImageFromCompressedDepth(const sensor_msgs::CompressedImage&, DepthImage*,
                                   std::string* error) {
  return withoutPng(error);
}

bool compressedDepthFromImage(const DepthImage&, sensor_msgs::CompressedImage*,
                              std::string* error) {
  return withoutPng(error);
}

#endif

}  // namespace ros_conv
}  // namespace gmm_mcl
