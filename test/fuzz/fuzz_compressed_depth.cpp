// libFuzzer target: a compressedDepth message (format string and data: 12-byte header and a
// 16-bit grey PNG) as the nodelet receives it, decoded by the core. Whatever decodes must be a
// consistent image that survives an encode/decode round trip (the same pixels valid; 16UC1
// depths exact) and prepares into a frame; whatever is rejected must say why.
#include <cmath>
#include <string>
#include <vector>

#include "fuzz_input.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/camera/png_io.h"
#include "gmm_mcl/map/gmm_map_io.h"  // crc32: PNG chunks use the same CRC-32

namespace gmm_mcl {
namespace {

std::string formatFrom(fuzz::Reader* in) {
  return in->nameOrString({"16UC1; compressedDepth png", "32FC1; compressedDepth png",
                           "16UC1; compressedDepth", "mono16; compressedDepth",
                           "32FC1; compressedDepth rvl", "16UC1", "8UC1; compressedDepth png"},
                          40);
}

}  // namespace
}  // namespace gmm_mcl

#ifdef GMM_MCL_LIBFUZZER
// Mutated PNG chunks nearly always fail libpng's CRC check. After half of the mutations, repair
// the CRC of every complete chunk (big-endian length, type, data, CRC over type and data).
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size,
                                          unsigned int seed) {
  using namespace gmm_mcl;
  return fuzz::mutateAndRepair(data, size, max_size, seed, [](uint8_t* data, size_t size) {
    fuzz::Reader in(data, size);
    formatFrom(&in);
    size_t pos = static_cast<size_t>(in.rest() - data) + 12 + 8;  // header, PNG signature
    while (pos + 12 <= size) {
      const uint32_t len = (uint32_t{data[pos]} << 24) | (uint32_t{data[pos + 1]} << 16) |
                           (uint32_t{data[pos + 2]} << 8) | uint32_t{data[pos + 3]};
      if (len > size - pos - 12) break;
      const uint32_t crc = gmm_mcl::crc32(data + pos + 4, 4 + len);
      for (int k = 0; k < 4; ++k) {
        data[pos + 8 + len + k] = static_cast<uint8_t>(crc >> (24 - 8 * k));
      }
      pos += 12 + len;
    }
  });
}
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace gmm_mcl;
  fuzz::Reader in(data, size);
  const std::string format = formatFrom(&in);
  DepthImage image;
  std::string error;
  if (!decodeCompressedDepth(format, in.rest(), in.restSize(), &image, &error)) {
    FUZZ_CHECK(!error.empty());
    return 0;
  }
  FUZZ_CHECK(image.checkLayout().empty());
  FUZZ_CHECK(image.data.size() == image.row_bytes * static_cast<size_t>(image.height_px));
  const bool is16 = image.encoding == DepthEncoding::kMono16Millimetres;
  FUZZ_CHECK(is16 == (format.compare(0, 5, "32FC1") != 0));

  std::string again_format;
  std::vector<uint8_t> again_data;
  FUZZ_CHECK(encodeCompressedDepth(image, &again_format, &again_data, &error));
  DepthImage again;
  FUZZ_CHECK(
      decodeCompressedDepth(again_format, again_data.data(), again_data.size(), &again, &error));
  FUZZ_CHECK(again.width_px == image.width_px && again.height_px == image.height_px);
  FUZZ_CHECK(again.encoding == image.encoding);
  for (int v = 0; v < image.height_px; ++v) {
    for (int u = 0; u < image.width_px; ++u) {
      const float a = image.depthMetres(u, v), b = again.depthMetres(u, v);
      FUZZ_CHECK(std::isnan(a) == std::isnan(b));
      if (is16 && !std::isnan(a)) FUZZ_CHECK(a == b);
    }
  }

  // A camera that matches the decoded size: the frame builds.
  const double K[9] = {525.0, 0.0, 0.5 * image.width_px, 0.0, 525.0, 0.5 * image.height_px, 0.0,
                       0.0,   1.0};
  const Intrinsics intrinsics = makeIntrinsics(K, image.width_px, image.height_px);
  FrameParams params;
  params.pixel_stride = 1;
  params.patch_size_px = 8;
  const DepthFrame frame = prepareFrame(image, intrinsics, params);
  FUZZ_CHECK(frame.total_pixels_sampled == image.width_px * image.height_px);
  return 0;
}
