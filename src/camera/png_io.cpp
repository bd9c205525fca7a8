#include "gmm_mcl/camera/png_io.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

namespace gmm_mcl {
namespace {

struct FileCloser {
  void operator()(FILE* f) const {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

// compressedDepth: int32 format, float depthParam[2], then the PNG.
constexpr size_t kCompressedDepthHeaderBytes = 12;
// Deflate expands at most 1032:1 (a 258-byte match per two bits), so `size` PNG bytes hold at
// most 1032 x size bytes of pixels.
constexpr uint64_t kMaxDeflateRatio = 1032;

struct ReadState {
  const uint8_t* data;
  size_t size;
  size_t pos;
};

void readFn(png_structp png, png_bytep out, png_size_t n) {
  ReadState* s = static_cast<ReadState*>(png_get_io_ptr(png));
  if (n > s->size - s->pos) png_error(png, "truncated PNG");
  std::memcpy(out, s->data + s->pos, n);
  s->pos += n;
}

void writeFn(png_structp png, png_bytep in, png_size_t n) {
  std::vector<uint8_t>* v = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
  v->insert(v->end(), in, in + n);
}

// libpng reports errors through this callback; it must not return.
void errorFn(png_structp, png_const_charp msg) { throw std::runtime_error(msg); }
void warningFn(png_structp, png_const_charp) {}

}  // namespace

DepthImage loadDepthPng16(const std::string& path) {
  FilePtr file(std::fopen(path.c_str(), "rb"));
  if (!file) fail(path, "cannot open");
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_stdio(&img, file.get())) fail(path, img.message);
  if ((img.format & PNG_FORMAT_FLAG_COLOR) != 0 || (img.format & PNG_FORMAT_FLAG_ALPHA) != 0) {
    png_image_free(&img);
    fail(path, "not a single-channel depth PNG");
  }
  // PNG_FORMAT_LINEAR_Y keeps 16-bit samples unchanged (no gamma for 16-bit gray input).
  img.format = PNG_FORMAT_LINEAR_Y;
  std::vector<uint16_t> raw(PNG_IMAGE_SIZE(img) / 2);
  if (!png_image_finish_read(&img, nullptr, raw.data(), 0, nullptr)) fail(path, img.message);
  return DepthImage::fromMillimetres(static_cast<int>(img.width), static_cast<int>(img.height),
                                     raw);
}

void saveDepthPng16(const DepthImage& image, const std::string& path) {
  if (image.encoding != DepthEncoding::kMono16Millimetres) fail(path, "image is not 16UC1");
  const std::string err = image.checkLayout();
  if (!err.empty()) fail(path, err);
  std::vector<uint16_t> raw(static_cast<size_t>(image.width_px) * image.height_px);
  for (int v = 0; v < image.height_px; ++v) {
    const uint8_t* row = image.data.data() + static_cast<size_t>(v) * image.row_bytes;
    for (int u = 0; u < image.width_px; ++u) {
      raw[static_cast<size_t>(v) * image.width_px + u] =
          static_cast<uint16_t>(row[2 * u] | (row[2 * u + 1] << 8));
    }
  }
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  img.width = static_cast<png_uint_32>(image.width_px);
  img.height = static_cast<png_uint_32>(image.height_px);
  img.format = PNG_FORMAT_LINEAR_Y;
  if (!png_image_write_to_file(&img, path.c_str(), 0, raw.data(), 0, nullptr)) {
    fail(path, img.message);
  }
}

void decodePng16(const uint8_t* data, size_t size, int* width, int* height,
                 std::vector<uint16_t>* values) {
  if (size < 8 || png_sig_cmp(data, 0, 8) != 0) throw std::runtime_error("payload is not a PNG");
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, errorFn, warningFn);
  png_infop info = png_create_info_struct(png);
  try {
    if (png == nullptr || info == nullptr) throw std::runtime_error("out of memory");
    ReadState st{data, size, 0};
    png_set_read_fn(png, &st, readFn);
    png_read_info(png, info);
    const int bit_depth = png_get_bit_depth(png, info);
    const int colour = png_get_color_type(png, info);
    if (bit_depth != 16 || colour != PNG_COLOR_TYPE_GRAY) {
      throw std::runtime_error("PNG is not 16-bit grey");
    }
    // libpng limits each side to 10^6 pixels; the compressed size limits the product.
    const png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
    if (uint64_t{w} * h * 2 > kMaxDeflateRatio * size) {
      throw std::runtime_error("PNG claims " + std::to_string(w) + "x" + std::to_string(h) +
                               " pixels, more than its " + std::to_string(size) +
                               " bytes can hold");
    }
    png_set_swap(png);  // PNG is big-endian; host order (little-endian) afterwards
    *width = static_cast<int>(w);
    *height = static_cast<int>(h);
    values->assign(static_cast<size_t>(w) * h, 0);
    std::vector<png_bytep> rows(h);
    for (png_uint_32 r = 0; r < h; ++r) {
      rows[r] = reinterpret_cast<png_bytep>(values->data() + static_cast<size_t>(r) * w);
    }
    png_read_image(png, rows.data());
    png_destroy_read_struct(&png, &info, nullptr);
  } catch (...) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw;
  }
}

