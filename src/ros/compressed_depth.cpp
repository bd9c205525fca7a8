// compressedDepth (compressed_depth_image_transport's PNG format) <-> DepthImage. The transport
// plugin is not packaged for Debian; the nodelet decodes the format itself, with the ROS-free
// core functions in gmm_mcl/camera/png_io.h (fuzzed in test/fuzz).
#include "gmm_mcl/ros/conversions.h"

#ifdef GMM_MCL_HAVE_PNG
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace ros_conv {

bool depthImageFromCompressedDepth(const sensor_msgs::CompressedImage& msg, DepthImage* out,
                                   std::string* error) {
#ifndef GMM_MCL_HAVE_PNG
  (void)msg;
  (void)out;
  *error = "compressedDepth needs libpng, which this build lacks";
  return false;
#else
  return decodeCompressedDepth(msg.format, msg.data.data(), msg.data.size(), out, error);
#endif
}

bool compressedDepthFromImage(const DepthImage& image, sensor_msgs::CompressedImage* out,
                              std::string* error) {
#ifndef GMM_MCL_HAVE_PNG
  (void)image;
  (void)out;
  *error = "compressedDepth needs libpng, which this build lacks";
  return false;
#else
  return encodeCompressedDepth(image, &out->format, &out->data, error);
#endif
}

}  // namespace ros_conv
}  // namespace gmm_mcl
