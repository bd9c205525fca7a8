#include "gmm_mcl/camera/png_io.h"

#include <png.h>

#include <cstdio>
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

}  // namespace gmm_mcl