void encodePng16(int width, int height, const std::vector<uint16_t>& values,
                 std::vector<uint8_t>* out) {
  if (width <= 0 || height <= 0 || values.size() != static_cast<size_t>(width) * height) {
    throw std::runtime_error("encodePng16: " + std::to_string(values.size()) + " values for a " +
                             std::to_string(width) + "x" + std::to_string(height) + " image");
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, errorFn, warningFn);
  png_infop info = png_create_info_struct(png);
  try {
    if (png == nullptr || info == nullptr) throw std::runtime_error("out of memory");
    png_set_write_fn(png, out, writeFn, nullptr);
    png_set_IHDR(png, info, width, height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 1);
    png_write_info(png, info);
    png_set_swap(png);
    std::vector<uint16_t> row(static_cast<size_t>(width));
    for (int r = 0; r < height; ++r) {
      // png_write_row does not modify its input, but takes a non-const pointer.
      std::memcpy(row.data(), values.data() + static_cast<size_t>(r) * width, 2 * row.size());
      png_write_row(png, reinterpret_cast<png_bytep>(row.data()));
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
  } catch (...) {
    png_destroy_write_struct(&png, &info);
    throw;
  }
}

bool decodeCompressedDepth(const std::string& format, const uint8_t* data, size_t size,
                           DepthImage* out, std::string* error) {
  const std::string& f = format;
  const bool is16 = f.compare(0, 5, "16UC1") == 0 || f.compare(0, 6, "mono16") == 0;
  const bool is32 = f.compare(0, 5, "32FC1") == 0;
  if ((!is16 && !is32) || f.find("compressedDepth") == std::string::npos) {
    *error =
        "unsupported compressed depth format '" + f + "' (expected 16UC1 or 32FC1 compressedDepth)";
    return false;
  }
  if (f.find("rvl") != std::string::npos) {
    *error = "compressedDepth rvl is not supported (png only)";
    return false;
  }
  if (size <= kCompressedDepthHeaderBytes) {
    *error = "compressedDepth message shorter than its header";
    return false;
  }
  float quant[2];
  std::memcpy(quant, data + 4, 8);
  int w = 0, h = 0;
  std::vector<uint16_t> v;
  try {
    decodePng16(data + kCompressedDepthHeaderBytes, size - kCompressedDepthHeaderBytes, &w, &h, &v);
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
}

bool encodeCompressedDepth(const DepthImage& image, std::string* format, std::vector<uint8_t>* data,
                           std::string* error) {
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
      uint16_t& q = v[static_cast<size_t>(r) * w + c];
      if (is16) {
        // 16UC1 samples are millimetres already: 65.534 m at most.
        q = static_cast<uint16_t>(std::lround(z * 1000.f));
      } else {
        q = static_cast<uint16_t>(
            std::min(65535.f, std::max(1.f, std::round(quant_a / z + quant_b))));
      }
    }
  }
  if (!is16) {
    quant[0] = quant_a;
    quant[1] = quant_b;
  }
  *format = is16 ? "16UC1; compressedDepth png" : "32FC1; compressedDepth png";
  data->assign(kCompressedDepthHeaderBytes, 0);
  std::memcpy(data->data() + 4, quant, 8);
  try {
    encodePng16(w, h, v, data);
  } catch (const std::exception& e) {
    *error = std::string("compressedDepth: ") + e.what();
    return false;
  }
  return true;
}

}  // namespace gmm_mcl
