// libFuzzer target: arbitrary bytes as a map file (DESIGN.md "Map file"), through the stream
// reader that loadMap uses and through decodeMap. Either the bytes are rejected with a MapError
// naming the source, or they load as a map that is valid for the backends and re-encodes to the
// same bytes.
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_input.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace {

const char kSource[] = "fuzz.gmm";

bool loadsFromStream(const uint8_t* data, size_t size, std::string* error) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    gmm_mcl::readMap(in, kSource);
  } catch (const gmm_mcl::MapError& e) {
    *error = e.what();
    return false;
  }
  return true;
}

}  // namespace

#ifdef GMM_MCL_LIBFUZZER
// libFuzzer's own mutations almost never keep the CRC-32 right, so nearly every input would
// stop at the checksum. After half of the mutations, recompute it (the inputs stay plain map
// files; the other half still exercises the checksum path).
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size,
                                          unsigned int seed) {
  return gmm_mcl::fuzz::mutateAndRepair(data, size, max_size, seed, [](uint8_t* data, size_t size) {
    if (size < 4) return;
    const uint32_t crc = gmm_mcl::crc32(data, size - 4);
    for (int k = 0; k < 4; ++k) data[size - 4 + k] = static_cast<uint8_t>(crc >> (8 * k));
  });
}
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace gmm_mcl;
  const std::vector<uint8_t> bytes(data, data + size);
  std::string stream_error;
  const bool stream_ok = loadsFromStream(data, size, &stream_error);
  GmmMap map;
  try {
    map = decodeMap(bytes, kSource);
  } catch (const MapError& e) {
    // Rejected: with the source name and a fault, and the stream reader agrees.
    const std::string what = e.what(), prefix = std::string(kSource) + ": ";
    FUZZ_CHECK(what.compare(0, prefix.size(), prefix) == 0 && what.size() > prefix.size());
    FUZZ_CHECK(!stream_ok && stream_error == what);
    return 0;
  }
  FUZZ_CHECK(stream_ok);
  // Accepted: exactly the declared size, and what the backends evaluate is finite.
  FUZZ_CHECK(!map.empty());
  FUZZ_CHECK(size == kMapHeaderBytes + kMapBytesPerComponent * map.size() + 4);
  double weight_sum = 0.0;
  for (size_t i = 0; i < map.size(); ++i) {
    const ComponentF& c = map.packed()[i];
    for (int k = 0; k < 3; ++k) FUZZ_CHECK(std::isfinite(c.mean_m[k]));
    for (int k = 0; k < 6; ++k) FUZZ_CHECK(std::isfinite(c.cov_m2[k]));
    for (int k = 0; k < 6; ++k) FUZZ_CHECK(std::isfinite(c.precision[k]));
    FUZZ_CHECK(std::isfinite(c.log_norm));
    FUZZ_CHECK(map.components()[i].weight > 0.0);
    FUZZ_CHECK(map.threeSigmaHalfExtent(i).allFinite());
    weight_sum += map.components()[i].weight;
  }
  FUZZ_CHECK(std::abs(weight_sum - 1.0) <= kWeightSumTolerance);
  // Re-encoding gives the same bytes, but for the reserved word (written as 0, not checked)
  // and so the checksum.
  std::vector<uint8_t> again = encodeMap(map);
  FUZZ_CHECK(again.size() == size);
  std::vector<uint8_t> expected = bytes;
  for (size_t k = 20; k < 24; ++k) expected[k] = 0;
  const uint32_t crc = crc32(expected.data(), expected.size() - 4);
  for (int k = 0; k < 4; ++k) expected[size - 4 + k] = static_cast<uint8_t>(crc >> (8 * k));
  FUZZ_CHECK(again == expected);
  return 0;
}
