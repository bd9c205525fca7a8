// The fault the fuzzing found in the map loader, as a named case with its message (the
// fuzz_replay_map_loader test replays the raw reproducers; this says what the fix promises).
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace {

TEST(MapInputValidationTest, NearlySingularCovarianceIsRejectedByTheLoader) {
  std::vector<GaussianComponent> comps(1);
  comps[0].weight = 1.0;
  comps[0].cov_m2 = Eigen::Matrix3d::Identity();
  std::vector<uint8_t> bytes = encodeMap(GmmMap(comps));
  // Denormal float variances: positive-definite, but the inverse (1e39) exceeds float32.
  const float tiny = 1e-39f;
  const size_t cov = kMapHeaderBytes + 16;
  for (size_t k : {size_t{0}, size_t{3}, size_t{5}}) std::memcpy(&bytes[cov + 4 * k], &tiny, 4);
  const uint32_t crc = crc32(bytes.data(), bytes.size() - 4);
  for (int k = 0; k < 4; ++k) bytes[bytes.size() - 4 + k] = static_cast<uint8_t>(crc >> (8 * k));
  try {
    decodeMap(bytes, "tiny.gmm");
    FAIL() << "loaded";
  } catch (const MapError& e) {
    EXPECT_NE(std::string(e.what()).find("tiny.gmm: component 0: covariance is too close to "
                                         "singular"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace gmm_mcl
