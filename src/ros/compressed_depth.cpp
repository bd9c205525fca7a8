// compressedDepth (compressed_depth_image_transport's PNG format) <-> DepthImage, via libpng in
// memory. The transport plugin is not packaged for Debian; the nodelet decodes it itself.
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "gmm_mcl/ros/conversions.h"

#ifdef GMM_MCL_HAVE_PNG
#include <png.h>
#endif

namespace gmm_mcl {
namespace ros_conv {
namespace {

constexpr size_t kHeaderBytes = 12;  // int32 format, float depthParam[2]

#ifdef GMM_MCL_HAVE_PNG
struct ReadState {
  const uint8_t* data;
  size_t size;
  size_t pos;
};

void readFn(png_structp png, png_bytep out, png_size_t n) {
  ReadState* s = static_cast<ReadState*>(png_get_io_ptr(png));
  if (s->pos + n > s->size) png_error(png, "truncated PNG");
  std::memcpy(out, s->data + s->pos, n);
  s->pos += n;
}

void writeFn(png_structp png, png_bytep in, png_size_t n) {
  std::vector<uint8_t>* v = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
  v->insert(v->end(), in, in + n);
}

void errorFn(png_structp, png_const_charp msg) { throw std::runtime_error(msg); }
void warningFn(png_structp, png_const_charp) {}

// 16-bit grey PNG in memory -> values (row-major); throws with the fault.
void decodePng16(const uint8_t* data, size_t size, int* w, int* h, std::vector<uint16_t>* v) {
  if (size < 8 || png_sig_cmp(data, 0, 8) != 0) throw std::runtime_error("payload is not a PNG");
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, errorFn, warningFn);
  png_infop info = png_create_info_struct(png);
  try {
    ReadState st{data, size, 0};
    png_set_read_fn(png, &st, readFn);
    png_read_info(png, info);
    const int bit_depth = png_get_bit_depth(png, info);
    const int colour = png_get_color_type(png, info);
    if (bit_depth != 16 || colour != PNG_COLOR_TYPE_GRAY) {
      throw std::runtime_error("PNG is not 16-bit grey");
    }
    png_set_swap(png);  // PNG is big-endian; host order (little-endian) afterwards
    *w = static_cast<int>(png_get_image_width(png, info));
    *h = static_cast<int>(png_get_image_height(png, info));
    v->assign(static_cast<size_t>(*w) * *h, 0);
    std::vector<png_bytep> rows(*h);
    for (int r = 0; r < *h; ++r) rows[r] = reinterpret_cast<png_bytep>(v->data() + static_cast<size_t>(r) * *w);
    png_read_image(png, rows.data());
    png_destroy_read_struct(&png, &info, nullptr);
  } catch (...) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw;
  }
}

void encodePng16(int w, int h, const std::vector<uint16_t>& v, std::vector<uint8_t>* out) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, errorFn, warningFn);
  png_infop info = png_create_info_struct(png);
  try {
    png_set_write_fn(png, out, writeFn, nullptr);
    png_set_IHDR(png, info, w, h, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 1);
    png_write_info(png, info);
    png_set_swap(png);
    std::vector<uint16_t> copy(v);
    for (int r = 0; r < h; ++r) png_write_row(png, reinterpret_cast<png_bytep>(copy.data() + static_cast<size_t>(r) * w));
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
  } catch (...) {
    png_destroy_write_struct(&png, &info);
    throw;
  }
}
#endif

}  // namespace

bool depthImageFromCompressedDepth(const sensor_msgs::CompressedImage& msg, DepthImage* out,
                                   std::string* error) {
#ifndef GMM_MCL_HAVE_PNG
  (void)msg;
  (void)out;
  *error = "compressedDepth needs libpng, which this build lacks";
  return false;
#else
  const std::string& f = msg.format;
  const bool is16 = f.compare(0, 5, "16UC1") == 0 || f.compare(0, 6, "mono16") == 0;
  const bool is32 = f.compare(0, 5, "32FC1") == 0;
  if ((!is16 && !is32) || f.find("compressedDepth") == std::string::npos) {
    *error = "unsupported compressed depth format '" + f + "' (expected 16UC1 or 32FC1 compressedDepth)";
    return false;
  }
  if (f.find("rvl") != std::string::npos) {
    *error = "compressedDepth rvl is not supported (png only)";
    return false;
  }
  if (msg.data.size() <= kHeaderBytes) {
    *error = "compressedDepth message shorter than its header";
    return false;
  }
  float quant[2];
  std::memcpy(quant, msg.data.data() + 4, 8);
  int w = 0, h = 0;
  std::vector<uint16_t> v;
  try {
    decodePng16(msg.data.data() + kHeaderBytes, msg.data.size() - kHeaderBytes, &w, &h, &v);
  } catch (const std::exception& e) {
    *error = std::string("compressedDepth: ") + e.what();
    return false;
  }
  if (is16) {
    *out = DepthImage::fromMillimetres(w, h, v);
    return true;
  }
  if (!(std::isfinite(quant[0]) && std::isfinite(quant[1]))) {
    *error = "compressedDepth: non-finite depth quantisation parameters";
    return false;
  }
  std::vector<float> m(v.size(), std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] != 0) m[i] = quant[0] / (static_cast<float>(v[i]) - quant[1]);
  }
  *out = DepthImage::fromMetres(w, h, m);
  return true;
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
  const std::string layout = image.checkLayout();
  if (!layout.empty()) {
    *error = layout;
    return false;
  }
  const int w = image.width_px, h = image.height_px;
  std::vector<uint16_t> v(static_cast<size_t>(w) * h, 0);
  // Inverse-depth quantisation as compressed_depth_image_transport does it, with its defaults
  // (depth_quantization 100, depth_max 10 m): q = A / z + B.
  const float quant_a = 100.f * (100.f + 1.f) / 2.f, quant_b = 1.f - quant_a / 10.f;
  float quant[2] = {0.f, 0.f};
  const bool is16 = image.encoding == DepthEncoding::kMono16Millimetres;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const float z = image.depthMetres(c, r);
      if (!(std::isfinite(z) && z > 0.f)) continue;
      if (is16) {
        v[static_cast<size_t>(r) * w + c] = static_cast<uint16_t>(std::lround(z * 1000.f));
      } else {
        const float q = quant_a / z + quant_b;
        v[static_cast<size_t>(r) * w + c] = static_cast<uint16_t>(std::min(65535.f, std::max(1.f, std::round(q))));
      }
    }
  }
  if (!is16) {
    quant[0] = quant_a;
    quant[1] = quant_b;
  }
  out->format = is16 ? "16UC1; compressedDepth png" : "32FC1; compressedDepth png";
  out->data.assign(kHeaderBytes, 0);
  std::memcpy(out->data.data() + 4, quant, 8);
  try {
    std::vector<uint8_t> png;
    encodePng16(w, h, v, &png);
    out->data.insert(out->data.end(), png.begin(), png.end());
  } catch (const std::exception& e) {
    *error = std::string("compressedDepth: ") + e.what();
    return false;
  }
  return true;
#endif
}

}  // namespace ros_conv
}  // namespace gmm_mcl
