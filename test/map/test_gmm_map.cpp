#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace {

GmmMap smallMap() {
  std::vector<GaussianComponent> comps(3);
  comps[0].weight = 0.5;
  comps[0].mean_m = Eigen::Vector3d(1.0, 2.0, 3.0);
  comps[0].cov_m2 << 0.04, 0.01, 0.0, 0.01, 0.09, 0.002, 0.0, 0.002, 0.0004;
  comps[1].weight = 0.3;
  comps[1].mean_m = Eigen::Vector3d(-1.25, 0.5, 0.1);
  comps[1].cov_m2 = Eigen::Vector3d(0.01, 0.02, 0.03).asDiagonal();
  comps[2].weight = 0.2;
  comps[2].mean_m = Eigen::Vector3d(0.0, -3.0, 1.5);
  comps[2].cov_m2 = 0.25 * Eigen::Matrix3d::Identity();
  return GmmMap(comps, "test");
}

// Writes bytes with a correct checksum so that content faults are reached.
std::vector<uint8_t> resealed(std::vector<uint8_t> bytes) {
  const uint32_t crc = crc32(bytes.data(), bytes.size() - 4);
  for (int k = 0; k < 4; ++k) bytes[bytes.size() - 4 + k] = static_cast<uint8_t>(crc >> (8 * k));
  return bytes;
}

void setF32(std::vector<uint8_t>* bytes, size_t offset, float v) {
  std::memcpy(bytes->data() + offset, &v, 4);  // little-endian host
}

std::string errorOf(const std::vector<uint8_t>& bytes) {
  try {
    decodeMap(bytes, "bad.gmm");
  } catch (const MapError& e) {
    return e.what();
  }
  return "";
}

size_t weightOffset(size_t i) { return kMapHeaderBytes + 4 * i; }
size_t covOffset(size_t m, size_t i) { return kMapHeaderBytes + 16 * m + 24 * i; }

TEST(GmmMapTest, PrecomputesNormaliserAndPrecision) {
  const GmmMap map = smallMap();
  const ComponentF& c = map.packed()[1];
  // The model's weights are surface-normalised: every log-weight carries ln(A / A_ref).
  const double scale = std::log(estimateSurfaceArea(map.components()) / kReferenceSurfaceAreaM2);
  EXPECT_NEAR(map.logWeightScale(), scale, 1e-12);
  const double expected =
      std::log(0.3) + scale - 1.5 * std::log(2 * M_PI) - 0.5 * std::log(0.01 * 0.02 * 0.03);
  EXPECT_NEAR(c.log_norm, expected, 1e-5);
  EXPECT_NEAR(c.precision[0], 100.0, 1e-3);
  EXPECT_NEAR(c.precision[3], 50.0, 1e-3);
  EXPECT_NEAR(map.threeSigmaHalfExtent(2).x(), 1.5, 1e-12);
  // Density at a mean equals the sum over components evaluated exactly.
  const double p = std::exp(map.logDensity(Eigen::Vector3d(0.0, -3.0, 1.5)));
  EXPECT_NEAR(p, std::exp(scale) * 0.2 / std::pow(2 * M_PI * 0.25, 1.5), 1e-9 * std::exp(scale));
}

TEST(GmmMapTest, WriteReadRoundTripsExactly) {
  const GmmMap map = smallMap();
  const std::string path = ::testing::TempDir() + "roundtrip.gmm";
  saveMap(map, path);
  const GmmMap back = loadMap(path);
  ASSERT_EQ(back.size(), map.size());
  for (size_t i = 0; i < map.size(); ++i) {
    const auto& a = map.components()[i];
    const auto& b = back.components()[i];
    EXPECT_EQ(static_cast<float>(a.weight), b.weight);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(static_cast<float>(a.mean_m[k]), b.mean_m[k]);
    for (int k = 0; k < 9; ++k) EXPECT_EQ(static_cast<float>(a.cov_m2(k)), b.cov_m2(k));
  }
  // Second generation is byte-identical; size is 40 bytes per component plus 28.
  EXPECT_EQ(encodeMap(back), encodeMap(map));
  EXPECT_EQ(encodeMap(map).size(), kMapHeaderBytes + 4 + 40 * map.size());
  std::remove(path.c_str());
}

