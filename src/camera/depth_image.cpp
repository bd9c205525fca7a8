#include "gmm_mcl/camera/depth_image.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "gmm_mcl/common/enum_names.h"

namespace gmm_mcl {

namespace {

// Names as sensor_msgs/Image writes them; the first of a value is its name.
const EnumName<DepthEncoding> kEncodingNames[] = {{"16UC1", DepthEncoding::kMono16Millimetres},
                                                  {"mono16", DepthEncoding::kMono16Millimetres},
                                                  {"32FC1", DepthEncoding::kFloat32Metres}};

}  // namespace

bool parseDepthEncoding(const std::string& encoding, DepthEncoding* out) {
  return parseEnumName(encoding, kEncodingNames, out);
}

const char* depthEncodingName(DepthEncoding encoding) {
  return enumNameOf(encoding, kEncodingNames);
}

namespace {

// An image of `values` depths of bytes_per_value bytes each, rows of `width` values, zeroed.
DepthImage blankImage(int width, int height, DepthEncoding encoding, size_t bytes_per_value,
                      size_t values) {
  DepthImage img;
  img.width_px = width;
  img.height_px = height;
  img.encoding = encoding;
  img.row_bytes = static_cast<size_t>(width) * bytes_per_value;
  img.data.resize(values * bytes_per_value);
  return img;
}

}  // namespace

DepthImage DepthImage::fromMillimetres(int width, int height, const std::vector<uint16_t>& mm) {
  DepthImage img = blankImage(width, height, DepthEncoding::kMono16Millimetres, 2, mm.size());
  for (size_t i = 0; i < mm.size(); ++i) {
    img.data[2 * i] = static_cast<uint8_t>(mm[i] & 0xFF);
    img.data[2 * i + 1] = static_cast<uint8_t>(mm[i] >> 8);
  }
  return img;
}

DepthImage DepthImage::fromMetres(int width, int height, const std::vector<float>& m) {
  DepthImage img = blankImage(width, height, DepthEncoding::kFloat32Metres, 4, m.size());
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
    err << "data holds " << data.size() << " bytes, expected " << row_bytes * height_px << " for "
        << height_px << " rows of " << row_bytes << " bytes";
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
  // Checked in double before the float conversion: a positive 1e-300 would become fx = 0, a
  // 1e300 does not fit a float at all.
  if (K[0] < kMinFocalLengthPx || K[4] < kMinFocalLengthPx || K[0] > kMaxIntrinsicsPx ||
      K[4] > kMaxIntrinsicsPx || std::abs(K[2]) > kMaxIntrinsicsPx ||
      std::abs(K[5]) > kMaxIntrinsicsPx) {
    std::ostringstream msg;
    msg << "camera matrix K is out of range (fx=" << K[0] << ", fy=" << K[4] << ", cx=" << K[2]
        << ", cy=" << K[5] << "; focal lengths must lie in [" << kMinFocalLengthPx << ", "
        << kMaxIntrinsicsPx << "] px, the principal point within " << kMaxIntrinsicsPx << " px)";
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

bool depthImageFromBuffer(const std::string& encoding, uint32_t width, uint32_t height,
                          uint32_t step, bool big_endian, const uint8_t* data, size_t size,
                          DepthImage* out, std::string* error) {
  DepthEncoding enc;
  if (!parseDepthEncoding(encoding, &enc)) {
    *error = "unsupported depth encoding '" + encoding + "' (expected 16UC1, mono16 or 32FC1)";
    return false;
  }
  const size_t sample = enc == DepthEncoding::kMono16Millimetres ? 2 : 4;
  if (width == 0 || height == 0) {
    *error = "empty depth image (" + std::to_string(width) + "x" + std::to_string(height) + ")";
    return false;
  }
  if (step < width * sample) {
    std::ostringstream s;
    s << "depth image step " << step << " is shorter than width " << width << " x " << sample
      << " bytes";
    *error = s.str();
    return false;
  }
  const size_t bytes = static_cast<size_t>(step) * height;
  if (size < bytes) {
    std::ostringstream s;
    s << "depth image data has " << size << " bytes, step x height = " << bytes;
    *error = s.str();
    return false;
  }
  if (width > static_cast<uint32_t>(std::numeric_limits<int>::max()) ||
      height > static_cast<uint32_t>(std::numeric_limits<int>::max())) {
    *error = "depth image size " + std::to_string(width) + "x" + std::to_string(height) +
             " is too large";
    return false;
  }
  out->width_px = static_cast<int>(width);
  out->height_px = static_cast<int>(height);
  out->encoding = enc;
  out->row_bytes = step;
  out->data.assign(data, data + bytes);
  // The core reads little-endian samples; swap when the message's order differs.
  if (big_endian) {
    for (size_t r = 0; r < height; ++r) {
      uint8_t* row = out->data.data() + r * step;
      for (size_t c = 0; c < width; ++c) {
        uint8_t* s = row + c * sample;
        for (size_t k = 0; k < sample / 2; ++k) std::swap(s[k], s[sample - 1 - k]);
      }
    }
  }
  const std::string layout = out->checkLayout();
  if (!layout.empty()) {
    *error = layout;
    return false;
  }
  return true;
}

bool intrinsicsFromCameraMatrix(const double K[9], uint32_t width, uint32_t height,
                                int expected_width, int expected_height, Intrinsics* out,
                                std::string* error) {
  bool all_zero = true;
  for (int i = 0; i < 9; ++i) all_zero = all_zero && K[i] == 0.0;
  if (all_zero) {
    *error = "CameraInfo is uncalibrated (K is all zero)";
    return false;
  }
  if (expected_width > 0 && expected_height > 0 &&
      (width != static_cast<uint32_t>(expected_width) ||
       height != static_cast<uint32_t>(expected_height))) {
    std::ostringstream s;
    s << "depth image is " << expected_width << "x" << expected_height << " but CameraInfo says "
      << width << "x" << height;
    *error = s.str();
    return false;
  }
  const uint32_t int_max = static_cast<uint32_t>(std::numeric_limits<int>::max());
  try {
    // A size beyond int is reported as the empty size it would wrap to.
    *out = makeIntrinsics(K, width > int_max ? -1 : static_cast<int>(width),
                          height > int_max ? -1 : static_cast<int>(height));
  } catch (const std::exception& e) {
    *error = std::string("CameraInfo: ") + e.what();
    return false;
  }
  return true;
}

bool depthImageFromCloudBuffer(const CloudLayout& layout, const uint8_t* data, size_t size,
                               DepthImage* out, Intrinsics* K, std::string* error) {
  if (layout.height <= 1 || layout.width == 0) {
    *error = "point cloud is not organized (height " + std::to_string(layout.height) + ")";
    return false;
  }
  if (layout.x_offset < 0 || layout.y_offset < 0 || layout.z_offset < 0) {
    *error = "point cloud lacks float32 x, y, z fields";
    return false;
  }
  if (layout.big_endian) {
    *error = "big-endian point clouds are not supported";
    return false;
  }
  // 64-bit products: width x point_step can exceed 32 bits.
  if (layout.point_step < 12 || layout.row_step < uint64_t{layout.width} * layout.point_step ||
      size < uint64_t{layout.row_step} * layout.height) {
    *error = "point cloud data is shorter than its declared layout";
    return false;
  }
  const int offsets[3] = {layout.x_offset, layout.y_offset, layout.z_offset};
  for (int k = 0; k < 3; ++k) {
    if (static_cast<uint64_t>(offsets[k]) + 4 > layout.point_step) {
      std::ostringstream s;
      s << "point cloud field "
        << "xyz"[k] << " at byte " << offsets[k] << " does not fit the " << layout.point_step
        << "-byte point";
      *error = s.str();
      return false;
    }
  }
  if (layout.width > static_cast<uint32_t>(std::numeric_limits<int>::max()) ||
      layout.height > static_cast<uint32_t>(std::numeric_limits<int>::max())) {
    *error = "point cloud size is too large";
    return false;
  }
  const int w = static_cast<int>(layout.width), h = static_cast<int>(layout.height);
  std::vector<float> depth(static_cast<size_t>(w) * h, std::numeric_limits<float>::quiet_NaN());
  // Normal equations for (fx, cx) from u = fx a + cx with a = x / z, and (fy, cy) likewise.
  double su[5] = {0, 0, 0, 0, 0}, sv[5] = {0, 0, 0, 0, 0};  // n, sum a, sum a^2, sum u, sum a u
  for (int v = 0; v < h; ++v) {
    const uint8_t* row = data + static_cast<size_t>(v) * layout.row_step;
    for (int u = 0; u < w; ++u) {
      const uint8_t* p = row + static_cast<size_t>(u) * layout.point_step;
      float x, y, z;
      std::memcpy(&x, p + layout.x_offset, 4);
      std::memcpy(&y, p + layout.y_offset, 4);
      std::memcpy(&z, p + layout.z_offset, 4);
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) || z <= 0.f) continue;
      depth[static_cast<size_t>(v) * w + u] = z;
      const double a = x / z, b = y / z;
      su[0] += 1;
      su[1] += a;
      su[2] += a * a;
      su[3] += u;
      su[4] += a * u;
      sv[0] += 1;
      sv[1] += b;
      sv[2] += b * b;
      sv[3] += v;
      sv[4] += b * v;
    }
  }
  auto fit = [](const double* s, double* f, double* c) {
    const double det = s[0] * s[2] - s[1] * s[1];
    if (!(std::abs(det) > 1e-12)) return false;
    *f = (s[0] * s[4] - s[1] * s[3]) / det;
    *c = (s[3] - *f * s[1]) / s[0];
    return std::isfinite(*f) && *f > 0.0 && std::isfinite(*c);
  };
  double fx, cx, fy, cy;
  if (su[0] < 16 || !fit(su, &fx, &cx) || !fit(sv, &fy, &cy)) {
    *error = "point cloud has too few valid points to recover the camera intrinsics";
    return false;
  }
  // The fitted values go through makeIntrinsics' checks: a degenerate cloud (points at 1e-38 m
  // and 1e38 m) fits focal lengths that no float holds.
  const double Kfit[9] = {fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0};
  try {
    *K = makeIntrinsics(Kfit, w, h);
  } catch (const std::exception& e) {
    *error = std::string("point cloud intrinsics: ") + e.what();
    return false;
  }
  *out = DepthImage::fromMetres(w, h, depth);
  return true;
}

}  // namespace gmm_mcl
