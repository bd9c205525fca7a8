#include "gmm_mcl/camera/depth_image.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace gmm_mcl {

bool parseDepthEncoding(const std::string& encoding, DepthEncoding* out) {
  if (encoding == "16UC1" || encoding == "mono16") {
    *out = DepthEncoding::kMono16Millimetres;
    return true;
  }
  if (encoding == "32FC1") {
    *out = DepthEncoding::kFloat32Metres;
    return true;
  }
  return false;
}

const char* depthEncodingName(DepthEncoding encoding) {
  return encoding == DepthEncoding::kMono16Millimetres ? "16UC1" : "32FC1";
}

DepthImage DepthImage::fromMillimetres(int width, int height, const std::vector<uint16_t>& mm) {
  DepthImage img;
  img.width_px = width;
  img.height_px = height;
  img.encoding = DepthEncoding::kMono16Millimetres;
  img.row_bytes = static_cast<size_t>(width) * 2;
  img.data.resize(mm.size() * 2);
  for (size_t i = 0; i < mm.size(); ++i) {
    img.data[2 * i] = static_cast<uint8_t>(mm[i] & 0xFF);
    img.data[2 * i + 1] = static_cast<uint8_t>(mm[i] >> 8);
  }
  return img;
}

DepthImage DepthImage::fromMetres(int width, int height, const std::vector<float>& m) {
  DepthImage img;
  img.width_px = width;
  img.height_px = height;
  img.encoding = DepthEncoding::kFloat32Metres;
  img.row_bytes = static_cast<size_t>(width) * 4;
  img.data.resize(m.size() * 4);
  if (!m.empty()) std::memcpy(img.data.data(), m.data(), img.data.size());
  return img;
}

float DepthImage::depthMetres(int u, int v) const {
  const uint8_t* row = data.data() + static_cast<size_t>(v) * row_bytes;
  if (encoding == DepthEncoding::kMono16Millimetres) {
    const uint16_t mm = static_cast<uint16_t>(row[2 * u] | (row[2 * u + 1] << 8));
    if (mm == 0 || mm == 65535) return std::numeric_limits<float>::quiet_NaN();
    return 0.001f * static_cast<float>(mm);
  }
  float d;
  std::memcpy(&d, row + 4 * static_cast<size_t>(u), 4);
  if (!std::isfinite(d) || d <= 0.f) return std::numeric_limits<float>::quiet_NaN();
  return d;
}

std::string DepthImage::checkLayout() const {
  std::ostringstream err;
  const size_t bytes_per_px = encoding == DepthEncoding::kMono16Millimetres ? 2 : 4;
  if (width_px <= 0 || height_px <= 0) {
    err << "image size " << width_px << "x" << height_px << " is empty";
  } else if (row_bytes < bytes_per_px * static_cast<size_t>(width_px)) {
    err << "row step " << row_bytes << " bytes is shorter than " << width_px << " pixels of "
        << depthEncodingName(encoding);
  } else if (data.size() < row_bytes * static_cast<size_t>(height_px)) {
    err << "data holds " << data.size() << " bytes, expected " << row_bytes * height_px
        << " for " << height_px << " rows of " << row_bytes << " bytes";
  }
  return err.str();
}

Intrinsics makeIntrinsics(const double K[9], int width_px, int height_px) {
  for (int i = 0; i < 9; ++i) {
    if (!std::isfinite(K[i])) throw std::invalid_argument("camera matrix K has a NaN or Inf entry");
  }
  if (!(K[0] > 0.0) || !(K[4] > 0.0)) {
    std::ostringstream msg;
    msg << "camera matrix K has non-positive focal length (fx=" << K[0] << ", fy=" << K[4]
        << "): uncalibrated camera";
    throw std::invalid_argument(msg.str());
  }
  if (width_px <= 0 || height_px <= 0) {
    std::ostringstream msg;
    msg << "camera image size " << width_px << "x" << height_px << " is empty";
    throw std::invalid_argument(msg.str());
  }
  Intrinsics in;
  in.fx_px = static_cast<float>(K[0]);
  in.fy_px = static_cast<float>(K[4]);
  in.cx_px = static_cast<float>(K[2]);
  in.cy_px = static_cast<float>(K[5]);
  in.width_px = width_px;
  in.height_px = height_px;
  return in;
}

}  // namespace gmm_mcl