TEST(GmmMapTest, MissingFileNamesThePath) {
  try {
    loadMap("/nonexistent/dir/map.gmm");
    FAIL() << "no error";
  } catch (const MapError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/map.gmm"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos);
  }
}

TEST(GmmMapTest, EachFaultHasItsOwnError) {
  const std::vector<uint8_t> good = encodeMap(smallMap());
  const size_t m = 3;
  ASSERT_EQ(errorOf(good), "");

  std::vector<uint8_t> b(good.begin(), good.begin() + 10);
  EXPECT_NE(errorOf(b).find("truncated"), std::string::npos) << errorOf(b);

  b = std::vector<uint8_t>(good.begin(), good.end() - 8);
  EXPECT_NE(errorOf(b).find("truncated"), std::string::npos) << errorOf(b);

  b = good;
  b[0] = 'X';
  EXPECT_NE(errorOf(b).find("bad magic"), std::string::npos) << errorOf(b);

  b = good;
  b[8] = 7;
  EXPECT_NE(errorOf(b).find("unsupported format version 7"), std::string::npos) << errorOf(b);

  b = good;
  b[12] = 5;  // count says 5, payload holds 3
  EXPECT_NE(errorOf(b).find("header says 5 components"), std::string::npos) << errorOf(b);

  b = good;
  b[12] = 0;
  EXPECT_NE(errorOf(b).find("component count is 0"), std::string::npos) << errorOf(b);

  b = good;
  b[kMapHeaderBytes + 5] ^= 0x40;  // flip a bit, keep the stored checksum
  EXPECT_NE(errorOf(b).find("checksum mismatch"), std::string::npos) << errorOf(b);

  b = good;
  setF32(&b, kMapHeaderBytes + 4 * m + 4, std::numeric_limits<float>::quiet_NaN());
  EXPECT_NE(errorOf(resealed(b)).find("component 0: NaN or Inf"), std::string::npos)
      << errorOf(resealed(b));

  b = good;
  setF32(&b, covOffset(m, 2), std::numeric_limits<float>::infinity());
  EXPECT_NE(errorOf(resealed(b)).find("component 2: NaN or Inf"), std::string::npos);

  b = good;
  setF32(&b, weightOffset(1), 0.4f);  // sum 1.1
  EXPECT_NE(errorOf(resealed(b)).find("weights sum to 1.1"), std::string::npos)
      << errorOf(resealed(b));

  b = good;
  setF32(&b, weightOffset(2), -0.2f);
  EXPECT_NE(errorOf(resealed(b)).find("component 2: weight -0.2"), std::string::npos)
      << errorOf(resealed(b));

  b = good;
  setF32(&b, covOffset(m, 1) + 4, 1.0f);  // xy = 1 with xx = 0.01, yy = 0.02: indefinite
  EXPECT_NE(errorOf(resealed(b)).find("component 1: covariance is not positive-definite"),
            std::string::npos)
      << errorOf(resealed(b));

  b = good;
  setF32(&b, covOffset(m, 2) + 20, -0.25f);  // zz < 0
  EXPECT_NE(errorOf(resealed(b)).find("component 2: covariance is not positive-definite"),
            std::string::npos);

  // Every message names the file.
  EXPECT_EQ(errorOf(resealed(b)).rfind("bad.gmm: ", 0), 0u);
}

TEST(GmmMapTest, InMemoryComponentsAreValidatedToo) {
  std::vector<GaussianComponent> comps(1);
  comps[0].weight = 1.0;
  comps[0].cov_m2 << 1.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0;  // not symmetric
  try {
    GmmMap map(comps, "memory map");
    FAIL() << "accepted a non-symmetric covariance";
  } catch (const MapError& e) {
    EXPECT_NE(std::string(e.what()).find("memory map: component 0: covariance is not symmetric"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(GmmMap(std::vector<GaussianComponent>(), "empty"), MapError);
}

TEST(GmmMapTest, Crc32MatchesTheStandardCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(crc32(reinterpret_cast<const uint8_t*>(s), 9), 0xCBF43926u);
}

}  // namespace
}  // namespace gmm_mcl
